// Synthetic SfM problems with exact ground truth, written into a COLMAP
// database: the input of the stage tests of `lisfm global_mapper`
// (view graph, averaging, tracks, triangulation, BA) and of its end-to-end
// tests. In the spirit of COLMAP's scene/synthetic.h, plus rigs, pose priors
// and LiDAR constraints.
//
// Geometry (world z up, metres):
//  - kRing: frames on a horizontal ring (radius 6 m, height 1-2 m) around a
//    cube of points ([-2, 2]^3), each looking at a point near the origin.
//  - kRoom: a forward-moving loop (ellipse 3.5 x 2 m, height ~1.5 m, small
//    yaw/pitch/roll wobble) inside a 12 x 8 x 3 m box; the points lie on
//    its walls, floor and ceiling.
//  The body (rig) frame has x forward, y left, z up. With a rig
//  (num_rig_cameras > 0) the body frame is the IMU frame and the cameras are a
//  HILTI-like ring, cam_from_rig = T_cam_imu: cam0/cam1 a forward stereo pair
//  (0.11 m baseline), cam2 up, cam3 left, cam4 right (each with a ~1 deg
//  mounting error). Without a rig, one forward camera per frame at the body
//  origin; its pose is the frame pose (cam_from_rig = identity in
//  MapperState terms).
//
// Database contents (COLMAP 3.8 schema, colmap_ext/database.h):
//  - cameras: one per rig camera (camera_id = K + 1), or one shared camera
//    (camera_id 1); has_prior_focal_length = true.
//  - images: image_id = 1 + frame * num_cameras + K, named
//    `camK/data/<stamp_ns>.png` (rig) or `image_%04d.png` (1-based).
//  - priors (when prior_position_noise / prior_rotation_noise > 0): the rig
//    pose is perturbed once per frame (position + N(0, sigma^2 I), rotation
//    R * Exp(N(0, sigma^2 I))) and propagated to each camera; prior_q* =
//    cam_from_world rotation, prior_t* = camera centre, pose_priors
//    covariance = sigma_position^2 I.
//  - keypoints (N x 2, COLMAP pixels): every visible point (depth > 0.2 m,
//    in the image, inside the invertible field of view of the model) at its
//    projection + N(0, pixel_noise^2) per axis, plus num_random_keypoints
//    uniform random ones, in a random order.
//  - matches = two_view_geometries inliers (config CALIBRATED) for every image
//    pair that shares >= min_shared_points points (and whose frames are at
//    most max_frame_gap apart when > 0); qvec/tvec = the exact cam2_from_cam1
//    with |t| = 1, E = [t]x R, F = K2^-T E K1^-1 from the pinhole part of the
//    intrinsics (ignores distortion), H = 0.
//  - outliers: outlier_match_ratio * n extra wrong matches (pairs of unused
//    keypoints that see different or no points) in each pair; and a fraction
//    outlier_pair_ratio of pairs whose matches are all wrong (random 1-to-1)
//    and whose stored relative pose is random, still listed as inliers.
// Deterministic for a given seed (same binary). Failures: options that fail
// Check() throw InternalError; I/O errors as in Database and the writers.
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "colmap_ext/io/database.h"
#include "core/io/lidar_constraints_io.h"
#include "core/geometry.h"
#include "core/rig.h"

namespace lisfm {
namespace colmap {

enum class SyntheticTrajectory {
  kRing,  // ring around a cube of points, looking in
  kRoom,  // forward-moving loop inside a box-shaped room of points
};

struct SyntheticSfmOptions {
  int num_frames = 12;       // rig poses (= images without a rig)
  int num_rig_cameras = 0;   // 0 = no rig; 1..5 = the first K cameras of the HILTI-like ring
  std::string camera_model = "PINHOLE";  // PINHOLE | OPENCV | OPENCV_FISHEYE
  int image_width = 720;     // px
  int image_height = 540;    // px
  double focal_length = 350.0;  // px (fx; fy = 1.002 fx)
  int num_points = 2000;     // 3D points
  SyntheticTrajectory trajectory = SyntheticTrajectory::kRing;
  double pixel_noise = 0.0;  // px, standard deviation per axis
  int num_random_keypoints = 10;     // unmatched random keypoints per image
  int min_shared_points = 30;        // a pair is written when it shares >= this many points
  int max_frame_gap = 0;             // > 0: only pairs of frames at most this far apart
  double outlier_match_ratio = 0.0;  // wrong matches added per pair, fraction of its true ones
  double outlier_pair_ratio = 0.0;   // fraction of pairs whose matches are all wrong
  double prior_position_noise = 0.0;  // m, sigma per axis (0 = no position priors)
  double prior_rotation_noise = 0.0;  // rad, sigma per axis (0 = no rotation priors)
  int num_lidar_neighbors = 0;        // constraints from each frame to its next N frames
  double lidar_translation_noise = 0.005;  // m, sigma per axis of the constraint noise
  double lidar_rotation_noise = 0.00175;   // rad (0.1 deg), sigma per axis
  int64_t first_stamp_ns = 1000000000;     // stamp of frame 0 (ns)
  int64_t frame_period_ns = 200000000;     // ns between frames
  std::string rig_path;                // rig YAML written here when non-empty (rig only)
  std::string lidar_constraints_path;  // constraints written here when non-empty
  uint32_t seed = 42;                  // RNG seed
  bool Check() const;
};

struct SyntheticSfmFrame {
  int64_t stamp_ns = 0;
  SE3 gt_rig_from_world;  // without a rig: the camera pose
  std::vector<image_t> image_ids;  // index K = rig camera K
};

struct SyntheticSfmScene {
  Rig rig;  // rig case: cam0..camN-1 with T_cam_imu; empty without a rig
  std::map<camera_t, Camera> cameras;
  std::map<camera_t, SE3> cam_from_rig;  // identity without a rig
  std::vector<SyntheticSfmFrame> frames;
  std::map<image_t, std::string> image_names;
  std::map<image_t, camera_t> image_camera_ids;
  std::map<image_t, SE3> gt_cam_from_world;
  std::map<int64_t, SE3> gt_rig_from_world;  // by stamp
  std::vector<Vec3> points;  // world, m
  // Per image, per keypoint: index into `points`, or -1 (random keypoint).
  std::map<image_t, std::vector<int>> keypoint_point_ids;
  std::set<image_pair_t> outlier_pairs;  // pairs whose matches are all wrong
  size_t num_pairs = 0;            // two_view_geometries rows
  size_t num_matches = 0;          // inlier matches written, outliers included
  size_t num_outlier_matches = 0;  // wrong matches (outlier pairs included)
  // Noisy relative poses: frame k to k + n, i_from_j = rig_k_from_rig_{k+n}
  // (* Exp(noise)). With a rig they carry stamps, otherwise the frame index.
  std::vector<LidarConstraintRecord> constraints;
};

// Writes a new database at `database_path` (an existing file is replaced; the
// file appears only once complete) and, when their paths are set, the rig
// YAML and the constraints file. Returns the ground truth.
SyntheticSfmScene WriteSyntheticSfmDatabase(const SyntheticSfmOptions& options,
                                            const std::string& database_path);

}  // namespace colmap
}  // namespace lisfm
