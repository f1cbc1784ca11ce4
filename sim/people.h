// People walking through a scene (simulator error source `dynamics`):
// moving, articulated bodies that the LiDARs and the cameras see
// (Scene::IntersectAt / Intersect16At cast every ray against the people posed
// at the ray's own time).
//
// Body, in the person frame (x forward, y left, z up, feet at the origin),
// sized after adult anthropometry (ISO 7250 / DIN 33402 means, rounded):
//   head   sphere, radius 0.11 m, centre at 1.62 m (top of head 1.73 m);
//   torso  two vertical capsules, radius 0.13 m, y = +-0.08 m, z 1.0 .. 1.38 m
//          (0.42 m wide, 0.26 m deep);
//   arms   capsules, radius 0.05 m, 0.6 m long from the shoulders (y = +-0.24 m,
//          z 1.42 m), swinging +-0.3 rad about y in antiphase with the legs;
//   legs   capsules, radius 0.075 m, 0.88 m long from the hips (y = +-0.1 m,
//          z 0.9 m), swinging +-0.35 rad about y.
// The gait phase advances 2 pi per stride of 1.45 m (two steps of 0.72 m, a
// cadence of 1.8 Hz at 1.3 m/s). Every part lies inside the bounding sphere
// of radius 1.0 m about (0, 0, 0.88 m).
//
// Motion: a person walks a closed path of feet positions (scene frame) at a
// constant speed, heading along the path; the pose is a pure function of the
// time, so scans and renders at any time, in any order and on any thread see
// the same people.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "core/time.h"
#include "core/types.h"

namespace lisfm {
namespace sim {

class Scene;
struct WalkingRoute;

// The `dynamics` error source: people walking along the scene's route.
struct DynamicsOptions {
  // People per 100 m of the walking route (per cycle of it; rounded, at least
  // one when > 0). 0 = no people.
  double people_per_100m = 2.0;
  // Mean walking speed of the people, m/s; each person walks at a speed drawn
  // uniformly within +-15 % of it.
  double speed = 1.3;
  bool Check() const;
};

// Surface ids per person: head, torso, arms, legs.
constexpr int kPersonSurfaces = 4;
constexpr int kBodyParts = 7;

// A capsule (the points within `radius` of the segment a-b; a sphere when
// a == b) in the scene frame.
struct BodyPart {
  Eigen::Vector3f a = Eigen::Vector3f::Zero();
  Eigen::Vector3f b = Eigen::Vector3f::Zero();
  float radius = 0;
  int surface = 0;  // 0 head, 1 torso, 2 arms, 3 legs (< kPersonSurfaces)
};

struct PersonPose {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();  // bounding sphere centre
  float radius = 1.0f;                               // bounding sphere radius, m
  std::array<BodyPart, kBodyParts> parts;
};

// Distance along the unit ray `origin + s * direction` at which it enters
// `part` (s > 0), or +infinity when it misses or starts inside; `normal`
// receives the outward unit normal at the entry point.
float IntersectBodyPart(const BodyPart& part,
                        const Eigen::Vector3f& origin,
                        const Eigen::Vector3f& direction,
                        Eigen::Vector3f* normal);

class WalkingPerson {
 public:
  // `path`: closed polyline of feet positions (scene frame; the last point
  // connects to the first) sampled every `spacing_m` of arc; at `start_ns`
  // the person is at arc `start_m` and walks `speed` m/s along the path
  // (negative: against its direction).
  WalkingPerson(
      std::vector<Vec3> path, double spacing_m, double start_m, double speed, TimestampNs start_ns);

  // Feet position (scene frame) and heading (rad about z, 0 = +x; not
  // computed when `yaw` is null) at t_ns.
  void Locate(TimestampNs t_ns, Vec3* feet, double* yaw) const;
  // Bounding sphere centre at t_ns (radius PersonPose::radius).
  Eigen::Vector3f BoundCentre(TimestampNs t_ns) const;
  // The posed body at t_ns.
  PersonPose Pose(TimestampNs t_ns) const;

  double speed() const { return speed_; }
  double path_length_m() const { return spacing_ * static_cast<double>(path_.size()); }
  const std::vector<Vec3>& path() const { return path_; }

 private:
  // Arc position on the path at t_ns, in [0, path_length_m()).
  double ArcAt(TimestampNs t_ns) const;

  std::vector<Vec3> path_;
  double spacing_;
  double start_m_;
  double speed_;
  TimestampNs start_ns_;
};

// The people of `scene` (error source `dynamics`): n = round(people_per_100m *
// cycle / 100) people (at least one when people_per_100m > 0) on the cycle of
// `route` (closed: the loop; open: out and back), starting spread along it (5
// m or more from its start), half of them walking against its direction, at
// speeds within +-15 % of options.speed. Each keeps to the right of its
// direction, 0.8 m from the route's centre line where the static geometry
// leaves room (0.35 m from walls, rails and obstacles, found by horizontal
// ray casts every 0.1 m from 0.1 to 1.8 m above the feet), else closer to the
// centre line;
// feet at the route's height minus kRouteDeviceHeight. Deterministic for
// `seed`; empty for a route with fewer than two waypoints.
std::vector<WalkingPerson> GeneratePeople(const Scene& scene,
                                          const WalkingRoute& route,
                                          const DynamicsOptions& options,
                                          TimestampNs start_ns,
                                          uint32_t seed);

}  // namespace sim
}  // namespace lisfm
