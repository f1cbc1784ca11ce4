// Simulated LiDAR scan pairs with exactly known relative pose, for the covariance
// calibration study (icp/bench/icp_covariance_bench.cc,
// scripts/bench_icp_covariance.sh) and its unit test (header-only; tests and
// benchmarks only, lisfm_icp does not depend on lisfm_sim).
//
// Each pair is two single spinning scans (sim::LidarSimulator, 32 rings, range
// noise sigma 1 cm) cast from two *static* poses (a constant spline, so there is
// no motion distortion and no de-skew question) at two points of the scene's
// walking route 0.3-1.5 m apart, with random yaw (+-180 deg), roll/pitch (+-3 deg)
// and a relative yaw of up to +-15 deg. The LiDAR frame is the pose frame (z up).
// Truth: target_from_source = world_from_target^-1 * world_from_source, exact.
// The initial guess is truth * Exp(delta) with delta ~ N(0, diag(s_rot^2 I3,
// s_trans^2 I3)). Deterministic for a given scene and seed.
#pragma once

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "core/geometry.h"
#include "icp/nearest_neighbors.h"
#include "sim/lidar_simulator.h"
#include "sim/scene.h"
#include "sim/spline_trajectory.h"

namespace lisfm {
namespace test {

struct SimScanPairOptions {
  int azimuth_steps = 2000;          // columns per revolution (XT-32: 2000)
  double range_sigma_m = 0.01;       // 1-sigma range noise (m)
  double min_baseline_m = 0.3;       // distance between the two poses along the route (m)
  double max_baseline_m = 1.5;
  double max_relative_yaw_deg = 15;  // |yaw_source - yaw_target| bound (deg)
  double init_sigma_rotation_deg = 2.0;   // initial-guess error, per axis (deg)
  double init_sigma_translation_m = 0.1;  // initial-guess error, per axis (m)
};

struct SimScanPair {
  PointCloud source, target;  // in their own LiDAR frames
  SE3 truth;                  // target_from_source, exact
  SE3 initial;                // truth perturbed by the initial-guess error
};

// A point at arc length s (m) along the polyline `route` (clamped to its ends).
inline Vec3 RoutePoint(const std::vector<Vec3>& route, double s) {
  for (size_t i = 0; i + 1 < route.size(); ++i) {
    const double len = (route[i + 1] - route[i]).norm();
    if (s <= len || i + 2 == route.size()) {
      const double a = len > 0 ? std::clamp(s / len, 0.0, 1.0) : 0.0;
      return route[i] + a * (route[i + 1] - route[i]);
    }
    s -= len;
  }
  return route.front();
}

inline double RouteLength(const std::vector<Vec3>& route) {
  double total = 0;
  for (size_t i = 0; i + 1 < route.size(); ++i) total += (route[i + 1] - route[i]).norm();
  return total;
}

// One static scan from world_from_lidar (`scan_index` seeds the range noise).
inline PointCloud SimulateStaticScan(const sim::Scene& scene, const SE3& world_from_lidar,
                                     const SimScanPairOptions& options, int64_t scan_index) {
  const std::vector<Quat> rotations(4, world_from_lidar.rotation());
  const std::vector<Vec3> positions(4, world_from_lidar.translation());
  const sim::SplineTrajectory still(0, 0.1, rotations, positions);
  RigLidar lidar;
  lidar.type = LidarType::kSpinning;
  lidar.rings = 32;
  lidar.min_range = 0.3;
  lidar.max_range = 120.0;
  lidar.scan_rate = 10.0;
  sim::LidarSimOptions sim_options;
  sim_options.noise_scale = 1.0;
  sim_options.range_sigma = options.range_sigma_m;
  sim_options.azimuth_steps = options.azimuth_steps;
  sim_options.seed = 7;
  sim::TextureOptions texture;
  const sim::LidarSimulator simulator(scene, still, lidar, texture, sim_options);
  return simulator.SimulateScan(0, scan_index);
}

// `count` pairs in `scene`, deterministic for `seed`.
inline std::vector<SimScanPair> SimulateScanPairs(const sim::Scene& scene, int count,
                                                  uint32_t seed,
                                                  const SimScanPairOptions& options) {
  std::vector<Vec3> route = scene.route().waypoints;
  if (scene.route().closed && !route.empty()) route.push_back(route.front());
  const double length = RouteLength(route);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
  constexpr double kDeg = M_PI / 180.0;
  std::vector<SimScanPair> pairs;
  pairs.reserve(count);
  for (int k = 0; k < count; ++k) {
    const double baseline = uniform(options.min_baseline_m, options.max_baseline_m);
    const double s = uniform(0.0, std::max(length - baseline, 0.0));
    const double yaw = uniform(-M_PI, M_PI);
    auto pose = [&](double arc, double yaw_rad) {
      const Quat q = Quat(Eigen::AngleAxisd(yaw_rad, Vec3::UnitZ())) *
                     Quat(Eigen::AngleAxisd(uniform(-3, 3) * kDeg, Vec3::UnitY())) *
                     Quat(Eigen::AngleAxisd(uniform(-3, 3) * kDeg, Vec3::UnitX()));
      return SE3(q.normalized(), RoutePoint(route, arc));
    };
    const SE3 world_from_target = pose(s, yaw);
    const double dyaw = uniform(-options.max_relative_yaw_deg, options.max_relative_yaw_deg) * kDeg;
    const SE3 world_from_source = pose(s + baseline, yaw + dyaw);
    SimScanPair pair;
    pair.target = SimulateStaticScan(scene, world_from_target, options, 2 * k);
    pair.source = SimulateStaticScan(scene, world_from_source, options, 2 * k + 1);
    pair.truth = world_from_target.Inverse() * world_from_source;
    Vec6 delta;
    for (int i = 0; i < 3; ++i) delta(i) = gauss(rng) * options.init_sigma_rotation_deg * kDeg;
    for (int i = 3; i < 6; ++i) delta(i) = gauss(rng) * options.init_sigma_translation_m;
    pair.initial = pair.truth * SE3::Exp(delta);
    pairs.push_back(std::move(pair));
  }
  return pairs;
}

// A straight corridor (width x height, `length` long along x, centred at the
// origin, floor at z = 0) without end walls within LiDAR range when length > 240 m:
// translation along x is unobservable (the degenerate case).
inline std::unique_ptr<sim::Scene> CorridorScene(double length, double width, double height) {
  const float hx = static_cast<float>(length / 2), hy = static_cast<float>(width / 2),
              hz = static_cast<float>(height);
  std::vector<sim::Triangle> tris;
  auto quad = [&](const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
                  const Eigen::Vector3f& d, uint32_t id) {
    tris.push_back({a, b, c, id});
    tris.push_back({a, c, d, id});
  };
  quad({-hx, -hy, 0}, {hx, -hy, 0}, {hx, hy, 0}, {-hx, hy, 0}, 0);      // floor
  quad({-hx, -hy, hz}, {-hx, hy, hz}, {hx, hy, hz}, {hx, -hy, hz}, 1);  // ceiling
  quad({-hx, -hy, 0}, {-hx, -hy, hz}, {hx, -hy, hz}, {hx, -hy, 0}, 2);  // wall y = -hy
  quad({-hx, hy, 0}, {hx, hy, 0}, {hx, hy, hz}, {-hx, hy, hz}, 3);      // wall y = +hy
  return sim::Scene::FromTriangles(std::move(tris));
}

// Pairs in CorridorScene(300, 3, 3): poses at x in [-20, 20], y in [-0.5, 0.5],
// height 1.5 m, yaw +-180 deg, source 0.3-1.5 m further along x.
inline std::vector<SimScanPair> SimulateCorridorPairs(const sim::Scene& corridor, int count,
                                                      uint32_t seed,
                                                      const SimScanPairOptions& options) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
  constexpr double kDeg = M_PI / 180.0;
  std::vector<SimScanPair> pairs;
  for (int k = 0; k < count; ++k) {
    auto pose = [&](double x, double yaw) {
      const Quat q = Quat(Eigen::AngleAxisd(yaw, Vec3::UnitZ())) *
                     Quat(Eigen::AngleAxisd(uniform(-3, 3) * kDeg, Vec3::UnitY())) *
                     Quat(Eigen::AngleAxisd(uniform(-3, 3) * kDeg, Vec3::UnitX()));
      return SE3(q.normalized(), Vec3(x, uniform(-0.5, 0.5), 1.5));
    };
    const double x = uniform(-20, 20), yaw = uniform(-M_PI, M_PI);
    const SE3 world_from_target = pose(x, yaw);
    const SE3 world_from_source =
        pose(x + uniform(options.min_baseline_m, options.max_baseline_m),
             yaw + uniform(-options.max_relative_yaw_deg, options.max_relative_yaw_deg) * kDeg);
    SimScanPair pair;
    pair.target = SimulateStaticScan(corridor, world_from_target, options, 2 * k);
    pair.source = SimulateStaticScan(corridor, world_from_source, options, 2 * k + 1);
    pair.truth = world_from_target.Inverse() * world_from_source;
    Vec6 delta;
    for (int i = 0; i < 3; ++i) delta(i) = gauss(rng) * options.init_sigma_rotation_deg * kDeg;
    for (int i = 3; i < 6; ++i) delta(i) = gauss(rng) * options.init_sigma_translation_m;
    pair.initial = pair.truth * SE3::Exp(delta);
    pairs.push_back(std::move(pair));
  }
  return pairs;
}

}  // namespace test
}  // namespace lisfm
