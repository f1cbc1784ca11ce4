// The COLMAP database importer (`lisfm database_importer`): turns a sequence
// folder, the pose_slam output and lio's de-skewed keyframe scans into
//   database.db        COLMAP 3.8 schema (colmap_ext/io/database.h): one camera per
//                      rig camera, one image per camera frame, pose priors;
//   image_list.txt     the database's image names (colmap feature_extractor
//                      --image_list_path);
//   pairs.txt          the image pairs to match (colmap matches_importer
//                      --match_type pairs);
//   rig.yaml, rig_config.json   the rig (lisfm global_mapper --rig_path; COLMAP 3.8
//                      rig_bundle_adjuster --rig_config_path);
//   constraints.txt    the LiDAR constraints re-expressed between rig frames;
//   covisibility.csv   every selected pair with its score and origin;
//   importer_summary.json.
//
// Times: an image's stamp is the `<ns>` of its name `camK/data/<ns>.png` (camera
// clock); its time on the IMU clock is stamp + timeshift_cam_imu of its camera
// (DESIGN.md "Time"). A rig frame is the set of images with the same stamp; its
// time is that of its lowest-index camera.
//
// Pose priors: world_from_cam = world_from_imu(t) * imu_from_cam with
// world_from_imu interpolated on SE(3) (InterpolatePoseSe3) from the pose_slam
// trajectory. The position covariance is that of the camera centre under the
// nearest keyframe's marginal (right perturbation [omega; v] of world_from_imu:
// d centre = R v - R [t_imu_cam]_x omega), plus (drift * |t - t_keyframe|)^2 and
// a floor min_position_sigma_m^2 on the diagonal.
//
// LiDAR-proxy co-visibility, source "map" (default): every keyframe scan (lio's keyframes/ at
// the pose_slam keyframe poses) goes into one world-frame map, voxel-downsampled to
// scan_voxel_size_m, so that the test does not depend on which scan pairs pose_slam
// constrained. Each image sees the map points that project into it and pass the z-buffer test
// below against the map itself (the LiDAR proxy of the surfaces; range at most
// max_point_range_m when > 0). A pair (a, b) gets one vote per map point both see with rays
// from the two camera centres at most max_view_angle_deg apart (wider baselines rarely match
// with SIFT). Images run in parallel (TBB); the counts do not depend on the thread count.
//
// Source "constraints" (FL2BIPS-GTSFM, "Co-Visibility Evaluation"): for each
// constrained keyframe pair (i, j) both scans go to the world frame with the
// pose_slam keyframe poses; each point of scan i (voxel-downsampled) whose
// nearest point of scan j is within max_point_distance_m is projected into the
// images of scan i and of scan j (every camera; an image belongs to the scan
// nearest to it in time, within max_image_time_offset_s: keyframes are spaced
// by motion, so a long gap means little motion), each with its camera model. A projection counts
// only when the point is the first surface along the ray: its range is at most the smallest range
// of the own scan's points covering the same z-buffer cell (zbuffer_cell_px; each point covers a
// disc of point_footprint_m, the LiDAR samples being sparser than the pixels nearby) times (1 +
// occlusion_tolerance_ratio) plus occlusion_tolerance_m. Every pair (image a seeing it from the
// side of i, image b seeing it from the side of j, a != b) gets one vote. Scan pairs run in
// parallel (TBB); the votes are merged in scan-pair order, so the result does not depend on the
// thread count. The importer adds every scan paired with itself (its images that see the same
// points). Selection: pairs with >= min_count votes, each kept when it is among the
// max_pairs_per_image best of either of its images by score (CovisibilityOptions::score); plus
// intra-rig pairs of cameras whose fields of view overlap and num_temporal_neighbors successive
// images per camera. The images of one rig frame whose cameras' views do not overlap are listed
// only when their votes select them. Without constraints the co-visibility part is replaced by
// the fallback_num_neighbors nearest images by prior camera centre (viewing
// directions within 90 degrees).
//
// Constraints: a keyframe constraint T_i_j (IMU frames at t_i, t_j) becomes
// T_a_b = T_a_i * T_i_j * T_j_b between the rig frames a, b nearest in time to
// t_i, t_j (T_a_i from the interpolated trajectory), stamped with the frames'
// name stamps so that global_mapper attaches it exactly; covariance
// Ad(T_j_b^-1) S Ad(T_j_b^-1)^T + (drift * (|t_a - t_i| + |t_b - t_j|))^2 on the
// diagonal. Constraints whose keyframes have no frame within
// max_frame_time_offset_s, or map to one frame, are dropped (counted).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/geometry.h"
#include "core/lidar_constraint.h"
#include "core/rig.h"
#include "core/time.h"
#include "core/trajectory.h"
#include "core/types.h"
#include "core/work_list.h"

