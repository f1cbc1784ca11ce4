// KITTI odometry (Geiger et al., CVPR 2012) -> a sequence folder
// (DESIGN.md "Formats").
//
// Input, one KITTI sequence folder (`dataset/sequences/NN/`):
//   velodyne/NNNNNN.bin   float32 x y z reflectance per point (m, Velodyne frame)
//   times.txt             one time per scan, s since the sequence start
//   calib.txt             "P0: .." .. "P3: ..", "Tr: r00 r01 r02 tx r10 .. tz":
//                         cam0_from_velo, 3x4 row-major
//   poses (optional)      `dataset/poses/NN.txt` (or poses.txt in the folder):
//                         3x4 row-major world_from_cam0 per scan, world = cam0 of scan 0
// Output:
//   lidar0/data.csv + data/<ns>.pcd  x y z, intensity = reflectance, t = 0
//                         (KITTI scans carry no per-point time), ring 0
//   rig.yaml              lidar0 (spinning, 64 rings, 10 Hz) with T_imu_lidar =
//                         Tr: the rig's body frame is KITTI's camera 0; no cameras
//   groundtruth.txt       TUM, world_from_cam0 at each scan time (when poses are given)
// Stamps: t_ns = time_origin_ns + round(times.txt * 1e9). KITTI odometry has
// no IMU, so the folder has no imu0/: `lisfm lio` (which needs one) cannot run
// on it; `lisfm evaluate` and `lisfm icp` can use its files.
//
// Errors (InputError naming file and line): a missing file, a .bin whose size
// is not a multiple of 16 bytes, a line that is not 12 numbers (calib Tr,
// poses) or one number (times), times not increasing, scan / time / pose
// counts that differ.
#pragma once

#include <cstddef>
#include <string>

#include "core/time.h"

namespace lisfm {

struct KittiImportSummary {
  size_t num_scans = 0;
  size_t num_points = 0;
  size_t num_poses = 0;  // 0 without poses
};

// Reads the KITTI sequence `sequence_dir` (and `poses_path` if not empty)
// into the existing, empty folder `output_dir`.
KittiImportSummary ImportKittiOdometry(const std::string& sequence_dir,
                                       const std::string& poses_path,
                                       TimestampNs time_origin_ns,
                                       const std::string& output_dir);

}  // namespace lisfm
