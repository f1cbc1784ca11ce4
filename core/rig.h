// The sensor rig: IMU (the body frame), cameras and LiDARs with their
// extrinsics, time offsets and noise parameters. File I/O lives in
// core/io/rig_io.h (Kalibr-style YAML, DESIGN.md "Formats").
#pragma once

#include <string>
#include <vector>

#include "core/camera_model.h"
#include "core/geometry.h"

namespace lisfm {

// Continuous-time IMU noise (Kalibr's imu.yaml names). The defaults are the
// Bosch BMI085 datasheet values used for the HILTI 2022 Alphasense IMU.
struct ImuNoise {
  double accelerometer_noise_density = 1.7e-3;  // m/s^2/sqrt(Hz)
  double gyroscope_noise_density = 2.4e-4;      // rad/s/sqrt(Hz)
  double accelerometer_random_walk = 4.0e-4;    // m/s^3/sqrt(Hz)
  double gyroscope_random_walk = 2.0e-5;        // rad/s^2/sqrt(Hz)
  double update_rate = 400.0;                   // Hz
};

struct RigCamera {
  std::string name;       // "cam0", ... (the index is the rig index)
  std::string rostopic;   // optional, e.g. /alphasense/cam0/image_raw
  CameraModel model;
  SE3 cam_from_imu;       // Kalibr T_cam_imu
  double timeshift_cam_imu_s = 0.0;  // t_imu = t_cam + timeshift_cam_imu
};

enum class LidarType { kSpinning, kLivox };
std::string LidarTypeName(LidarType type);
LidarType ParseLidarType(const std::string& name);  // throws InputError

struct RigLidar {
  std::string name;  // "lidar0", ...
  std::string rostopic;
  LidarType type = LidarType::kSpinning;
  SE3 imu_from_lidar;          // T_imu_lidar
  double time_offset_s = 0.0;  // t_imu = t_lidar + time_offset
  int rings = 32;              // 0 for solid-state
  double min_range = 0.5;      // m
  double max_range = 120.0;    // m
  double scan_rate = 10.0;     // Hz
};

struct Rig {
  std::vector<RigCamera> cameras;
  std::vector<RigLidar> lidars;
  ImuNoise imu;
  std::string imu_rostopic;

  const RigCamera* FindCamera(const std::string& name) const;
  const RigLidar* FindLidar(const std::string& name) const;
};

}  // namespace lisfm
