// Procedural simulation scenes (DESIGN.md "sim/"): triangle meshes in the
// scene frame (metres, z up, gravity along -z) with one surface id per
// triangle, ray cast through an Embree 3 BVH.
//
// Four scene types are generated from a seed: "office" (rooms around a
// corridor loop, doorways, pillars, furniture boxes), "staircase" (a narrow
// two-storey stairwell with corridors at both levels, LiDAR-degenerate),
// "hall" (a parking-garage-size hall with a pillar grid and parked cars) and
// "site" (a construction-site floor: a double-height hall, a two-storey wing
// with long corridors and rooms, an open-plan upper floor, two staircases).
// Each type also defines the walking route that generated motion follows
// (WalkingRoute), so scene and motion always agree.
//
// People (sim/people.h) may be added to a scene; they move, so every ray that
// should see them is cast at its own time (IntersectAt, Intersect16At).
//
// Thread safety: after Generate() / FromTriangles() and SetPeople(), the
// Intersect* functions may be called concurrently.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/time.h"
#include "core/types.h"
#include "sim/materials.h"
#include "sim/people.h"

namespace lisfm {
namespace sim {

// Parameters of a procedural scene; configs/sim_<type>.yaml lists them with
// their defaults. Sizes in metres.
struct SceneOptions {
  std::string type = "office";  // office | staircase | hall | site
  int seed = 1;                 // layout and texture seed
  double length = 40.0;         // footprint along x (office, hall, site), m
  double width = 24.0;          // footprint along y (office, hall, site), m
  double height = 3.0;          // floor-to-ceiling height (site: storey height), m
  double corridor_width = 3.0;  // office / site corridor width, m
  double room_depth = 5.0;      // office / site room depth, m
  int furniture_per_room = 3;   // boxes per office room (site: clutter density)
  double pillar_spacing = 8.0;  // hall / site-hall pillar grid, m
  double car_density = 0.6;     // fraction of hall parking bays occupied
  double texture_scale = 1.0;   // multiplies the spatial frequencies of the texture
  // The materials each surface class draws from (YAML: `materials: {wall:
  // [painted_plaster, wood], ...}`, names from sim/materials.h).
  MaterialPools materials;

  bool Check() const;
  // Throws InputError naming `where` (a scene file) and the failing field
  // unless Check() passes.
  void CheckOrThrow(const std::string& where) const;
};

// Returns the defaults of a scene type; throws InputError for an unknown type.
SceneOptions DefaultSceneOptions(const std::string& type);
// Reads `configs/sim_*.yaml` (keys as the SceneOptions fields; missing keys keep
// the defaults of its `type`). Throws InputError for unknown keys/bad values,
// unknown surface classes and unknown material names.
SceneOptions ReadSceneOptions(const std::string& path);

// Resolves `--scene`: a type name ("office", "staircase", "hall", "site") or a
// YAML path.
SceneOptions ResolveSceneOptions(const std::string& scene);

// Route waypoints are this far above the floor (the handheld device), m.
constexpr double kRouteDeviceHeight = 1.4;

struct Triangle {
  Eigen::Vector3f a, b, c;
  uint32_t surface_id = 0;
};

struct RayHit {
  bool hit = false;
  float distance = 0;    // along the unit ray direction, m
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();  // unit geometric normal, facing the ray origin
  uint32_t surface_id = 0;
};

// The route a person walks through a scene: 3D waypoints of the device
// position (device height above the floor already added), in order.
struct WalkingRoute {
  std::vector<Vec3> waypoints;
  bool closed = false;  // true: loop back to the first waypoint; false: ping-pong
};

class Scene {
 public:
  Scene();
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  // Generates the scene of `options`. If `keep_clear` is not empty (a real
  // trajectory's positions), the footprint grows to contain it with 3 m margin
  // and every interior obstacle within 0.7 m of it (horizontally) is removed,
  // so that the trajectory never passes through geometry.
  static std::unique_ptr<Scene> Generate(const SceneOptions& options,
                                         const std::vector<Vec3>& keep_clear = {});
  // A scene from explicit triangles (tests).
  static std::unique_ptr<Scene> FromTriangles(std::vector<Triangle> triangles);

