// Synthetic SfM datasets with exact ground truth, for tests and benchmarks. In
// the spirit of COLMAP's scene/synthetic.h (SynthesizeDataset): one scene
// (cameras, frames / rig, points, observations with noise, pose priors, LiDAR
// constraints), written as the ground-truth Reconstruction and/or as the
// COLMAP database that feature matching would give (with outliers).
//
// Geometry (world z up, metres):
//  - kRing: frames on a horizontal ring (radius 6 m, height 1-2 m) around a
//    cube of points ([-2, 2]^3), each looking at a point near the origin with
//    a small random roll.
//  - kRoom: a forward-moving loop (ellipse 3.5 x 2 m, height ~1.5 m, small
//    yaw/pitch/roll wobble) inside a 12 x 8 x 3 m box; the points lie on its
//    walls, floor and ceiling.
//  The body (rig) frame has x forward, y left, z up. With a rig (with_rig) the
//  body frame is the IMU frame, every frame has one image per camera, and the
//  cameras are a HILTI-like ring, cam_from_rig = T_cam_imu: cam0/cam1 a
//  forward stereo pair (0.11 m baseline), cam2 up, cam3 left, cam4 right (each
//  with a ~1 deg mounting error). Without a rig, frame f has one image, taken
//  by camera f % num_cameras at the body origin looking along x; the frame
//  pose is that camera's pose (cam_from_rig = identity in MapperState terms).
//
// Cameras: camera_id = k + 1 with model camera_models[k % size] (PINHOLE |
// OPENCV | OPENCV_FISHEYE), fx = focal_length + 2k px, fy = 1.002 fx, the
// principal point a few px off the centre (depending on k), a fixed distortion
// per model; has_prior_focal_length = true.
// Images: image_id = 1 + frame * images_per_frame + K, named
// `camK/data/<stamp_ns>.png` (rig) or `image_%04d.png` (1-based, no rig).
// Observations: an image sees a point that lies in front of it (depth > 0.2 m),
// projects into the image and lies inside the invertible field of view of the
// model. track_length = 0: every image observes every point it sees;
// track_length = n > 0: every point is observed by exactly n images drawn at
// random among those that see it (a point seen by fewer images is drawn
// again). An observation is the exact projection + N(0, pixel_noise^2) px per
// axis; each image also has num_random_keypoints uniform random keypoints
// that see no point; an image's keypoints are in random order.
// Priors (prior_position_noise / prior_rotation_noise > 0): the rig pose of
// each frame perturbed once (position + N(0, s^2 I), rotation R Exp(N(0, s^2
// I))) and propagated to its cameras.
// LiDAR constraints (num_lidar_neighbors = N > 0): from frame k to frames
// k + 1 .. k + N, i_from_j = rig_k_from_rig_{k+n} * Exp(xi) with xi ~ N(0,
// diag(sr^2 I3, st^2 I3)) and that covariance; with a rig they name their
// frames by stamp, otherwise by frame index.
//
// Random streams: the geometry, the observations, the priors, the constraints
// and the database's outliers draw from separate streams of `seed`, so that
// changing one of them (e.g. adding outliers) leaves the others unchanged.
// Deterministic for a given seed and standard library. Failures: options that
// fail Check() throw InternalError; I/O errors as in Database and the writers.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "colmap_ext/io/database.h"
#include "colmap_ext/io/reconstruction.h"
#include "core/geometry.h"
#include "core/lidar_constraint.h"
#include "core/rig.h"