namespace lisfm {

struct CovisibilityOptions {
  // "map": every keyframe scan in one map, image pairs by shared visible map points (header
  // comment); "constraints": only the constrained scan pairs vote.
  std::string source = "map";
  double max_view_angle_deg = 60.0;      // deg, map: largest angle between the two rays to a point
  double max_point_range_m = 0.0;        // m, map: farthest point an image counts (0: no limit)
  double max_point_distance_m = 0.05;    // m, a point of scan i matches scan j within this
  double scan_voxel_size_m = 0.1;        // m, voxel of the projected points (0: off)
  double max_image_time_offset_s = 2.5;  // s, an image belongs to its nearest scan within this
  int zbuffer_cell_px = 8;               // px, edge of a z-buffer cell
  double point_footprint_m = 0.15;       // m, diameter of the surface patch a z-buffer point covers
  double occlusion_tolerance_m = 0.15;   // m, depth margin of the visibility test
  double occlusion_tolerance_ratio = 0.05;  // relative depth margin of the visibility test
  int min_count = 10;                       // votes a pair needs to be listed
  // Ranking score of a pair (map source; the constraints source always ranks by votes):
  // "area" sum over the shared points of voxel^2 / (range_a range_b), the solid angle (sr) the
  // shared surface covers in the two images (features spread over the image, not over the
  // scene's square metres); "count" the votes; "fraction" the votes / the smaller number of map
  // points the two images see.
  std::string score = "area";
  int max_pairs_per_image = 25;    // best pairs kept per image (a pair stays when either keeps it)
  int num_temporal_neighbors = 1;  // successive images of the same camera paired with each image
  bool intra_rig_pairs = true;     // pair the cameras of one rig frame whose views overlap
  double min_view_overlap = 0.1;   // fraction of one camera's rays the other sees (rig pairs)
  double view_overlap_depth_m = 5.0;  // m, depth of the view-overlap test
  int fallback_num_neighbors = 10;    // nearest images by prior position without constraints
  int num_threads = -1;               // TBB threads (-1: all)
  bool Check() const;
};

struct ImporterPriorOptions {
  double min_position_sigma_m = 0.01;  // m, floor of the prior position sigma per axis
  double drift_m_per_s = 0.02;         // m/s, sigma growth away from a keyframe
  double drift_rad_per_s = 0.002;      // rad/s, rotation sigma growth (constraints)
  double max_extrapolation_s = 0.01;  // s, images this far outside the trajectory keep its end pose
  double max_frame_time_offset_s = 0.6;  // s, a constraint's keyframe to its rig frame at most
  bool Check() const;
};

struct DatabaseImporterOptions {
  CovisibilityOptions covisibility;
  ImporterPriorOptions priors;
  bool Check() const;
};

// Pose at t_ns on the geodesic of SE(3) between the bracketing samples:
// a * Exp(s * Log(a^-1 b)); nullopt outside [start, end].
std::optional<SE3> InterpolatePoseSe3(const Trajectory& trajectory, TimestampNs t_ns);

// One image of the database.
struct ImporterImage {
  std::string name;                             // camK/data/<file>, relative to the image path
  std::string path;                             // file on disk
  int camera_index = 0;                         // rig camera
  TimestampNs stamp_ns = 0;                     // camera clock (the name)
  TimestampNs t_imu_ns = 0;                     // IMU clock
  SE3 world_from_cam;                           // prior
  Mat3 position_covariance = Mat3::Identity();  // m^2, of the camera centre
  int frame = -1;                               // index of its rig frame
};

struct ImporterFrame {
  TimestampNs stamp_ns = 0;  // name stamp
  TimestampNs t_imu_ns = 0;  // IMU clock
  SE3 world_from_imu;
};

// A keyframe scan: the de-skewed points in the IMU frame at t_ns, and the pose.
struct KeyframeScan {
  TimestampNs t_ns = 0;
  SE3 world_from_imu;
  std::vector<Eigen::Vector3f> points_in_imu;
};

// Votes of one image pair (a < b, indices into the image list).
struct PairVotes {
  int64_t count = 0;
  double score = 0;  // ranking score (CovisibilityOptions::score)
  // (keyframe i, keyframe j) -> votes it gave, in keyframe-pair order.
  std::vector<std::pair<std::pair<int, int>, int64_t>> voters;
};

// Co-visibility votes (header comment) for `scan_pairs` (indices into scans).
std::map<std::pair<int, int>, PairVotes> ComputeCovisibility(
    const Rig& rig,
    const std::vector<ImporterImage>& images,
    const std::vector<KeyframeScan>& scans,
    const std::vector<std::pair<int, int>>& scan_pairs,
    const CovisibilityOptions& options);

// Map co-visibility (header comment) from every scan in `scans`; voters stay empty.
std::map<std::pair<int, int>, PairVotes> ComputeMapCovisibility(
    const Rig& rig,
    const std::vector<ImporterImage>& images,
    const std::vector<KeyframeScan>& scans,
    const CovisibilityOptions& options);

// The same with the heavy part run by `runner` (core/work_list.h; empty: here):
// the scan pairs' votes (ComputeCovisibility), the images' visible map points
// (ComputeMapCovisibility). With `shared_runner` too, ComputeMapCovisibility
// runs the projection with it (every process gets every image's visible points)
// and then splits the vote count over the images a (pairs (a, b > a)) with
// `runner`; without, the votes are counted where `runner` returns the lists.
// std::nullopt where the runner returned std::nullopt (an MPI rank other than
// 0: its share went to rank 0). Results do not depend on how the runners split
// the work.
std::optional<std::map<std::pair<int, int>, PairVotes>> ComputeCovisibility(
    const Rig& rig,
    const std::vector<ImporterImage>& images,
    const std::vector<KeyframeScan>& scans,
    const std::vector<std::pair<int, int>>& scan_pairs,
    const CovisibilityOptions& options,
    const WorkListRunner& runner);
// Wall seconds of ComputeMapCovisibility's steps on this process.
struct MapCovisibilityTimings {
  double map = 0;       // the scans into one voxel map
  double project = 0;   // this process's images: the map projected, visible points kept
  double exchange = 0;  // the runners' transfers, incl. waiting for the other processes
  double tally = 0;     // this process's share of the pair votes
};
std::optional<std::map<std::pair<int, int>, PairVotes>> ComputeMapCovisibility(
    const Rig& rig,
    const std::vector<ImporterImage>& images,
    const std::vector<KeyframeScan>& scans,
    const CovisibilityOptions& options,
    const WorkListRunner& runner,
    const SharedWorkListRunner& shared_runner = {},
    MapCovisibilityTimings* timings = nullptr);

// Camera index pairs (a < b) of the rig whose views overlap (header comment).
std::vector<std::pair<int, int>> OverlappingRigCameras(const Rig& rig,
                                                       const CovisibilityOptions& options);

enum class PairSource { kCovisibility, kRig, kTemporal, kPriors };
std::string PairSourceName(PairSource source);

struct SelectedPair {
  int a = 0, b = 0;  // image indices, a < b
  PairSource source = PairSource::kCovisibility;
  int64_t count = 0;  // votes (co-visibility), else 0
};

// The pair list (header comment), sorted by (a, b); `votes` empty means the
// priors-based fallback.
std::vector<SelectedPair> SelectPairs(const Rig& rig,
                                      const std::vector<ImporterImage>& images,
                                      const std::map<std::pair<int, int>, PairVotes>& votes,
                                      bool use_priors_fallback,
                                      const CovisibilityOptions& options);

// Constraints between keyframes re-expressed between `frames` (header
// comment). `keyframe_stamps` maps index-based (GTSFM) records to stamps.
// *num_dropped counts the records left out.
std::vector<LidarConstraintRecord> ReexpressConstraints(
    const std::vector<LidarConstraintRecord>& records,
    const Trajectory& world_from_imu,
    const std::vector<TimestampNs>& keyframe_stamps,
    const std::vector<ImporterFrame>& frames,
    const ImporterPriorOptions& options,
    size_t* num_dropped);

// Width and height of a PNG or JPEG file from its header; InputError naming the
// file when it is neither or truncated.
std::pair<int, int> ReadImageSize(const std::string& path);

// The inputs of one run.
struct DatabaseImporterInput {
  std::string input_path;  // sequence folder (or the HILTI GTSFM folder)
  std::string image_path;  // image root ("" = input_path)
  std::string
      pose_slam_path;    // trajectory.txt, keyframes.txt, keyframe_covariances.txt, constraints.txt
  std::string lio_path;  // keyframes/<t_ns>.pcd
  std::string input_type = "sequence";  // sequence | hilti_gtsfm
};

// What a run did (importer_summary.json).
struct DatabaseImporterSummary {
  size_t num_cameras = 0;
  size_t num_images = 0;
  size_t num_images_skipped = 0;  // outside the trajectory
  size_t num_frames = 0;
  size_t num_keyframes = 0;
  size_t num_constraints_read = 0;
  size_t num_constraints_written = 0;
  size_t num_constraints_dropped = 0;
  size_t num_covisibility_votes_pairs = 0;  // image pairs with any vote
  size_t num_pairs = 0;
  size_t num_pairs_covisibility = 0;
  size_t num_pairs_rig = 0;
  size_t num_pairs_temporal = 0;
  size_t num_pairs_priors = 0;
  bool priors_fallback = false;
  // Only this process's share of the co-visibility was computed and sent to
  // the process that writes (RunDatabaseImporter's runner); nothing written.
  bool share_only = false;
  double seconds_read = 0, seconds_covisibility = 0, seconds_write = 0, seconds_total = 0;
  // Parts of seconds_covisibility: reading the keyframe scans, the map
  // co-visibility's steps (source "map"), pair selection and the rest.
  double seconds_scans = 0, seconds_select = 0;
  MapCovisibilityTimings map_timings;
};

// Runs the importer and writes every output file into `output_dir` (an
// existing, empty folder: the caller's OutputFolder). Throws InputError
// naming the file for bad input.
// `runner` (core/work_list.h), if set, runs the co-visibility work (see
// ComputeCovisibility) and is called exactly once (with an empty list when
// there is no co-visibility to compute); where it returns std::nullopt the
// importer returns right after it with share_only and writes nothing.
// `shared_runner`, if set, runs the map co-visibility's projection before it
// (ComputeMapCovisibility).
DatabaseImporterSummary RunDatabaseImporter(const DatabaseImporterInput& input,
                                            const DatabaseImporterOptions& options,
                                            const std::string& output_dir,
                                            const WorkListRunner& runner = {},
                                            const SharedWorkListRunner& shared_runner = {});

}  // namespace lisfm
