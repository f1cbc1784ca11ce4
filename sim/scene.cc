#include "sim/scene.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <set>

#include <embree3/rtcore.h>
#include <yaml-cpp/yaml.h>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/option_check.h"

namespace lisfm {
namespace sim {

bool SceneOptions::Check() const {
  CHECK_OPTION_MSG(type, type == "office" || type == "staircase" || type == "hall",
                   "one of office, staircase, hall");
  CHECK_OPTION_MSG(length, length >= 10.0 && length <= 1000.0, "in [10, 1000] m");
  // The staircase is a narrow shaft (two 1.3 m flights); rooms need 6 m.
  CHECK_OPTION_MSG(width, width >= (type == "staircase" ? 2.0 : 6.0) && width <= 1000.0,
                   type == "staircase" ? "in [2, 1000] m" : "in [6, 1000] m");
  CHECK_OPTION_MSG(height, height >= 2.2 && height <= 20.0, "in [2.2, 20] m");
  CHECK_OPTION_MSG(corridor_width, corridor_width >= 1.5 && corridor_width <= 10.0,
                   "in [1.5, 10] m");
  CHECK_OPTION_MSG(room_depth, room_depth >= 2.0 && room_depth <= 20.0, "in [2, 20] m");
  CHECK_OPTION_MSG(width, type != "office" || width - 2 * room_depth - 2 * corridor_width >= 2.0,
                   ">= 2*room_depth + 2*corridor_width + 2 m for an office");
  CHECK_OPTION_MSG(length,
                   type != "office" || length - 2 * room_depth - 2 * corridor_width >= 2.0,
                   ">= 2*room_depth + 2*corridor_width + 2 m for an office");
  CHECK_OPTION_MSG(furniture_per_room, furniture_per_room >= 0 && furniture_per_room <= 50,
                   "in [0, 50]");
  CHECK_OPTION_MSG(pillar_spacing, pillar_spacing >= 4.0 && pillar_spacing <= 50.0,
                   "in [4, 50] m");
  CHECK_OPTION_MSG(car_density, car_density >= 0.0 && car_density <= 1.0, "in [0, 1]");
  CHECK_OPTION_MSG(texture_scale, texture_scale > 0.1 && texture_scale < 10.0, "in (0.1, 10)");
  return true;
}

void SceneOptions::CheckOrThrow(const std::string& where) const {
  if (Check()) return;
  const OptionCheckFailure& f = LastOptionCheckFailure();
  throw InputError(where, "field " + f.name, "expected " + f.requirement + ", found " + f.value);
}

SceneOptions DefaultSceneOptions(const std::string& type) {
  SceneOptions o;
  o.type = type;
  if (type == "office") {
    return o;
  } else if (type == "staircase") {
    o.length = 14.0;  // x in [-8, 6]
    o.width = 2.8;    // narrow: two 1.3 m flights and a 0.2 m spine wall
    o.height = 3.0;   // storey height
    return o;
  } else if (type == "hall") {
    o.length = 60.0;
    o.width = 40.0;
    o.height = 3.0;
    return o;
  }
  throw InputError("--scene", "value",
                   "expected office, staircase, hall or a configs/sim_*.yaml path, found '" +
                       type + "'");
}

namespace {

// `materials:` of a scene file: a map from surface class to a list of
// material names, each list replacing that class's pool.
void ReadMaterialPools(const std::string& path, const YAML::Node& node, MaterialPools* pools) {
  if (!node.IsMap()) {
    throw InputError(path, "field materials",
                     "expected a map from surface class (floor, ceiling, wall, object) to a "
                     "list of material names");
  }
  for (const auto& kv : node) {
    const std::string cls = kv.first.as<std::string>();
    int index = -1;
    for (int c = 0; c < kNumSurfaceClasses; ++c) {
      if (cls == SurfaceClassName(static_cast<SurfaceClass>(c))) index = c;
    }
    const std::string field = "field materials." + cls;
    if (index < 0) {
      throw InputError(path, field,
                       "unknown surface class; expected floor, ceiling, wall or object");
    }
    if (!kv.second.IsSequence() || kv.second.size() == 0) {
      throw InputError(path, field, "expected a non-empty list of material names");
    }
    std::vector<MaterialId> pool;
    for (const YAML::Node& name_node : kv.second) {
      if (!name_node.IsScalar()) throw InputError(path, field, "expected material names");
      const std::string name = name_node.as<std::string>();
      const std::optional<MaterialId> id = FindMaterial(name);
      if (!id) {
        throw InputError(path, field,
                         "unknown material '" + name + "'; expected one of " + MaterialNames());
      }
      pool.push_back(*id);
    }
    pools->pool[index] = pool;
  }
}

}  // namespace

SceneOptions ReadSceneOptions(const std::string& path) {
  CheckFileExists(path, "scene config");
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw InputError(path, "line " + std::to_string(e.mark.line + 1), e.msg);
  }
  if (!root.IsMap()) throw InputError(path, "line 1", "expected a YAML map of scene options");
  if (!root["type"]) throw InputError(path, "field type", "expected office|staircase|hall");
  SceneOptions o;
  try {
    o = DefaultSceneOptions(root["type"].as<std::string>());
  } catch (const InputError&) {
    throw InputError(path, "field type",
                     "expected office, staircase or hall, found '" +
                         root["type"].as<std::string>() + "'");
  }
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    try {
      if (key == "type") continue;
      else if (key == "seed") o.seed = kv.second.as<int>();
      else if (key == "length") o.length = kv.second.as<double>();
      else if (key == "width") o.width = kv.second.as<double>();
      else if (key == "height") o.height = kv.second.as<double>();
      else if (key == "corridor_width") o.corridor_width = kv.second.as<double>();
      else if (key == "room_depth") o.room_depth = kv.second.as<double>();
      else if (key == "furniture_per_room") o.furniture_per_room = kv.second.as<int>();
      else if (key == "pillar_spacing") o.pillar_spacing = kv.second.as<double>();
      else if (key == "car_density") o.car_density = kv.second.as<double>();
      else if (key == "texture_scale") o.texture_scale = kv.second.as<double>();
      else if (key == "materials") ReadMaterialPools(path, kv.second, &o.materials);
      else throw InputError(path, "field " + key, "unknown scene option");
    } catch (const YAML::Exception& e) {
      throw InputError(path, "field " + key, "expected a number, " + e.msg);
    }
  }
  o.CheckOrThrow(path);
  return o;
}