namespace lisfm {
namespace colmap {

enum class SyntheticTrajectory {
  kRing,  // ring around a cube of points, looking in
  kRoom,  // forward-moving loop inside a box-shaped room of points
};

struct SyntheticDatasetOptions {
  // Frames and cameras.
  int num_frames = 12;    // rig poses
  bool with_rig = false;  // true: every frame has one image per camera of the HILTI-like ring
  int num_cameras = 1;    // with a rig 1..5 (the first cameras of the ring); without, >= 1
  std::vector<std::string> camera_models = {"PINHOLE"};  // camera k: camera_models[k % size]
  int image_width = 720;                                 // px
  int image_height = 540;                                // px
  double focal_length = 350.0;                           // px (fx of camera 0)
  SyntheticTrajectory trajectory = SyntheticTrajectory::kRing;
  int64_t first_stamp_ns = 1000000000;  // stamp of frame 0 (ns)
  int64_t frame_period_ns = 200000000;  // ns between frames
  // Points and observations.
  int num_points = 2000;          // 3D points
  int track_length = 0;           // 0: all images that see a point; n > 0: exactly n of them
  double pixel_noise = 0.0;       // px, standard deviation per axis
  int num_random_keypoints = 10;  // keypoints per image that see no point
  // Pose priors and LiDAR constraints.
  double prior_position_noise = 0.0;       // m, sigma per axis (0 = no position priors)
  double prior_rotation_noise = 0.0;       // rad, sigma per axis (0 = no rotation priors)
  int num_lidar_neighbors = 0;             // constraints from each frame to its next N frames
  double lidar_translation_noise = 0.005;  // m, sigma per axis of the constraint noise
  double lidar_rotation_noise = 0.00175;   // rad (0.1 deg), sigma per axis
  // Database only: image pairs and outliers.
  int min_shared_points = 30;        // a pair is written when it shares >= this many points
  int max_frame_gap = 0;             // > 0: only pairs of frames at most this far apart
  double outlier_match_ratio = 0.0;  // wrong matches added per pair, fraction of its true ones
  double outlier_pair_ratio = 0.0;   // fraction of pairs whose matches are all wrong
  uint32_t seed = 42;                // RNG seed
  int ImagesPerFrame() const { return with_rig ? num_cameras : 1; }
  bool Check() const;
};

struct SyntheticKeypoint {
  Vec2 xy = Vec2::Zero();  // px, COLMAP convention (top-left pixel centre at (0.5, 0.5))
  int point_index = -1;    // index into SyntheticDataset::points; -1: a random keypoint
  double error = 0.0;      // px, |xy - exact projection of the point| (0 for random keypoints)
};

struct SyntheticImage {
  image_t image_id = 0;
  camera_t camera_id = 0;
  size_t frame_index = 0;  // into SyntheticDataset::frames
  std::string name;
  SE3 gt_cam_from_world;
  std::vector<SyntheticKeypoint> keypoints;
};

struct SyntheticFrame {
  int64_t stamp_ns = 0;
  SE3 gt_rig_from_world;           // without a rig: the camera pose
  SE3 prior_rig_from_world;        // the perturbed pose of the priors (= gt without priors)
  std::vector<image_t> image_ids;  // index K = rig camera K
};

struct SyntheticDataset {
  SyntheticDatasetOptions options;
  Rig rig;  // with a rig: cam0..camN-1 with T_cam_imu; empty otherwise
  std::map<camera_t, Camera> cameras;
  std::map<camera_t, SE3> cam_from_rig;  // identity without a rig
  std::vector<SyntheticFrame> frames;
  std::vector<SyntheticImage> images;                // images[image_id - 1]
  std::vector<Vec3> points;                          // world, m; point3D_id = index + 1
  std::vector<std::array<uint8_t, 3>> point_colors;  // RGB
  std::vector<LidarConstraintRecord> constraints;

  // Throws InternalError for an id that is not in the dataset.
  const SyntheticImage& GetImage(image_t image_id) const;
};

// What WriteSyntheticDatabase wrote besides the scene itself.
struct SyntheticMatches {
  size_t num_pairs = 0;                  // two_view_geometries rows
  size_t num_matches = 0;                // inlier matches written, outliers included
  size_t num_outlier_matches = 0;        // wrong matches (outlier pairs included)
  std::set<image_pair_t> outlier_pairs;  // pairs whose matches are all wrong
};

// The scene of `options`: O(num_points * images) projections with
// track_length = 0, O(num_points * track_length) otherwise.
SyntheticDataset SynthesizeDataset(const SyntheticDatasetOptions& options);

// The ground truth as a COLMAP model: the cameras, every image at its true
// pose (qvec a fixed point of COLMAP's normalisation) with its keypoints as 2D
// points in keypoint order, and every observed point (id = index + 1) at its
// true position with its colour, track (image order) and error = the mean
// distance of its observations from their exact projections (px). With a rig
// also the COLMAP 3.12 rig (reference sensor: camera 1) and frames.
Reconstruction SyntheticReconstruction(const SyntheticDataset& dataset);

// Writes a new COLMAP 3.8 database at `path` (an existing file is replaced;
// the file appears only once complete): the cameras; the images with their
// priors (prior_q* = cam_from_world rotation, prior_t* = camera centre,
// pose_priors covariance = sigma_position^2 I); the keypoints (N x 2); and for
// every image pair that shares >= min_shared_points points (and whose frames
// are at most max_frame_gap apart when > 0) matches = two-view geometry
// inliers (config CALIBRATED): the true correspondences, qvec / tvec = the
// exact cam2_from_cam1 with |t| = 1, E = [t]x R, F = K2^-T E K1^-1 of the
// pinhole part of the intrinsics (ignores distortion), H = 0. Outliers:
// round(outlier_match_ratio * n) extra wrong matches in each pair of n true
// ones (pairs of keypoints not matched yet that see different or no points),
// and a fraction outlier_pair_ratio of pairs whose matches are all wrong
// (random 1-to-1) and whose stored relative pose is random (>= 0.3 rad off),
// still listed as inliers.
SyntheticMatches WriteSyntheticDatabase(const SyntheticDataset& dataset, const std::string& path);

}  // namespace colmap
}  // namespace lisfm
