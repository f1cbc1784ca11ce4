// Simulated LiDAR scan pairs with exactly known relative pose, for the covariance
// calibration study (bench/icp_covariance_bench.cc,
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
#include "core/option_check.h"
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
  bool Check() const {
    CHECK_OPTION_GE(azimuth_steps, 1);
    CHECK_OPTION_GE(range_sigma_m, 0.0);
    CHECK_OPTION_GE(min_baseline_m, 0.0);
    CHECK_OPTION_GE(max_baseline_m, min_baseline_m);
    CHECK_OPTION_GE(max_relative_yaw_deg, 0.0);
    CHECK_OPTION_GE(init_sigma_rotation_deg, 0.0);
    CHECK_OPTION_GE(init_sigma_translation_m, 0.0);
    return true;
  }
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

// `count` pairs in `scene` along `walking_route`, deterministic for `seed`.
inline std::vector<SimScanPair> SimulateScanPairs(const sim::Scene& scene,
                                                  const sim::WalkingRoute& walking_route,
                                                  int count, uint32_t seed,
                                                  const SimScanPairOptions& options) {
  THROW_CHECK_OPTIONS(options);
  std::vector<Vec3> route = walking_route.waypoints;
  if (walking_route.closed && !route.empty()) route.push_back(route.front());
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

// `count` pairs along the scene's own walking route.
inline std::vector<SimScanPair> SimulateScanPairs(const sim::Scene& scene, int count,
                                                  uint32_t seed,
                                                  const SimScanPairOptions& options) {
  return SimulateScanPairs(scene, scene.route(), count, seed, options);
}

// The 12 triangles of the axis-aligned box [lo, hi] (surface id `id`).
inline void AppendBoxTriangles(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, uint32_t id,
                               std::vector<sim::Triangle>* tris) {
  const Eigen::Vector3f c[8] = {{lo.x(), lo.y(), lo.z()}, {hi.x(), lo.y(), lo.z()},
                                {hi.x(), hi.y(), lo.z()}, {lo.x(), hi.y(), lo.z()},
                                {lo.x(), lo.y(), hi.z()}, {hi.x(), lo.y(), hi.z()},
                                {hi.x(), hi.y(), hi.z()}, {lo.x(), hi.y(), hi.z()}};
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                           {2, 3, 7, 6}, {1, 2, 6, 5}, {3, 0, 4, 7}};
  for (const auto& f : faces) {
    tris->push_back({c[f[0]], c[f[1]], c[f[2]], id});
    tris->push_back({c[f[0]], c[f[2]], c[f[3]], id});
  }
}