SceneOptions ResolveSceneOptions(const std::string& scene) {
  if (scene.size() > 5 && (scene.substr(scene.size() - 5) == ".yaml" ||
                           scene.substr(scene.size() - 4) == ".yml")) {
    return ReadSceneOptions(scene);
  }
  return DefaultSceneOptions(scene);
}

namespace {

using Box = Eigen::AlignedBox3d;

struct Part {
  Box box;
  bool removable = false;  // interior obstacle (may be removed to keep a path clear)
};

// Horizontal distance from a box footprint to a point.
double FootprintDistance(const Box& box, const Vec3& p) {
  const double dx = std::max({box.min().x() - p.x(), 0.0, p.x() - box.max().x()});
  const double dy = std::max({box.min().y() - p.y(), 0.0, p.y() - box.max().y()});
  return std::hypot(dx, dy);
}

// Dense samples of a polyline (spacing <= 0.2 m).
std::vector<Vec3> Densify(const std::vector<Vec3>& points, bool closed) {
  std::vector<Vec3> out;
  const size_t n = points.size();
  for (size_t i = 0; i + (closed ? 0 : 1) < n; ++i) {
    const Vec3& a = points[i];
    const Vec3& b = points[(i + 1) % n];
    const int steps = std::max(1, static_cast<int>(std::ceil((b - a).norm() / 0.2)));
    for (int k = 0; k < steps; ++k) out.push_back(a + (b - a) * (double(k) / steps));
  }
  if (!closed && n > 0) out.push_back(points.back());
  return out;
}

// The class of face `face` (the kFaces order of Builder::Triangles: -x, +x,
// -y, +y, -z, +z) of `box`: large upward faces are floors, large downward
// faces ceilings, vertical faces of at least 1.8 m walls (thresholds in
// materials.h SurfaceClass).
SurfaceClass ClassifyFace(const Box& box, int face) {
  const Vec3 e = box.max() - box.min();
  if (face == 5) return e.x() * e.y() >= 2.0 ? SurfaceClass::kFloor : SurfaceClass::kObject;
  if (face == 4) return e.x() * e.y() >= 4.0 ? SurfaceClass::kCeiling : SurfaceClass::kObject;
  return e.z() >= 1.8 ? SurfaceClass::kWall : SurfaceClass::kObject;
}

class Builder {
 public:
  explicit Builder(uint32_t seed) : rng_(seed) {}

