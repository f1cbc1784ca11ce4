// The procedural scenes with their generated walks: the construction site's
// layout (two levels, footprint), clearance of every walk from the geometry
// (stairs included), revisits, and the control points of every scene (six or
// more, well spread, visible).
#include "sim/scene.h"

#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cstdio>

#include "sim/motion.h"
#include "sim/simulator.h"
#include "tests/common/point_triangle_distance.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

using test::PointTriangleDistance;

// Distance from a point to the nearest triangle of a scene, exact up to
// `cap` (farther triangles are skipped by their bounding boxes).
class DistanceField {
 public:
  explicit DistanceField(const Scene& scene) : triangles_(scene.triangles()) {
    for (const Triangle& t : triangles_) {
      Eigen::AlignedBox3d box;
      box.extend(t.a.cast<double>());
      box.extend(t.b.cast<double>());
      box.extend(t.c.cast<double>());
      boxes_.push_back(box);
    }
  }
  double Distance(const Vec3& p, double cap) const {
    double best = cap;
    for (size_t i = 0; i < triangles_.size(); ++i) {
      if (boxes_[i].exteriorDistance(p) >= best) continue;
      const Triangle& t = triangles_[i];
      best = std::min(
          best,
          PointTriangleDistance(p, t.a.cast<double>(), t.b.cast<double>(), t.c.cast<double>()));
    }
    return best;
  }

 private:
  const std::vector<Triangle>& triangles_;
  std::vector<Eigen::AlignedBox3d> boxes_;
};

struct Walk {
  std::unique_ptr<Scene> scene;
  SplineTrajectory trajectory;
  std::vector<StationaryPeriod> stationary;
  double duration_s = 0;
};

// The scene's generated walk with the default walking options, as
// `lisfm simulate --scene <type> --duration <duration_s>` makes it (seed 1).
Walk DefaultWalk(const std::string& type, double duration_s) {
  Walk walk;
  SceneOptions options = DefaultSceneOptions(type);
  options.seed = options.seed * 1000003 + 1;  // as Simulate combines it with --seed 1
  walk.scene = Scene::Generate(options);
  walk.duration_s = duration_s;
  walk.trajectory = GenerateWalking(
      walk.scene->route(), duration_s, kDefaultStartNs, 1, WalkingOptions(), &walk.stationary);
  return walk;
}

TEST(SiteScene, TwoLevelsOnAtLeast60By40Metres) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto scene = Scene::Generate(DefaultSceneOptions("site"));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("site: %zu triangles, %d surfaces, built in %.3f s\n",
              scene->triangles().size(),
              scene->num_surfaces(),
              seconds);
  const Eigen::AlignedBox3d bounds = scene->Bounds();
  EXPECT_GE(bounds.sizes().x(), 60.0);
  EXPECT_GE(bounds.sizes().y(), 40.0);
  // The walk reaches the upper level (3.5 m storeys) and comes back down.
  double z_min = 1e9, z_max = -1e9;
  for (const Vec3& w : scene->route().waypoints) {
    z_min = std::min(z_min, w.z());
    z_max = std::max(z_max, w.z());
  }
  EXPECT_NEAR(z_min, kRouteDeviceHeight, 1e-9);
  EXPECT_NEAR(z_max, 3.5 + kRouteDeviceHeight, 1e-9);
  EXPECT_TRUE(scene->route().closed);
  // Looking up from the ground floor of the wing there is a ceiling at the
  // storey height; in the hall the roof is two storeys up.
  const RayHit wing = scene->Intersect(Vec3(40.0, 20.0, 1.4), Vec3::UnitZ());
  ASSERT_TRUE(wing.hit);
  EXPECT_NEAR(1.4 + wing.distance, 3.5 - 0.2, 1e-4);
  const RayHit hall = scene->Intersect(Vec3(4.0, 5.0, 1.4), Vec3::UnitZ());
  ASSERT_TRUE(hall.hit);
  EXPECT_NEAR(1.4 + hall.distance, 7.0, 1e-4);
}

// Every generated walk keeps 0.3 m from the geometry (walls, door jambs, stair
// steps, rails, furniture), sampled every 50 ms (5 cm of walk).
TEST(Scenes, GeneratedWalksKeepClearOfTheGeometry) {
  for (const auto& [type, duration] : std::vector<std::pair<std::string, double>>{
           {"site", 330.0}, {"office", 90.0}, {"staircase", 60.0}, {"hall", 150.0}}) {
    const Walk walk = DefaultWalk(type, duration);
    const DistanceField field(*walk.scene);
    double closest = 1e9;
    TimestampNs t_closest = 0;
    for (TimestampNs t = walk.trajectory.start_ns(); t <= walk.trajectory.end_ns(); t += 50000000) {
      const double d = field.Distance(walk.trajectory.Pose(t).translation(), 2.0);
      if (d < closest) {
        closest = d;
        t_closest = t;
      }
    }
    std::printf("%s: closest approach %.3f m at %.1f s\n",
                type.c_str(),
                closest,
                NsToSeconds(t_closest - walk.trajectory.start_ns()));
    EXPECT_GE(closest, 0.3) << type << " at " << NsToSeconds(t_closest - walk.trajectory.start_ns())
                            << " s";
  }
}