// A stair tower (a tuning check of the covariance calibration; NOT the sim's
// held-out "staircase" generator): a 6 x 4.4 m shaft of three 3 m storeys
// with a switchback stair around an open 1.8 m well. Per storey, flight A (y in
// [0, 1.3]) climbs +x over x in [1.6, 4.4] to a landing (x in [4.4, 6]) at +1.5 m,
// flight B (y in [3.1, 4.4]) climbs -x to the next floor slab (x in [0, 1.6]);
// 10 steps of 0.15 x 0.28 m, the ground flight solid, the others 0.25 m slabs;
// handrail posts and rails along the well, a few crates on floors and landings
// (placed from `seed`). The route walks from the ground floor up two storeys.
inline std::unique_ptr<sim::Scene> StairTowerScene(uint32_t seed, sim::WalkingRoute* route) {
  std::vector<sim::Triangle> tris;
  uint32_t id = 0;
  auto box = [&](double x0, double y0, double z0, double x1, double y1, double z1) {
    AppendBoxTriangles(Eigen::Vector3f(x0, y0, z0), Eigen::Vector3f(x1, y1, z1), id++, &tris);
  };
  constexpr double kX = 6.0, kY = 4.4, kStorey = 3.0, kWall = 0.2;
  constexpr int kStoreys = 3, kSteps = 10;
  const double rise = 0.5 * kStorey / kSteps, tread = 2.8 / kSteps;
  // Shell: floor, ceiling and four walls (boxes outside the shaft).
  box(-kWall, -kWall, -kWall, kX + kWall, kY + kWall, 0);
  box(-kWall, -kWall, kStoreys * kStorey, kX + kWall, kY + kWall, kStoreys * kStorey + kWall);
  box(-kWall, -kWall, 0, 0, kY + kWall, kStoreys * kStorey);
  box(kX, -kWall, 0, kX + kWall, kY + kWall, kStoreys * kStorey);
  box(0, -kWall, 0, kX, 0, kStoreys * kStorey);
  box(0, kY, 0, kX, kY + kWall, kStoreys * kStorey);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
  for (int s = 0; s < kStoreys; ++s) {
    const double z = s * kStorey;
    if (s > 0) box(0, 0, z - 0.2, 1.6, kY, z);             // floor slab
    box(4.4, 0, z + 1.3, kX, kY, z + 1.5);  // landing slab
    for (int i = 0; i < kSteps; ++i) {
      const double top_a = z + (i + 1) * rise, top_b = z + 0.5 * kStorey + (i + 1) * rise;
      const double bottom_a = s == 0 ? 0.0 : top_a - 0.25;
      box(1.6 + i * tread, 0, bottom_a, 1.6 + (i + 1) * tread, 1.3, top_a);
      box(4.4 - (i + 1) * tread, 3.1, top_b - 0.25, 4.4 - i * tread, kY, top_b);
    }
    // Handrail posts every ~0.7 m along both flights' well edges, and the rails.
    for (int k = 0; k <= 4; ++k) {
      const double x = 1.65 + k * 0.675;
      const double za = z + (x - 1.6) / tread * rise, zb = z + 0.5 * kStorey + (4.4 - x) / tread * rise;
      box(x, 1.25, za, x + 0.05, 1.3, za + 0.9);
      box(x, 3.1, zb, x + 0.05, 3.15, zb + 0.9);
    }
    // Crates on the floor slab / ground floor and on the landing.
    for (int k = 0; k < 2; ++k) {
      const double w = uniform(0.3, 0.6), d = uniform(0.3, 0.6), h = uniform(0.3, 1.0);
      const double y = uniform(0.0, kY - d);
      box(0.0, y, z, w, y + d, z + h);
      const double y2 = k == 0 ? uniform(0.0, 1.3 - d) : uniform(3.1, kY - d);
      box(kX - w, y2, z + 1.5, kX, y2 + d, z + 1.5 + h);
    }
    // A pipe along the ceiling of each storey and a wall cabinet.
    box(0, kY - 0.3, z + kStorey - 0.5, kX, kY - 0.2, z + kStorey - 0.4);
    const double cy = uniform(1.4, 2.6);
    box(0, cy, z + 1.2, 0.25, cy + 0.5, z + 1.9);
  }
  route->closed = false;
  route->waypoints.clear();
  constexpr double kDevice = 1.4;
  for (int s = 0; s + 1 < kStoreys; ++s) {
    const double z = s * kStorey + kDevice;
    route->waypoints.push_back({0.8, 2.2, z});
    route->waypoints.push_back({1.6, 0.65, z});
    route->waypoints.push_back({4.4, 0.65, z + 0.5 * kStorey});
    route->waypoints.push_back({5.2, 0.65, z + 0.5 * kStorey});
    route->waypoints.push_back({5.2, 3.75, z + 0.5 * kStorey});
    route->waypoints.push_back({4.4, 3.75, z + 0.5 * kStorey});
    route->waypoints.push_back({1.6, 3.75, z + kStorey});
  }
  route->waypoints.push_back({0.8, 2.2, (kStoreys - 1) * kStorey + kDevice});
  return sim::Scene::FromTriangles(std::move(tris));
}

