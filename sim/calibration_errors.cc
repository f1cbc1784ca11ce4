#include "sim/calibration_errors.h"

#include <cmath>
#include <random>

#include "core/errors.h"
#include "core/option_check.h"
#include "sim/hash_random.h"

namespace lisfm {
namespace sim {
namespace {

constexpr uint64_t kLidarStream = 0x4C69446172ULL;   // "LiDar"
constexpr uint64_t kCameraStream = 0x43616D6572ULL;  // "Camer"
constexpr uint64_t kSharedCameraIndex = ~uint64_t{0};

// The random stream of one sensor: a function of (seed, kind, index) only.
std::mt19937_64 SensorRng(uint64_t seed, uint64_t kind, uint64_t index) {
  return std::mt19937_64(Mix64(Mix64(seed * 0x9E3779B97F4A7C15ULL + kind) + index));
}

SensorCalibrationError DrawPose(std::mt19937_64* rng,
                                double rotation_sigma_rad,
                                double translation_sigma_m) {
  std::normal_distribution<double> normal(0.0, 1.0);
  SensorCalibrationError e;
  for (int i = 0; i < 3; ++i) e.rotation_rad[i] = rotation_sigma_rad * normal(*rng);
  for (int i = 0; i < 3; ++i) e.translation_m[i] = translation_sigma_m * normal(*rng);
  return e;
}

TimestampNs DrawNs(std::mt19937_64* rng, double sigma_s) {
  std::normal_distribution<double> normal(0.0, 1.0);
  return static_cast<TimestampNs>(std::llround(sigma_s * normal(*rng) * 1e9));
}

bool HasPoseError(const SensorCalibrationError& e) {
  return e.rotation_rad != Vec3::Zero() || e.translation_m != Vec3::Zero();
}

// imu_from_sensor_true = (R * Exp(dtheta), t + dt).
SE3 Perturb(const SE3& imu_from_sensor, const SensorCalibrationError& e) {
  return SE3(imu_from_sensor.rotation() * so3::Exp(e.rotation_rad),
             imu_from_sensor.translation() + e.translation_m);
}

}  // namespace

bool CalibrationErrorOptions::Check() const {
  CHECK_OPTION_MSG(lidar_translation_sigma_m,
                   lidar_translation_sigma_m >= 0 && lidar_translation_sigma_m <= 1,
                   "in [0, 1] m");
  CHECK_OPTION_MSG(lidar_rotation_sigma_deg,
                   lidar_rotation_sigma_deg >= 0 && lidar_rotation_sigma_deg <= 30,
                   "in [0, 30] deg");
  CHECK_OPTION_MSG(lidar_time_offset_sigma_s,
                   lidar_time_offset_sigma_s >= 0 && lidar_time_offset_sigma_s <= 1,
                   "in [0, 1] s");
  CHECK_OPTION_MSG(camera_translation_sigma_m,
                   camera_translation_sigma_m >= 0 && camera_translation_sigma_m <= 1,
                   "in [0, 1] m");
  CHECK_OPTION_MSG(camera_rotation_sigma_deg,
                   camera_rotation_sigma_deg >= 0 && camera_rotation_sigma_deg <= 30,
                   "in [0, 30] deg");
  CHECK_OPTION_MSG(camera_time_offset_sigma_s,
                   camera_time_offset_sigma_s >= 0 && camera_time_offset_sigma_s <= 1,
                   "in [0, 1] s");
  CHECK_OPTION_MSG(camera_time_offset_spread_s,
                   camera_time_offset_spread_s >= 0 && camera_time_offset_spread_s <= 1,
                   "in [0, 1] s");
  return true;
}

CalibrationErrors DrawCalibrationErrors(const CalibrationErrorOptions& options,
                                        double noise_scale,
                                        uint64_t seed,
                                        size_t num_lidars,
                                        size_t num_cameras) {
  THROW_CHECK_OPTIONS(options);
  THROW_CHECK_GE(noise_scale, 0.0);
  const double k = noise_scale;
  const double deg = M_PI / 180.0;
  CalibrationErrors errors;
  for (size_t i = 0; i < num_lidars; ++i) {
    std::mt19937_64 rng = SensorRng(seed, kLidarStream, i);
    SensorCalibrationError e = DrawPose(
        &rng, k * options.lidar_rotation_sigma_deg * deg, k * options.lidar_translation_sigma_m);
    e.time_offset_ns = DrawNs(&rng, k * options.lidar_time_offset_sigma_s);
    errors.lidars.push_back(e);
  }
  std::mt19937_64 shared_rng = SensorRng(seed, kCameraStream, kSharedCameraIndex);
  const TimestampNs shared_ns = DrawNs(&shared_rng, k * options.camera_time_offset_sigma_s);
  for (size_t i = 0; i < num_cameras; ++i) {
    std::mt19937_64 rng = SensorRng(seed, kCameraStream, i);
    SensorCalibrationError e = DrawPose(
        &rng, k * options.camera_rotation_sigma_deg * deg, k * options.camera_translation_sigma_m);
    e.time_offset_ns = shared_ns + DrawNs(&rng, k * options.camera_time_offset_spread_s);
    errors.cameras.push_back(e);
  }
  return errors;
}

Rig ApplyCalibrationErrors(const Rig& believed, const CalibrationErrors& errors) {
  THROW_CHECK_EQ(errors.lidars.size(), believed.lidars.size());
  THROW_CHECK_EQ(errors.cameras.size(), believed.cameras.size());
  // A zero error leaves the transform's bits as they are (no round trip
  // through the inverse), so zero-sized errors reproduce the believed rig.
  Rig rig = believed;
  for (size_t i = 0; i < rig.lidars.size(); ++i) {
    RigLidar& lidar = rig.lidars[i];
    if (HasPoseError(errors.lidars[i])) {
      lidar.imu_from_lidar = Perturb(lidar.imu_from_lidar, errors.lidars[i]);
    }
    lidar.time_offset_s += NsToSeconds(errors.lidars[i].time_offset_ns);
  }
  for (size_t i = 0; i < rig.cameras.size(); ++i) {
    RigCamera& camera = rig.cameras[i];
    if (HasPoseError(errors.cameras[i])) {
      camera.cam_from_imu = Perturb(camera.cam_from_imu.Inverse(), errors.cameras[i]).Inverse();
    }
    camera.timeshift_cam_imu_s += NsToSeconds(errors.cameras[i].time_offset_ns);
  }
  return rig;
}

}  // namespace sim
}  // namespace lisfm
