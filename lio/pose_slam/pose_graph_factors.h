// Residuals of the pose graph (Ceres autodiff functors). Pose blocks:
//  - 3D: 7 doubles [qx qy qz qw tx ty tz] = world_from_body (PoseManifold);
//  - 2D: 3 doubles [x y theta] (Euclidean; theta in rad, unwrapped).
// Each measurement is Z = i_from_j with Z = (R~, t~); the estimate of it is
// T_i^-1 T_j = (R_i^T R_j, R_i^T (t_j - t_i)).
#pragma once

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "core/geometry.h"

namespace lisfm {

// SE-Sync's objective term (Rosen et al., IJRR 2019, Problem 1, eq. (12)):
//   F_ij = kappa ||R_j - R_i R~||_F^2 + tau ||t_j - t_i - R_i t~||^2
// kappa, tau > 0 are the isotropic weights (1/rad^2-like and 1/m^2). With the
// rotation error E = R~^T R_i^T R_j of angle theta and unit quaternion
// q_E = q~^-1 q_i^-1 q_j, ||R_j - R_i R~||_F^2 = ||E - I||_F^2 = 6 - 2 tr(E)
// = 4 (1 - cos theta) = 8 sin^2(theta / 2) = 8 |vec(q_E)|^2, so the 6 residuals
//   r = [sqrt(8 kappa) vec(q_E); sqrt(tau) (t_j - t_i - R_i t~)]
// give ||r||^2 = F_ij exactly (Ceres' cost is F_ij / 2), with half the
// residuals of the 9 + 3 matrix entries.
struct ChordalFactor3 {
  ChordalFactor3(const SE3& i_from_j, double kappa, double tau)
      : q_ij_inverse(i_from_j.rotation().conjugate()),
        t_ij(i_from_j.translation()),
        sqrt_8_kappa(std::sqrt(8.0 * kappa)),
        sqrt_tau(std::sqrt(tau)) {}

  template <typename T>
  bool operator()(const T* const pose_i, const T* const pose_j, T* residuals) const {
    using Vec3T = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(pose_i), q_j(pose_j);
    const Eigen::Map<const Vec3T> t_i(pose_i + 4), t_j(pose_j + 4);
    const Eigen::Quaternion<T> q_error = q_ij_inverse.cast<T>() * (q_i.conjugate() * q_j);
    const Vec3T dt = t_j - t_i - q_i * t_ij.cast<T>();
    for (int r = 0; r < 3; ++r) {
      residuals[r] = T(sqrt_8_kappa) * q_error.vec()(r);
      residuals[3 + r] = T(sqrt_tau) * dt(r);
    }
    return true;
  }

  static ceres::CostFunction* Create(const SE3& i_from_j, double kappa, double tau) {
    return new ceres::AutoDiffCostFunction<ChordalFactor3, 6, 7, 7>(
        new ChordalFactor3(i_from_j, kappa, tau));
  }

  Quat q_ij_inverse;
  Vec3 t_ij;
  double sqrt_8_kappa;
  double sqrt_tau;

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// The same term in 2D on SO(2) x R^2, 1 + 2 residuals:
// ||R(theta_j) - R(theta_i + theta~)||_F^2 = 4 (1 - cos d) = 8 sin^2(d / 2),
// d = theta_j - theta_i - theta~.
struct ChordalFactor2 {
  ChordalFactor2(double dx, double dy, double dtheta, double kappa, double tau)
      : dx(dx),
        dy(dy),
        dtheta(dtheta),
        sqrt_8_kappa(std::sqrt(8.0 * kappa)),
        sqrt_tau(std::sqrt(tau)) {}

  template <typename T>
  bool operator()(const T* const pose_i, const T* const pose_j, T* residuals) const {
    using std::cos;
    using std::sin;
    const T ci = cos(pose_i[2]), si = sin(pose_i[2]);
    residuals[0] = T(sqrt_8_kappa) * sin(T(0.5) * (pose_j[2] - pose_i[2] - T(dtheta)));
    residuals[1] = T(sqrt_tau) * (pose_j[0] - pose_i[0] - (ci * dx - si * dy));
    residuals[2] = T(sqrt_tau) * (pose_j[1] - pose_i[1] - (si * dx + ci * dy));
    return true;
  }

  static ceres::CostFunction* Create(
      double dx, double dy, double dtheta, double kappa, double tau) {
    return new ceres::AutoDiffCostFunction<ChordalFactor2, 3, 3, 3>(
        new ChordalFactor2(dx, dy, dtheta, kappa, tau));
  }

  double dx, dy, dtheta, sqrt_8_kappa, sqrt_tau;
};

// An information-weighted relative pose (ICP or odometry constraint) in 3D.
// With the estimate T_i^-1 T_j = Z (+) e on PoseManifold's right retraction,
// Z (+) [omega; v] = (R~ Exp(omega), t~ + R~ v), the error is
//   e = [Log(R~^T R_i^T R_j); R~^T (R_i^T (t_j - t_i) - t~)]   (rad, m)
// and the residual r = L e with L^T L = information (6x6, xi = [omega; v]
// order, the inverse of the measurement's covariance on the right
// perturbation). ||r||^2 is the squared Mahalanobis distance of the
// measurement. Exact at e = 0 to first order for the SE(3) right perturbation
// Z * Exp(xi) as well.
struct RelativePoseFactor {
  RelativePoseFactor(const SE3& i_from_j, const Mat6& sqrt_information)
      : q_ij_inverse(i_from_j.rotation().conjugate()),
        t_ij(i_from_j.translation()),
        sqrt_information(sqrt_information) {}

  template <typename T>
  bool operator()(const T* const pose_i, const T* const pose_j, T* residuals) const {
    using Vec3T = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(pose_i), q_j(pose_j);
    const Eigen::Map<const Vec3T> t_i(pose_i + 4), t_j(pose_j + 4);
    const Eigen::Quaternion<T> q_inverse_ij = q_ij_inverse.cast<T>();
    const Eigen::Quaternion<T> q_error = q_inverse_ij * (q_i.conjugate() * q_j);
    const Vec3T t_estimate = q_i.conjugate() * (t_j - t_i);
    Eigen::Matrix<T, 6, 1> error;
    const T q_wxyz[4] = {q_error.w(), q_error.x(), q_error.y(), q_error.z()};
    ceres::QuaternionToAngleAxis(q_wxyz, error.data());
    error.template tail<3>() = q_inverse_ij * (t_estimate - t_ij.cast<T>());
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residuals);
    r = sqrt_information.cast<T>() * error;
    return true;
  }

  // `sqrt_information`: any L with L^T L = information (e.g. the transposed
  // lower Cholesky factor).
  static ceres::CostFunction* Create(const SE3& i_from_j, const Mat6& sqrt_information) {
    return new ceres::AutoDiffCostFunction<RelativePoseFactor, 6, 7, 7>(
        new RelativePoseFactor(i_from_j, sqrt_information));
  }

  Quat q_ij_inverse;
  Vec3 t_ij;
  Mat6 sqrt_information;

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

}  // namespace lisfm
