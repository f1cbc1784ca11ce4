#include "lio/pose_slam/imu_preintegration.h"

#include <fmt/format.h>

#include <algorithm>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

Vec6 ImuBias::Vector() const {
  Vec6 v;
  v << gyro, accel;
  return v;
}

ImuBias ImuBias::FromVector(const Vec6& vector) {
  ImuBias bias;
  bias.gyro = vector.head<3>();
  bias.accel = vector.tail<3>();
  return bias;
}

bool PreintegrationOptions::Check() const {
  CHECK_OPTION_GT(max_sample_gap_s, 0.0);
  return true;
}

ImuSample InterpolateImu(const ImuSample& a, const ImuSample& b, TimestampNs t_ns) {
  THROW_CHECK_LT(a.t_ns, b.t_ns);
  THROW_CHECK(a.t_ns <= t_ns && t_ns <= b.t_ns);
  const double s = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  ImuSample m;
  m.t_ns = t_ns;
  m.gyro = (1.0 - s) * a.gyro + s * b.gyro;
  m.accel = (1.0 - s) * a.accel + s * b.accel;
  return m;
}

namespace {

// Integral of the gyro signal over [a_ns, b_ns] inside [t_k, t_k+1]: the
// polynomial through samples k-1 .. k+2 (those in [lo, hi]: cubic inside the
// data, quadratic at its ends) integrated exactly by 2-point Gauss-Legendre.
// Fourth order in the sample spacing for a smooth rate (the trapezoidal rule
// is second order).
Vec3 IntegrateRate(const std::vector<ImuSample>& samples,
                   size_t k,
                   size_t lo,
                   size_t hi,
                   TimestampNs a_ns,
                   TimestampNs b_ns) {
  const size_t first = k > lo ? k - 1 : k;
  const size_t last = std::min(hi, k + 2);
  const TimestampNs origin = samples[k].t_ns;
  const auto seconds = [&](size_t m) { return NsToSeconds(samples[m].t_ns - origin); };
  const double a = NsToSeconds(a_ns - origin), b = NsToSeconds(b_ns - origin);
  const double half = 0.5 * (b - a), mid = 0.5 * (a + b);
  const double offset = half / std::sqrt(3.0);
  Vec3 integral = Vec3::Zero();
  for (const double t : {mid - offset, mid + offset}) {
    for (size_t m = first; m <= last; ++m) {
      double basis = 1.0;  // Lagrange basis polynomial of node m at t
      for (size_t n = first; n <= last; ++n) {
        if (n != m) basis *= (t - seconds(n)) / (seconds(m) - seconds(n));
      }
      integral += half * basis * samples[m].gyro;
    }
  }
  return integral;
}

}  // namespace

Preintegration::Preintegration(const ImuSample& first,
                               const ImuBias& bias_hat,
                               const ImuNoise& noise)
    : bias_hat_(bias_hat),
      gyro_noise_density_(noise.gyroscope_noise_density),
      accel_noise_density_(noise.accelerometer_noise_density),
      start_ns_(first.t_ns),
      last_(first) {}

