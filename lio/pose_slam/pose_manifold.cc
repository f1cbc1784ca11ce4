#include "lio/pose_slam/pose_manifold.h"

#include <Eigen/Core>

namespace lisfm {
namespace {

using RowMajor76 = Eigen::Matrix<double, 7, 6, Eigen::RowMajor>;
using RowMajor67 = Eigen::Matrix<double, 6, 7, Eigen::RowMajor>;

Quat Pure(const Vec3& v) { return Quat(0.0, v.x(), v.y(), v.z()); }

}  // namespace

void PoseManifold::ToBlock(const SE3& pose, double* block) {
  Eigen::Map<Eigen::Matrix<double, 4, 1>> q(block);
  Eigen::Map<Vec3> t(block + 4);
  q = pose.rotation().coeffs();
  t = pose.translation();
}

SE3 PoseManifold::FromBlock(const double* block) {
  return SE3(Quat(Eigen::Map<const Eigen::Matrix<double, 4, 1>>(block)).normalized(),
             Vec3(Eigen::Map<const Vec3>(block + 4)));
}

bool PoseManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::Map<const Quat> q(x);
  const Eigen::Map<const Vec3> t(x + 4);
  const Eigen::Map<const Vec3> omega(delta);
  const Eigen::Map<const Vec3> v(delta + 3);
  Eigen::Map<Quat> q_out(x_plus_delta);
  Eigen::Map<Vec3> t_out(x_plus_delta + 4);
  const Vec3 t_new = t + q * v;
  q_out = (q * so3::Exp(omega)).normalized();
  t_out = t_new;
  return true;
}

bool PoseManifold::PlusJacobian(const double* x, double* jacobian) const {
  // q * Exp(omega) = q + q * (0, omega / 2) + O(|omega|^2); t + R v.
  const Eigen::Map<const Quat> q(x);
  Eigen::Map<RowMajor76> J(jacobian);
  J.setZero();
  for (int k = 0; k < 3; ++k) {
    J.block<4, 1>(0, k) = (q * Pure(0.5 * Vec3::Unit(k))).coeffs();
  }
  J.block<3, 3>(4, 3) = q.toRotationMatrix();
  return true;
}

bool PoseManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  const Eigen::Map<const Quat> qx(x), qy(y);
  const Eigen::Map<const Vec3> tx(x + 4), ty(y + 4);
  Eigen::Map<Vec3> omega(y_minus_x), v(y_minus_x + 3);
  omega = so3::Log(qx.conjugate() * qy);
  v = qx.conjugate() * (ty - tx);
  return true;
}

bool PoseManifold::MinusJacobian(const double* x, double* jacobian) const {
  // Log(qx^-1 (qx + dq)) = 2 vec(qx^-1 dq) + O(|dq|^2) for unit qx.
  const Eigen::Map<const Quat> q(x);
  Eigen::Map<RowMajor67> J(jacobian);
  J.setZero();
  for (int c = 0; c < 4; ++c) {
    Quat unit(0.0, 0.0, 0.0, 0.0);
    unit.coeffs()(c) = 1.0;
    J.block<3, 1>(0, c) = 2.0 * (q.conjugate() * unit).vec();
  }
  J.block<3, 3>(3, 4) = q.toRotationMatrix().transpose();
  return true;
}

}  // namespace lisfm
