// The state shared by the stages of `lisfm global_mapper`: cameras,
// images with their keypoints, rig frames, the view graph, LiDAR constraints
// and tracks. Every stage is a free function that reads and updates one
// MapperState (view_graph.h, rotation_averaging.h, translation_averaging.h,
// tracks.h, triangulation.h, bundle_adjustment.h); global_mapper.h runs them.
//
// Rig model (one formulation for rigs and for plain image sets):
//  - A *frame* is one rig pose rig_from_world (the unknowns of rotation and
//    translation averaging and of BA). An image belongs to exactly one frame;
//    its pose is cam_from_world = cam_from_rig[camera_id] * rig_from_world.
//  - Without a rig every image is its own frame and cam_from_rig is the
//    identity for every camera (the "trivial rig").
//  - With a rig YAML (core/rig.h), the rig frame is the IMU frame:
//    cam_from_rig = T_cam_imu of rig camera K, for the images named
//    `camK/data/<ns>.png`; the images with the same <ns> form one frame with
//    stamp_ns = <ns>. LiDAR constraints (IMU frame) then act on frames directly.
//
// Conventions: poses are target_from_source SE3 (core/geometry.h); keypoints in
// COLMAP pixels; `normalized` keypoints are undistorted points on the z = 1
// plane of the camera (Camera::CamFromImg). Relative poses in the view graph
// are cam2_from_cam1 with |t| = 1 (COLMAP's two-view geometry convention).
// Covariances are on the right perturbation T = T_hat * Exp(xi), xi = [omega; v].
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "colmap_ext/io/camera_models.h"
#include "colmap_ext/io/database.h"
#include "colmap_ext/io/reconstruction.h"
#include "core/geometry.h"
#include "core/types.h"

namespace lisfm {

struct Rig;

namespace colmap {

struct SfmImage {
  image_t image_id = kInvalidImageId;
  camera_t camera_id = kInvalidCameraId;
  std::string name;
  frame_t frame_id = 0;
  std::vector<Vec2> keypoints;   // pixels (COLMAP convention)
  std::vector<Vec2> normalized;  // undistorted, z = 1 plane (same order)
  // Per keypoint: index into MapperState::tracks, or -1.
  std::vector<int> track_ids;
  // Priors from the database (camera centre in world and cam_from_world rotation).
  bool has_prior_rotation = false;
  Quat prior_cam_from_world_rotation = Quat::Identity();
  bool has_prior_position = false;
  Vec3 prior_position = Vec3::Zero();
  Mat3 prior_position_covariance = Mat3::Identity();  // m^2; from the database or the default
};

struct SfmFrame {
  frame_t frame_id = 0;
  int64_t stamp_ns = -1;  // from `camK/data/<ns>.png`; -1 when names carry no stamp
  std::vector<image_t> image_ids;
  SE3 rig_from_world;
  bool registered = false;  // true once the pose has been estimated
  // Prior on the rig pose (from the images' priors, via cam_from_rig).
  bool has_prior_rotation = false;
  Quat prior_rig_from_world_rotation = Quat::Identity();
  double prior_rotation_sigma = 0.0;  // rad, isotropic
  bool has_prior_position = false;
  Vec3 prior_position = Vec3::Zero();  // rig origin in world (m)
  Mat3 prior_position_covariance = Mat3::Identity();  // m^2
};

struct ViewGraphEdge {
  image_t image_id1 = kInvalidImageId;  // image_id1 < image_id2
  image_t image_id2 = kInvalidImageId;
  // Inlier matches (keypoint index in image 1, in image 2) of the relative pose.
  std::vector<std::pair<point2D_t, point2D_t>> inliers;
  SE3 cam2_from_cam1;  // |t| = 1 (direction only); metric only if `metric`
  bool metric = false;
  bool valid = true;  // false once a stage rejects the edge (it stays listed)
  std::string rejected_by;  // stage that set valid = false ("rotation_averaging", ...)
  double weight = 0.0;      // number of inliers by default
};

struct ViewGraph {
  std::vector<ViewGraphEdge> edges;
  std::unordered_map<image_pair_t, size_t> edge_index;  // ImagePairToPairId -> index
  size_t NumValidEdges() const;
  void AddEdge(ViewGraphEdge edge);  // keeps image_id1 < image_id2 (inverts if needed)
};

// A LiDAR relative pose constraint attached to two frames:
// rig1_from_rig2 (= T_i_j of the constraints file, IMU frame) with a 6x6
// covariance on the right perturbation.
struct LidarConstraint {
  frame_t frame_id1 = 0;
  frame_t frame_id2 = 0;
  SE3 rig1_from_rig2;
  Mat6 covariance = Mat6::Identity();
};

struct Track {
  std::vector<TrackElement> elements;  // active observations, at most one per image
  // Observations removed by filtering (kept so that retriangulation can
  // re-add them once the geometry has improved).
  std::vector<TrackElement> rejected;
  Vec3 xyz = Vec3::Zero();
  bool triangulated = false;
  double error = -1.0;  // mean reprojection error (px) after the last update
};

struct MapperState {
  std::map<camera_t, Camera> cameras;
  // Cameras whose intrinsics bundle adjustment holds constant (reset to their
  // prior after an adjustment made them bogus, global_mapper.h).
  std::set<camera_t> constant_intrinsics;
  std::map<image_t, SfmImage> images;
  std::map<frame_t, SfmFrame> frames;
  std::map<camera_t, SE3> cam_from_rig;  // identity for every camera without a rig
  bool has_rig = false;
  ViewGraph view_graph;
  std::vector<LidarConstraint> lidar_constraints;
  std::vector<Track> tracks;
  // rig_from_prior: the rig frame from the frame in which the pose priors and
  // the LiDAR constraints are expressed (their "IMU" frame). Identity unless
  // bundle adjustment refines it (BundleAdjustmentOptions::refine_prior_frame).
  SE3 rig_from_prior;

  const SfmFrame& FrameOf(image_t image_id) const;
  SE3 CamFromWorld(image_t image_id) const;
  Vec3 ProjectionCenter(image_t image_id) const;  // camera centre in world
  bool IsRegistered(image_t image_id) const;
  size_t NumRegisteredFrames() const;
  size_t NumRegisteredImages() const;
};

struct LoadMapperStateOptions {
  // Default prior standard deviations where the database gives no covariance.
  double prior_position_sigma = 0.05;  // m
  double prior_rotation_sigma = 0.01;  // rad
  bool use_priors = true;
  bool Check() const;
};

// Parses `camK/data/<ns>.<ext>` at the end of an image name (DESIGN.md
// "Formats"): the rig camera index K and the stamp <ns>. False when the name
// does not follow it.
bool ParseRigImageName(const std::string& name, int* camera_index, int64_t* stamp_ns);

// Reads cameras, images, keypoints (normalised via the camera models) and
// priors. `rig` (may be null) groups images into frames as described above.
// Does not read matches (view_graph.h does). Throws InputError for cameras
// without usable intrinsics (naming the camera id), image names that do not
// follow `camK/data/<ns>.png` when a rig is given, or an image of camera K
// that the rig lacks.
MapperState LoadMapperState(const Database& database, const Rig* rig,
                            const LoadMapperStateOptions& options);

// The registered images (with their 2D points) and the triangulated tracks as
// a COLMAP model; point colours stay black unless `image_path` is non-empty
// (then read from the images). When the state has a rig, also COLMAP 3.12
// rigs/frames (reference sensor = the first camera of the rig).
Reconstruction ToReconstruction(const MapperState& state, const std::string& image_path);

}  // namespace colmap
}  // namespace lisfm