Preintegration Preintegration::Integrate(const std::vector<ImuSample>& samples,
                                         TimestampNs t_i_ns,
                                         TimestampNs t_j_ns,
                                         const ImuBias& bias_hat,
                                         const ImuNoise& noise,
                                         const PreintegrationOptions& options) {
  THROW_CHECK_OPTIONS(options);
  THROW_CHECK_LT(t_i_ns, t_j_ns);
  if (samples.empty() || samples.front().t_ns > t_i_ns || samples.back().t_ns < t_j_ns) {
    throw InputError(
        fmt::format("the IMU samples ({}) do not cover the keyframe interval [{}, {}] s",
                    samples.empty() ? std::string("none")
                                    : fmt::format("[{}, {}] s",
                                                  FormatNsAsSeconds(samples.front().t_ns),
                                                  FormatNsAsSeconds(samples.back().t_ns)),
                    FormatNsAsSeconds(t_i_ns),
                    FormatNsAsSeconds(t_j_ns)));
  }
  // first: the last sample at or before t_i; last: the first one at or after t_j.
  const auto by_time = [](const ImuSample& s, TimestampNs t) { return s.t_ns < t; };
  const size_t last =
      std::lower_bound(samples.begin(), samples.end(), t_j_ns, by_time) - samples.begin();
  size_t first =
      std::lower_bound(samples.begin(), samples.end(), t_i_ns, by_time) - samples.begin();
  if (samples[first].t_ns > t_i_ns) --first;
  const TimestampNs max_gap_ns = SecondsToNs(options.max_sample_gap_s);
  for (size_t k = first; k < last; ++k) {
    const TimestampNs gap = samples[k + 1].t_ns - samples[k].t_ns;
    if (gap <= 0) {
      throw InputError(
          fmt::format("IMU samples {} and {} are not in increasing time order ({} s, then {} s)",
                      k,
                      k + 1,
                      FormatNsAsSeconds(samples[k].t_ns),
                      FormatNsAsSeconds(samples[k + 1].t_ns)));
    }
    if (gap > max_gap_ns) {
      throw InputError(fmt::format(
          "IMU gap of {:.4f} s between the samples at {} s and {} s inside the keyframe "
          "interval [{}, {}] s (max_sample_gap_s {})",
          NsToSeconds(gap),
          FormatNsAsSeconds(samples[k].t_ns),
          FormatNsAsSeconds(samples[k + 1].t_ns),
          FormatNsAsSeconds(t_i_ns),
          FormatNsAsSeconds(t_j_ns),
          options.max_sample_gap_s));
    }
  }
  // Steps: [t_i, s_first+1], [s_first+1, s_first+2], ..., [s_last-1, t_j];
  // step k lies inside [s_k, s_k+1].
  const ImuSample start = samples[first].t_ns == t_i_ns
                              ? samples[first]
                              : InterpolateImu(samples[first], samples[first + 1], t_i_ns);
  Preintegration pim(start, bias_hat, noise);
  for (size_t k = first; k < last; ++k) {
    const ImuSample next = k + 1 < last || samples[last].t_ns == t_j_ns
                               ? samples[k + 1]
                               : InterpolateImu(samples[k], samples[k + 1], t_j_ns);
    pim.Step(next, IntegrateRate(samples, k, first, last, pim.last_.t_ns, next.t_ns));
  }
  return pim;
}

