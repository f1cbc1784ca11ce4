// Ceres factors of pose_slam's inertial part (autodiff functors):
//  - ImuFactor: a preintegrated IMU measurement between keyframes i and j
//    (Forster et al., T-RO 2017, Eq. (45)) on (pose_i, v_i, pose_j, v_j, bias);
//  - BiasRandomWalkFactor: consecutive bias variables of the piecewise-constant
//    bias model differ by a random walk;
//  - ZeroVelocityFactor and StationaryPoseFactor: a stationary keyframe has zero
//    velocity, and two keyframes of one stationary period the same pose.
//
// Parameter blocks (the layout of lio/pose_slam's pose graph):
//  - pose: 7 doubles [qx qy qz qw tx ty tz] = world_from_imu (unit Hamilton
//    quaternion in Eigen's coefficient order, then the IMU position in m);
//  - velocity: 3 doubles, the IMU velocity in the world frame (m/s);
//  - bias: 6 doubles [b_g; b_a] (rad/s, m/s^2; lio/pose_slam/imu_preintegration.h).
// Residuals are whitened (||r||^2 is a squared Mahalanobis distance). The
// functors hold no pointers; Create() returns a cost function Ceres owns.
#pragma once

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/geometry.h"
#include "lio/pose_slam/imu_preintegration.h"

namespace lisfm {

// A square root of the information matrix of a symmetric positive definite
// covariance: L with L^T L = covariance^-1 (L = C^-1 for the lower Cholesky
// factor C C^T = covariance). Throws InternalError when `covariance` is not
// positive definite (e.g. zero noise densities).
Eigen::MatrixXd SqrtInformation(const Eigen::MatrixXd& covariance);

namespace internal {

// Log of a unit quaternion (templated for autodiff): the rotation vector, rad.
template <typename T>
Eigen::Matrix<T, 3, 1> QuaternionLog(const Eigen::Quaternion<T>& q) {
  const T q_wxyz[4] = {q.w(), q.x(), q.y(), q.z()};
  Eigen::Matrix<T, 3, 1> omega;
  ceres::QuaternionToAngleAxis(q_wxyz, omega.data());
  return omega;
}

// Exp of a rotation vector (rad) to a unit quaternion (templated for autodiff).
template <typename T>
Eigen::Quaternion<T> QuaternionExp(const Eigen::Matrix<T, 3, 1>& omega) {
  T q_wxyz[4];
  ceres::AngleAxisToQuaternion(omega.data(), q_wxyz);
  return Eigen::Quaternion<T>(q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3]);
}

}  // namespace internal

// The IMU factor between keyframes i and j with the bias variable of their
// interval. With db = bias - bias_hat and the bias-corrected measurement of
// Eq. (44) (Preintegration::Corrected*), the 9 residuals are (Eq. (45))
//   e_R = Log(dR(b)^T R_i^T R_j)                                  (rad)
//   e_v = R_i^T (v_j - v_i - g dt) - dv(b)                         (m/s)
//   e_p = R_i^T (p_j - p_i - v_i dt - g dt^2 / 2) - dp(b)          (m)
// whitened by L with L^T L = Sigma^-1, Sigma the preintegration covariance
// (same error order [e_R; e_v; e_p], right perturbation of dR).
//
// `extra_covariance` (9x9, same order and units) is added to Sigma: errors the
// noise model leaves out (e.g. scale-factor and axis-misalignment errors).
struct ImuFactor {
  ImuFactor(const Preintegration& preintegration,
            const Vec3& gravity_world,
            const Mat9& extra_covariance = Mat9::Zero())
      : delta_rotation(preintegration.delta_rotation()),
        delta_velocity(preintegration.delta_velocity()),
        delta_position(preintegration.delta_position()),
        bias_jacobian(preintegration.bias_jacobian()),
        bias_hat(preintegration.bias_hat().Vector()),
        dt(preintegration.dt_s()),
        gravity(gravity_world),
        sqrt_information(SqrtInformation(preintegration.covariance() + extra_covariance)) {}

  template <typename T>
  bool operator()(const T* const pose_i,
                  const T* const velocity_i,
                  const T* const pose_j,
                  const T* const velocity_j,
                  const T* const bias,
                  T* residuals) const {
    return Evaluate(pose_i, velocity_i, pose_j, velocity_j, bias,
                    Eigen::Matrix<T, 3, 1>(gravity.cast<T>()), residuals);
  }