  void AddBox(const Vec3& lo, const Vec3& hi, bool removable) {
    parts_.push_back({Box(lo.cwiseMin(hi), lo.cwiseMax(hi)), removable});
  }
  // An axis-aligned wall from (x0, y0) to (x1, y1) (x0 == x1 or y0 == y1) of
  // `thickness`, z in [z0, z1], with doorways (centre along the wall, width)
  // of height `door_height` above z0.
  void AddWall(double x0, double y0, double x1, double y1, double z0, double z1,
               double thickness, std::vector<std::pair<double, double>> doors,
               double door_height, bool removable) {
    const bool along_x = std::abs(y1 - y0) < 1e-9;
    const double a0 = along_x ? std::min(x0, x1) : std::min(y0, y1);
    const double a1 = along_x ? std::max(x0, x1) : std::max(y0, y1);
    const double c = along_x ? y0 : x0;
    std::sort(doors.begin(), doors.end());
    double s = a0;
    auto segment = [&](double from, double to, double zlo, double zhi) {
      if (to - from < 1e-3) return;
      if (along_x) {
        AddBox({from, c - thickness / 2, zlo}, {to, c + thickness / 2, zhi}, removable);
      } else {
        AddBox({c - thickness / 2, from, zlo}, {c + thickness / 2, to, zhi}, removable);
      }
    };
    for (const auto& [centre, w] : doors) {
      const double d0 = std::max(a0, centre - w / 2), d1 = std::min(a1, centre + w / 2);
      if (d1 <= d0) continue;
      segment(s, d0, z0, z1);
      segment(d0, d1, z0 + door_height, z1);  // lintel
      s = d1;
    }
    segment(s, a1, z0, z1);
  }
  // A random box of footprint size in [min_size, max_size] inside `region`
  // (x/y extents), standing on z0.
  void AddRandomFurniture(const Box& region, double min_size, double max_size,
                          double max_height, double z0) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const double sx = min_size + (max_size - min_size) * u(rng_);
    const double sy = min_size + (max_size - min_size) * u(rng_);
    const double h = 0.4 + (max_height - 0.4) * u(rng_);
    const Vec3 extent = region.max() - region.min();
    if (extent.x() < sx || extent.y() < sy) return;
    const double x = region.min().x() + (extent.x() - sx) * u(rng_);
    const double y = region.min().y() + (extent.y() - sy) * u(rng_);
    AddBox({x, y, z0}, {x + sx, y + sy, z0 + h}, true);
  }
  double Uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng_);
  }

  // Drops removable parts closer than `clearance` (horizontally) to any of the
  // dense path points whose height lies within the part's z range (+ 0.5 m).
  void KeepClear(const std::vector<Vec3>& path, double clearance) {
    std::vector<Part> kept;
    for (const Part& part : parts_) {
      bool blocked = false;
      if (part.removable) {
        for (const Vec3& p : path) {
          if (p.z() < part.box.min().z() - 0.5 || p.z() > part.box.max().z() + 1.0) continue;
          if (FootprintDistance(part.box, p) < clearance) {
            blocked = true;
            break;
          }
        }
      }
      if (!blocked) kept.push_back(part);
    }
    parts_ = std::move(kept);
  }

  // Six faces of every box, two triangles each, one surface id per face;
  // `classes` gets each face's SurfaceClass (ClassifyFace).
  std::vector<Triangle> Triangles(int* num_surfaces, std::vector<SurfaceClass>* classes) const {
    std::vector<Triangle> tris;
    classes->clear();
    uint32_t id = 0;
    for (const Part& part : parts_) {
      for (int face = 0; face < 6; ++face) classes->push_back(ClassifyFace(part.box, face));
      const Eigen::Vector3f lo = part.box.min().cast<float>();
      const Eigen::Vector3f hi = part.box.max().cast<float>();
      auto corner = [&](int i) {
        return Eigen::Vector3f((i & 1) ? hi.x() : lo.x(), (i & 2) ? hi.y() : lo.y(),
                               (i & 4) ? hi.z() : lo.z());
      };
      // Quads (outward winding) of the cube corners.
      static const int kFaces[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1},
                                       {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
      for (const auto& f : kFaces) {
        tris.push_back({corner(f[0]), corner(f[1]), corner(f[2]), id});
        tris.push_back({corner(f[0]), corner(f[2]), corner(f[3]), id});
        ++id;
      }
    }
    *num_surfaces = static_cast<int>(id);
    return tris;
  }

 private:
  std::mt19937 rng_;
  std::vector<Part> parts_;
};

