// Rig bundle adjustment of `lisfm global_mapper` (stage 5).
//
// Unknowns (mapper_state.h's rig model):
//  - per registered frame: rig_from_world, a unit quaternion on
//    ceres::EigenQuaternionManifold plus a translation (m, or the arbitrary
//    unit of the view graph when nothing metric is known);
//  - per camera: cam_from_rig (constant unless `refine_cam_from_rig` and the
//    state has a rig; the camera with the smallest id among those observed
//    stays the reference and is never refined, which removes the gauge
//    between rig frame and cameras), and the intrinsics
//    (focal length / principal point / extra parameters refined per options;
//    subsets held with ceres::SubsetManifold);
//  - per triangulated track: its point in world.
// Residuals:
//  - reprojection, observed pixel - Project(cam_from_rig * rig_from_world * X)
//    in pixels, any COLMAP model (camera_model_functors.h), robust loss;
//  - frame position prior (use_priors): L^-1 (c - c_prior) with c the rig
//    origin in world and L L^T = frame.prior_position_covariance;
//  - frame rotation prior (use_priors): Log(R_prior^-1 R) / sigma with
//    R = rig_from_world rotation (right perturbation, rad);
//  - LiDAR relative pose (use_lidar_constraints): with T_meas = rig1_from_rig2
//    and T_est = rig1_from_world * rig2_from_world^-1, the right perturbation
//    T_est = T_meas * Exp(xi), xi = [omega; v] = SE3 Log(T_meas^-1 T_est),
//    whitened as U^T xi with U U^T = covariance^-1 (LLT of the information).
// Prior frame (refine_prior_frame): the priors and LiDAR constraints are
// measured in a body frame P (lio's IMU frame, built on the believed LiDAR
// extrinsic) that may differ from the rig frame by a constant rigid transform
// X = rig_from_prior (MapperState::rig_from_prior, identity by default). With
// the option, X is one more unknown (a quaternion on EigenQuaternionManifold
// and a translation, m) and the terms above compare the priors with
// prior_from_world = X^-1 * rig_from_world:
//  - position prior on the origin of P in world, c = (rig_from_world^-1 * X).t;
//  - rotation prior Log(R_prior^-1 * R_X^-1 * R) / sigma;
//  - LiDAR term with T_est = X^-1 * rig1_from_world * rig2_from_world^-1 * X
//    (equivalently, the measurement seen between rig frames is
//    X * T_meas * X^-1).
//   X is a hand-eye calibration: a rotation of X shows only through relative
//   motions that turn about other axes than its own (X^-1 T X = T for T about
//   X's axis) or translate across it, and its translation only through
//   relative rotations, (I - R_ij) t_X. Guard: a linear model of the prior
//   and LiDAR terms at the initial values whose unknowns are X and the
//   similarity of the world that the images leave free (scale, rotation,
//   translation: the images fix the relative rig poses up to it) predicts X's
//   marginal covariance. X's rotation is refined only when the largest axis
//   of its block has a standard deviation below
//   prior_frame_max_rotation_sigma_deg; X's translation is refined along
//   each eigenvector of its block whose standard deviation is below
//   prior_frame_max_translation_sigma_m and held along the others (a walk
//   that turns only about the vertical determines the horizontal components
//   of t_X but not the vertical one). Without LiDAR terms X is held.
// Gauge (seven degrees of freedom of a similarity; fixed explicitly):
//  - absolute pose: given by the priors when >= 3 registered frames have a
//    position prior, or >= 1 has a position prior and >= 1 a rotation prior;
//    otherwise the first registered frame (smallest frame_id with
//    observations) is held constant;
//  - scale: given by >= 2 position priors or >= 1 LiDAR constraint; otherwise
//    (as COLMAP) the largest-magnitude coordinate of the translation of the
//    frame farthest from the first one is held constant.
//   So priors give a metric result in the priors' world frame; LiDAR
//   constraints alone give a metric result with the first frame fixed.
// Threads: the Schur solver uses `num_threads` (deterministic reductions);
// Ceres runs on ceres_num_threads = 1 thread by default (its multi-threaded Schur
// elimination adds up in thread-timing order), so the result is the same bit for
// bit from run to run.
// The state must not be shared meanwhile.
// Failures: a non-positive-definite prior or LiDAR covariance is user data
// (InputError naming the frame / constraint); a problem without observations
// returns stats with num_reprojection_residuals = 0 and changes nothing.
#pragma once

#include <ceres/autodiff_cost_function.h>
#include <ceres/jet.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "colmap_ext/sfm/mapper_state.h"

