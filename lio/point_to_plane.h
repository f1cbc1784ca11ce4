// Point-to-plane measurement of the LIO update with the LiDAR–IMU calibration
// in the state: FAST-LIO2's online extrinsic (Xu et al., T-RO 2022, Eq. (12)-(14)
// with `extrinsic_est_en`) plus a LiDAR–IMU time offset.
//
// A frame's points are de-skewed to its end time t_e with the calibration the
// filter held before the update: extrinsic (R̂_e, t̂_e) = imu_from_lidar and time
// offset t̂_d. x_l (m) is such a point in the LiDAR frame at t_e. At an iterate
// of the state — world_from_imu (R, p) at t_e, extrinsic (R_e, t_e) and time
// offset t_d, δ = t_d − t̂_d (s) — the point is, in the IMU frame and the world:
//
//   q   = R_e x_l + t_e
//   x_w = R (q + δ ω×q) + p + δ v
//   r   = nᵀ x_w + d                      (plane n·x + d = 0, |n| = 1)
//
// x_w is first order in δ: a point stamped t was captured at t + δ on the IMU
// clock, when the body had moved on by δ times its angular rate ω (body, rad/s)
// and velocity v (world, m/s); both are the propagated values at t_e, held
// fixed during the update. With right perturbations R = R̂·Exp(dθ),
// R_e = R̂_e·Exp(dθ_e) (DESIGN.md), q' = q + δ ω×q and S = I + δ[ω]×:
//
//   ∂r/∂θ   = −nᵀ R [q']×
//   ∂r/∂p   =  nᵀ
//   ∂r/∂θ_e = −nᵀ R S R_e [x_l]×
//   ∂r/∂t_e =  nᵀ R S
//   ∂r/∂t_d =  nᵀ (R (ω×q) + v)
//
// Without the calibration in the state (δ = 0, R_e, t_e fixed) the first two
// rows are FAST-LIO2's point-to-plane Jacobian (lio/lio_odometry.cc).
#pragma once

#include "core/geometry.h"

namespace lisfm {

// Columns of the Jacobian row: [dθ (3), dp (3), dθ_e (3), dt_e (3), dt_d (1)].
using CalibratedPointJacobian = Eigen::Matrix<double, 13, 1>;

// The state an update iterate holds for one point's LiDAR.
struct CalibratedPose {
  Mat3 world_R_imu = Mat3::Identity();  // R
  Vec3 world_p_imu = Vec3::Zero();      // p, m
  Mat3 imu_R_lidar = Mat3::Identity();  // R_e
  Vec3 imu_p_lidar = Vec3::Zero();      // t_e, m
  double time_offset_change_s = 0;      // δ = t_d − t̂_d, s
};

// Body motion at the frame end, fixed during an update.
struct BodyRates {
  Vec3 angular_velocity = Vec3::Zero();  // ω, body frame, rad/s
  Vec3 velocity = Vec3::Zero();          // v, world frame, m/s
};

// x_w of the model above; `x_in_imu` (optional) receives q.
inline Vec3 CalibratedPointInWorld(const CalibratedPose& s,
                                   const BodyRates& rates,
                                   const Vec3& x_in_lidar,
                                   Vec3* x_in_imu = nullptr) {
  const Vec3 q = s.imu_R_lidar * x_in_lidar + s.imu_p_lidar;
  if (x_in_imu != nullptr) *x_in_imu = q;
  const double dt = s.time_offset_change_s;
  return s.world_R_imu * (q + dt * rates.angular_velocity.cross(q)) + s.world_p_imu +
         dt * rates.velocity;
}

// r of the model above for `plane` = (n, d); `jacobian` (optional) receives
// ∂r/∂[dθ, dp, dθ_e, dt_e, dt_d], `x_in_imu` (optional) q.
inline double CalibratedPointToPlaneResidual(const CalibratedPose& s,
                                             const BodyRates& rates,
                                             const Vec3& x_in_lidar,
                                             const Vec4& plane,
                                             CalibratedPointJacobian* jacobian = nullptr,
                                             Vec3* x_in_imu = nullptr) {
  Vec3 q;
  const Vec3 x_w = CalibratedPointInWorld(s, rates, x_in_lidar, &q);
  const Vec3 n = plane.head<3>();
  if (jacobian != nullptr) {
    const double dt = s.time_offset_change_s;
    const Vec3& w = rates.angular_velocity;
    const Vec3 m = s.world_R_imu.transpose() * n;  // the normal in the IMU frame: nᵀR = mᵀ
    const Vec3 q_moved = q + dt * w.cross(q);
    // mᵀ S = (Sᵀ m)ᵀ with Sᵀ = I − δ[ω]×.
    const Vec3 m_s = m - dt * w.cross(m);
    // −aᵀ[b]× = (b × a)ᵀ.
    jacobian->segment<3>(0) = q_moved.cross(m);
    jacobian->segment<3>(3) = n;
    jacobian->segment<3>(6) = x_in_lidar.cross(s.imu_R_lidar.transpose() * m_s);
    jacobian->segment<3>(9) = m_s;
    (*jacobian)(12) = m.dot(w.cross(q)) + n.dot(rates.velocity);
  }
  if (x_in_imu != nullptr) *x_in_imu = q;
  return n.dot(x_w) + plane(3);
}

}  // namespace lisfm