constexpr double kWall = 0.2;          // wall thickness, m
constexpr double kDoorHeight = 2.1;    // m
constexpr double kDeviceHeight = 1.4;  // handheld device above the floor, m

void BuildShell(Builder* b, double x0, double y0, double x1, double y1, double z1) {
  b->AddBox({x0 - kWall, y0 - kWall, -kWall}, {x1 + kWall, y1 + kWall, 0.0}, false);  // floor
  b->AddBox({x0 - kWall, y0 - kWall, z1}, {x1 + kWall, y1 + kWall, z1 + kWall}, false);
  b->AddBox({x0 - kWall, y0 - kWall, 0}, {x0, y1 + kWall, z1}, false);
  b->AddBox({x1, y0 - kWall, 0}, {x1 + kWall, y1 + kWall, z1}, false);
  b->AddBox({x0, y0 - kWall, 0}, {x1, y0, z1}, false);
  b->AddBox({x0, y1, 0}, {x1, y1 + kWall, z1}, false);
}

// Office: rooms between the outer walls and a corridor loop, an open-plan
// block with pillars inside the loop, doorways, furniture, wall cabinets.
WalkingRoute BuildOffice(const SceneOptions& o, Builder* b) {
  const double L = o.length, W = o.width, H = o.height;
  const double d = o.room_depth, c = o.corridor_width;
  BuildShell(b, 0, 0, L, W, H);
  // Ring walls: the outer edge of the corridor [d, L-d] x [d, W-d] and the
  // inner edge [d+c, L-d-c] x [d+c, W-d-c].
  const double ox0 = d, ox1 = L - d, oy0 = d, oy1 = W - d;
  const double ix0 = d + c, ix1 = L - d - c, iy0 = d + c, iy1 = W - d - c;
  auto room_walls = [&](double a0, double a1, bool along_x, double wall_c, double outer_c) {
    // Rooms of 5..8 m along the wall, one doorway each, partitions to the outer wall.
    std::vector<std::pair<double, double>> doors;
    double s = a0;
    while (a1 - s > 3.0) {
      const double room = std::min(a1 - s, b->Uniform(5.0, 8.0));
      doors.push_back({s + b->Uniform(1.0, room - 1.0), 1.0});
      s += room;
      if (a1 - s > 3.0) {
        if (along_x) {
          b->AddWall(s, wall_c, s, outer_c, 0, H, kWall, {}, kDoorHeight, true);
        } else {
          b->AddWall(wall_c, s, outer_c, s, 0, H, kWall, {}, kDoorHeight, true);
        }
      }
    }
    if (along_x) {
      b->AddWall(a0, wall_c, a1, wall_c, 0, H, kWall, doors, kDoorHeight, true);
    } else {
      b->AddWall(wall_c, a0, wall_c, a1, 0, H, kWall, doors, kDoorHeight, true);
    }
  };
  room_walls(ox0 - kWall / 2, ox1 + kWall / 2, true, oy0, 0.0);
  room_walls(ox0 - kWall / 2, ox1 + kWall / 2, true, oy1, W);
  room_walls(oy0 + kWall / 2, oy1 - kWall / 2, false, ox0, 0.0);
  room_walls(oy0 + kWall / 2, oy1 - kWall / 2, false, ox1, L);
  // Inner block walls with two wide openings each.
  auto openings = [&](double a0, double a1) {
    return std::vector<std::pair<double, double>>{
        {a0 + (a1 - a0) * b->Uniform(0.2, 0.4), 1.6},
        {a0 + (a1 - a0) * b->Uniform(0.6, 0.8), 1.6}};
  };
  b->AddWall(ix0, iy0, ix1, iy0, 0, H, kWall, openings(ix0, ix1), kDoorHeight, true);
  b->AddWall(ix0, iy1, ix1, iy1, 0, H, kWall, openings(ix0, ix1), kDoorHeight, true);
  b->AddWall(ix0, iy0, ix0, iy1, 0, H, kWall, openings(iy0, iy1), kDoorHeight, true);
  b->AddWall(ix1, iy0, ix1, iy1, 0, H, kWall, openings(iy0, iy1), kDoorHeight, true);
  // Pillars in the open-plan block.
  for (double x = ix0 + 3.0; x < ix1 - 1.5; x += 5.0) {
    for (double y = iy0 + 2.0; y < iy1 - 1.0; y += 4.0) {
      b->AddBox({x - 0.25, y - 0.25, 0}, {x + 0.25, y + 0.25, H}, true);
    }
  }
  // Furniture in the rooms (all four room bands) and in the open-plan block.
  const Box bands[5] = {Box(Vec3(0.3, 0.3, 0), Vec3(L - 0.3, d - 0.4, 0)),
                        Box(Vec3(0.3, W - d + 0.4, 0), Vec3(L - 0.3, W - 0.3, 0)),
                        Box(Vec3(0.3, d, 0), Vec3(d - 0.4, W - d, 0)),
                        Box(Vec3(L - d + 0.4, d, 0), Vec3(L - 0.3, W - d, 0)),
                        Box(Vec3(ix0 + 0.4, iy0 + 0.4, 0), Vec3(ix1 - 0.4, iy1 - 0.4, 0))};
  for (const Box& band : bands) {
    const double area = (band.max() - band.min()).head<2>().prod();
    const int n = static_cast<int>(o.furniture_per_room * area / 30.0);
    for (int i = 0; i < n; ++i) b->AddRandomFurniture(band, 0.5, 2.0, 2.0, 0.0);
  }
  // Cabinets and crates along the corridor walls (<= 0.5 m deep).
  for (int i = 0; i < static_cast<int>((L + W) / 4); ++i) {
    const int side = i % 4;
    const double len = b->Uniform(0.6, 2.0), depth = b->Uniform(0.3, 0.5);
    const double h = b->Uniform(0.5, 2.0);
    if (side < 2) {
      const double x = b->Uniform(ox0 + 0.5, ox1 - 0.5 - len);
      const double y = side == 0 ? oy0 + kWall / 2 : oy1 - kWall / 2 - depth;
      b->AddBox({x, y, 0}, {x + len, y + depth, h}, true);
    } else {
      const double y = b->Uniform(oy0 + 0.5, oy1 - 0.5 - len);
      const double x = side == 2 ? ox0 + kWall / 2 : ox1 - kWall / 2 - depth;
      b->AddBox({x, y, 0}, {x + depth, y + len, h}, true);
    }
  }
  WalkingRoute route;
  const double rx0 = d + c / 2, rx1 = L - d - c / 2, ry0 = d + c / 2, ry1 = W - d - c / 2;
  const double z = kDeviceHeight;
  route.waypoints = {{rx0, ry0, z}, {rx1, ry0, z}, {rx1, ry1, z}, {rx0, ry1, z}};
  route.closed = true;
  return route;
}

