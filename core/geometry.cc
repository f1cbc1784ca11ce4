#include "core/geometry.h"

#include <cmath>

#include <Eigen/Eigenvalues>

#include "core/errors.h"

namespace lisfm {

namespace {
constexpr double kSmallAngle = 1e-8;
}

Mat3 Hat(const Vec3& v) {
  Mat3 m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Vec3 Vee(const Mat3& m) { return Vec3(m(2, 1), m(0, 2), m(1, 0)); }

namespace so3 {

Quat Exp(const Vec3& omega) {
  const double theta2 = omega.squaredNorm();
  const double theta = std::sqrt(theta2);
  double real, imag_factor;
  if (theta < 1e-4) {
    // Taylor series: cos(x/2), sin(x/2)/x.
    real = 1.0 - theta2 / 8.0 + theta2 * theta2 / 384.0;
    imag_factor = 0.5 - theta2 / 48.0 + theta2 * theta2 / 3840.0;
  } else {
    real = std::cos(0.5 * theta);
    imag_factor = std::sin(0.5 * theta) / theta;
  }
  Quat q(real, imag_factor * omega.x(), imag_factor * omega.y(), imag_factor * omega.z());
  q.normalize();
  return q;
}

Vec3 Log(const Quat& q_in) {
  Quat q = q_in.normalized();
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // shortest rotation, angle <= pi
  const Vec3 v = q.vec();
  const double n = v.norm();
  if (n < 1e-8) {
    // atan2(n, w) / n ~= 1/w - n^2/(3 w^3)
    const double w = q.w();
    return (2.0 / w - 2.0 * n * n / (3.0 * w * w * w)) * v;
  }
  const double theta = 2.0 * std::atan2(n, q.w());
  return (theta / n) * v;
}

Mat3 ExpMatrix(const Vec3& omega) { return Exp(omega).toRotationMatrix(); }

Vec3 LogMatrix(const Mat3& R) { return Log(Quat(R)); }

Mat3 RightJacobian(const Vec3& omega) { return LeftJacobian(-omega); }

Mat3 RightJacobianInverse(const Vec3& omega) { return LeftJacobianInverse(-omega); }

Mat3 LeftJacobian(const Vec3& omega) {
  const double theta2 = omega.squaredNorm();
  const Mat3 W = Hat(omega);
  if (theta2 < kSmallAngle) {
    return Mat3::Identity() + 0.5 * W + W * W / 6.0;
  }
  const double theta = std::sqrt(theta2);
  const double a = (1.0 - std::cos(theta)) / theta2;
  const double b = (theta - std::sin(theta)) / (theta2 * theta);
  return Mat3::Identity() + a * W + b * W * W;
}

Mat3 LeftJacobianInverse(const Vec3& omega) {
  const double theta2 = omega.squaredNorm();
  const Mat3 W = Hat(omega);
  if (theta2 < kSmallAngle) {
    return Mat3::Identity() - 0.5 * W + W * W / 12.0;
  }
  const double theta = std::sqrt(theta2);
  const double half = 0.5 * theta;
  const double c = (1.0 - half * std::cos(half) / std::sin(half)) / theta2;
  return Mat3::Identity() - 0.5 * W + c * W * W;
}

double AngularDistance(const Quat& a, const Quat& b) {
  return Log(a.conjugate() * b).norm();
}

Quat Average(const std::vector<Quat>& rotations, const std::vector<double>& weights) {
  THROW_CHECK_MSG(!rotations.empty(), "so3::Average of no rotations");
  THROW_CHECK(weights.empty() || weights.size() == rotations.size());
  Mat4 M = Mat4::Zero();
  for (size_t i = 0; i < rotations.size(); ++i) {
    const Vec4 q = rotations[i].normalized().coeffs();
    M += (weights.empty() ? 1.0 : weights[i]) * q * q.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Mat4> solver(M);
  const Vec4 v = solver.eigenvectors().col(3);  // largest eigenvalue
  Quat mean(v(3), v(0), v(1), v(2));
  mean.normalize();
  return mean;
}

Quat Interpolate(const Quat& a, const Quat& b, double s) {
  return a.slerp(s, b).normalized();
}

}  // namespace so3

SE3::SE3(const Quat& rotation, const Vec3& translation)
    : rotation_(rotation.normalized()), translation_(translation) {}

SE3::SE3(const Mat3& rotation, const Vec3& translation)
    : rotation_(Quat(rotation).normalized()), translation_(translation) {}

SE3::SE3(const Mat4& matrix)
    : rotation_(Quat(Mat3(matrix.block<3, 3>(0, 0))).normalized()),
      translation_(matrix.block<3, 1>(0, 3)) {}

SE3 SE3::Exp(const Vec6& xi) {
  const Vec3 omega = xi.head<3>();
  const Vec3 v = xi.tail<3>();
  return SE3(so3::Exp(omega), so3::LeftJacobian(omega) * v);
}

Vec6 SE3::Log() const {
  Vec6 xi;
  const Vec3 omega = so3::Log(rotation_);
  xi.head<3>() = omega;
  xi.tail<3>() = so3::LeftJacobianInverse(omega) * translation_;
  return xi;
}

Mat4 SE3::Matrix() const {
  Mat4 m = Mat4::Identity();
  m.block<3, 3>(0, 0) = RotationMatrix();
  m.block<3, 1>(0, 3) = translation_;
  return m;
}

Eigen::Matrix<double, 3, 4> SE3::Matrix3x4() const { return Matrix().topRows<3>(); }

void SE3::SetRotation(const Quat& q) { rotation_ = q.normalized(); }

SE3 SE3::Inverse() const {
  const Quat inv = rotation_.conjugate();
  return SE3(inv, -(inv * translation_));
}

SE3 SE3::operator*(const SE3& other) const {
  return SE3(rotation_ * other.rotation_, rotation_ * other.translation_ + translation_);
}

Mat6 SE3::Adjoint() const {
  // For xi = [omega; v]: Ad = [[R, 0], [t^ R, R]].
  Mat6 ad = Mat6::Zero();
  const Mat3 R = RotationMatrix();
  ad.block<3, 3>(0, 0) = R;
  ad.block<3, 3>(3, 3) = R;
  ad.block<3, 3>(3, 0) = Hat(translation_) * R;
  return ad;
}

SE3 Interpolate(const SE3& a, const SE3& b, double s) {
  return SE3(so3::Interpolate(a.rotation(), b.rotation(), s),
             (1.0 - s) * a.translation() + s * b.translation());
}

SE3 Average(const std::vector<SE3>& poses, const std::vector<double>& weights) {
  THROW_CHECK_MSG(!poses.empty(), "Average of no poses");
  THROW_CHECK(weights.empty() || weights.size() == poses.size());
  std::vector<Quat> rotations;
  Vec3 t = Vec3::Zero();
  double total = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    rotations.push_back(poses[i].rotation());
    t += w * poses[i].translation();
    total += w;
  }
  THROW_CHECK_GT(total, 0.0);
  return SE3(so3::Average(rotations, weights), t / total);
}

SE3 Sim3::Transform(const SE3& world_from_body) const {
  return SE3(pose.rotation() * world_from_body.rotation(), (*this) * world_from_body.translation());
}

Sim3 AlignUmeyama(const Eigen::Matrix3Xd& source,
                  const Eigen::Matrix3Xd& target,
                  bool estimate_scale) {
  if (source.cols() != target.cols()) {
    throw InputError("alignment: " + std::to_string(source.cols()) + " source vs " +
                     std::to_string(target.cols()) + " target points");
  }
  if (source.cols() < 3) {
    throw InputError("alignment needs at least 3 associated positions, found " +
                     std::to_string(source.cols()));
  }
  // Degenerate (collinear) sets: the second singular value of the centred points vanishes.
  const Eigen::Matrix3Xd centred = source.colwise() - source.rowwise().mean();
  Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(centred);
  const Vec3 sv = svd.singularValues();
  if (sv(0) <= 0 || sv(1) < 1e-9 * sv(0)) {
    throw InputError("alignment: the associated positions are collinear or identical");
  }
  const Mat4 T = Eigen::umeyama(source, target, estimate_scale);
  Sim3 s;
  const Mat3 sR = T.block<3, 3>(0, 0);
  s.scale = estimate_scale ? std::cbrt(sR.determinant()) : 1.0;
  s.pose = SE3(Mat3(sR / s.scale), Vec3(T.block<3, 1>(0, 3)));
  return s;
}

}  // namespace lisfm