  // The residuals with gravity `g` (m/s^2, world frame) in place of `gravity`.
  template <typename T>
  bool Evaluate(const T* const pose_i,
                const T* const velocity_i,
                const T* const pose_j,
                const T* const velocity_j,
                const T* const bias,
                const Eigen::Matrix<T, 3, 1>& g,
                T* residuals) const {
    using Vec3T = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(pose_i), q_j(pose_j);
    const Eigen::Map<const Vec3T> p_i(pose_i + 4), p_j(pose_j + 4);
    const Eigen::Map<const Vec3T> v_i(velocity_i), v_j(velocity_j);
    const Eigen::Map<const Eigen::Matrix<T, 6, 1>> b(bias);
    const Eigen::Matrix<T, 6, 1> db = b - bias_hat.cast<T>();
    const Vec3T db_g = db.template head<3>();
    const Eigen::Matrix<T, 9, 6> J = bias_jacobian.cast<T>();

    const Vec3T rotation_correction = J.template block<3, 3>(0, 0) * db_g;
    const Eigen::Quaternion<T> dR =
        delta_rotation.cast<T>() * internal::QuaternionExp<T>(rotation_correction);
    const Vec3T dv = delta_velocity.cast<T>() + J.template block<3, 6>(3, 0) * db;
    const Vec3T dp = delta_position.cast<T>() + J.template block<3, 6>(6, 0) * db;

    const Eigen::Quaternion<T> q_i_inverse = q_i.conjugate();
    const T dt_t(dt);
    Eigen::Matrix<T, 9, 1> e;
    e.template segment<3>(0) = internal::QuaternionLog<T>(dR.conjugate() * (q_i_inverse * q_j));
    e.template segment<3>(3) = q_i_inverse * (v_j - v_i - g * dt_t) - dv;
    e.template segment<3>(6) =
        q_i_inverse * (p_j - p_i - v_i * dt_t - T(0.5) * g * dt_t * dt_t) - dp;
    Eigen::Map<Eigen::Matrix<T, 9, 1>> r(residuals);
    r = sqrt_information.cast<T>() * e;
    return true;
  }

  // `gravity_world`: (0, 0, -9.81) m/s^2 in lio's world frame.
  static ceres::CostFunction* Create(const Preintegration& preintegration,
                                     const Vec3& gravity_world,
                                     const Mat9& extra_covariance = Mat9::Zero()) {
    return new ceres::AutoDiffCostFunction<ImuFactor, 9, 7, 3, 7, 3, 6>(
        new ImuFactor(preintegration, gravity_world, extra_covariance));
  }

  Quat delta_rotation;
  Vec3 delta_velocity;
  Vec3 delta_position;
  PreintegrationBiasJacobian bias_jacobian;
  Vec6 bias_hat;
  double dt;
  Vec3 gravity;
  Mat9 sqrt_information;

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// The IMU factor with the gravity direction as a sixth parameter block: a unit
// vector u (3 doubles, on ceres::SphereManifold<3>), gravity = magnitude * u.
// For a world frame whose "down" is known only approximately (lio's is levelled
// by its first second of accelerometer data).
struct ImuGravityFactor {
  ImuGravityFactor(const Preintegration& preintegration,
                   double gravity_magnitude,
                   const Mat9& extra_covariance)
      : imu(preintegration, Vec3::Zero(), extra_covariance), magnitude(gravity_magnitude) {}

  template <typename T>
  bool operator()(const T* const pose_i,
                  const T* const velocity_i,
                  const T* const pose_j,
                  const T* const velocity_j,
                  const T* const bias,
                  const T* const gravity_direction,
                  T* residuals) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> u(gravity_direction);
    return imu.Evaluate(pose_i, velocity_i, pose_j, velocity_j, bias,
                        Eigen::Matrix<T, 3, 1>(T(magnitude) * u), residuals);
  }

  static ceres::CostFunction* Create(const Preintegration& preintegration,
                                     double gravity_magnitude,
                                     const Mat9& extra_covariance = Mat9::Zero()) {
    return new ceres::AutoDiffCostFunction<ImuGravityFactor, 9, 7, 3, 7, 3, 6, 3>(
        new ImuGravityFactor(preintegration, gravity_magnitude, extra_covariance));
  }