namespace lisfm {
namespace colmap {

struct BundleAdjustmentOptions {
  bool refine_focal_length = true;      // per camera focal length(s)
  bool refine_principal_point = false;  // per camera cx, cy
  bool refine_extra_params = true;      // distortion parameters
  bool refine_cam_from_rig = false;     // rig extrinsics (only with a rig)
  bool refine_frame_poses = true;  // false: structure-only (poses constant)
  bool use_priors = true;          // frame position / rotation prior residuals
  bool use_lidar_constraints = true;  // LiDAR relative pose residuals
  // Refine X = rig_from_prior between the frame of the priors / LiDAR
  // constraints and the rig frame (header comment; needs LiDAR terms).
  bool refine_prior_frame = false;
  // Guard: refine X's rotation only when its predicted standard deviation
  // (largest axis) is below this (deg): half the 0.1 deg camera target, well
  // below a LiDAR extrinsic calibration's typical 0.1-0.5 deg error ...
  double prior_frame_max_rotation_sigma_deg = 0.05;
  // ... and its translation along the directions whose predicted standard
  // deviation is below this (m): half the 1 cm camera target, below a LiDAR
  // extrinsic calibration's typical 5-20 mm error.
  double prior_frame_max_translation_sigma_m = 0.005;
  std::string loss_type = "cauchy";   // trivial | huber | cauchy (reprojection)
  double loss_scale = 1.0;            // px; residual scale of the robust loss
  int max_num_iterations = 100;       // Levenberg-Marquardt iterations
  double function_tolerance = 1e-6;   // relative cost change to stop
  double gradient_tolerance = 1e-10;  // Ceres gradient tolerance
  double parameter_tolerance = 1e-8;  // relative step size to stop
  // Point subsampling for speed: > 0 keeps, per registered image, its best
  // this many tracks (longest, then lowest error) and adjusts their union;
  // the other points keep their coordinates (re-triangulate them after the
  // poses moved). 0 = every triangulated track.
  int max_tracks_per_image = 0;
  int dense_schur_max_frames = 50;    // up to this many frames: DENSE_SCHUR
  // auto: lisfm's dense-Schur Levenberg-Marquardt (schur_bundle_adjuster.h)
  // up to dense_schur_max_frames frames when cam_from_rig is not refined,
  // Ceres otherwise; ceres / schur force one (schur cannot refine cam_from_rig).
  std::string solver = "auto";
  int num_threads = -1;               // Schur solver threads; -1: hardware threads
  // Ceres threads (solver ceres). 1 keeps the result the same bit for bit
  // from run to run (header comment); more may differ in the last bits.
  int ceres_num_threads = 1;
  bool verbose = false;               // Ceres progress to stdout
  bool Check() const;
};

struct BundleAdjustmentStats {
  size_t num_frames = 0;           // frames with reprojection residuals
  size_t num_images = 0;           // images with reprojection residuals
  size_t num_cameras = 0;          // cameras used
  size_t num_cameras_refined = 0;  // cameras with refined intrinsics
  size_t num_points = 0;           // tracks in the problem
  size_t num_reprojection_residuals = 0;
  size_t num_position_prior_residuals = 0;
  size_t num_rotation_prior_residuals = 0;
  size_t num_lidar_residuals = 0;
  size_t num_lidar_constraints_skipped =
      0;              // a frame not registered / not in the problem
  std::string gauge;  // how the gauge was fixed (see the header comment)
  // Prior frame X = rig_from_prior (refine_prior_frame): which parts were
  // refined, the guard's predicted standard deviations (largest axis; +inf
  // when unobservable; 0 when not evaluated), why a part was held, and X
  // after the adjustment (MapperState::rig_from_prior).
  bool prior_frame_used = false;  // the option was on and X entered the terms
  bool prior_frame_rotation_refined = false;
  bool prior_frame_translation_refined = false;        // along at least one direction
  int prior_frame_translation_directions_refined = 0;  // 0-3 (header comment)
  double prior_frame_rotation_sigma_deg = 0.0;
  double prior_frame_translation_sigma_m = 0.0;          // the largest of the three below
  Vec3 prior_frame_translation_sigmas_m = Vec3::Zero();  // per direction, ascending
  std::string prior_frame_note;
  SE3 rig_from_prior;
  double initial_cost = 0.0;  // Ceres cost (0.5 sum rho) before / after
  double final_cost = 0.0;
  double initial_mean_reprojection_error_px = 0.0;
  double final_mean_reprojection_error_px = 0.0;
  int num_iterations = 0;
  bool converged = false;   // Ceres CONVERGENCE
  bool usable = false;      // Ceres IsSolutionUsable()
  std::string termination;  // Ceres brief report
  std::string linear_solver;
  double seconds = 0.0;             // whole call
  double setup_seconds = 0.0;       // building the Ceres problem
  double ceres_seconds = 0.0;       // ceres::Solve: preprocessing + minimiser
  double linear_solver_seconds = 0.0;  // of which the linear solves
  double evaluation_seconds = 0.0;     // of which residuals + Jacobians
};

// Optimises the registered frames, cameras (per options) and the triangulated
// tracks with >= 2 observations in registered images (fewer leave the point
// undetermined; such tracks are left unchanged); writes back poses,
// intrinsics, cam_from_rig, track xyz and track.error (mean px over the track's
// registered observations). Registered frames without such observations get
// no parameters (their priors / LiDAR constraints are skipped; the pose is
// left unchanged).
BundleAdjustmentStats RunBundleAdjustment(
    const BundleAdjustmentOptions& options, MapperState* state);

// ---------------------------------------------------------------------------
// Templated SO(3)/SE(3) helpers and the prior / LiDAR cost functors (exposed
// for tests). Quaternions are Eigen (x, y, z, w) coefficient arrays.

// Rotation vector of a unit quaternion (|omega| <= pi), as so3::Log.
template <typename T>
Eigen::Matrix<T, 3, 1> QuaternionLogT(const Eigen::Quaternion<T>& q_in) {
  T w = q_in.w();
  Eigen::Matrix<T, 3, 1> vec = q_in.vec();
  if (w < T(0.0)) {
    w = -w;
    vec = -vec;
  }
  const T n2 = vec.squaredNorm();
  if (n2 < T(1e-16)) {
    // atan2(n, w) / n ~= 1/w - n^2 / (3 w^3); avoids sqrt at 0 for Jets.
    return (T(2.0) / w - T(2.0) * n2 / (T(3.0) * w * w * w)) * vec;
  }
  const T n = ceres::sqrt(n2);
  return (T(2.0) * ceres::atan2(n, w) / n) * vec;
}

// SE(3) Log: xi = [omega; J_l(omega)^-1 t] (Barfoot 2017, Eq. 7.95 / 7.97:
// J_l^-1 = I - omega^/2 + (1/theta^2 - (1 + cos theta) / (2 theta sin theta))
// omega^2).
template <typename T>
Eigen::Matrix<T, 6, 1> SE3LogT(const Eigen::Quaternion<T>& q,
                               const Eigen::Matrix<T, 3, 1>& t) {
  const Eigen::Matrix<T, 3, 1> omega = QuaternionLogT(q);
  const T theta2 = omega.squaredNorm();
  T c;
  if (theta2 < T(1e-8)) {
    c = T(1.0 / 12.0) + theta2 / T(720.0);  // series; next term O(theta^4)
  } else {
    const T theta = ceres::sqrt(theta2);
    c = T(1.0) / theta2 -
        (T(1.0) + ceres::cos(theta)) / (T(2.0) * theta * ceres::sin(theta));
  }
  const Eigen::Matrix<T, 3, 1> w_x_t = omega.cross(t);
  Eigen::Matrix<T, 6, 1> xi;
  xi.template head<3>() = omega;
  xi.template tail<3>() = t - T(0.5) * w_x_t + c * omega.cross(w_x_t);
  return xi;
}

// Position prior on the rig origin in world, c = -R^T t of rig_from_world:
// residual = sqrt_information * (c - prior) (3, unitless).
struct PositionPriorFunctor {
  PositionPriorFunctor(const Eigen::Vector3d& prior_position,
                       const Eigen::Matrix3d& sqrt_information)
      : prior_(prior_position), sqrt_information_(sqrt_information) {}
  static ceres::CostFunction* Create(const Eigen::Vector3d& prior_position,
                                     const Eigen::Matrix3d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<PositionPriorFunctor, 3, 4, 3>(
        new PositionPriorFunctor(prior_position, sqrt_information));
  }
  template <typename T>
  bool operator()(const T* rig_from_world_q,
                  const T* rig_from_world_t,
                  T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(rig_from_world_q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(rig_from_world_t);
    const Eigen::Matrix<T, 3, 1> center = -(q.conjugate() * t);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    r = sqrt_information_.cast<T>() * (center - prior_.cast<T>());
    return true;
  }

 private:
  Eigen::Vector3d prior_;
  Eigen::Matrix3d sqrt_information_;
};

// Rotation prior: residual = Log(R_prior^-1 * R) / sigma (3, unitless), with R
// the rig_from_world rotation.
struct RotationPriorFunctor {
  RotationPriorFunctor(const Eigen::Quaterniond& prior_rig_from_world,
                       double sigma_rad)
      : prior_inverse_(prior_rig_from_world.conjugate()),
        inv_sigma_(1.0 / sigma_rad) {}
  static ceres::CostFunction* Create(
      const Eigen::Quaterniond& prior_rig_from_world, double sigma_rad) {
    return new ceres::AutoDiffCostFunction<RotationPriorFunctor, 3, 4>(
        new RotationPriorFunctor(prior_rig_from_world, sigma_rad));
  }
  template <typename T>
  bool operator()(const T* rig_from_world_q, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(rig_from_world_q);
    const Eigen::Quaternion<T> delta = prior_inverse_.cast<T>() * q;
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    r = QuaternionLogT(delta) * T(inv_sigma_);
    return true;
  }

