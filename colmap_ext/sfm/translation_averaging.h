// Translation averaging of `lisfm global_mapper` (stage 3): frame
// positions from the view graph's relative directions, with the frame
// rotations held fixed (rotation_averaging.h ran before).
//
// Model. For image i of frame a and camera ci, the camera centre in world is
//   c_i = C_a + R_a^T p_ci,
// where C_a is frame a's origin in world, R_a the rotation of rig_from_world
// and p_ci the camera centre in rig coordinates (p_ci = -R_cr^T t_cr for
// cam_from_rig = [R_cr | t_cr]; zero without a rig). A view-graph edge carries
// cam2_from_cam1 = [R | t] with |t| = 1: x_cam2 = R x_cam1 + t, so t is cam1's
// centre in cam2 coordinates and cam2's centre in cam1 coordinates is -R^T t.
// In world, with the *estimated* camera rotation R_cam2 = R_c2r R_b:
//   d_12 = (c_2 - c_1) / |c_2 - c_1| = -R_cam2^T t.                    (1)
// The unknowns are the frame origins C; afterwards rig_from_world.t = -R_a C_a.
//
// Stage 1, outlier filtering (1dSfM, Wilson & Snavely, ECCV 2014, Sec. 3):
// the world directions (1) of all edges are projected on many random axes;
// each projection is a 1-D ordering problem whose consistent solution is a
// minimum feedback arc set (MFAS), approximated by the greedy heuristic of
// Eades et al. as in the paper (OrderNodesGreedyMfas below). An edge whose
// projection disagrees with the ordering is "broken" in that projection.
// Projections whose magnitude |d . axis| is below `min_projection_magnitude`
// are left out of that subproblem (their sign is decided by noise), as in the
// paper. The axes are sampled around the edge directions themselves (a random
// edge direction plus Gaussian noise), so that they follow the distribution
// of the motion (the paper samples from the directions' distribution for the
// same reason). The broken ratio of an edge is sum(|d . axis| over broken projections) /
// sum(|d . axis| over used projections); edges above `max_broken_ratio` are
// invalidated (valid = false, rejected_by = "1dsfm"). Projections run in
// parallel (TBB), each with its own seeded RNG: the result is deterministic.
//
// Stage 2, robust position solve (Ceres). Residual choice: the BATA form of
// Zhuang et al. (CVPR 2018) as used by GLOMAP / COLMAP 4's global positioner,
//   r_ij = (d_ij - s_ij (c_j - c_i)) / sigma_d,  s_ij >= lower bound > 0,   (2)
// with one scale s_ij per edge. Why this one: unlike the plain scaled-direction
// residual s d - (c_j - c_i), it has no trivial zero at collapsed positions
// (|r| = 1 / sigma_d when all c coincide), so it needs no scale constraint;
// unlike the chordal residual of 1dSfM (d - (c_j - c_i)/|c_j - c_i|) it is
// smooth everywhere and its magnitude does not explode for short baselines;
// at the optimum over s_ij, |d - s (c_j - c_i)| = sin(angle error), so
// dividing by sigma_d (rad) whitens it consistently with the metric residuals
// below. A Cauchy loss (scale `direction_loss_threshold`, in the units of
// |d - s dc| ~ rad) bounds the influence of the outliers that 1dSfM misses;
// GLOMAP uses Huber 0.1, but with camera positions only (no points) Huber's
// linear tail let the surviving >= 30 deg outliers of our synthetic tests
// bias whole neighbourhoods (RMS errors 2-4x those with Cauchy).
// Start: without priors, the linear solution (smallest eigenvector of
// sum |(I - d d^T)(C_b - C_a)|^2, Govindu 2001) instead of a random start:
// random starts of (2) on view graphs without points ended in poor local
// minima in our synthetic trials (2 of 4 scenes of degree 6 even without
// outliers; none with the linear start).
// Edges between two images of the same frame carry no information on frame
// positions and are skipped.
//
// Metric information, whitened by its covariance (no robust loss):
//  - frame position priors (frame.has_prior_position):
//      r = L^-1 (C_a - prior),  L L^T = prior_position_covariance;          (3)
//  - LiDAR constraints rig1_from_rig2 = [R_12 | t_12] (right perturbation
//    xi = [omega; v], translation perturbation R_12 v): frame 2's origin is
//    C_1 + R_1^T t_12, so
//      r = L^-1 (C_2 - C_1 - R_1^T t_12),
//      L L^T = R_1^T R_12 Sigma_vv R_12^T R_1 (Sigma_vv: translation block); (4)
//  - rig baselines: the offsets p_ci in (2) are metric, so with several
//    cameras per frame (distinct centres) the scale is observable.
//
// Gauge (explicit):
//  - with frame position priors in the solved set: nothing is fixed; the
//    result is metric and in the priors' world frame;
//  - otherwise the first solved frame (smallest frame id of its component) is
//    fixed at the origin; with LiDAR constraints, or rig baselines when
//    `use_rig_baselines_for_scale`, the scale follows from them (metric);
//    without any metric information the scale is left free during the solve
//    (a one-dimensional null space that Levenberg-Marquardt's damping
//    handles, as in GLOMAP; holding one s_ij at 1 instead collapses the
//    solution when that edge is an outlier) and fixed afterwards: positions
//    are scaled about the fixed frame so that the median baseline of the used
//    edges is 1 (the two-view convention |t| = 1).
// With `max_residual_angle_deg` > 0 the solve runs twice: edges whose
// direction differs from the first solution's baseline by more than that
// angle are invalidated (rejected_by = "translation_averaging") and the
// positions re-solved from the first solution without them.
// Frames are initialised at their priors, by chaining LiDAR constraints from
// the fixed frame, by the linear solution (no priors), or else uniformly at
// random in a cube (`random_init_extent`).
//
// Which frames get a position: the registered frames among `frame_ids`.
// After filtering, the link graph (valid direction edges + LiDAR constraints)
// may fall apart; a component is solved when its gauge is determined (with
// priors: it holds a prior frame and either >= 2 prior frames, a LiDAR link,
// rig baselines for scale, or only one frame; without priors: the largest
// component, preferring one with a LiDAR link). Frames of other components
// are set registered = false and counted in the stats (logged as a warning).
//
// Threads: the 1dSfM projections use TBB (`num_threads`), Ceres one thread
// (bit-reproducible: its multi-threaded sums follow thread timing). The function
// only touches `state` (frames' rig_from_world translations, registered flags,
// edges' valid / rejected_by). Failures: THROW_CHECK (InternalError) on an
// inconsistent state (an edge naming an unknown image, a camera without
// cam_from_rig); bad options throw InputError naming the option.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <ceres/ceres.h>