// Staircase: x in [-8, 6], y in [0, 2.8], two storeys of height h. Flight 1
// (y in [0, 1.3]) climbs +x to a landing at h/2, flight 2 (y in [1.5, 2.8])
// climbs -x to the upper floor; corridors at both levels for x < 1.
WalkingRoute BuildStaircase(const SceneOptions& o, Builder* b) {
  const double h = o.height, x0 = 6.0 - o.length, x1 = 6.0, wy = o.width;
  BuildShell(b, x0, 0, x1, wy, 2 * h);
  const double spine0 = wy / 2 - 0.1, spine1 = wy / 2 + 0.1;
  b->AddBox({x0, 0, h - 0.2}, {1.0, wy, h}, false);                   // upper floor slab
  b->AddBox({1.0, spine0, 0}, {4.6, spine1, 2 * h - 0.8}, false);     // spine wall
  b->AddBox({4.6, 0, h / 2 - 0.2}, {x1, wy, h / 2}, false);           // landing slab
  b->AddBox({4.6, 0, 0}, {4.8, spine0, h / 2 - 0.2}, false);          // wall under the landing
  const int steps = 9;
  const double rise = (h / 2) / steps, tread = 3.6 / steps;
  for (int i = 0; i < steps; ++i) {
    const double top1 = (i + 1) * rise;
    b->AddBox({1.0 + i * tread, 0, 0}, {1.0 + (i + 1) * tread, spine0, top1}, false);
    const double top2 = h / 2 + (i + 1) * rise;
    b->AddBox({4.6 - (i + 1) * tread, spine1, top2 - 0.35},
              {4.6 - i * tread, wy, top2}, false);
  }
  // Handrail posts on the open side of the upper landing, pipes under the ceilings,
  // crates along the corridor walls (removable obstacles).
  for (double x = x0 + 0.8; x < 0.0; x += b->Uniform(1.5, 2.5)) {
    const double len = b->Uniform(0.5, 1.2);
    b->AddBox({x, 0, 0}, {x + len, 0.3, b->Uniform(0.4, 1.2)}, true);
    b->AddBox({x, wy - 0.3, h}, {x + len, wy, h + b->Uniform(0.3, 1.0)}, true);
  }
  b->AddBox({x0, 0.2, h - 0.45}, {1.0, 0.3, h - 0.35}, false);          // pipe
  b->AddBox({x0, wy - 0.5, 2 * h - 0.4}, {x1, wy - 0.4, 2 * h - 0.3}, false);
  b->AddBox({1.2, 0.1, h + 0.6}, {1.3, 0.2, 2 * h}, false);             // riser pipe
  const double z = kDeviceHeight;
  const double ya = spine0 / 2, yb = (spine1 + wy) / 2;
  WalkingRoute route;
  route.waypoints = {{x0 + 2.0, wy / 2, z},     {0.0, ya, z},
                     {1.0, ya, z},              {4.6, ya, h / 2 + z},
                     {5.3, ya, h / 2 + z},      {5.3, yb, h / 2 + z},
                     {4.6, yb, h / 2 + z},      {1.0, yb, h + z},
                     {0.0, yb, h + z},          {x0 + 2.0, wy / 2, h + z}};
  route.closed = false;
  return route;
}