 private:
  Eigen::Quaterniond prior_inverse_;
  double inv_sigma_;
};

// LiDAR relative pose: residual = sqrt_information * Log(T_meas^-1 *
// rig1_from_world * rig2_from_world^-1) (6, unitless, [omega; v] order), with
// T_meas = rig1_from_rig2 and sqrt_information^T sqrt_information = cov^-1.
struct RelativePoseFunctor {
  RelativePoseFunctor(const SE3& rig1_from_rig2, const Mat6& sqrt_information)
      : meas_inverse_(rig1_from_rig2.Inverse()),
        sqrt_information_(sqrt_information) {}
  static ceres::CostFunction* Create(const SE3& rig1_from_rig2,
                                     const Mat6& sqrt_information) {
    return new ceres::AutoDiffCostFunction<RelativePoseFunctor, 6, 4, 3, 4, 3>(
        new RelativePoseFunctor(rig1_from_rig2, sqrt_information));
  }
  template <typename T>
  bool operator()(const T* rig1_from_world_q,
                  const T* rig1_from_world_t,
                  const T* rig2_from_world_q,
                  const T* rig2_from_world_t,
                  T* residual) const {
    using Vec3T = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> q1(rig1_from_world_q);
    const Eigen::Map<const Vec3T> t1(rig1_from_world_t);
    const Eigen::Map<const Eigen::Quaternion<T>> q2(rig2_from_world_q);
    const Eigen::Map<const Vec3T> t2(rig2_from_world_t);
    // rig1_from_rig2 = rig1_from_world * world_from_rig2.
    const Eigen::Quaternion<T> q12 = q1 * q2.conjugate();
    const Vec3T t12 = t1 - q12 * t2;
    // T_meas^-1 * T_est.
    const Eigen::Quaternion<T> q_m = meas_inverse_.rotation().cast<T>();
    const Eigen::Quaternion<T> q_err = q_m * q12;
    const Vec3T t_err = q_m * t12 + meas_inverse_.translation().cast<T>();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual);
    r = sqrt_information_.cast<T>() * SE3LogT(q_err, t_err);
    return true;
  }