#include "colmap_ext/sfm/mapper_state.h"

namespace lisfm {
namespace colmap {

struct TranslationAveragingOptions {
  // --- 1dSfM filter ---
  bool filter_1dsfm = true;  // run the 1dSfM direction filter before the solve
  int num_projections = 48;  // random 1-D projections (Theia's default)
  // Projections |d . axis| below this are left out of a subproblem (unitless, in [0, 1)).
  double min_projection_magnitude = 0.1;
  // Edges whose weighted broken ratio exceeds this are rejected (in [0, 1]).
  double max_broken_ratio = 0.2;
  // Std. dev. (unitless) of the Gaussian added to a sampled edge direction to form an axis.
  double axis_perturbation_sigma = 0.3;
  // --- position solve ---
  // Expected angular noise of an edge direction (rad); whitens residual (2).
  double direction_sigma = 0.01;
  // Robust loss on the direction residuals: "cauchy", "huber" or "none".
  std::string direction_loss = "cauchy";
  // Loss scale on |d - s dc| (~rad, unwhitened; GLOMAP uses Huber at 0.1).
  double direction_loss_threshold = 0.1;
  // Lower bound of the per-edge scales s_ij (1/m or 1/unit); keeps them positive.
  double min_edge_scale = 1e-5;
  // Use frame position priors (frame.has_prior_position) when present.
  bool use_priors = true;
  // Use state.lidar_constraints between solved frames when present.
  bool use_lidar_constraints = true;
  // Let metric rig baselines fix the scale (no scale gauge) when cameras of one
  // frame have centres at least `min_rig_baseline` apart.
  bool use_rig_baselines_for_scale = true;
  double min_rig_baseline = 0.02;  // m
  // Initialise from the frames' current rig_from_world translations (e.g. a
  // previous run) instead of priors / LiDAR chaining / random positions.
  bool init_from_current = false;
  // Half side of the cube for random initial positions (same units as the result).
  double random_init_extent = 1.0;
  // After a first solve, invalidate edges whose direction disagrees with the
  // positions by more than this (deg; rejected_by = "translation_averaging")
  // and solve again without them; <= 0: a single solve.
  double max_residual_angle_deg = 10.0;
  int max_num_iterations = 300;       // Ceres iterations
  double function_tolerance = 1e-10;  // Ceres relative cost change to stop
  int num_threads = -1;               // 1dSfM (TBB) threads; <= 0: all cores
  // Ceres threads; 1 keeps the result the same bit for bit from run to run.
  int ceres_num_threads = 1;
  uint64_t random_seed = 1;           // seeds the 1dSfM axes and the random init
  bool verbose = false;               // Ceres progress to stdout (CLI only)