// Five minutes on the site: both levels, a few hundred metres, and several
// returns to places walked after a loop (loop closures).
TEST(SiteScene, FiveMinuteWalkVisitsBothLevelsAndRevisits) {
  const Walk walk = DefaultWalk("site", 300.0);
  std::vector<Vec3> p;  // 1 Hz
  double length = 0;
  for (TimestampNs t = walk.trajectory.start_ns(); t <= walk.trajectory.end_ns(); t += 1000000000) {
    p.push_back(walk.trajectory.Pose(t).translation());
    if (p.size() > 1) length += (p.back() - p[p.size() - 2]).norm();
  }
  double z_min = 1e9, z_max = -1e9;
  for (const Vec3& q : p) {
    z_min = std::min(z_min, q.z());
    z_max = std::max(z_max, q.z());
  }
  EXPECT_GT(z_max - z_min, 3.0);
  EXPECT_GT(length, 200.0);
  // Revisit episodes (loop closures): within 1.5 m of a position passed >= 25 s
  // (about 25 m of walk) earlier; episodes are separated by >= 10 s of new ground.
  int episodes = 0;
  int last = -100;
  for (size_t j = 0; j < p.size(); ++j) {
    bool revisit = false;
    for (size_t i = 0; i + 25 <= j && !revisit; ++i) revisit = (p[j] - p[i]).norm() < 1.5;
    if (revisit) {
      if (static_cast<int>(j) - last > 10) ++episodes;
      last = static_cast<int>(j);
    }
  }
  std::printf("site 300 s: path %.0f m, z %.2f..%.2f m, %d revisit episodes\n",
              length,
              z_min,
              z_max,
              episodes);
  EXPECT_GE(episodes, 2);
}

// Control points (HILTI-style): at least six per sequence, spread in the plane
// (not collinear: the second singular value of the centred coordinates, as an
// RMS distance, is >= 1 m; the staircase shaft is 2.8 m wide) and visible:
// the device touches the point (the tip
// lies in free space and the segment from the IMU to it is clear) and a
// surveyor can see it from the walk (a clear line of sight from a device
// position >= 5 s away in time and 1..15 m away in space).
TEST(ControlPoints, SixOrMoreWellSpreadAndVisibleInEveryScene) {
  for (const auto& [type, duration] : std::vector<std::pair<std::string, double>>{
           {"office", 60.0}, {"staircase", 60.0}, {"hall", 120.0}, {"site", 300.0}}) {
    // The hall's walk turns its first corner after 48 m: 60 s are one straight lane.
    const Walk walk = DefaultWalk(type, duration);
    const TimestampNs start = walk.trajectory.start_ns();
    const std::vector<ControlPoint> points =
        SurveyControlPoints(walk.trajectory, walk.stationary, start, start + SecondsToNs(duration));
    ASSERT_GE(points.size(), 6u) << type;
    Eigen::MatrixXd centred(points.size(), 3);
    Vec3 mean = Vec3::Zero();
    for (const ControlPoint& c : points) mean += c.position / points.size();
    for (size_t i = 0; i < points.size(); ++i) centred.row(i) = points[i].position - mean;
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::MatrixXd>(centred).singularValues();
    const double rms2 = sv(1) / std::sqrt(static_cast<double>(points.size()));
    std::printf("%s: %zu control points, RMS spread along the principal axes %.2f %.2f %.2f m\n",
                type.c_str(),
                points.size(),
                sv(0) / std::sqrt(points.size()),
                rms2,
                sv(2) / std::sqrt(points.size()));
    EXPECT_GE(rms2, 1.0) << type;
    const DistanceField field(*walk.scene);
    for (const ControlPoint& c : points) {
      const Vec3 imu = walk.trajectory.Pose(c.t_ns).translation();
      const Vec3 to_tip = c.position - imu;
      EXPECT_FALSE(walk.scene->Intersect(imu, to_tip.normalized(), 0.0, to_tip.norm()).hit)
          << type << " at " << NsToSeconds(c.t_ns - start) << " s";
      EXPECT_GT(field.Distance(c.position, 1.0), 0.05) << type;
      bool seen = false;
      for (TimestampNs t = start; t <= walk.trajectory.end_ns() && !seen; t += 250000000) {
        if (std::abs(NsToSeconds(t - c.t_ns)) < 5.0) continue;
        const Vec3 device = walk.trajectory.Pose(t).translation();
        const Vec3 ray = c.position - device;
        if (ray.norm() < 1.0 || ray.norm() > 15.0) continue;
        seen = !walk.scene->Intersect(device, ray.normalized(), 0.0, ray.norm()).hit;
      }
      EXPECT_TRUE(seen) << type << ": control point at " << NsToSeconds(c.t_ns - start)
                        << " s is seen from nowhere else on the walk";
    }
  }
}