 private:
  SE3 meas_inverse_;
  Mat6 sqrt_information_;
};

// The prior / LiDAR terms through X = rig_from_prior (quaternion block
// rig_from_prior_q, translation block rig_from_prior_t; header comment).
//
// Position prior through X: residual = sqrt_information * (c - prior), with c
// the origin of the prior frame in world, world_from_prior = world_from_rig *
// X, so c = R^T (t_X - t) for rig_from_world = (R, t).
struct PriorFramePositionPriorFunctor {
  PriorFramePositionPriorFunctor(const Eigen::Vector3d& prior_position,
                                 const Eigen::Matrix3d& sqrt_information)
      : prior_(prior_position), sqrt_information_(sqrt_information) {}
  static ceres::CostFunction* Create(const Eigen::Vector3d& prior_position,
                                     const Eigen::Matrix3d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<PriorFramePositionPriorFunctor, 3, 4, 3, 3>(
        new PriorFramePositionPriorFunctor(prior_position, sqrt_information));
  }
  // The origin of P does not depend on R_X: no rig_from_prior_q block.
  template <typename T>
  bool operator()(const T* rig_from_world_q,
                  const T* rig_from_world_t,
                  const T* rig_from_prior_t,
                  T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(rig_from_world_q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(rig_from_world_t);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> tx(rig_from_prior_t);
    const Eigen::Matrix<T, 3, 1> center = q.conjugate() * (tx - t);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    r = sqrt_information_.cast<T>() * (center - prior_.cast<T>());
    return true;
  }

 private:
  Eigen::Vector3d prior_;
  Eigen::Matrix3d sqrt_information_;
};

// Rotation prior through X: residual = Log(R_prior^-1 * R_X^-1 * R) / sigma,
// with R_X^-1 R the prior_from_world rotation.
struct PriorFrameRotationPriorFunctor {
  PriorFrameRotationPriorFunctor(const Eigen::Quaterniond& prior_from_world, double sigma_rad)
      : prior_inverse_(prior_from_world.conjugate()), inv_sigma_(1.0 / sigma_rad) {}
  static ceres::CostFunction* Create(const Eigen::Quaterniond& prior_from_world, double sigma_rad) {
    return new ceres::AutoDiffCostFunction<PriorFrameRotationPriorFunctor, 3, 4, 4>(
        new PriorFrameRotationPriorFunctor(prior_from_world, sigma_rad));
  }
  template <typename T>
  bool operator()(const T* rig_from_world_q, const T* rig_from_prior_q, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(rig_from_world_q);
    const Eigen::Map<const Eigen::Quaternion<T>> qx(rig_from_prior_q);
    const Eigen::Quaternion<T> delta = prior_inverse_.cast<T>() * (qx.conjugate() * q);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    r = QuaternionLogT(delta) * T(inv_sigma_);
    return true;
  }