  // Closest hit of the static geometry along `origin + s * direction`, s in
  // [min_range, max_range]; `direction` must be unit length.
  RayHit Intersect(const Vec3& origin,
                   const Vec3& direction,
                   double min_range = 0.0,
                   double max_range = 1e4) const;
  // Sixteen rays from one origin at once (Embree ray packet), static
  // geometry; `valid[i]` = 0 skips ray i. `coherent`: the rays are neighbours
  // (e.g. a 4x4 pixel block), which lets Embree trace them as a packet.
  void Intersect16(const int valid[16],
                   const float origin[3],
                   const float directions[16][3],
                   float max_range,
                   bool coherent,
                   RayHit hits[16]) const;

  // The same at time `t_ns`: the closest hit of the static geometry and of the
  // people posed at t_ns (analytic ray-capsule tests after a bounding-sphere
  // test; a ray that starts inside a person does not see that person). The
  // people's poses at t_ns are computed once per thread and time and reused
  // by the following calls at the same t_ns (a LiDAR column, a camera image).
  // Without people these equal Intersect / Intersect16 exactly.
  RayHit IntersectAt(TimestampNs t_ns,
                     const Vec3& origin,
                     const Vec3& direction,
                     double min_range = 0.0,
                     double max_range = 1e4) const;
  void Intersect16At(TimestampNs t_ns,
                     const int valid[16],
                     const float origin[3],
                     const float directions[16][3],
                     float max_range,
                     bool coherent,
                     RayHit hits[16]) const;

  // Adds people who walk through the scene (replacing earlier ones). Their
  // surface ids are num_static_surfaces() + kPersonSurfaces * i + part.
  // Not thread-safe: call before any concurrent Intersect*At.
  void SetPeople(std::vector<WalkingPerson> people);
  const std::vector<WalkingPerson>& people() const { return people_; }

  const std::vector<Triangle>& triangles() const { return triangles_; }
  const WalkingRoute& route() const { return route_; }
  const SceneOptions& options() const { return options_; }
  // Surface ids in [0, num_surfaces()): the static surfaces first
  // ([0, num_static_surfaces())), then kPersonSurfaces per person.
  int num_surfaces() const {
    return num_surfaces_ + kPersonSurfaces * static_cast<int>(people_.size());
  }
  int num_static_surfaces() const { return num_surfaces_; }

  // Per surface id: how the builder made it (kObject for FromTriangles
  // scenes) and its material (DefaultMaterial() where none is assigned, e.g.
  // people and ids beyond num_static_surfaces()).
  SurfaceClass surface_class(uint32_t surface_id) const {
    return surface_id < surface_classes_.size() ? surface_classes_[surface_id]
                                                : SurfaceClass::kObject;
  }
  MaterialId material_id(uint32_t surface_id) const {
    return surface_id < materials_.size() ? materials_[surface_id] : DefaultMaterial();
  }
  const Material& material(uint32_t surface_id) const {
    return Materials()[material_id(surface_id)];
  }
  // Draws the material of every surface from options().materials
  // (sim/materials.h AssignMaterials, seeded by options().seed). Generate()
  // calls it with MaterialOptions' default fraction. Not thread-safe.
  void AssignMaterials(double texture_poor_fraction);
  // Sets the materials explicitly (one per surface id; tests). Not thread-safe.
  void SetMaterials(std::vector<MaterialId> per_surface) { materials_ = std::move(per_surface); }
  Eigen::AlignedBox3d Bounds() const;

  // Writes the mesh as binary PLY (vertex x y z float, face list, per-face
  // uchar red green blue from the surface id), atomically.
  void WritePly(const std::string& path) const;

 private:
  void Build();

  // Adds the people posed at t_ns to `hits` of rays from `origin`: hits[i]
  // is replaced where ray i (unit `directions[i]`, valid[i] != 0) enters a
  // person closer than its current hit (or than max_range without one).
  void IntersectPeople(TimestampNs t_ns,
                       int num_rays,
                       const int* valid,
                       const float origin[3],
                       const float (*directions)[3],
                       float min_range,
                       float max_range,
                       RayHit* hits) const;

  SceneOptions options_;
  std::vector<Triangle> triangles_;
  WalkingRoute route_;
  int num_surfaces_ = 0;  // static surfaces
  std::vector<SurfaceClass> surface_classes_;  // per static surface id
  std::vector<MaterialId> materials_;          // per static surface id
  std::vector<WalkingPerson> people_;
  uint64_t people_key_ = 0;  // unique per SetPeople call (pose cache key)
  struct EmbreeState;
  std::unique_ptr<EmbreeState> embree_;
};

}  // namespace sim
}  // namespace lisfm