void Preintegration::Step(const ImuSample& next, const Vec3& gyro_integral) {
  THROW_CHECK_GT(next.t_ns, last_.t_ns);
  const double h = NsToSeconds(next.t_ns - last_.t_ns);
  const Vec3 a0 = last_.accel - bias_hat_.accel, a1 = next.accel - bias_hat_.accel;
  const Vec3 theta = gyro_integral - bias_hat_.gyro * h;
  const Quat step = so3::Exp(theta);
  const Mat3 E = step.toRotationMatrix();
  const Mat3 Jr = so3::RightJacobian(theta);
  const Mat3 R0 = delta_rotation_.toRotationMatrix();
  const Quat q1 = (delta_rotation_ * step).normalized();
  const Mat3 R1 = q1.toRotationMatrix();
  const Vec3 a_mid = 0.5 * (R0 * a0 + R1 * a1);

  // Linearised step on e = [e_R; e_v; e_p] (right perturbation dR Exp(e_R)):
  //   e_R' = E^T e_R + Jr h dw,
  //   dA   = d a_mid / d e_R = -(R0 [a0]x + R1 [a1]x E^T) / 2,
  //   e_v' = e_v + h (dA e_R + d a_mid),  e_p' = e_p + h e_v + h^2/2 (dA e_R + d a_mid),
  // where dw perturbs the step's mean rate theta / h and da both
  // accelerations: d a_mid = -R1 [a1]x Jr h dw / 2 + (R0 + R1) da / 2.
  Mat9 A = Mat9::Identity();
  const Mat3 dA = -0.5 * (R0 * Hat(a0) + R1 * Hat(a1) * E.transpose());
  A.block<3, 3>(0, 0) = E.transpose();
  A.block<3, 3>(3, 0) = h * dA;
  A.block<3, 3>(6, 0) = 0.5 * h * h * dA;
  A.block<3, 3>(6, 3) = h * Mat3::Identity();
  Eigen::Matrix<double, 9, 3> B_w = Eigen::Matrix<double, 9, 3>::Zero();
  const Mat3 da_dw = -0.5 * h * R1 * Hat(a1) * Jr;
  B_w.block<3, 3>(0, 0) = h * Jr;
  B_w.block<3, 3>(3, 0) = h * da_dw;
  B_w.block<3, 3>(6, 0) = 0.5 * h * h * da_dw;
  Eigen::Matrix<double, 9, 3> B_a = Eigen::Matrix<double, 9, 3>::Zero();
  const Mat3 da_da = 0.5 * (R0 + R1);
  B_a.block<3, 3>(3, 0) = h * da_da;
  B_a.block<3, 3>(6, 0) = 0.5 * h * h * da_da;

  // A bias change db moves the mean rate by -db_g (the quadrature weights sum
  // to h) and both accelerations by -db_a.
  PreintegrationBiasJacobian J = A * bias_jacobian_;
  J.leftCols<3>() -= B_w;
  J.rightCols<3>() -= B_a;
  bias_jacobian_ = J;
  // White noise over the step: the mean rate and acceleration carry variance
  // sigma_c^2 / h per axis (the step's integral carries sigma_c^2 h).
  const double var_w = gyro_noise_density_ * gyro_noise_density_ / h;
  const double var_a = accel_noise_density_ * accel_noise_density_ / h;
  covariance_ = A * covariance_ * A.transpose() + var_w * B_w * B_w.transpose() +
                var_a * B_a * B_a.transpose();
  covariance_ = 0.5 * (covariance_ + covariance_.transpose()).eval();

  delta_position_ += delta_velocity_ * h + 0.5 * h * h * a_mid;
  delta_velocity_ += a_mid * h;
  delta_rotation_ = q1;
  dt_s_ = NsToSeconds(next.t_ns - start_ns_);
  ++num_steps_;
  last_ = next;
}

Quat Preintegration::CorrectedDeltaRotation(const ImuBias& bias) const {
  const Vec3 dbg = bias.gyro - bias_hat_.gyro;
  return (delta_rotation_ * so3::Exp(bias_jacobian_.block<3, 3>(0, 0) * dbg)).normalized();
}

Vec3 Preintegration::CorrectedDeltaVelocity(const ImuBias& bias) const {
  return delta_velocity_ + bias_jacobian_.block<3, 6>(3, 0) * (bias.Vector() - bias_hat_.Vector());
}

Vec3 Preintegration::CorrectedDeltaPosition(const ImuBias& bias) const {
  return delta_position_ + bias_jacobian_.block<3, 6>(6, 0) * (bias.Vector() - bias_hat_.Vector());
}

void Preintegration::Predict(const SE3& world_from_imu_i,
                             const Vec3& velocity_i,
                             const ImuBias& bias,
                             const Vec3& gravity_world,
                             SE3* world_from_imu_j,
                             Vec3* velocity_j) const {
  THROW_CHECK(world_from_imu_j != nullptr && velocity_j != nullptr);
  const Quat& R_i = world_from_imu_i.rotation();
  const Vec3& p_i = world_from_imu_i.translation();
  const double dt = dt_s_;
  *world_from_imu_j = SE3(
      R_i * CorrectedDeltaRotation(bias),
      p_i + velocity_i * dt + 0.5 * dt * dt * gravity_world + R_i * CorrectedDeltaPosition(bias));
  *velocity_j = velocity_i + gravity_world * dt + R_i * CorrectedDeltaVelocity(bias);
}

}  // namespace lisfm
