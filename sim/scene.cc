#include "sim/scene.h"

#include <algorithm>
#include <array>
#include <atomic>
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
  CHECK_OPTION_MSG(type,
                   type == "office" || type == "staircase" || type == "hall" || type == "site",
                   "one of office, staircase, hall, site");
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
  if (type == "site") {
    // The site's layout (hall lanes, stairs, route rooms) is drawn for these.
    CHECK_OPTION_MSG(length, length >= 60.0, ">= 60 m for a site");
    CHECK_OPTION_MSG(width, width >= 40.0, ">= 40 m for a site");
    CHECK_OPTION_MSG(height, height >= 3.0 && height <= 5.0, "in [3, 5] m for a site");
    CHECK_OPTION_MSG(corridor_width, corridor_width >= 2.4 && corridor_width <= 4.0,
                     "in [2.4, 4] m for a site");
    CHECK_OPTION_MSG(room_depth, room_depth >= 5.5 && room_depth <= 8.0,
                     "in [5.5, 8] m for a site");
  }
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
  } else if (type == "site") {
    o.length = 64.0;
    o.width = 40.0;
    o.height = 3.5;  // storey height; the hall is two storeys high
    o.corridor_width = 2.8;
    o.room_depth = 6.0;
    return o;
  }
  throw InputError("--scene", "value",
                   "expected office, staircase, hall, site or a configs/sim_*.yaml path, found '" +
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
    if (!kv.first.IsScalar()) {
      throw InputError(path, "field materials", "expected a surface class name as map key");
    }
    const std::string cls = kv.first.Scalar();
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
  if (!root["type"]) throw InputError(path, "field type", "expected office|staircase|hall|site");
  if (!root["type"].IsScalar()) {
    throw InputError(path, "field type", "expected office, staircase, hall or site");
  }
  SceneOptions o;
  try {
    o = DefaultSceneOptions(root["type"].Scalar());
  } catch (const InputError&) {
    throw InputError(path, "field type",
                     "expected office, staircase, hall or site, found '" + root["type"].Scalar() +
                         "'");
  }
  for (const auto& kv : root) {
    if (!kv.first.IsScalar()) {
      throw InputError(path, "line " + std::to_string(kv.first.Mark().line + 1),
                       "expected a scene option name as map key");
    }
    const std::string key = kv.first.Scalar();
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

  // An opening in a wall: [a0, a1] along the wall, [z0, z1] in height.
  struct Opening {
    double a0, a1, z0, z1;
  };
  // An axis-aligned wall along x (at y = c) or along y (at x = c) over
  // [from, to], z in [z0, z1], of `thickness`, with `openings` (doorways,
  // windows; they may share a stretch of wall at different heights). Each
  // stretch between opening edges is one box per solid height interval.
  void AddWallWithOpenings(bool along_x, double c, double from, double to, double z0, double z1,
                           double thickness, const std::vector<Opening>& openings,
                           bool removable) {
    std::vector<double> cuts = {from, to};
    for (const Opening& o : openings) {
      cuts.push_back(std::clamp(o.a0, from, to));
      cuts.push_back(std::clamp(o.a1, from, to));
    }
    std::sort(cuts.begin(), cuts.end());
    cuts.erase(std::unique(cuts.begin(), cuts.end()), cuts.end());
    for (size_t i = 0; i + 1 < cuts.size(); ++i) {
      const double a = cuts[i], b = cuts[i + 1];
      if (b - a < 1e-3) continue;
      std::vector<std::pair<double, double>> gaps;
      for (const Opening& o : openings) {
        if (o.a0 < b - 1e-9 && o.a1 > a + 1e-9) gaps.push_back({o.z0, o.z1});
      }
      std::sort(gaps.begin(), gaps.end());
      double z = z0;
      auto solid = [&](double zlo, double zhi) {
        if (zhi - zlo < 1e-3) return;
        if (along_x) {
          AddBox({a, c - thickness / 2, zlo}, {b, c + thickness / 2, zhi}, removable);
        } else {
          AddBox({c - thickness / 2, a, zlo}, {c + thickness / 2, b, zhi}, removable);
        }
      };
      for (const auto& [g0, g1] : gaps) {
        solid(z, std::min(g0, z1));
        z = std::max(z, g1);
      }
      solid(z, z1);
    }
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
constexpr double kDeviceHeight = kRouteDeviceHeight;  // handheld device above the floor, m

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

// Site: a construction-site floor (the HILTI 2022 construction sequences) of
// L x W (>= 60 x 40 m), storey height h, corridor width c, room depth d:
//  - a hall x in [0, X1] (X1 = L - 36 m), two storeys high: a pillar grid,
//    roof beams, containers, pallets and stacks, a scaffold tower, and an
//    open steel stair (20 steps) along its east wall up to a landing at h
//    and a door into the wing's upper floor;
//  - a two-storey wing x in [X1, L]. Ground floor: corridors A (y in [d,
//    d + c]) and B (y in [W - d - c, W - d]) from the hall to the east wall,
//    a cross corridor C (x in [X1 + 16, X1 + 16 + c]) joining them, rooms
//    (one doorway each) between them and the outer walls, and an enclosed
//    two-flight stairwell at A's east end. Upper floor: corridor A with rooms
//    to the south, an open-plan floor with pillars and stacks to the north
//    (wide openings in A's north wall, windows onto the hall).
// Every box face is its own surface (materials can be assigned per wall,
// floor and object). The route (closed, 290 m for the defaults): across the
// hall into corridor B, a loop through a room, C, A back into the hall, up the
// hall stair, the upper corridor with a loop through the open-plan floor back
// onto it, down the stairwell, and A through the hall back to the start:
// corridor A, the upper corridor and the start are revisited after loops.
WalkingRoute BuildSite(const SceneOptions& o, Builder* b) {
  const double L = o.length, W = o.width, h = o.height, c = o.corridor_width, d = o.room_depth;
  const double g = kDeviceHeight, u = h + kDeviceHeight, m = h / 2 + kDeviceHeight;
  constexpr double kSlab = 0.2;           // floor slab thickness, m
  constexpr double kOpeningHeight = 2.6;  // corridor openings into the hall, m
  const double X1 = L - 36.0;             // hall | wing wall
  BuildShell(b, 0, 0, L, W, 2 * h);
  const double a0 = d, a1 = d + c, yA = d + c / 2;          // corridor A
  const double b0 = W - d - c, b1 = W - d, yB = W - d - c / 2;  // corridor B
  const double xC = X1 + 16.0, xCc = xC + c / 2;            // corridor C
  // East stairwell at A's east end: two flights of kFlight (10 steps each)
  // in lanes either side of a spine at y = yA, a landing of kLanding at h/2.
  constexpr double kFlight = 3.0, kLanding = 1.6;
  const double sE = L - kFlight - kLanding;
  const double lane = (c - 2 * kWall) / 2;
  const double ya = a0 + kWall / 2 + lane / 2, yb = a1 - kWall / 2 - lane / 2;
  // Hall stair: against the hall's east wall, climbing -y to a landing at h.
  constexpr double kHallStairWidth = 1.5, kHallStairRun = 6.0;
  const double hx0 = X1 - kWall / 2 - kHallStairWidth, hx1 = X1 - kWall / 2;
  const double xS = (hx0 + hx1) / 2;
  const double yTop = yA + 1.4, yBottom = yTop + kHallStairRun;
  // The route loops through the north room with its door at xRn.
  const double xRn = X1 + 10.5;
  using Opening = Builder::Opening;

  // ---- floors, stairs ----
  b->AddBox({X1, 0, h - kSlab}, {L, a0, h}, false);  // upper floor, open over the stairwell
  b->AddBox({X1, a0, h - kSlab}, {sE, a1, h}, false);
  b->AddBox({X1, a1, h - kSlab}, {L, W, h}, false);
  b->AddBox({hx0, yA - 1.4, h - kSlab}, {hx1, yTop, h}, false);  // hall stair landing
  for (const double y : {yA - 1.4, yTop - 0.15}) {                 // its posts
    b->AddBox({hx0, y, 0}, {hx0 + 0.15, y + 0.15, h - kSlab}, false);
  }
  constexpr int kHallSteps = 20;
  const double hall_rise = h / kHallSteps, hall_tread = kHallStairRun / kHallSteps;
  for (int i = 0; i < kHallSteps; ++i) {  // step 0 is the lowest
    const double y0 = yBottom - (i + 1) * hall_tread, y1 = yBottom - i * hall_tread;
    const double top = (i + 1) * hall_rise;
    b->AddBox({hx0, y0, std::max(0.0, top - 0.3)}, {hx1, y1, top}, false);
    b->AddBox({hx0, y0, top + 0.9}, {hx0 + 0.05, y1, top + 1.0}, false);  // handrail
    if (i % 4 == 0) b->AddBox({hx0, y0, top}, {hx0 + 0.05, y0 + 0.05, top + 0.9}, false);
  }
  b->AddBox({hx0, yA - 1.4, h + 0.9}, {hx0 + 0.05, yTop, h + 1.0}, false);  // landing rails
  b->AddBox({hx0, yA - 1.4, h + 0.9}, {hx1, yA - 1.35, h + 1.0}, false);
  b->AddBox({hx0, yA - 1.4, h}, {hx0 + 0.05, yA - 1.35, h + 0.9}, false);
  constexpr int kFlightSteps = 10;
  const double rise = (h / 2) / kFlightSteps, tread = kFlight / kFlightSteps;
  for (int i = 0; i < kFlightSteps; ++i) {
    b->AddBox({sE + i * tread, a0, 0}, {sE + (i + 1) * tread, yA - kWall / 2, (i + 1) * rise},
              false);
    const double top = h / 2 + (i + 1) * rise;
    b->AddBox({sE + kFlight - (i + 1) * tread, yA + kWall / 2, top - 0.35},
              {sE + kFlight - i * tread, a1, top}, false);
  }
  b->AddBox({sE, yA - kWall / 2, 0}, {sE + kFlight, yA + kWall / 2, 2 * h - 0.8}, false);  // spine
  b->AddBox({sE + kFlight, a0, h / 2 - kSlab}, {L, a1, h / 2}, false);                  // landing
  b->AddBox({sE + kFlight, a0, 0}, {sE + kFlight + kWall, yA - kWall / 2, h / 2 - kSlab}, false);
  b->AddBox({sE - 0.05, a0, h + 0.9}, {sE, yA - kWall / 2, h + 1.0}, false);  // guard rail
  b->AddBox({sE - 0.05, a0, h}, {sE, a0 + 0.05, h + 0.9}, false);

  // ---- walls ----
  b->AddWallWithOpenings(false, X1, 0, W, 0, 2 * h, kWall,
                         {{a0 + kWall / 2, a1 - kWall / 2, 0, kOpeningHeight},
                          {b0 + kWall / 2, b1 - kWall / 2, 0, kOpeningHeight},
                          {yA - 1.0, yA + 1.0, h, h + 2.2},
                          {a1 + 4.5, a1 + 8.0, h + 0.9, h + 2.2},
                          {a1 + 13.0, a1 + 16.5, h + 0.9, h + 2.2}},
                         false);
  // A row of rooms along x in [x0, x1] between the corridor wall at y = wall_y
  // and y = far_y, z in [z0, z1]: 5..8 m rooms (and `fixed` ones: x0, x1,
  // door centre), partitions between them, furniture; returns the doorways.
  auto room_row = [&](double x0, double x1, double wall_y, double far_y, double z0, double z1,
                      const std::vector<std::array<double, 3>>& fixed) {
    std::vector<double> bounds = {x0}, doors;
    auto fill = [&](double to) {  // rooms from bounds.back() to `to`
      while (to - bounds.back() > 11.0) bounds.push_back(bounds.back() + b->Uniform(5.0, 8.0));
      if (to - bounds.back() > 8.0) bounds.push_back((bounds.back() + to) / 2);
      if (to - bounds.back() < 1.0 && bounds.size() > 1) {
        bounds.back() = to;  // a sliver joins the room before it
      } else if (to > bounds.back()) {
        bounds.push_back(to);
      }
    };
    std::vector<Opening> openings;
    for (const auto& [lo, hi, door] : fixed) {
      fill(lo);
      bounds.push_back(hi);
      openings.push_back({door - 0.7, door + 0.7, z0, z0 + kDoorHeight});
    }
    fill(x1);
    const double ylo = std::min(wall_y, far_y), yhi = std::max(wall_y, far_y);
    for (size_t i = 0; i + 1 < bounds.size(); ++i) {
      const double r0 = bounds[i], r1 = bounds[i + 1];
      if (i > 0) b->AddBox({r0 - kWall / 2, ylo, z0}, {r0 + kWall / 2, yhi, z1}, false);
      bool is_fixed = false;
      for (const auto& f : fixed) is_fixed |= std::abs(f[0] - r0) < 1e-9;
      if (!is_fixed && r1 - r0 > 1.8) {
        const double door = b->Uniform(r0 + 0.8, r1 - 0.8);
        openings.push_back({door - 0.5, door + 0.5, z0, z0 + kDoorHeight});
      }
      const Box region(Vec3(r0 + 0.3, ylo + 0.3, 0), Vec3(r1 - 0.3, yhi - 0.3, 0));
      const int n = static_cast<int>(o.furniture_per_room * (r1 - r0) * (yhi - ylo) / 30.0);
      for (int k = 0; k < n; ++k) b->AddRandomFurniture(region, 0.5, 1.8, 1.8, z0);
    }
    return openings;
  };
  // Corridor A: south wall (both storeys) with the south rooms' doors.
  std::vector<Opening> a_south = room_row(X1, sE, a0, 0, 0, h, {});
  for (const Opening& door : room_row(X1, sE, a0, 0, h, 2 * h, {})) a_south.push_back(door);
  b->AddWallWithOpenings(true, a0, X1, L, 0, 2 * h, kWall, a_south, false);
  b->AddBox({sE - kWall / 2, 0, 0}, {sE + kWall / 2, a0, 2 * h}, false);  // behind the stairwell
  // Corridor A: north wall with the middle rooms' doors, C, and the upper
  // floor's openings onto the open-plan floor.
  std::vector<Opening> a_north = room_row(X1, xC, a1, W / 2, 0, h, {});
  a_north.push_back({xC + kWall / 2, xC + c - kWall / 2, 0, kOpeningHeight});
  for (const double x : {X1 + 5.0, X1 + 12.5, X1 + 20.0, X1 + 27.0}) {
    a_north.push_back({x - 1.2, x + 1.2, h, h + 2.5});
  }
  b->AddWallWithOpenings(true, a1, X1, L, 0, 2 * h, kWall, a_north, false);
  // Corridor B (ground floor): rooms on both sides, C.
  std::vector<Opening> b_south = room_row(X1, xC, b0, W / 2, 0, h, {});
  b_south.push_back({xC + kWall / 2, xC + c - kWall / 2, 0, kOpeningHeight});
  b->AddWallWithOpenings(true, b0, X1, L, 0, h, kWall, b_south, false);
  b->AddWallWithOpenings(true, b1, X1, L, 0, h, kWall,
                         room_row(X1, L, b1, W, 0, h, {{X1 + 8.5, X1 + 16.0, xRn}}), false);
  // Corridor C and the two rooms east of it (doors onto C), middle partition.
  b->AddWallWithOpenings(false, xC, a1, b0, 0, h, kWall, {}, false);
  const double e0 = a1 + (W / 2 - a1) / 2, e1 = W / 2 + (b0 - W / 2) / 2;
  b->AddWallWithOpenings(false, xC + c, a1, b0, 0, h, kWall,
                         {{e0 - 0.6, e0 + 0.6, 0, kDoorHeight}, {e1 - 0.6, e1 + 0.6, 0, kDoorHeight}},
                         false);
  b->AddWallWithOpenings(true, W / 2, X1, xC, 0, h, kWall, {}, false);
  b->AddWallWithOpenings(true, W / 2, xC + c, L, 0, h, kWall, {}, false);
  for (const Box& room : {Box(Vec3(xC + c + 0.4, a1 + 0.4, 0), Vec3(L - 0.4, W / 2 - 0.4, 0)),
                          Box(Vec3(xC + c + 0.4, W / 2 + 0.4, 0), Vec3(L - 0.4, b0 - 0.4, 0))}) {
    const int n = static_cast<int>(o.furniture_per_room * (room.max() - room.min()).head<2>().prod() / 30.0);
    for (int k = 0; k < n; ++k) b->AddRandomFurniture(room, 0.5, 1.8, 1.8, 0.0);
  }
  // Ducts and cable trays under the corridor ceilings.
  b->AddBox({X1, a1 - 0.55, h - kSlab - 0.45}, {sE, a1 - 0.15, h - kSlab - 0.2}, false);
  b->AddBox({X1, a1 - 0.55, 2 * h - 0.45}, {sE, a1 - 0.15, 2 * h - 0.2}, false);
  b->AddBox({X1, b0 + 0.15, h - kSlab - 0.3}, {L, b0 + 0.5, h - kSlab - 0.25}, false);
  b->AddBox({xC + 0.15, a1, h - kSlab - 0.3}, {xC + 0.5, b0, h - kSlab - 0.25}, false);

  // ---- hall: pillars, roof beams, containers, a scaffold tower, stacks ----
  const double s = o.pillar_spacing;
  for (double x = s; x < X1 - 2.5; x += s) {
    for (const double y : {W / 4, W / 2, 3 * W / 4}) {
      b->AddBox({x - 0.3, y - 0.3, 0}, {x + 0.3, y + 0.3, 2 * h}, true);
    }
  }
  for (const double y : {W / 4, W / 2, 3 * W / 4}) {
    b->AddBox({0, y - 0.2, 2 * h - 0.7}, {X1 - kWall / 2, y + 0.2, 2 * h}, false);
  }
  for (int i = 0; i < 2; ++i) {
    const double y = b->Uniform(1.0 + i * W / 2, W / 2 - 7.0 + i * W / 2);
    b->AddBox({0.4, y, 0}, {2.8, y + 6.0, 2.6}, true);
  }
  {
    const double x = b->Uniform(3.0, X1 - 20.0), y = b->Uniform(3.0, W - 6.0);
    for (const double dx : {0.0, 2.45}) {
      for (const double dy : {0.0, 1.45}) {
        b->AddBox({x + dx, y + dy, 0}, {x + dx + 0.05, y + dy + 0.05, 4.0}, true);
      }
    }
    for (const double z : {2.0, 4.0}) b->AddBox({x, y, z - 0.05}, {x + 2.5, y + 1.5, z}, true);
  }
  const Box hall(Vec3(0.5, 0.5, 0), Vec3(X1 - 2.0, W - 0.5, 0));
  const int hall_stacks = static_cast<int>(o.furniture_per_room * X1 * W / 80.0);
  for (int k = 0; k < hall_stacks; ++k) b->AddRandomFurniture(hall, 0.8, 2.4, 2.2, 0.0);

  // ---- upper open-plan floor: pillars and stacks ----
  for (double x = X1 + 8.0; x < L - 1.0; x += 8.0) {
    for (double y = a1 + 4.2; y < W - 1.0; y += 8.0) {
      b->AddBox({x - 0.25, y - 0.25, h}, {x + 0.25, y + 0.25, 2 * h}, true);
    }
  }
  const Box open_floor(Vec3(X1 + 0.5, a1 + 0.5, 0), Vec3(L - 0.5, W - 0.5, 0));
  const int floor_stacks = static_cast<int>(o.furniture_per_room * (L - X1) * (W - a1) / 100.0);
  for (int k = 0; k < floor_stacks; ++k) b->AddRandomFurniture(open_floor, 0.6, 2.0, 1.5, h);

  // ---- route ----
  WalkingRoute route;
  route.closed = true;
  route.waypoints = {
      // Across the hall into corridor B, a loop through a north room, C.
      {4.0, yA, g}, {4.0, yB, g}, {xRn, yB, g}, {xRn, b1 + 2.2, g}, {xRn + 3.3, b1 + 2.2, g},
      {xRn + 3.3, b1 + 4.0, g}, {xRn, b1 + 4.0, g}, {xRn, yB, g}, {xCc, yB, g}, {xCc, yA, g},
      // Corridor A back into the hall, up the hall stair.
      {X1 - 8.0, yA, g}, {X1 - 8.0, yBottom + 2.7, g}, {xS, yBottom + 2.7, g}, {xS, yBottom, g},
      {xS, yTop, u}, {xS, yA, u},
      // The upper corridor, a loop through the open-plan floor back onto it.
      {X1 + 12.5, yA, u}, {X1 + 12.5, a1 + 8.2, u}, {X1 + 5.0, a1 + 8.2, u}, {X1 + 5.0, yA, u},
      // Down the stairwell, corridor A back through the hall to the start.
      {sE - 3.0, yA, u}, {sE - 1.0, yb, u}, {sE, yb, u}, {sE + kFlight, yb, m},
      {sE + kFlight + kLanding / 2, yb, m}, {sE + kFlight + kLanding / 2, ya, m},
      {sE + kFlight, ya, m}, {sE, ya, g}, {sE - 1.0, ya, g}, {sE - 3.0, yA, g}};
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
  } else if (options.type == "site") {
    scene->route_ = BuildSite(options, &builder);
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

namespace {

// Source of Scene::people_key_ values (0 = no people set).
std::atomic<uint64_t> next_people_key{0};

// The people of one scene posed at one time, kept per thread by
// Scene::IntersectPeople: bounding-sphere centres at once, full poses on the
// first ray that reaches a person's bounding sphere.
struct PeopleAtTime {
  uint64_t key = 0;
  TimestampNs t_ns = 0;
  std::vector<Eigen::Vector3f> centres;
  std::vector<char> posed;
  std::vector<PersonPose> poses;
};

}  // namespace

void Scene::SetPeople(std::vector<WalkingPerson> people) {
  people_ = std::move(people);
  people_key_ = next_people_key.fetch_add(1) + 1;
}

RayHit Scene::IntersectAt(TimestampNs t_ns,
                          const Vec3& origin,
                          const Vec3& direction,
                          double min_range,
                          double max_range) const {
  RayHit hit = Intersect(origin, direction, min_range, max_range);
  if (people_.empty()) return hit;
  const int valid = 1;
  const float o[3] = {static_cast<float>(origin.x()), static_cast<float>(origin.y()),
                      static_cast<float>(origin.z())};
  const float d[1][3] = {{static_cast<float>(direction.x()), static_cast<float>(direction.y()),
                          static_cast<float>(direction.z())}};
  IntersectPeople(t_ns, 1, &valid, o, d, static_cast<float>(min_range),
                  static_cast<float>(max_range), &hit);
  return hit;
}

void Scene::Intersect16At(TimestampNs t_ns,
                          const int valid[16],
                          const float origin[3],
                          const float directions[16][3],
                          float max_range,
                          bool coherent,
                          RayHit hits[16]) const {
  Intersect16(valid, origin, directions, max_range, coherent, hits);
  if (people_.empty()) return;
  IntersectPeople(t_ns, 16, valid, origin, directions, 0.f, max_range, hits);
}

void Scene::IntersectPeople(TimestampNs t_ns,
                            int num_rays,
                            const int* valid,
                            const float origin[3],
                            const float (*directions)[3],
                            float min_range,
                            float max_range,
                            RayHit* hits) const {
  thread_local PeopleAtTime cache;
  const size_t n = people_.size();
  if (cache.key != people_key_ || cache.t_ns != t_ns || cache.centres.size() != n) {
    cache.key = people_key_;
    cache.t_ns = t_ns;
    cache.centres.resize(n);
    cache.posed.assign(n, 0);
    cache.poses.resize(n);
    for (size_t p = 0; p < n; ++p) cache.centres[p] = people_[p].BoundCentre(t_ns);
  }
  const Eigen::Vector3f o(origin[0], origin[1], origin[2]);
  const float radius = PersonPose().radius;
  // People beyond every ray's current hit are hidden (most of them, behind walls).
  float reach = 0.f;
  for (int k = 0; k < num_rays; ++k) {
    if (valid[k]) reach = std::max(reach, hits[k].hit ? hits[k].distance : max_range);
  }
  for (size_t p = 0; p < n; ++p) {
    const Eigen::Vector3f oc = cache.centres[p] - o;
    const float q = oc.squaredNorm() - radius * radius;
    if (q > 0.f && oc.squaredNorm() > (reach + radius) * (reach + radius)) continue;
    for (int k = 0; k < num_rays; ++k) {
      if (!valid[k]) continue;
      const Eigen::Vector3f d(directions[k][0], directions[k][1], directions[k][2]);
      const float limit = hits[k].hit ? hits[k].distance : max_range;
      // Entry into the bounding sphere (0 when the origin is inside it).
      float entry = 0.f;
      if (q > 0.f) {
        const float b = oc.dot(d);
        const float disc = b * b - q;
        if (b <= 0.f || disc < 0.f) continue;
        entry = b - std::sqrt(disc);
        if (entry > limit) continue;
      }
      if (!cache.posed[p]) {
        cache.poses[p] = people_[p].Pose(t_ns);
        cache.posed[p] = 1;
      }
      // Tested from the sphere entry point (short distances keep float precision).
      const Eigen::Vector3f start = o + entry * d;
      float best = limit;
      int best_part = -1;
      Eigen::Vector3f best_normal;
      for (int part = 0; part < kBodyParts; ++part) {
        Eigen::Vector3f normal;
        const float t = entry + IntersectBodyPart(cache.poses[p].parts[part], start, d, &normal);
        if (t >= min_range && t < best) {
          best = t;
          best_part = part;
          best_normal = normal;
        }
      }
      if (best_part < 0) continue;
      hits[k].hit = true;
      hits[k].distance = best;
      hits[k].normal = best_normal;
      hits[k].surface_id = static_cast<uint32_t>(num_surfaces_ + kPersonSurfaces * p +
                                                 cache.poses[p].parts[best_part].surface);
    }
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