  // True when every field is in range. AverageTranslations throws InputError
  // naming the first bad field ("TranslationAveraging.<field>") otherwise.
  bool Check() const;
};

struct TranslationAveragingStats {
  size_t num_frames = 0;               // registered frames among frame_ids
  size_t num_frames_solved = 0;        // frames with a position after the solve
  size_t num_frames_unregistered = 0;  // left without a determined position (registered = false)
  size_t num_edges_input = 0;          // valid edges between different registered frames of the set
  size_t num_rejected_1dsfm = 0;       // edges invalidated by the 1dSfM filter
  size_t num_rejected_residual = 0;    // edges invalidated after the solve (max_residual_angle_deg)
  size_t num_edges_used = 0;           // direction residuals in the solve
  size_t num_prior_residuals = 0;      // frame position priors used
  size_t num_lidar_residuals = 0;      // LiDAR relative translations used
  bool metric = false;                 // the result has metric scale
  std::string gauge;                   // how the gauge was fixed (human readable)
  bool converged = false;              // Ceres reported a usable solution
  int iterations = 0;                  // Ceres iterations
  double initial_cost = 0.0;           // Ceres cost (0.5 * sum of squared whitened residuals)
  double final_cost = 0.0;
  std::string message;                 // Ceres termination message
  double seconds_1dsfm = 0.0;          // wall time of the filter
  double seconds = 0.0;                // wall time of the whole stage
};

// Runs the 1dSfM filter and the position solve described above on the
// registered frames of `frame_ids` (usually one component of FrameComponents).
// Sets rig_from_world.t for the solved frames; rotations are not changed.
TranslationAveragingStats AverageTranslations(const TranslationAveragingOptions& options,
                                              const std::vector<frame_t>& frame_ids,
                                              MapperState* state);

// --- Building blocks (exposed for tests and reuse) ---

// Stage 1 alone: invalidates the edges (rejected_by = "1dsfm") among the
// registered frames of `frame_ids` and returns how many it rejected.
size_t FilterEdges1DSfM(const TranslationAveragingOptions& options,
                        const std::vector<frame_t>& frame_ids,
                        MapperState* state);

// A weighted arc `from -> to` of a 1-D ordering problem ("to" should come after
// "from"); weight > 0.
struct OrderingArc {
  size_t from = 0;
  size_t to = 0;
  double weight = 0.0;
};

// Greedy minimum-feedback-arc-set ordering (Eades, Lin & Smyth 1993, with
// 1dSfM's ratio rule): returns position[node] in [0, num_nodes), a
// permutation. Repeatedly: a remaining source (no remaining incoming arc) goes
// to the front, else a remaining sink to the back, else the remaining node with
// the largest (w_out + 1) / (w_in + 1) over arcs to remaining nodes to the
// front (ties: smaller index). An acyclic input gets an order without broken
// arcs. O(E log N). Throws InternalError for an arc naming a node >= num_nodes.
std::vector<size_t> OrderNodesGreedyMfas(size_t num_nodes, const std::vector<OrderingArc>& arcs);

// Residual (2): r = (d - s (c2 - c1)) / sigma with c1 = C1 + o1, c2 = C2 + o2,
// o = R^T p the (constant) world offset of the camera centre from its frame
// origin. Parameters: C1 (3), C2 (3), s (1).
struct BataDirectionCost {
  BataDirectionCost(const Vec3& direction, const Vec3& offset1, const Vec3& offset2, double sigma)
      : direction_(direction), offset1_(offset1), offset2_(offset2), inv_sigma_(1.0 / sigma) {}

