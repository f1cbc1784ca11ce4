// On-manifold IMU preintegration between two keyframe times (Forster et al.,
// "On-Manifold Preintegration for Real-Time Visual-Inertial Odometry", T-RO
// 2017), the measurement of pose_slam's IMU factors (lio/pose_slam/imu_factors.h).
//
// Model (body = IMU frame, world = lio's gravity-aligned frame, g = (0, 0, -9.81)):
//   gyro  = omega_body + b_g + n_g,   accel = R^T (a_world - g) + b_a + n_a,
// with white noises of continuous-time densities sigma_g, sigma_a (core/rig.h
// ImuNoise, rad/s/sqrt(Hz) and m/s^2/sqrt(Hz)). Between keyframes i and j
// (dt = t_j - t_i) the preintegrated measurements are (Forster Eq. (33))
//   dR = R_i^T R_j,
//   dv = R_i^T (v_j - v_i - g dt),
//   dp = R_i^T (p_j - p_i - v_i dt - g dt^2 / 2),
// which depend on the IMU samples and the bias only, not on the states.
//
// Integration, one step per pair of consecutive samples (spacing h), with
// w = gyro - b_g and a = accel - b_a:
//   dR_{k+1} = dR_k Exp(theta_k),  theta_k = integral of w over the step,
//   a_mid    = (dR_k a_k + dR_{k+1} a_{k+1}) / 2,
//   dv_{k+1} = dv_k + a_mid h,   dp_{k+1} = dp_k + dv_k h + a_mid h^2 / 2,
// the trapezoidal (mid-point) form of Forster's Euler steps (Eq. (33)), second
// order in h, with theta_k from the cubic through the neighbouring gyro
// samples (fourth order): on simulated walking at 400 Hz the error against the
// exact motion is below 1e-6 relative (imu_preintegration_test.cc). The
// boundary samples at t_i and t_j are linearly interpolated between their
// neighbours.
//
// Errors live on the right: dR_true = dR Exp(e_R), dv_true = dv + e_v,
// dp_true = dp + e_p; the 9x9 covariance is over e = [e_R; e_v; e_p] (rad,
// m/s, m), propagated through the linearised steps (Forster Appendix A,
// iterative noise propagation), with each step's noise the integral of the
// continuous-time white noise over h (variance sigma^2 / h on the mean rate).
// The bias Jacobians are the exact derivatives of the discrete integration
// above at the linearisation bias b_hat (Forster Appendix B, same recursion),
// so that for a bias b = b_hat + db (Eq. (44)):
//   dR(b) ~= dR Exp(J_R_bg db_g),
//   dv(b) ~= dv + J_v_bg db_g + J_v_ba db_a,
//   dp(b) ~= dp + J_p_bg db_g + J_p_ba db_a.
//
// Accelerometer samples must be in m/s^2 (an IMU that reports in g is scaled
// by the caller, lio/imu.h ImuInitialization::accel_scale). Plain values; no
// threads, no I/O.
#pragma once

#include <vector>

#include "core/geometry.h"
#include "core/rig.h"
#include "core/sensor_data.h"
#include "core/time.h"

namespace lisfm {

// Additive IMU biases (the b_g, b_a of the model above). As a Ceres parameter
// block: 6 doubles [b_g; b_a].
struct ImuBias {
  static constexpr int kBlockSize = 6;

  Vec3 gyro = Vec3::Zero();   // b_g, rad/s
  Vec3 accel = Vec3::Zero();  // b_a, m/s^2