  ImuFactor imu;
  double magnitude;  // m/s^2

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// Consecutive bias variables b_k, b_k+1 of the piecewise-constant model: the
// bias performs a random walk of densities sigma_bg (rad/s^2/sqrt(Hz)) and
// sigma_ba (m/s^3/sqrt(Hz)) (core/rig.h ImuNoise) over `dt_s` seconds, so
//   r = [(b_g,k+1 - b_g,k) / (sigma_bg sqrt(dt)); (b_a,k+1 - b_a,k) / (sigma_ba sqrt(dt))].
struct BiasRandomWalkFactor {
  BiasRandomWalkFactor(const ImuNoise& noise, double dt_s);

  template <typename T>
  bool operator()(const T* const bias_k, const T* const bias_k1, T* residuals) const {
    for (int r = 0; r < 6; ++r) {
      residuals[r] = T(inverse_sigma(r)) * (bias_k1[r] - bias_k[r]);
    }
    return true;
  }

  // dt_s > 0 and both random walks > 0 (InternalError otherwise).
  static ceres::CostFunction* Create(const ImuNoise& noise, double dt_s) {
    return new ceres::AutoDiffCostFunction<BiasRandomWalkFactor, 6, 6, 6>(
        new BiasRandomWalkFactor(noise, dt_s));
  }

  Vec6 inverse_sigma;  // 1 / sigma per component, [b_g; b_a] order
};

// Strength of the zero-velocity constraints of stationary periods
// (FL2BIPS-GTSFM: "hard equality constraints"; strong priors here).
struct ZeroVelocityOptions {
  double velocity_sigma = 1e-3;     // m/s, of a stationary keyframe's velocity
  double rotation_sigma = 1e-4;     // rad, between two keyframes of one period
  double translation_sigma = 1e-4;  // m, between two keyframes of one period
  bool Check() const;
};

// r = v / velocity_sigma: the velocity of a keyframe inside a stationary period.
struct ZeroVelocityFactor {
  explicit ZeroVelocityFactor(double velocity_sigma) : inverse_sigma(1.0 / velocity_sigma) {}

  template <typename T>
  bool operator()(const T* const velocity, T* residuals) const {
    for (int r = 0; r < 3; ++r) residuals[r] = T(inverse_sigma) * velocity[r];
    return true;
  }

  static ceres::CostFunction* Create(const ZeroVelocityOptions& options) {
    return new ceres::AutoDiffCostFunction<ZeroVelocityFactor, 3, 3>(
        new ZeroVelocityFactor(options.velocity_sigma));
  }

  double inverse_sigma;
};

// Two keyframes of one stationary period have the same pose (relative pose
// identity): r = [Log(R_i^T R_j) / rotation_sigma; R_i^T (p_j - p_i) / translation_sigma].
struct StationaryPoseFactor {
  StationaryPoseFactor(double rotation_sigma, double translation_sigma)
      : inverse_rotation_sigma(1.0 / rotation_sigma),
        inverse_translation_sigma(1.0 / translation_sigma) {}

  template <typename T>
  bool operator()(const T* const pose_i, const T* const pose_j, T* residuals) const {
    using Vec3T = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(pose_i), q_j(pose_j);
    const Eigen::Map<const Vec3T> p_i(pose_i + 4), p_j(pose_j + 4);
    const Eigen::Quaternion<T> q_i_inverse = q_i.conjugate();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residuals);
    r.template head<3>() =
        T(inverse_rotation_sigma) * internal::QuaternionLog<T>(q_i_inverse * q_j);
    r.template tail<3>() = T(inverse_translation_sigma) * (q_i_inverse * (p_j - p_i));
    return true;
  }

  static ceres::CostFunction* Create(const ZeroVelocityOptions& options) {
    return new ceres::AutoDiffCostFunction<StationaryPoseFactor, 6, 7, 7>(
        new StationaryPoseFactor(options.rotation_sigma, options.translation_sigma));
  }

  double inverse_rotation_sigma;
  double inverse_translation_sigma;
};

}  // namespace lisfm