// People (error source `dynamics`) on the office loop and the site: their
// number follows the density, half walk against the route, speeds within
// +-15 % of the mean, and their torsos (1 m above the feet) stay clear of the
// static geometry along the whole path (they keep right where there is room).
TEST(GeneratePeople, DensitySpeedsAndClearance) {
  for (const std::string type : {"office", "site"}) {
    const auto scene = Scene::Generate(DefaultSceneOptions(type));
    const WalkingRoute& route = scene->route();
    double cycle = 0;
    for (size_t i = 0; i < route.waypoints.size(); ++i) {
      cycle += (route.waypoints[(i + 1) % route.waypoints.size()] - route.waypoints[i]).norm();
    }
    DynamicsOptions options;
    options.people_per_100m = 3.0;
    const std::vector<WalkingPerson> people = GeneratePeople(*scene, route, options, 0, 7);
    EXPECT_EQ(static_cast<double>(people.size()), std::max(1.0, std::round(3.0 * cycle / 100)))
        << type;
    const DistanceField field(*scene);
    int against = 0;
    for (const WalkingPerson& person : people) {
      against += person.speed() < 0;
      EXPECT_GE(std::abs(person.speed()), 0.85 * options.speed - 1e-9);
      EXPECT_LE(std::abs(person.speed()), 1.15 * options.speed + 1e-9);
      EXPECT_NEAR(person.path_length_m(), cycle, 0.2) << type;
      double closest = 1e9;
      Vec3 where = Vec3::Zero();
      for (const Vec3& feet : person.path()) {
        const double d = field.Distance(feet + Vec3(0, 0, 1.0), 1.0);
        if (d < closest) {
          closest = d;
          where = feet;
        }
      }
      std::printf(
          "%s: person at %.2f m/s, torso axis >= %.2f m from the geometry (feet at "
          "%.2f %.2f %.2f)\n",
          type.c_str(),
          person.speed(),
          closest,
          where.x(),
          where.y(),
          where.z());
      EXPECT_GE(closest, 0.3) << type;
    }
    EXPECT_EQ(against, static_cast<int>(people.size()) / 2) << type;
  }
  DynamicsOptions none;
  none.people_per_100m = 0;
  const auto office = Scene::Generate(DefaultSceneOptions("office"));
  EXPECT_TRUE(GeneratePeople(*office, office->route(), none, 0, 7).empty());
}

// num_stops rests of length r: [0, r], [T - r, T] and the others centred at
// k T / (N - 1); each exactly still; 3 stops = start, middle, end.
TEST(GenerateWalking, RestsAreSpreadEvenlyInTime) {
  const auto scene = Scene::Generate(DefaultSceneOptions("office"));
  for (const int n : {3, 6, 9}) {
    WalkingOptions options;
    options.num_stops = n;
    const double duration = 90.0;
    std::vector<StationaryPeriod> rests;
    const SplineTrajectory walk = GenerateWalking(scene->route(), duration, 0, 1, options, &rests);
    ASSERT_EQ(rests.size(), static_cast<size_t>(n));
    const double rest = std::min(options.stationary_s, duration / (2.0 * n));
    for (int k = 0; k < n; ++k) {
      const double centre = duration * k / (n - 1);
      const double t0 = k == 0 ? 0.0 : (k == n - 1 ? duration - rest : centre - rest / 2);
      const double t1 = k == 0 ? rest : (k == n - 1 ? duration : centre + rest / 2);
      // The constant part: the rest less 2 knots (0.2 s) at each inner end.
      EXPECT_NEAR(NsToSeconds(rests[k].start_ns), k == 0 ? 0.0 : t0 + 0.2, 1e-6) << n << " " << k;
      EXPECT_NEAR(NsToSeconds(rests[k].end_ns), k == n - 1 ? duration : t1 - 0.2, 1e-6)
          << n << " " << k;
      const SE3 still = walk.Pose(rests[k].start_ns);
      for (TimestampNs t = rests[k].start_ns; t <= rests[k].end_ns; t += 100000000) {
        EXPECT_TRUE(test::PosesNear(walk.Pose(t), still, 1e-12, 1e-12));
      }
    }
  }
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
