// Motion sources of the simulator: generated handheld walking along a scene's
// route, and real handheld motion from a TUM ground-truth file.
//
// The device is held as in the HILTI 2022 recordings (checked against
// ../shared/data/hilti2022_groundtruth/exp_04_*_imu.txt: while walking the IMU
// x axis points forward along the motion and z points down, i.e. an FRD body
// frame; world up is -z_imu within ~10 degrees). Generated motion therefore
// uses world_from_imu = Rz(yaw) * sway * diag(1, -1, -1).
#pragma once

#include <string>
#include <vector>

#include "core/time.h"
#include "sim/scene.h"
#include "sim/spline_trajectory.h"

namespace lisfm {
namespace sim {

// A time interval in which the device is at rest (exactly, for generated
// motion; speed below 2 cm/s for real motion).
struct StationaryPeriod {
  TimestampNs start_ns = 0;
  TimestampNs end_ns = 0;
};

struct WalkingOptions {
  double speed = 1.0;          // mean walking speed, m/s
  double stationary_s = 3.0;   // length of each rest, s
  // Rests (each a HILTI-style control-point survey): the first at the start,
  // the last at the end, the others centred at equal time steps between.
  int num_stops = 6;
  double step_frequency = 1.8; // gait frequency, Hz (vertical bob; sway at half)
  double sway_scale = 1.0;     // multiplies bob/sway/roll/pitch/yaw-jitter amplitudes
  double knot_spacing = 0.1;   // spline knot spacing, s
  bool Check() const;
};

// Walks `route` (rounded corners, heading along the path, gait bob and sway,
// smooth 1.2 s speed ramps) for `duration_s` = T, resting N =
// options.num_stops times for r = min(stationary_s, T / (2 N)) each: over
// [0, r], over [T - r, T] and centred at k T / (N - 1) for k = 1 .. N - 2.
// `stationary` receives the exactly constant part of each rest (2 knot
// spacings shorter at each end inside the sequence; a rest whose constant
// part is under 0.5 s gives none). Deterministic for `seed`.
SplineTrajectory GenerateWalking(const WalkingRoute& route,
                                 double duration_s,
                                 TimestampNs start_ns,
                                 uint32_t seed,
                                 const WalkingOptions& options,
                                 std::vector<StationaryPeriod>* stationary);

// Rest periods of a trajectory: speed < max_speed for at least min_duration_s
// (sampled every 50 ms).
std::vector<StationaryPeriod> FindStationaryPeriods(const SplineTrajectory& trajectory,
                                                    double max_speed = 0.02,
                                                    double min_duration_s = 1.5);

}  // namespace sim
}  // namespace lisfm
