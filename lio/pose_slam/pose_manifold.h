// The manifold of a 3D pose parameter block for Ceres.
//
// Ambient layout (7 doubles): [qx qy qz qw tx ty tz], the unit Hamilton
// quaternion of world_from_body in Eigen's coefficient order followed by the
// translation (m). Tangent (6): xi = [omega; v] (rad, m), on the right:
//   Plus(T, xi)  = (R Exp(omega), t + R v)
//   Minus(T2, T) = (Log(R^T R2), R^T (t2 - t))
// This is SO(3) x R^3 with the translation increment in the body frame; it
// agrees with T * Exp(xi) on SE(3) to first order (the translation of Exp(xi)
// is J_l(omega) v = v + O(|omega||v|)). Ceres' covariance in the tangent space
// of this manifold is therefore DESIGN.md's covariance on the right
// perturbation T = T_hat * Exp(xi), xi = [omega; v].
//
// Plus renormalises the quaternion; Minus returns |omega| <= pi.
#pragma once

#include <ceres/manifold.h>

#include "core/geometry.h"

namespace lisfm {

class PoseManifold : public ceres::Manifold {
 public:
  static constexpr int kAmbientSize = 7;
  static constexpr int kTangentSize = 6;

  int AmbientSize() const override { return kAmbientSize; }
  int TangentSize() const override { return kTangentSize; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  // d Plus(x, delta) / d delta at delta = 0: 7x6, row-major.
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  // d Minus(y, x) / d y at y = x: 6x7, row-major.
  bool MinusJacobian(const double* x, double* jacobian) const override;

  // Conversions between SE3 and the 7-double block.
  static void ToBlock(const SE3& pose, double* block);
  static SE3 FromBlock(const double* block);
};

}  // namespace lisfm
