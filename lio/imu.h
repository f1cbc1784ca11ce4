// IMU samples and the static initialisation of a LiDAR-inertial filter.
//
// Frames (docs/FORMATS.md): the body frame is the IMU frame. The world frame
// of lio is gravity-aligned with z up and fixed at the initialisation time
// t_ns (the last sample within min_duration_s of the first one): its origin is
// the IMU position then, and world_from_imu(t_ns) is the minimal rotation
// taking the window's measured "up" to +z (for a level IMU, world x = IMU x).
#pragma once

#include <vector>

#include "core/geometry.h"
#include "core/sensor_data.h"
#include "core/time.h"

namespace lisfm {

struct ImuInitializerOptions {
  double min_duration_s = 0.5;       // stationary window length needed (s)
  int min_samples = 50;              // and at least this many samples
  double max_gyro_std = 0.02;        // rad/s: above this the IMU is not static
  double max_accel_std = 0.15;       // m/s^2 (after scale): above this not static
  double gravity_magnitude = 9.81;   // m/s^2
  bool Check() const;
};

struct ImuInitialization {
  bool success = false;
  TimestampNs t_ns = 0;          // time of the last sample used
  Quat world_from_imu = Quat::Identity();
  Vec3 gyro_bias = Vec3::Zero();  // rad/s
  double accel_scale = 1.0;       // multiply raw accel by this to get m/s^2 (9.81 if in g)
  Vec3 gravity_world = Vec3(0, 0, -9.81);
  std::string message;
};

// Estimates gravity direction, gyro bias and accelerometer scale from the
// first stationary window of `samples` (sorted by time). The window is the
// longest prefix shorter than max(min_duration_s, ...) whose statistics pass
// the static checks; returns success = false with a message otherwise.
ImuInitialization InitializeFromStaticImu(const std::vector<ImuSample>& samples,
                                          const ImuInitializerOptions& options);

}  // namespace lisfm