 private:
  Eigen::Quaterniond prior_inverse_;
  double inv_sigma_;
};

// LiDAR relative pose through X: with T12 = rig1_from_world * rig2_from_world^-1,
// the estimate in the prior frame is T_est = X^-1 * T12 * X =
// (R_X^T R12 R_X, R_X^T (R12 t_X + t12 - t_X)); residual = sqrt_information *
// Log(T_meas^-1 * T_est) (6, [omega; v]) as RelativePoseFunctor, T_meas =
// prior1_from_prior2.
struct PriorFrameRelativePoseFunctor {
  PriorFrameRelativePoseFunctor(const SE3& prior1_from_prior2, const Mat6& sqrt_information)
      : meas_inverse_(prior1_from_prior2.Inverse()), sqrt_information_(sqrt_information) {}
  static ceres::CostFunction* Create(const SE3& prior1_from_prior2, const Mat6& sqrt_information) {
    return new ceres::AutoDiffCostFunction<PriorFrameRelativePoseFunctor, 6, 4, 3, 4, 3, 4, 3>(
        new PriorFrameRelativePoseFunctor(prior1_from_prior2, sqrt_information));
  }
  template <typename T>
  bool operator()(const T* rig1_from_world_q,
                  const T* rig1_from_world_t,
                  const T* rig2_from_world_q,
                  const T* rig2_from_world_t,
                  const T* rig_from_prior_q,
                  const T* rig_from_prior_t,
                  T* residual) const {
    using Vec3T = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> q1(rig1_from_world_q);
    const Eigen::Map<const Vec3T> t1(rig1_from_world_t);
    const Eigen::Map<const Eigen::Quaternion<T>> q2(rig2_from_world_q);
    const Eigen::Map<const Vec3T> t2(rig2_from_world_t);
    const Eigen::Map<const Eigen::Quaternion<T>> qx(rig_from_prior_q);
    const Eigen::Map<const Vec3T> tx(rig_from_prior_t);
    const Eigen::Quaternion<T> q12 = q1 * q2.conjugate();
    const Vec3T t12 = t1 - q12 * t2;
    // prior1_from_prior2 = X^-1 * rig1_from_rig2 * X.
    const Eigen::Quaternion<T> qx_inv = qx.conjugate();
    const Eigen::Quaternion<T> q_est = qx_inv * q12 * qx;
    const Vec3T t_est = qx_inv * (q12 * tx + t12 - tx);
    const Eigen::Quaternion<T> q_m = meas_inverse_.rotation().cast<T>();
    const Eigen::Quaternion<T> q_err = q_m * q_est;
    const Vec3T t_err = q_m * t_est + meas_inverse_.translation().cast<T>();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual);
    r = sqrt_information_.cast<T>() * SE3LogT(q_err, t_err);
    return true;
  }

 private:
  SE3 meas_inverse_;
  Mat6 sqrt_information_;
};

}  // namespace colmap
}  // namespace lisfm