// A service corridor (a tuning check of the covariance calibration; NOT the sim's
// held-out "staircase" generator): 14 m long (x in [0, 14]), 2.6 m wide,
// 2.8 m high, closed at both ends; door recesses (1 m wide, 0.15 m deep) in both
// walls, crates and cabinets along the walls, a cable tray and a pipe under the
// ceiling, a fire-door frame halfway (placed from `seed`). Long, narrow and sparsely
// cluttered, so translation along it rests on the clutter and the far end walls.
// The route walks along it about 0.4 m off the middle.
inline std::unique_ptr<sim::Scene> CrateCorridorScene(uint32_t seed, sim::WalkingRoute* route) {
  std::vector<sim::Triangle> tris;
  uint32_t id = 0;
  auto box = [&](double x0, double y0, double z0, double x1, double y1, double z1) {
    AppendBoxTriangles(Eigen::Vector3f(x0, y0, z0), Eigen::Vector3f(x1, y1, z1), id++, &tris);
  };
  constexpr double kX = 14.0, kY = 2.6, kZ = 2.8, kWall = 0.2, kRecess = 0.15;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
  box(-kWall, -kWall - kRecess, -kWall, kX + kWall, kY + kWall + kRecess, 0);  // floor
  box(-kWall, -kWall - kRecess, kZ, kX + kWall, kY + kWall + kRecess, kZ + kWall);  // ceiling
  box(-kWall, -kRecess, 0, 0, kY + kRecess, kZ);                            // end walls
  box(kX, -kRecess, 0, kX + kWall, kY + kRecess, kZ);
  // Side walls with door recesses: wall segments between doors (doors 1 m wide,
  // 2.1 m high, 0.15 m deep, every 3-5 m, independently on both sides).
  for (int side = 0; side < 2; ++side) {
    const double y0 = side == 0 ? -kRecess - kWall : kY, y1 = side == 0 ? 0.0 : kY + kRecess + kWall;
    const double ry0 = side == 0 ? -kRecess : kY, ry1 = side == 0 ? 0.0 : kY + kRecess;
    double x = 0;
    while (x < kX) {
      const double door = x + uniform(2.0, 4.0);
      if (door + 1.0 > kX - 0.5) {
        box(x, y0, 0, kX, y1, kZ);
        break;
      }
      box(x, y0, 0, door, y1, kZ);                                    // wall up to the door
      box(door, side == 0 ? y0 : ry1, 0, door + 1.0, side == 0 ? -kRecess : y1, kZ);  // door leaf
      box(door, ry0, 2.1, door + 1.0, ry1, kZ);                      // lintel
      x = door + 1.0;
    }
  }
  // Crates and cabinets along both walls.
  for (int side = 0; side < 2; ++side) {
    for (double x = uniform(0.3, 1.5); x < kX - 1.0; x += uniform(1.2, 3.0)) {
      const double len = uniform(0.4, 1.0), depth = uniform(0.25, 0.5), h = uniform(0.3, 1.6);
      if (side == 0) {
        box(x, 0, 0, x + len, depth, h);
      } else {
        box(x, kY - depth, 0, x + len, kY, h);
      }
    }
  }
  box(0, 0.2, kZ - 0.35, kX, 0.6, kZ - 0.3);        // cable tray
  box(0, kY - 0.3, kZ - 0.5, kX, kY - 0.2, kZ - 0.4);  // pipe
  const double frame = uniform(6.0, 8.0);           // fire-door frame
  box(frame, 0, 0, frame + 0.1, 0.15, kZ);
  box(frame, kY - 0.15, 0, frame + 0.1, kY, kZ);
  box(frame, 0, 2.2, frame + 0.1, kY, kZ);
  route->closed = false;
  route->waypoints = {{1.0, 0.9, 1.4}, {6.5, 1.7, 1.4}, {13.0, 0.9, 1.4}};
  return sim::Scene::FromTriangles(std::move(tris));
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
  THROW_CHECK_OPTIONS(options);
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
