// A Levenberg-Marquardt bundle adjuster with an explicit Schur complement on
// the points and a dense reduced camera system: the fast path of
// RunBundleAdjustment (bundle_adjustment.h) for problems with up to a few
// dozen frames (the reduced system has 6 per frame + the free intrinsics).
//
// Same objective as the Ceres formulation in bundle_adjustment.cc:
//   0.5 sum_obs rho(|pixel(frame, camera, point) - observed|^2)
//   + 0.5 sum_pose_terms |r_k|^2
// with rho the robust loss (Ceres' definitions of Huber / Cauchy) and the pose
// terms (position / rotation priors, LiDAR relative poses) given as Ceres cost
// functions of the frames' quaternion (x, y, z, w) and translation blocks
// and, for terms through the prior frame, of X = rig_from_prior's blocks
// (bundle_adjustment.h, refine_prior_frame): 6 more variables [dtheta; dt] of
// the reduced system, X's rotation updated as the frames' (q <- Exp(dtheta) q).
// Parametrisation (as Ceres' EigenQuaternionManifold): rig_from_world rotation
// q <- Exp(dtheta) * q, translation t <- t + dt, point x <- x + dx, camera
// parameters p_i <- p_i + dp_i for the free indices.
// The robust loss is applied by iteratively reweighted least squares
// (weight rho'(s) on residual and Jacobian), which gives the exact gradient;
// damping: Marquardt (diag of J^T J, clamped to [1e-6, 1e32]) with Ceres'
// trust-region radius update; termination on the relative cost change, the
// gradient max-norm, the relative step size or the iteration cap, as Ceres.
//
// Threads: linearisation, the Schur complement and back-substitution run in
// parallel (TBB, `num_threads`); the reduction is deterministic (results do
// not depend on the thread count).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <ceres/cost_function.h>

#include "core/geometry.h"

namespace lisfm {
namespace colmap {

struct SchurBaFrame {
  Quat rig_from_world_rotation = Quat::Identity();
  Vec3 rig_from_world_translation = Vec3::Zero();
  std::array<bool, 6> fixed{};  // tangent coordinates held: [dtheta; dt]
};

struct SchurBaCamera {
  int model_id = 0;
  std::vector<double> params;
  std::vector<int> free_indices;  // refined parameter indices (ascending)
  Mat3 cam_from_rig_rotation = Mat3::Identity();
  Vec3 cam_from_rig_translation = Vec3::Zero();
};

struct SchurBaObservation {
  int frame = 0;   // index into frames
  int camera = 0;  // index into cameras
  int point = 0;   // index into points
  Vec2 observed = Vec2::Zero();
};

// A residual on frame poses only. kind: kPose (blocks q, t of frame1),
// kRotation (block q of frame1), kRelative (q1, t1, q2, t2). With
// uses_rig_from_prior the cost function takes X's blocks after those: kPose
// (q, t, t_X), kRotation (q, q_X), kRelative (q1, t1, q2, t2, q_X, t_X).
struct SchurBaPoseTerm {
  enum Kind { kPose, kRotation, kRelative };
  Kind kind = kPose;
  const ceres::CostFunction* cost = nullptr;  // not owned
  int frame1 = 0;
  int frame2 = -1;
  bool uses_rig_from_prior = false;  // needs SchurBaProblem::has_rig_from_prior
};

struct SchurBaProblem {
  std::vector<SchurBaFrame> frames;
  std::vector<SchurBaCamera> cameras;
  std::vector<Vec3> points;
  std::vector<SchurBaObservation> observations;  // sorted by point
  std::vector<SchurBaPoseTerm> pose_terms;
  // X = rig_from_prior, shared by the terms with uses_rig_from_prior.
  bool has_rig_from_prior = false;
  Quat rig_from_prior_rotation = Quat::Identity();
  Vec3 rig_from_prior_translation = Vec3::Zero();
  // X's translation tangent: t_X <- t_X + axes * dt (orthonormal columns), so
  // that rig_from_prior_fixed can hold it along any directions.
  Mat3 rig_from_prior_translation_axes = Mat3::Identity();
  std::array<bool, 6> rig_from_prior_fixed{};  // tangent coordinates held: [dtheta; dt]
};

struct SchurBaOptions {
  std::string loss_type = "cauchy";  // trivial | huber | cauchy
  double loss_scale = 1.0;
  int max_num_iterations = 100;
  double function_tolerance = 1e-6;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  int num_threads = -1;  // -1: all hardware threads
  bool Check() const;
};

struct SchurBaSummary {
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int num_iterations = 0;  // as Ceres: including iteration 0
  int num_successful_steps = 0;
  bool converged = false;
  std::string termination;
  double evaluation_seconds = 0.0;
  double linear_solver_seconds = 0.0;
};

// Optimises problem->frames / cameras / points (and X) in place. The observations must
// be sorted by point (throws InternalError otherwise) and every index valid.
SchurBaSummary SolveSchurBundleAdjustment(const SchurBaOptions& options,
                                          SchurBaProblem* problem);

// One observation's residual r = pixel - observed and its Jacobians in the
// solver's parametrisation, without a robust loss (weight 1): the code path
// of the solver's linearisation, exposed so that tests check its hand-written
// Jacobians against automatic differentiation. Throws InternalError for an
// invalid index.
struct SchurBaObservationLinearisation {
  Vec2 residual = Vec2::Zero();
  Eigen::Matrix<double, 2, 6> d_frame;  // [dtheta; dt] of the observation's frame
  Eigen::Matrix<double, 2, 3> d_point;
  Eigen::MatrixXd d_free_params;  // 2 x free_indices.size(), in that order
};
SchurBaObservationLinearisation LineariseSchurBaObservation(const SchurBaProblem& problem,
                                                            int observation);

}  // namespace colmap
}  // namespace lisfm