// Hall: parking garage with a pillar grid, parked cars, a driving-lane loop.
WalkingRoute BuildHall(const SceneOptions& o, Builder* b) {
  const double L = o.length, W = o.width, H = o.height, s = o.pillar_spacing;
  BuildShell(b, 0, 0, L, W, H);
  std::vector<double> px, py;
  for (double x = s; x < L - 1.0; x += s) px.push_back(x);
  for (double y = s; y < W - 1.0; y += s) py.push_back(y);
  for (double x : px) {
    for (double y : py) b->AddBox({x - 0.3, y - 0.3, 0}, {x + 0.3, y + 0.3, H}, true);
  }
  // Beams along x under the ceiling at every pillar row.
  for (double y : py) b->AddBox({0, y - 0.2, H - 0.5}, {L, y + 0.2, H}, false);
  std::uniform_real_distribution<double> u(0, 1);
  for (double x = 1.5; x + 2.0 < L - 1.0; x += 2.6) {
    for (double y = 1.0; y + 4.8 < W - 1.0; y += 5.5) {
      if (b->Uniform(0, 1) > o.car_density) continue;
      const double l = b->Uniform(4.0, 4.8), w = b->Uniform(1.7, 2.0);
      b->AddBox({x, y, 0.3}, {x + w, y + l, 1.0}, true);  // body
      b->AddBox({x + 0.1, y + 0.2 * l, 1.0}, {x + w - 0.1, y + 0.75 * l, 1.5}, true);
    }
  }
  WalkingRoute route;
  const double z = kDeviceHeight;
  const double rx0 = px.size() > 1 ? px[0] / 2 : 3.0;
  const double rx1 = px.size() > 1 ? (px[px.size() - 2] + px.back()) / 2 : L - 3.0;
  const double ry0 = py.size() > 1 ? (py[0] + py[1]) / 2 : 3.0;
  const double ry1 = py.size() > 1 ? (py[py.size() - 2] + py.back()) / 2 : W - 3.0;
  route.waypoints = {{rx0, ry0, z}, {rx1, ry0, z}, {rx1, ry1, z}, {rx0, ry1, z}};
  route.closed = true;
  return route;
}

}  // namespace

