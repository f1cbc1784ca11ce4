#include "sim/motion.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {
namespace sim {
namespace {

// The route unrolled into a long polyline (loops repeated, ping-pong routes
// mirrored) sampled every 5 cm, with the arc length of each sample.
struct Path {
  std::vector<Vec3> points;
  double spacing = 0.05;
  Vec3 At(double s) const {
    const double f = std::clamp(s / spacing, 0.0, static_cast<double>(points.size() - 1));
    const size_t i = std::min(static_cast<size_t>(f), points.size() - 2);
    return points[i] + (points[i + 1] - points[i]) * (f - i);
  }
  double Length() const { return spacing * (points.size() - 1); }
};

Path UnrollRoute(const WalkingRoute& route, double min_length) {
  THROW_CHECK_GE(route.waypoints.size(), 2u);
  std::vector<Vec3> cycle = route.waypoints;
  if (route.closed) {
    cycle.push_back(route.waypoints.front());
  } else {
    for (int i = static_cast<int>(route.waypoints.size()) - 2; i >= 0; --i) {
      cycle.push_back(route.waypoints[i]);
    }
  }
  Path path;
  double length = 0;
  path.points.push_back(cycle.front());
  while (length < min_length + 10.0) {
    for (size_t i = 0; i + 1 < cycle.size(); ++i) {
      const Vec3 a = cycle[i], b = cycle[i + 1];
      const double seg = (b - a).norm();
      const int n = std::max(1, static_cast<int>(std::round(seg / path.spacing)));
      for (int k = 1; k <= n; ++k) path.points.push_back(a + (b - a) * (double(k) / n));
      length += seg;
    }
  }
  // Resample at exact spacing by arc length, then round corners with a
  // moving average over +-0.7 m of arc length.
  std::vector<double> arc(path.points.size(), 0.0);
  for (size_t i = 1; i < arc.size(); ++i) {
    arc[i] = arc[i - 1] + (path.points[i] - path.points[i - 1]).norm();
  }
  std::vector<Vec3> uniform;
  size_t j = 0;
  for (double s = 0; s <= arc.back(); s += path.spacing) {
    while (j + 2 < arc.size() && arc[j + 1] < s) ++j;
    const double seg = std::max(1e-12, arc[j + 1] - arc[j]);
    const double f = std::clamp((s - arc[j]) / seg, 0.0, 1.0);
    uniform.push_back(path.points[j] + (path.points[j + 1] - path.points[j]) * f);
  }
  const int half = static_cast<int>(0.7 / path.spacing);
  std::vector<Vec3> smooth(uniform.size());
  for (size_t i = 0; i < uniform.size(); ++i) {
    Vec3 sum = Vec3::Zero();
    int count = 0;
    for (int k = -half; k <= half; ++k) {
      const int idx = std::clamp(static_cast<int>(i) + k, 0, static_cast<int>(uniform.size()) - 1);
      sum += uniform[idx];
      ++count;
    }
    smooth[i] = sum / count;
  }
  path.points = std::move(smooth);
  return path;
}

// 0 -> 1 smoothly (C1) over [0, 1].
double Ramp(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return 0.5 - 0.5 * std::cos(M_PI * x);
}

}  // namespace

bool WalkingOptions::Check() const {
  CHECK_OPTION_GT(speed, 0.0);
  CHECK_OPTION_GE(stationary_s, 0.0);
  CHECK_OPTION_MSG(num_stops, num_stops >= 2 && num_stops <= 1000, "in [2, 1000]");
  CHECK_OPTION_GT(step_frequency, 0.0);
  CHECK_OPTION_GE(sway_scale, 0.0);
  CHECK_OPTION_GT(knot_spacing, 0.0);
  return true;
}

SplineTrajectory GenerateWalking(const WalkingRoute& route,
                                 double duration_s,
                                 TimestampNs start_ns,
                                 uint32_t seed,
                                 const WalkingOptions& options,
                                 std::vector<StationaryPeriod>* stationary) {
  THROW_CHECK_GT(duration_s, 0.0);
  THROW_CHECK_OPTIONS(options);
  const double dt = options.knot_spacing;
  // Rests at the start, at the end and centred at equal steps between; shorter
  // for short sequences (at most half of the time between rest centres).
  const int n = options.num_stops;
  const double rest = std::min(options.stationary_s, duration_s / (2.0 * n));
  const double ramp = std::min(1.2, rest);
  struct Rest {
    double t0, t1;
  };
  std::vector<Rest> rests = {{-1.0, rest}};
  for (int k = 1; k + 1 < n; ++k) {
    const double centre = duration_s * k / (n - 1);
    rests.push_back({centre - rest / 2, centre + rest / 2});
  }
  rests.push_back({duration_s - rest, duration_s + 1.0});
  // Walking factor w(t) in [0, 1]: 0 at rest, ramping over `ramp` seconds.
  auto walking = [&](double t) {
    double w = 1.0;
    for (const Rest& r : rests) {
      if (t >= r.t0 && t <= r.t1) return 0.0;
      if (t < r.t0) w = std::min(w, Ramp((r.t0 - t) / ramp));
      if (t > r.t1) w = std::min(w, Ramp((t - r.t1) / ramp));
    }
    return w;
  };
  const int num_controls = static_cast<int>(std::ceil(duration_s / dt)) + 3;
  // Integrate arc length at a fine step with a slowly varying speed.
  std::mt19937 rng(seed * 7919u + 3u);
  std::uniform_real_distribution<double> phase(0, 2 * M_PI);
  const double ph_speed = phase(rng), ph_bob = phase(rng), ph_sway = phase(rng),
               ph_yaw = phase(rng), ph_look = phase(rng);
  const double fine = 0.005;
  std::vector<double> arc;  // at t = (j - 1) dt
  double s = 0;
  double t_fine = -dt;
  Path path = UnrollRoute(route, options.speed * 1.3 * duration_s);
  for (int j = 0; j < num_controls; ++j) {
    const double t_target = (j - 1) * dt;
    while (t_fine < t_target - 1e-12) {
      const double v = options.speed * (1.0 + 0.1 * std::sin(0.21 * t_fine + ph_speed));
      s += v * walking(t_fine) * fine;
      t_fine += fine;
    }
    arc.push_back(std::min(s, path.Length() - 1.0));
  }
  const double a = options.sway_scale;
  const double f = options.step_frequency;
  const Mat3 frd_to_flu = Vec3(1, -1, -1).asDiagonal();
  std::vector<Quat> rotations(num_controls);
  std::vector<Vec3> positions(num_controls);
  double previous_yaw = 0;
  for (int j = 0; j < num_controls; ++j) {
    // Gait phases advance with the distance walked, so they freeze at rest.
    const double t = (j - 1) * dt;
    const double w = walking(t);
    const double step_phase = 2 * M_PI * f * arc[j] / options.speed;
    const Vec3 p = path.At(arc[j]);
    const Vec3 ahead = path.At(arc[j] + 0.6) - path.At(std::max(0.0, arc[j] - 0.6));
    double yaw = std::atan2(ahead.y(), ahead.x());
    if (j > 0) {  // unwrap
      while (yaw - previous_yaw > M_PI) yaw -= 2 * M_PI;
      while (yaw - previous_yaw < -M_PI) yaw += 2 * M_PI;
    }
    previous_yaw = yaw;
    const Vec3 forward(std::cos(yaw), std::sin(yaw), 0), left(-std::sin(yaw), std::cos(yaw), 0);
    // Bob (vertical, at the step frequency) and sway (lateral, half of it).
    const double bob = a * 0.015 * std::sin(step_phase + ph_bob);
    const double sway = a * 0.025 * std::sin(0.5 * step_phase + ph_sway);
    positions[j] = p + Vec3(0, 0, bob) + left * sway;
    // Look-around (slow yaw), yaw jitter, roll and pitch sway; constant 3 deg
    // forward tilt of the handheld device as in the HILTI ground truth.
    const double look = w * a * 0.15 * std::sin(0.35 * arc[j] + ph_look);
    const double yaw_jitter = a * 0.025 * std::sin(0.5 * step_phase + ph_yaw);
    const double roll = a * 0.03 * std::sin(0.5 * step_phase + ph_sway + 0.5);
    const double pitch = a * 0.02 * std::sin(step_phase + ph_bob + 0.8) + 0.05;
    const Quat world_from_flu = Eigen::AngleAxisd(yaw + look + yaw_jitter, Vec3::UnitZ()) *
                                Eigen::AngleAxisd(pitch, Vec3::UnitY()) *
                                Eigen::AngleAxisd(roll, Vec3::UnitX());
    rotations[j] = Quat(world_from_flu.toRotationMatrix() * frd_to_flu);
  }
  // Exact rest: control points of a rest repeat the first one of the rest.
  for (const Rest& r : rests) {
    int first = -1;
    for (int j = 0; j < num_controls; ++j) {
      const double t = (j - 1) * dt;
      if (t < r.t0 - 2 * dt || t > r.t1 + 2 * dt) continue;
      if (walking(t) > 0) continue;
      if (first < 0) {
        first = j;
        continue;
      }
      positions[j] = positions[first];
      rotations[j] = rotations[first];
    }
  }
  if (stationary) {
    stationary->clear();
    for (const Rest& r : rests) {
      // A spline segment is constant when its 4 control points are equal, i.e.
      // 2 knots inside the rest interval on either side.
      const double t0 = std::max(0.0, r.t0 + 2 * dt), t1 = std::min(duration_s, r.t1 - 2 * dt);
      if (t1 - t0 < 0.5) continue;
      stationary->push_back({start_ns + SecondsToNs(t0), start_ns + SecondsToNs(t1)});
    }
  }
  return SplineTrajectory(start_ns, dt, std::move(rotations), std::move(positions));
}

std::vector<StationaryPeriod> FindStationaryPeriods(const SplineTrajectory& trajectory,
                                                    double max_speed,
                                                    double min_duration_s) {
  std::vector<StationaryPeriod> out;
  const int64_t step = 50 * 1000 * 1000;
  TimestampNs begin = -1;
  for (TimestampNs t = trajectory.start_ns(); t <= trajectory.end_ns(); t += step) {
    const TrajectorySample s = trajectory.Evaluate(t);
    const bool still = s.velocity_world.norm() < max_speed &&
                       s.angular_velocity_body.norm() < 0.05;
    if (still && begin < 0) begin = t;
    if ((!still || t + step > trajectory.end_ns()) && begin >= 0) {
      if (NsToSeconds(t - begin) >= min_duration_s) out.push_back({begin, t});
      begin = -1;
    }
  }
  return out;
}

}  // namespace sim
}  // namespace lisfm
