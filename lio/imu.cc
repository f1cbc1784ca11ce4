#include "lio/imu.h"

#include <cmath>

#include <fmt/format.h>

#include "core/option_check.h"

namespace lisfm {

bool ImuInitializerOptions::Check() const {
  CHECK_OPTION_GT(min_duration_s, 0.0);
  CHECK_OPTION_GE(min_samples, 10);
  CHECK_OPTION_GT(max_gyro_std, 0.0);
  CHECK_OPTION_GT(max_accel_std, 0.0);
  CHECK_OPTION_GT(gravity_magnitude, 0.0);
  return true;
}

ImuInitialization InitializeFromStaticImu(const std::vector<ImuSample>& samples,
                                          const ImuInitializerOptions& options) {
  ImuInitialization init;
  if (samples.empty()) {
    init.message = "no IMU samples";
    return init;
  }
  // The window: all samples within min_duration_s of the first one.
  const TimestampNs t0 = samples.front().t_ns;
  const TimestampNs window_ns = SecondsToNs(options.min_duration_s);
  size_t n = 0;
  while (n < samples.size() && samples[n].t_ns - t0 <= window_ns) ++n;
  if (n < static_cast<size_t>(options.min_samples) || samples[n - 1].t_ns - t0 < window_ns * 0.9) {
    init.message = fmt::format("only {} IMU samples ({:.3f} s) before the data ends; need {} s",
                               n, NsToSeconds(samples[n - 1].t_ns - t0), options.min_duration_s);
    return init;
  }
  Vec3 mean_gyro = Vec3::Zero(), mean_acc = Vec3::Zero();
  for (size_t i = 0; i < n; ++i) {
    mean_gyro += samples[i].gyro;
    mean_acc += samples[i].accel;
  }
  mean_gyro /= n;
  mean_acc /= n;
  double var_gyro = 0, var_acc = 0;
  for (size_t i = 0; i < n; ++i) {
    var_gyro += (samples[i].gyro - mean_gyro).squaredNorm();
    var_acc += (samples[i].accel - mean_acc).squaredNorm();
  }
  const double acc_norm = mean_acc.norm();
  if (acc_norm < 1e-6) {
    init.message = "mean accelerometer reading is zero";
    return init;
  }
  // An IMU reporting in g reads ~1 when static.
  // An IMU that reports in g reads ~1 when static: convert units, nothing more
  // (the residual norm error is accelerometer bias, which the filter estimates).
  init.accel_scale = (acc_norm < 3.0) ? options.gravity_magnitude : 1.0;
  const double std_gyro = std::sqrt(var_gyro / n);
  const double std_acc = std::sqrt(var_acc / n) * init.accel_scale;
  if (std_gyro > options.max_gyro_std || std_acc > options.max_accel_std) {
    init.message = fmt::format(
        "IMU is not stationary in the first {:.2f} s (gyro std {:.4f} rad/s, accel std {:.4f} m/s^2)",
        options.min_duration_s, std_gyro, std_acc);
    return init;
  }
  init.gyro_bias = mean_gyro;
  // Static: specific force = -g expressed in the body frame, i.e. it points up.
  const Vec3 up_in_imu = mean_acc.normalized();
  init.world_from_imu = Quat::FromTwoVectors(up_in_imu, Vec3::UnitZ());
  init.gravity_world = Vec3(0, 0, -options.gravity_magnitude);
  init.t_ns = samples[n - 1].t_ns;
  init.success = true;
  init.message = fmt::format("static init over {} samples: |acc| {:.4f} (scale {:.4f}), gyro bias "
                             "[{:.5f} {:.5f} {:.5f}] rad/s",
                             n, acc_norm, init.accel_scale, mean_gyro.x(), mean_gyro.y(),
                             mean_gyro.z());
  return init;
}

}  // namespace lisfm
