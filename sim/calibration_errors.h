// Calibration errors of a simulated recording (error source `calibration`).
//
// A simulated recording is made with TRUE extrinsics and time offsets that
// differ from the calibration written to the sequence's rig.yaml (the values
// a user believes); truth/rig.yaml holds the true ones. For every sensor s
// (each LiDAR, each camera) the error is drawn from the seed:
//
//   imu_from_s_true = ( R_rig * Exp(dtheta),  t_rig + dt )
//     dtheta ~ N(0, sigma_r^2 I)  rad, about the sensor's own axes,
//     dt     ~ N(0, sigma_t^2 I)  m, the sensor origin's error in the IMU frame;
//   time offset error d = (true - believed) offset, rounded to whole ns, in
//   the Kalibr sense t_imu = t_sensor + offset:
//     LiDAR k: d_k ~ N(0, sigma_lidar^2);
//     camera c: d_c = d_shared + e_c, d_shared ~ N(0, sigma_camera^2) drawn once
//       (the rig's cameras share one trigger), e_c ~ N(0, spread^2) per camera.
//
// A stamp in the folder is what the sensor reported; its true capture time on
// the IMU clock is stamp + rig offset + d (docs/FORMATS.md "Sequence folder").
// Every size is multiplied by the simulator's noise_scale. A sensor's draw
// depends only on (seed, sensor kind, sensor index): adding a camera does not
// change a LiDAR's errors.
#pragma once

#include <cstdint>
#include <vector>

#include "core/geometry.h"
#include "core/rig.h"
#include "core/time.h"

namespace lisfm {
namespace sim {

// Sizes of the calibration errors (1-sigma; 0 turns that part off).
struct CalibrationErrorOptions {
  double lidar_translation_sigma_m = 0.003;   // m per axis (RMS length 5.2 mm)
  double lidar_rotation_sigma_deg = 0.12;     // deg per axis (RMS angle 0.21 deg)
  double lidar_time_offset_sigma_s = 0.002;   // s, LiDAR-IMU time offset
  double camera_translation_sigma_m = 0.003;  // m per axis
  double camera_rotation_sigma_deg = 0.12;    // deg per axis
  double camera_time_offset_sigma_s = 0.002;  // s, the offset shared by all cameras
  double camera_time_offset_spread_s = 1e-4;  // s, per camera around the shared offset

  bool Check() const;
};

// The error of one sensor's calibration: true = believed (+) error.
struct SensorCalibrationError {
  Vec3 rotation_rad = Vec3::Zero();   // dtheta, about the sensor's axes
  Vec3 translation_m = Vec3::Zero();  // dt, in the IMU frame
  TimestampNs time_offset_ns = 0;     // d, true - believed time offset
};

struct CalibrationErrors {
  std::vector<SensorCalibrationError> lidars;   // by rig LiDAR index
  std::vector<SensorCalibrationError> cameras;  // by rig camera index
};

// Draws the errors of `num_lidars` LiDARs and `num_cameras` cameras (sizes
// times `noise_scale`, >= 0), deterministic in `seed`.
CalibrationErrors DrawCalibrationErrors(const CalibrationErrorOptions& options,
                                        double noise_scale,
                                        uint64_t seed,
                                        size_t num_lidars,
                                        size_t num_cameras);

// The true rig: `believed` with `errors` applied to every LiDAR's
// imu_from_lidar and time_offset_s and every camera's cam_from_imu and
// timeshift_cam_imu_s (the time offsets become believed + d seconds).
// `errors` must have one entry per LiDAR and camera of `believed`.
Rig ApplyCalibrationErrors(const Rig& believed, const CalibrationErrors& errors);

}  // namespace sim
}  // namespace lisfm