  Vec6 Vector() const;  // [b_g; b_a]
  static ImuBias FromVector(const Vec6& vector);
};

struct PreintegrationOptions {
  // A larger spacing between consecutive IMU samples inside a keyframe
  // interval is an IMU gap (InputError); 20 samples missing at 400 Hz.
  double max_sample_gap_s = 0.05;  // s
  bool Check() const;
};

// Error-state Jacobians of the preintegrated measurement with respect to the
// bias (rows [e_R; e_v; e_p], columns [b_g; b_a]); the e_R / b_a block is zero.
using PreintegrationBiasJacobian = Eigen::Matrix<double, 9, 6>;
using Mat9 = Eigen::Matrix<double, 9, 9>;

class Preintegration {
 public:
  // Integrates from t_i_ns to t_j_ns (t_i_ns < t_j_ns) over `samples`
  // (sorted by time, strictly increasing) with the linearisation bias
  // `bias_hat` and the continuous-time noise densities of `noise`
  // (update_rate is not used: steps use the sample spacing). Throws
  // InputError when the samples do not cover [t_i_ns, t_j_ns], are not
  // strictly increasing there, or leave a gap longer than
  // options.max_sample_gap_s; the message names the times (s).
  static Preintegration Integrate(const std::vector<ImuSample>& samples,
                                  TimestampNs t_i_ns,
                                  TimestampNs t_j_ns,
                                  const ImuBias& bias_hat,
                                  const ImuNoise& noise,
                                  const PreintegrationOptions& options = {});

  TimestampNs start_ns() const { return start_ns_; }
  TimestampNs end_ns() const { return last_.t_ns; }
  double dt_s() const { return dt_s_; }  // end - start, s
  int num_steps() const { return num_steps_; }
  const ImuBias& bias_hat() const { return bias_hat_; }

  // The preintegrated measurement at bias_hat.
  const Quat& delta_rotation() const { return delta_rotation_; }  // dR = R_i^T R_j
  const Vec3& delta_velocity() const { return delta_velocity_; }  // dv (m/s)
  const Vec3& delta_position() const { return delta_position_; }  // dp (m)
  // 9x9 covariance of [e_R; e_v; e_p] (rad, m/s, m).
  const Mat9& covariance() const { return covariance_; }
  const PreintegrationBiasJacobian& bias_jacobian() const { return bias_jacobian_; }

  // The measurement corrected to first order for `bias` (Eq. (44)).
  Quat CorrectedDeltaRotation(const ImuBias& bias) const;
  Vec3 CorrectedDeltaVelocity(const ImuBias& bias) const;
  Vec3 CorrectedDeltaPosition(const ImuBias& bias) const;

  // The state at t_j from the state at t_i (world_from_imu, world velocity in
  // m/s) with the bias-corrected measurement and gravity `gravity_world`
  // (m/s^2): R_j = R_i dR, v_j = v_i + g dt + R_i dv,
  // p_j = p_i + v_i dt + g dt^2 / 2 + R_i dp.
  void Predict(const SE3& world_from_imu_i,
               const Vec3& velocity_i,
               const ImuBias& bias,
               const Vec3& gravity_world,
               SE3* world_from_imu_j,
               Vec3* velocity_j) const;

 private:
  // An empty preintegration at `first` (identity, zero covariance).
  Preintegration(const ImuSample& first, const ImuBias& bias_hat, const ImuNoise& noise);
  // One step from the last sample to `next` (later); `gyro_integral` is the
  // integral of the raw gyro signal over the step (rad).
  void Step(const ImuSample& next, const Vec3& gyro_integral);

  ImuBias bias_hat_;
  double gyro_noise_density_;   // rad/s/sqrt(Hz)
  double accel_noise_density_;  // m/s^2/sqrt(Hz)
  TimestampNs start_ns_;
  ImuSample last_;  // the sample at the end of the last step (raw, with bias)
  double dt_s_ = 0.0;
  int num_steps_ = 0;
  Quat delta_rotation_ = Quat::Identity();
  Vec3 delta_velocity_ = Vec3::Zero();
  Vec3 delta_position_ = Vec3::Zero();
  Mat9 covariance_ = Mat9::Zero();
  PreintegrationBiasJacobian bias_jacobian_ = PreintegrationBiasJacobian::Zero();
};

// Linear interpolation of two IMU samples at t_ns (a.t_ns <= t_ns <= b.t_ns,
// a.t_ns < b.t_ns).
ImuSample InterpolateImu(const ImuSample& a, const ImuSample& b, TimestampNs t_ns);

}  // namespace lisfm
