// Stage 2 of `lisfm global_mapper`: rotation averaging over rig frames.
//
// Measurements (all relative rotations between two DIFFERENT frames a, b of
// the given component):
//  - every valid view-graph edge between image i (frame a, camera ci) and
//    image j (frame b, camera cj) with relative pose R_ij = cam_j_from_cam_i.
//    From cam_from_world = cam_from_rig * rig_from_world,
//      R_ij = C_j R_b R_a^T C_i^T   =>   R_b R_a^T = C_j^T R_ij C_i,
//    with C = cam_from_rig rotation (held fixed) and R = rig_from_world
//    rotation (the unknowns). Edges within one frame carry no information and
//    are ignored.
//  - LiDAR constraints rig_a_from_rig_b (when use_lidar_constraints):
//    R_a R_b^T = R_ab  =>  R_b R_a^T = R_ab^T, weighted by the rotation block
//    of their covariance and never rejected.
//  - unary rotation priors of the frames (when use_rotation_priors), weighted
//    by frame.prior_rotation_sigma.
//
// Method:
//  1. Initialisation: frames with a rotation prior start from it; the others
//     are propagated along a maximum spanning tree of the measurement graph
//     from the prior frames, or from the first frame (which keeps its current
//     rotation) when no frame has a prior. Tree order: LiDAR links first,
//     then the number of triangles whose loop closes within
//     max_loop_error_deg (Zach et al. CVPR 2010; outliers close none), then
//     the edge weight (number of inliers).
//  2. Robust refinement by IRLS on the linearised problem of Chatterjee &
//     Govindu, "Robust Relative Rotation Averaging" (TPAMI 2018), Eq. 7-9:
//     with the world-frame (right) perturbation R <- R Exp(w), the residual
//     u_ab = Log(R_a^T R_ba_meas^T R_b) gives w_b - w_a = -u_ab, and a prior
//     u_a = Log(R_prior_a^T R_a) gives w_a = -u_a. The three coordinates
//     decouple into one weighted graph Laplacian (conjugate gradients with
//     an incomplete-Cholesky preconditioner). An L1-like stage (IRLS weights
//     min(1, s / |u|), s = relative_rotation_sigma_deg: Huber, i.e. L1 for
//     large residuals) is followed by Geman-McClure weights
//     (sigma^2 / (sigma^2 + |u|^2))^2 (Eq. 11 there).
//  3. Edges with a residual angle above max_rotation_error_deg are
//     invalidated (edge.valid = false, rejected_by = "rotation_averaging") and
//     the refinement runs once more on what is left.
// Gauge: fixed by the priors when any frame of the component has one,
// otherwise by holding the first frame of `frame_ids` at its rotation.
//
// Output: for the frames of the largest connected part (over the remaining
// measurements) of `frame_ids`: rig_from_world rotation set (translation left
// as it was) and registered = true; the other frames of `frame_ids` get
// registered = false. Frames not in `frame_ids` are untouched.
// Failures: unknown frame ids or images throw InternalError (THROW_CHECK).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "colmap_ext/sfm/mapper_state.h"

namespace lisfm {
namespace colmap {

struct RotationAveragingOptions {
  // Edges with a final residual above this are invalidated (deg). Relative
  // rotations from >= 30 inliers are good to a fraction of a degree; an error
  // of several degrees means a wrong two-view pose, not noise.
  double max_rotation_error_deg = 5.0;
  double geman_mcclure_sigma_deg =
      5.0;  // robust loss scale (deg), Chatterjee & Govindu
  // A triangle of relative rotations is consistent when its loop closes
  // within this (deg); the spanning tree prefers edges in consistent loops.
  double max_loop_error_deg = 5.0;
  int max_l1_iterations = 50;  // L1 IRLS iterations before GM (0 = none)
  double l1_tolerance_rad =
      1e-4;  // L1 stage stops when max |update| is below (rad)
  int max_irls_iterations = 100;  // Geman-McClure IRLS iterations
  double convergence_tolerance_rad =
      1e-7;  // stop when max |update| is below (rad)
  double relative_rotation_sigma_deg =
      0.5;  // per-axis std of an edge's relative rotation (deg)
  bool use_rotation_priors =
      true;  // unary prior terms and prior initialisation
  double fallback_prior_sigma_rad =
      0.01;  // used when frame.prior_rotation_sigma <= 0 (rad)
  bool use_lidar_constraints =
      true;  // LiDAR relative rotations as measurements
  bool weight_by_num_inliers =
      false;  // scale edge information by edge.weight / mean weight
  bool Check() const;
};

struct RotationAveragingStats {
  size_t num_input_frames = 0;        // frame_ids.size()
  size_t num_registered_frames = 0;   // frames with a rotation on return
  size_t num_edge_measurements = 0;   // view-graph edges used (first solve)
  size_t num_lidar_measurements = 0;  // LiDAR constraints used
  size_t num_prior_frames = 0;        // frames with a rotation prior used
  size_t num_rejected_edges = 0;      // edges invalidated by this stage
  int num_iterations = 0;             // IRLS iterations over all solves
  bool converged = false;             // the last IRLS loop met the tolerance
  double mean_residual_deg = 0.0;     // over the remaining valid edges (deg)
  double max_residual_deg = 0.0;      // same (deg)
  std::string
      initialization;  // "priors", "spanning_tree" or "priors+spanning_tree"
  double seconds = 0.0;
};

RotationAveragingStats AverageRotations(const RotationAveragingOptions& options,
                                        const std::vector<frame_t>& frame_ids,
                                        MapperState* state);

// Relative frame rotation R_b R_a^T (b_from_a) implied by a view-graph edge
// (see the header comment); a = frame of edge.image_id1. Exposed for tests.
Quat RelativeFrameRotation(const MapperState& state, const ViewGraphEdge& edge);

}  // namespace colmap
}  // namespace lisfm
