// Rig calibration files: lisfm's rig YAML (Kalibr camchain style plus IMU
// noise and LiDAR sections), Kalibr camchain-imucam files and the HILTI 2022
// calibration folder.
//
// lisfm rig YAML (a map; every length in m, angle in rad, time in s):
//
//   cam0:                              # cameras cam0..camN-1, no gaps; the
//     camera_model: pinhole            #   number is the rig index. Optional,
//                                      #   only "pinhole" is supported.
//     intrinsics: [fu, fv, pu, pv]     # required, pixels
//     distortion_model: equidistant    # required: radtan | equidistant | none
//     distortion_coeffs: [k1, k2, k3, k4]  # radtan [k1 k2 p1 p2]; none: [] or absent
//     resolution: [720, 540]           # required, [width height] pixels
//     T_cam_imu:                       # required, 4x4 nested list, cam_from_imu,
//     - [r00, r01, r02, tx]            #   rigid: |R^T R - I| <= 1e-3 (re-orthonormalised
//     - [r10, r11, r12, ty]            #   by SVD), det R > 0, last row [0 0 0 1]
//     - [r20, r21, r22, tz]
//     - [0, 0, 0, 1]
//     timeshift_cam_imu: 0.0019        # optional (0): t_imu = t_cam + timeshift
//     rostopic: /alphasense/cam0/image_raw  # optional
//   imu:                               # optional ("imu0" accepted, Kalibr imu.yaml names);
//     accelerometer_noise_density: 1.7e-3   # m/s^2/sqrt(Hz)   every missing field
//     gyroscope_noise_density: 2.4e-4       # rad/s/sqrt(Hz)    takes the Bosch BMI085
//     accelerometer_random_walk: 4.0e-4     # m/s^3/sqrt(Hz)    default of core/rig.h
//     gyroscope_random_walk: 2.0e-5         # rad/s^2/sqrt(Hz)  (logged with LogInfo)
//     update_rate: 400                      # Hz
//     rostopic: /alphasense/imu             # optional
//   lidars:                            # optional; a map name -> entry, or a list of
//     lidar0:                          #   entries with an optional `name` (default lidarK)
//       type: spinning                 # required: spinning | livox
//       T_imu_lidar: [[...], ...]      # required, 4x4 nested list, imu_from_lidar, rigid
//       time_offset: 0.0               # optional (0): t_imu = t_lidar + time_offset
//       rings: 32                      # optional (spinning 32, livox 0); spinning > 0
//       min_range: 0.05                # optional (0.5), m, >= 0
//       max_range: 120                 # optional (120), m, > min_range
//       scan_rate: 10                  # optional (10), Hz, > 0
//       rostopic: /hesai/pandar        # optional
//
// Kalibr extras (T_cn_cnm1, cam_overlaps) are ignored silently, other unknown
// keys with a LogWarning. Failures throw InputError "<path>:<field>: <what>"
// (e.g. "rig.yaml:cam2.intrinsics: missing (section at line 3)"), with
// the YAML line where yaml-cpp reports one; malformed YAML gives
// "<path>:line N: <parser message>".
#pragma once

#include <string>
#include <vector>

#include "core/rig.h"

namespace lisfm {

// Reads and validates a rig YAML file (format above).
Rig ReadRigYaml(const std::string& path);
// The same from text; `path_for_errors` names the source in error messages.
Rig ParseRigYaml(const std::string& text, const std::string& path_for_errors);

// Writes `rig` atomically in the format above; doubles are written in their
// shortest exact (round-trip) decimal form, so ReadRigYaml(WriteRigYaml(rig))
// reproduces every number bit for bit (poses up to the 1e-16 of the matrix <->
// quaternion conversion). `header_comment` lines are written as "# ..." first.
void WriteRigYaml(const std::string& path,
                  const Rig& rig,
                  const std::string& header_comment = "");
std::string RigToYaml(const Rig& rig, const std::string& header_comment = "");

// Builds a rig from Kalibr camchain-imucam files (one or more) and an optional
// LiDAR calibration (`lidar_calibration_path` may be empty).
//  - Every Kalibr file names its cameras from cam0, so the rig indices come
//    from the FILE NAME: "...cam2-camchain-imucam.yaml" -> cam2,
//    "...cam0-1-camchain-imucam.yaml" -> the file's cam0, cam1 become rig cam0,
//    cam1 in that order. Without a "camK[-L...]" tag the file's own names are kept.
//  - The union must be cam0..camN-1 without gaps or duplicates.
//  - Kalibr camchains carry no IMU noise: the BMI085 defaults are used (LogInfo).
//  - The LiDAR file is the HILTI "lidar_calibration.yaml" layout (see
//    ReadLidarCalibration).
Rig LoadKalibrRig(const std::vector<std::string>& camchain_paths,
                  const std::string& lidar_calibration_path);

// Reads the LiDARs of a HILTI-style `lidar_calibration.yaml`:
//   sensors: { <name>: { parent: imu, extrinsics: { quaternion: [x, y, z, w],
//                                                  translation: [x, y, z] } } }
// Entries whose name looks like a LiDAR (Pandar/Hesai/Ouster/Velodyne/Livox/
// "lidar") become lidar0, lidar1, ... in file order; the others (imu,
// measurement_tip) are skipped. Conventions (evidence in rig_io.cc):
// quaternion order x, y, z, w and the pose is the child in its parent frame,
// i.e. T_imu_lidar. A parent other than "imu" throws InputError.
// "PandarXT-32" gets its datasheet specs (spinning, 32 rings, 0.05-120 m, 10 Hz);
// other models keep the RigLidar defaults (LogWarning).
std::vector<RigLidar> ReadLidarCalibration(const std::string& path);

// The rig indices named by a Kalibr file name ("calib_3_cam0-1-camchain-imucam.yaml"
// -> {0, 1}); empty when the name carries no "camK" tag.
std::vector<int> KalibrFileCameraIndices(const std::string& path);

// The HILTI 2022 calibration folder (e.g. hilti_exp4_small/calibration/): all
// "*camchain-imucam*.yaml" files plus the required lidar_calibration.yaml
// (april_hilti.yaml, the calibration target, is ignored). Adds the HILTI 2022
// ROS topics (/alphasense/camK/image_raw from the files, /alphasense/imu,
// /hesai/pandar). Throws InputError when a file is missing or invalid.
Rig LoadHiltiCalibration(const std::string& calibration_dir);

}  // namespace lisfm
