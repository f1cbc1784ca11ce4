// Stage 1 of `lisfm global_mapper`: the view graph.
//
// BuildViewGraph reads the two_view_geometries of a COLMAP database and keeps
// the image pairs that can carry a relative pose:
//  1. pairs whose images are not in the MapperState, and geometries with
//     config UNDEFINED, DEGENERATE, WATERMARK or MULTIPLE are skipped;
//  2. pairs with fewer than `min_num_inliers` inlier matches, or with an
//     inlier ratio (inliers / raw matches of the `matches` table; 1 when the
//     pair has no raw matches row) below `min_inlier_ratio`, are rejected;
//  3. pairs between images of two different frames: the relative pose
//     cam2_from_cam1 is re-estimated from the inlier matches on the
//     normalised (undistorted, z = 1) coordinates of SfmImage::normalized:
//     5-point essential matrix in RANSAC (Nister 2004; cv::findEssentialMat with
//     USAC_ACCURATE, 4x faster than cv::RANSAC on 1000-match pairs here,
//     with K = I and threshold = max_error_px / mean focal length of the two
//     cameras; on an even subsample of at most ransac_max_num_matches
//     matches), the cheirality test of cv::recoverPose, then a robust
//     least-squares refinement of (R, t) on the Sampson error (Hartley &
//     Zisserman 2003, Eq. 11.9) of all matches within the threshold of the
//     RANSAC pose. Only the matches within
//     the threshold under the refined pose are kept; the pair is rejected when
//     fewer than `min_num_inliers` remain. |t| = 1, metric = false.
//  4. pairs between two images of the SAME frame (rig): nothing is estimated,
//     the pose is known from the rig, cam2_from_cam1 = cam_from_rig[c2] *
//     cam_from_rig[c1]^-1 (metric = true); only the matches whose Sampson
//     error under that epipolar geometry is within the threshold are kept
//     (angle between the rays when the two centres coincide).
// Edge weight = number of kept inlier matches. Pairs are processed in
// parallel (TBB); the database itself is read on the calling thread. Each
// pair's result depends on that pair alone (RANSAC's generator starts from
// the same state for every pair), so the pairs may also be split across
// processes (`runner`, core/work_list.h: MPI ranks, balanced by match count).
//
// Frames and units: poses target_from_source; thresholds in pixels; the
// pixel threshold is mapped to the normalised plane by the mean focal length.
// Failures: InputError naming the database when it has no two_view_geometries
// rows, or when an inlier match references a keypoint the image does not
// have (record = the pair id). Invalid options throw InternalError (Check()).
#pragma once

#include <cstddef>
#include <vector>

#include "colmap_ext/io/database.h"
#include "colmap_ext/sfm/mapper_state.h"
#include "core/work_list.h"

namespace lisfm {
namespace colmap {

struct ViewGraphOptions {
  int min_num_inliers = 30;        // minimum inlier matches of a pair (count)
  double min_inlier_ratio = 0.25;  // minimum inliers / raw matches (0..1)
  double max_error_px = 4.0;       // epipolar (Sampson) inlier threshold (px)
  // Re-estimate poses between different frames. When false, the database's
  // qvec/tvec are used where they are set (|tvec| > 0), else it estimates.
  bool reestimate_relative_poses = true;
  // For CALIBRATED pairs, start from the database's essential matrix (the
  // matcher's RANSAC result on the same normalised coordinates) instead of a
  // new 5-point RANSAC; the pose is still decomposed, checked for cheirality
  // and Sampson-polished on the inliers.
  bool use_database_essential = false;
  int num_threads = -1;               // worker threads; -1 = all cores
  double ransac_confidence = 0.9999;  // RANSAC success probability (0..1)
  int ransac_max_iterations = 2000;   // RANSAC iteration cap (count)
  int ransac_max_num_matches =
      1000;  // RANSAC on at most this many matches (count)
  bool refine_relative_poses =
      true;  // Sampson least-squares polish after RANSAC
  int refine_max_num_matches =
      1500;  // the polish uses at most this many matches (count)
  bool Check() const;
};

struct ViewGraphStats {
  size_t num_pairs_in_database = 0;  // two_view_geometries rows
  size_t num_edges = 0;              // edges added to state->view_graph
  size_t num_intra_frame_edges = 0;  // of which between images of one frame
  size_t num_skipped_unknown_images = 0;  // an image not in the state
  size_t num_skipped_config = 0;  // UNDEFINED/DEGENERATE/WATERMARK/MULTIPLE
  size_t num_rejected_few_inliers = 0;   // < min_num_inliers or ratio too low
  size_t num_rejected_reestimation = 0;  // too few inliers after re-estimation
  size_t num_inlier_matches = 0;         // sum of the edges' kept inliers
  double seconds = 0.0;                  // wall time of BuildViewGraph
  // The runner sent this process's pairs to another process: state is left
  // as it was (the counts above are not filled) and the caller stops.
  bool share_only = false;
};

// Adds one edge per accepted pair to state->view_graph (which should be empty
// on entry; pairs that already have an edge are left alone). Reads `state`
// images, cameras, frames and cam_from_rig; see the header comment.
// `runner` runs the per-pair estimation (empty: all pairs here); every
// process calls BuildViewGraph with the same database, options and state.
ViewGraphStats BuildViewGraph(const Database& database,
                              const ViewGraphOptions& options,
                              MapperState* state,
                              const WorkListRunner& runner = {});

// Connected components of frames: two frames are linked by a valid view-graph
// edge between images of the two (different) frames, or by a LiDAR
// constraint. Every frame of state.frames is in exactly one component (frames
// without links are singletons). Components are sorted by size, largest
// first (ties: smallest frame id first); frame ids ascend inside each.
std::vector<std::vector<frame_t>> FrameComponents(const MapperState& state);

// Exposed for tests. Signed Sampson residual (Hartley & Zisserman 2003, Eq.
// 11.9) of x2^T E x1 = 0 on the normalised plane (its square is the Sampson
// distance; invariant to the scale of E).
double SampsonResidual(const Mat3& E, const Vec2& x1, const Vec2& x2);
// Robust cost sum 0.5 c^2 log(1 + r_i^2 / c^2) (Cauchy, c = loss_scale) of the
// Sampson residuals for E = [t]x R of cam2_from_cam1 (t normalised).
double SampsonCost(const SE3& cam2_from_cam1,
                   const std::vector<Vec2>& x1,
                   const std::vector<Vec2>& x2,
                   double loss_scale);
// Minimises SampsonCost over cam2_from_cam1 (rotation, unit translation) from
// `initial` by Levenberg-Marquardt with analytic Jacobians; returns the
// refined pose with |t| = 1 (the start when no step decreases the cost).
SE3 RefineRelativePose(const SE3& initial,
                       const std::vector<Vec2>& x1,
                       const std::vector<Vec2>& x2,
                       double loss_scale);

}  // namespace colmap
}  // namespace lisfm