struct Scene::EmbreeState {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ~EmbreeState() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

Scene::Scene() = default;
Scene::~Scene() = default;

std::unique_ptr<Scene> Scene::Generate(const SceneOptions& options,
                                       const std::vector<Vec3>& keep_clear) {
  options.CheckOrThrow("scene options");
  auto scene = std::make_unique<Scene>();
  scene->options_ = options;
  Builder builder(static_cast<uint32_t>(options.seed) * 2654435761u + 17u);
  if (options.type == "office") {
    scene->route_ = BuildOffice(options, &builder);
  } else if (options.type == "staircase") {
    scene->route_ = BuildStaircase(options, &builder);
  } else {
    scene->route_ = BuildHall(options, &builder);
  }
  if (keep_clear.empty()) {
    builder.KeepClear(Densify(scene->route_.waypoints, scene->route_.closed), 0.8);
  } else {
    scene->route_ = WalkingRoute();
    builder.KeepClear(keep_clear, 0.7);
  }
  scene->triangles_ = builder.Triangles(&scene->num_surfaces_, &scene->surface_classes_);
  scene->Build();
  scene->AssignMaterials(MaterialOptions().texture_poor_fraction);
  return scene;
}

void Scene::AssignMaterials(double texture_poor_fraction) {
  std::vector<SurfaceClass> classes(num_surfaces_, SurfaceClass::kObject);
  std::copy_n(surface_classes_.begin(), std::min(surface_classes_.size(), classes.size()),
              classes.begin());
  materials_ = sim::AssignMaterials(classes, options_.materials, texture_poor_fraction,
                                    static_cast<uint32_t>(options_.seed));
}

std::unique_ptr<Scene> Scene::FromTriangles(std::vector<Triangle> triangles) {
  auto scene = std::make_unique<Scene>();
  scene->triangles_ = std::move(triangles);
  uint32_t max_id = 0;
  for (const Triangle& t : scene->triangles_) max_id = std::max(max_id, t.surface_id);
  scene->num_surfaces_ = static_cast<int>(max_id) + 1;
  scene->Build();
  return scene;
}

void Scene::Build() {
  THROW_CHECK(!triangles_.empty());
  embree_ = std::make_unique<EmbreeState>();
  embree_->device = rtcNewDevice(nullptr);
  THROW_CHECK_MSG(embree_->device != nullptr, "rtcNewDevice failed");
  embree_->scene = rtcNewScene(embree_->device);
  rtcSetSceneBuildQuality(embree_->scene, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry geom = rtcNewGeometry(embree_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  const size_t n = triangles_.size();
  float* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n));
  unsigned* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), n));
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f* v[3] = {&triangles_[i].a, &triangles_[i].b, &triangles_[i].c};
    for (int k = 0; k < 3; ++k) {
      for (int j = 0; j < 3; ++j) vertices[9 * i + 3 * k + j] = (*v[k])[j];
      indices[3 * i + k] = static_cast<unsigned>(3 * i + k);
    }
  }
  rtcCommitGeometry(geom);
  rtcAttachGeometry(embree_->scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(embree_->scene);
}

