// SO(3) and SE(3) on Eigen, in lisfm's conventions (DESIGN.md):
//  - transforms are named target_from_source; `a_from_b * b_from_c = a_from_c`;
//  - rotations are unit Hamilton quaternions;
//  - tangent vectors of SE(3) are xi = [omega; v] (rotation first), SI units;
//  - uncertainty lives on the right: T = T_hat * Exp(xi).
// Jacobian conventions follow Barfoot, "State Estimation for Robotics" (2017),
// Sec. 7.1: J_l(phi) = sum (1/(n+1)!) (phi^)^n, J_r(phi) = J_l(-phi), and
// Exp(phi + d) ~= Exp(phi) * Exp(J_r(phi) d) (Eq. 7.75 in right form).
#pragma once

#include <vector>

#include "core/types.h"

namespace lisfm {

// Skew-symmetric matrix: Hat(a) * b == a.cross(b).
Mat3 Hat(const Vec3& v);
// Inverse of Hat for a skew-symmetric matrix.
Vec3 Vee(const Mat3& m);

namespace so3 {
// Exponential map, rotation vector (rad) -> unit quaternion. Stable near 0.
Quat Exp(const Vec3& omega);
// Logarithm, unit quaternion -> rotation vector with |omega| <= pi.
Vec3 Log(const Quat& q);
Mat3 ExpMatrix(const Vec3& omega);
Vec3 LogMatrix(const Mat3& R);
// Right Jacobian J_r and its inverse; left Jacobian J_l = J_r(-omega).
Mat3 RightJacobian(const Vec3& omega);
Mat3 RightJacobianInverse(const Vec3& omega);
Mat3 LeftJacobian(const Vec3& omega);
Mat3 LeftJacobianInverse(const Vec3& omega);
// Geodesic angle between two rotations, radians in [0, pi].
double AngularDistance(const Quat& a, const Quat& b);
// Chordal L2 mean of rotations (Markley et al. 2007, eigenvector of sum w q q^T).
// Weights default to 1. Throws InternalError for an empty input.
Quat Average(const std::vector<Quat>& rotations, const std::vector<double>& weights = {});
// Slerp from a (s = 0) to b (s = 1) along the shortest path.
Quat Interpolate(const Quat& a, const Quat& b, double s);
}  // namespace so3

// A rigid transform target_from_source: x_target = R * x_source + t.
class SE3 {
 public:
  SE3() : rotation_(Quat::Identity()), translation_(Vec3::Zero()) {}
  SE3(const Quat& rotation, const Vec3& translation);
  SE3(const Mat3& rotation, const Vec3& translation);
  explicit SE3(const Mat4& matrix);

  static SE3 Identity() { return SE3(); }
  // xi = [omega; v]: rotation Exp(omega), translation J_l(omega) * v.
  static SE3 Exp(const Vec6& xi);
  Vec6 Log() const;

  const Quat& rotation() const { return rotation_; }
  const Vec3& translation() const { return translation_; }
  Mat3 RotationMatrix() const { return rotation_.toRotationMatrix(); }
  Mat4 Matrix() const;
  Eigen::Matrix<double, 3, 4> Matrix3x4() const;

  void SetRotation(const Quat& q);
  void SetTranslation(const Vec3& t) { translation_ = t; }

  SE3 Inverse() const;
  SE3 operator*(const SE3& other) const;
  Vec3 operator*(const Vec3& x) const { return rotation_ * x + translation_; }

  // Adjoint in the [omega; v] order: Exp(Ad(T) xi) = T Exp(xi) T^-1.
  Mat6 Adjoint() const;

 private:
  Quat rotation_;
  Vec3 translation_;
};

// Interpolates a (s = 0) to b (s = 1) on SO(3) x R^3 (slerp + linear); this is
// what trajectory interpolation between close samples needs.
SE3 Interpolate(const SE3& a, const SE3& b, double s);

// Weighted average: chordal rotation mean and weighted mean translation.
SE3 Average(const std::vector<SE3>& poses, const std::vector<double>& weights = {});

// A similarity transform: x_target = scale * R * x_source + t.
struct Sim3 {
  double scale = 1.0;
  SE3 pose;  // rotation and translation
  Vec3 operator*(const Vec3& x) const {
    return scale * (pose.rotation() * x) + pose.translation();
  }
  // Applies the similarity to a pose world_from_body (body orientation rotated, position mapped).
  SE3 Transform(const SE3& world_from_body) const;
};

// Least-squares alignment target ~= T * source (Umeyama 1991), via Eigen::umeyama.
// `source` and `target` are 3xN, N >= 3 non-collinear points (throws InputError
// otherwise). With estimate_scale = false the scale is fixed to 1 (SE(3)).
Sim3 AlignUmeyama(const Eigen::Matrix3Xd& source,
                  const Eigen::Matrix3Xd& target,
                  bool estimate_scale);

}  // namespace lisfm
