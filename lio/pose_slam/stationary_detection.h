// Stationary periods of a recording and what pose_slam derives from them
// (FL2BIPS, Sec. II-C and III-B.3):
//  - detection from the IMU: sliding windows in which the gyroscope and
//    accelerometer scatter stay at the sensor's noise floor (optionally
//    intersected with the periods in which lio's trajectory stands still);
//  - the piecewise-constant bias: a new bias variable at each stationary period;
//  - the rules for zero-velocity factors and for ICP pairs (none inside a period).
// All times are IMU-clock nanoseconds. Plain values, deterministic, no threads.
#pragma once

#include <vector>

#include "core/sensor_data.h"
#include "core/time.h"
#include "core/trajectory.h"

namespace lisfm {

// A closed time interval [start_ns, end_ns] in which the rig is at rest.
struct StationaryPeriod {
  TimestampNs start_ns = 0;
  TimestampNs end_ns = 0;
  double duration_s() const { return NsToSeconds(end_ns - start_ns); }
  bool Contains(TimestampNs t_ns) const { return start_ns <= t_ns && t_ns <= end_ns; }
};

// Thresholds of the IMU test. A window passes when the scatter of the gyro and
// of the accelerometer samples (the root of the trace of their sample
// covariance, i.e. the RMS distance to the window mean) is below the maxima
// and the mean rate below max_gyro_mean. Defaults from the BMI085 datasheet
// (HILTI 2022 Alphasense IMU) at 400 Hz: white-noise scatter
// sqrt(3) * 2.4e-4 rad/s/sqrt(Hz) * sqrt(400 Hz) = 8.3e-3 rad/s and
// sqrt(3) * 1.7e-3 m/s^2/sqrt(Hz) * sqrt(400 Hz) = 0.059 m/s^2; zero-rate
// offset <= 1 deg/s = 0.017 rad/s. Walking gives ~0.3 rad/s and ~1 m/s^2.
struct StationaryDetectionOptions {
  double window_s = 0.5;        // s, length of the sliding test window
  double max_gyro_std = 0.015;  // rad/s, gyro scatter in a window (1.8x BMI085 noise)
  double max_accel_std = 0.1;   // m/s^2, accelerometer scatter in a window (1.7x BMI085 noise)
  double max_gyro_mean = 0.05;  // rad/s, norm of the window's mean rate (3x BMI085 offset)
  double min_duration_s = 1.0;  // s, shorter still stretches are not stationary periods
  bool Check() const;
};

// Stationary periods of `samples` (sorted by time, SI units): the union of the
// windows that pass the test, shrunk by half a window at each end that is not
// an end of the data (a passing window may still hold the first instants of a
// gentle motion; zero-velocity factors must not reach into it), kept where it
// lasts at least min_duration_s. Sorted and disjoint. Empty when there are
// fewer samples than one window.
std::vector<StationaryPeriod> DetectStationaryPeriods(const std::vector<ImuSample>& samples,
                                                      const StationaryDetectionOptions& options);

// Stretches of at least min_duration_s in which the trajectory (e.g. lio's, one
// pose per scan) stands still: the finite-difference speed between consecutive
// poses is below max_speed (m/s) and the angular rate below max_angular_rate
// (rad/s). Sorted and disjoint.
std::vector<StationaryPeriod> DetectStationaryPeriodsFromPoses(const Trajectory& trajectory,
                                                               double max_speed,
                                                               double max_angular_rate,
                                                               double min_duration_s);

// Periods covered by both lists (each sorted and disjoint), shorter ones than
// min_duration_s dropped.
std::vector<StationaryPeriod> IntersectStationaryPeriods(const std::vector<StationaryPeriod>& a,
                                                         const std::vector<StationaryPeriod>& b,
                                                         double min_duration_s);

// Index of the period (sorted, disjoint) that contains t_ns, or -1.
int StationaryPeriodIndex(const std::vector<StationaryPeriod>& periods, TimestampNs t_ns);

// True when both keyframe times lie in the same stationary period: such a pair
// gets no ICP constraint (FL2BIPS-GTSFM, Sec. III-B.3); zero-velocity factors
// hold it instead.
bool PairInsideStationaryPeriod(const std::vector<StationaryPeriod>& periods,
                                TimestampNs t_i_ns,
                                TimestampNs t_j_ns);

// The piecewise-constant bias (FL2BIPS, Sec. II-C) over keyframes at sorted
// times t_0 < t_1 < ...: bias variable 0 starts at the first keyframe, and a
// new one at the first keyframe at or after the start of each stationary
// period (after the first keyframe), so a rest calibrates the bias of the
// motion that follows it until the next rest.
struct PiecewiseBias {
  // Bias variable of keyframe interval k (keyframes k and k + 1), size
  // num_keyframes - 1; non-decreasing, 0, 1, ... without holes.
  std::vector<int> interval_bias;
  // Keyframe index where each bias variable starts; first is 0.
  std::vector<int> first_keyframe;
  int num_biases() const { return static_cast<int>(first_keyframe.size()); }
};

PiecewiseBias AssignPiecewiseBias(const std::vector<TimestampNs>& keyframe_times_ns,
                                  const std::vector<StationaryPeriod>& periods);

// Elapsed time between bias variables b and b + 1 for their random-walk factor
// (lio/pose_slam/imu_factors.h BiasRandomWalkFactor): each constant stands for
// its span of keyframes, so the time between the midpoints of the two spans.
double BiasRandomWalkSeconds(const PiecewiseBias& bias,
                             const std::vector<TimestampNs>& keyframe_times_ns,
                             int b);

}  // namespace lisfm