RayHit Scene::Intersect(const Vec3& origin,
                        const Vec3& direction,
                        double min_range,
                        double max_range) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  rh.ray.org_x = static_cast<float>(origin.x());
  rh.ray.org_y = static_cast<float>(origin.y());
  rh.ray.org_z = static_cast<float>(origin.z());
  rh.ray.dir_x = static_cast<float>(direction.x());
  rh.ray.dir_y = static_cast<float>(direction.y());
  rh.ray.dir_z = static_cast<float>(direction.z());
  rh.ray.tnear = static_cast<float>(min_range);
  rh.ray.tfar = static_cast<float>(max_range);
  rh.ray.time = 0.f;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(embree_->scene, &context, &rh);
  RayHit hit;
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
  hit.hit = true;
  hit.distance = rh.ray.tfar;
  hit.normal = Eigen::Vector3f(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z).normalized();
  if (hit.normal.dot(direction.cast<float>()) > 0) hit.normal = -hit.normal;
  hit.surface_id = triangles_[rh.hit.primID].surface_id;
  return hit;
}

void Scene::Intersect16(const int valid[16],
                        const float origin[3],
                        const float directions[16][3],
                        float max_range,
                        bool coherent,
                        RayHit hits[16]) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags =
      coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  alignas(64) RTCRayHit16 rh;
  alignas(64) int valid_aligned[16];
  for (int i = 0; i < 16; ++i) {
    valid_aligned[i] = valid[i] ? -1 : 0;
    rh.ray.org_x[i] = origin[0];
    rh.ray.org_y[i] = origin[1];
    rh.ray.org_z[i] = origin[2];
    rh.ray.dir_x[i] = directions[i][0];
    rh.ray.dir_y[i] = directions[i][1];
    rh.ray.dir_z[i] = directions[i][2];
    rh.ray.tnear[i] = 0.f;
    rh.ray.tfar[i] = max_range;
    rh.ray.time[i] = 0.f;
    rh.ray.mask[i] = 0xFFFFFFFFu;
    rh.ray.id[i] = static_cast<unsigned>(i);
    rh.ray.flags[i] = 0;
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect16(valid_aligned, embree_->scene, &context, &rh);
  for (int i = 0; i < 16; ++i) {
    hits[i] = RayHit();
    if (!valid[i] || rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
    hits[i].hit = true;
    hits[i].distance = rh.ray.tfar[i];
    Eigen::Vector3f n(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]);
    n.normalize();
    if (n.dot(Eigen::Vector3f(directions[i][0], directions[i][1], directions[i][2])) > 0) {
      n = -n;
    }
    hits[i].normal = n;
    hits[i].surface_id = triangles_[rh.hit.primID[i]].surface_id;
  }
}

Eigen::AlignedBox3d Scene::Bounds() const {
  Eigen::AlignedBox3d box;
  for (const Triangle& t : triangles_) {
    box.extend(t.a.cast<double>());
    box.extend(t.b.cast<double>());
    box.extend(t.c.cast<double>());
  }
  return box;
}

void Scene::WritePly(const std::string& path) const {
  AtomicOutputFile file(path, /*binary=*/true);
  std::ofstream& out = file.stream();
  out << "ply\nformat binary_little_endian 1.0\ncomment lisfm simulate scene (scene frame, "
         "metres, z up)\nelement vertex "
      << 3 * triangles_.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nelement face "
      << triangles_.size()
      << "\nproperty list uchar int vertex_indices\nproperty uchar red\nproperty uchar "
         "green\nproperty uchar blue\nend_header\n";
  for (const Triangle& t : triangles_) {
    for (const Eigen::Vector3f* v : {&t.a, &t.b, &t.c}) {
      out.write(reinterpret_cast<const char*>(v->data()), 3 * sizeof(float));
    }
  }
  for (size_t i = 0; i < triangles_.size(); ++i) {
    const unsigned char count = 3;
    out.write(reinterpret_cast<const char*>(&count), 1);
    for (int k = 0; k < 3; ++k) {
      const int32_t index = static_cast<int32_t>(3 * i + k);
      out.write(reinterpret_cast<const char*>(&index), sizeof(index));
    }
    const uint32_t h = triangles_[i].surface_id * 2654435761u;
    const unsigned char rgb[3] = {static_cast<unsigned char>(80 + (h >> 8) % 160),
                                  static_cast<unsigned char>(80 + (h >> 16) % 160),
                                  static_cast<unsigned char>(80 + (h >> 24) % 160)};
    out.write(reinterpret_cast<const char*>(rgb), 3);
  }
  file.Commit();
}

}  // namespace sim
}  // namespace lisfm