  template <typename T>
  bool operator()(const T* origin1, const T* origin2, const T* scale, T* residual) const {
    for (int k = 0; k < 3; ++k) {
      const T c1 = origin1[k] + T(offset1_[k]);
      const T c2 = origin2[k] + T(offset2_[k]);
      residual[k] = (T(direction_[k]) - scale[0] * (c2 - c1)) * T(inv_sigma_);
    }
    return true;
  }

  static ceres::CostFunction* Create(const Vec3& direction,
                                     const Vec3& offset1,
                                     const Vec3& offset2,
                                     double sigma) {
    return new ceres::AutoDiffCostFunction<BataDirectionCost, 3, 3, 3, 1>(
        new BataDirectionCost(direction, offset1, offset2, sigma));
  }

 private:
  Vec3 direction_;
  Vec3 offset1_;
  Vec3 offset2_;
  double inv_sigma_;
};

// Residual (3) and, with two origins, (4): r = W (C2 - C1 - delta) where W is
// the inverse Cholesky factor of the covariance (W^T W = Sigma^-1). The prior
// form uses one parameter block: r = W (C - prior).
struct WhitenedPositionCost {
  WhitenedPositionCost(const Vec3& target, const Mat3& sqrt_information)
      : target_(target), sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* origin, T* residual) const {
    Eigen::Matrix<T, 3, 1> e;
    for (int k = 0; k < 3; ++k) e[k] = origin[k] - T(target_[k]);
    const Eigen::Matrix<T, 3, 1> r = sqrt_information_.cast<T>() * e;
    for (int k = 0; k < 3; ++k) residual[k] = r[k];
    return true;
  }

  template <typename T>
  bool operator()(const T* origin1, const T* origin2, T* residual) const {
    Eigen::Matrix<T, 3, 1> e;
    for (int k = 0; k < 3; ++k) e[k] = origin2[k] - origin1[k] - T(target_[k]);
    const Eigen::Matrix<T, 3, 1> r = sqrt_information_.cast<T>() * e;
    for (int k = 0; k < 3; ++k) residual[k] = r[k];
    return true;
  }

  // Prior on one origin: target = prior position (m).
  static ceres::CostFunction* CreatePrior(const Vec3& prior, const Mat3& covariance);
  // Relative translation C2 - C1 = delta (world, m).
  static ceres::CostFunction* CreateRelative(const Vec3& delta, const Mat3& covariance);

 private:
  Vec3 target_;
  Mat3 sqrt_information_;
};

}  // namespace colmap
}  // namespace lisfm
