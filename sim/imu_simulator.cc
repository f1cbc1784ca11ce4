#include "sim/imu_simulator.h"

#include <cmath>
#include <random>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {
namespace sim {

ImuSample ExactImu(const SplineTrajectory& trajectory, TimestampNs t_ns) {
  const TrajectorySample s = trajectory.Evaluate(t_ns);
  ImuSample m;
  m.t_ns = t_ns;
  m.gyro = s.angular_velocity_body;
  const Vec3 gravity(0, 0, -kGravity);
  m.accel = s.world_from_imu.rotation().conjugate() * (s.acceleration_world - gravity);
  return m;
}

bool ImuSimOptions::Check() const {
  CHECK_OPTION_GE(noise_scale, 0.0);
  CHECK_OPTION_GE(initial_gyro_bias_sigma, 0.0);
  CHECK_OPTION_GE(initial_accel_bias_sigma, 0.0);
  return true;
}

std::vector<ImuSample> SimulateImu(const SplineTrajectory& trajectory,
                                   const ImuNoise& noise,
                                   TimestampNs start_ns,
                                   TimestampNs end_ns,
                                   const ImuSimOptions& options,
                                   const ImuErrors* errors,
                                   std::vector<ImuBias>* biases) {
  THROW_CHECK_GT(noise.update_rate, 0.0);
  THROW_CHECK_OPTIONS(options);
  const double rate = noise.update_rate;
  const double k = options.noise_scale;
  std::mt19937_64 rng(options.seed * 0x9E3779B97F4A7C15ULL + 11);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto random_vec = [&]() { return Vec3(normal(rng), normal(rng), normal(rng)); };
  // Constant initial bias, then random walk.
  Vec3 bias_g = k * options.initial_gyro_bias_sigma * random_vec();
  Vec3 bias_a = k * options.initial_accel_bias_sigma * random_vec();
  const double sigma_g = k * noise.gyroscope_noise_density * std::sqrt(rate);
  const double sigma_a = k * noise.accelerometer_noise_density * std::sqrt(rate);
  const double walk_g = k * noise.gyroscope_random_walk * std::sqrt(1.0 / rate);
  const double walk_a = k * noise.accelerometer_random_walk * std::sqrt(1.0 / rate);
  std::vector<ImuSample> samples;
  if (biases) biases->clear();
  const double period_ns = 1e9 / rate;
  const Mat3 gyro_matrix = errors ? errors->gyro.Matrix() : Mat3::Identity();
  const Mat3 accel_matrix = errors ? errors->accel.Matrix() : Mat3::Identity();
  for (int64_t i = 0;; ++i) {
    const TimestampNs t = start_ns + static_cast<TimestampNs>(std::llround(i * period_ns));
    if (t > end_ns) break;
    ImuSample m = ExactImu(trajectory, t);
    Vec3 total_bias_g = bias_g, total_bias_a = bias_a;
    if (errors) {
      m.gyro = gyro_matrix * m.gyro;
      m.accel = accel_matrix * m.accel;
      const double dT = errors->temperature.At(t);
      total_bias_g += dT * errors->gyro.temperature_coefficient;
      total_bias_a += dT * errors->accel.temperature_coefficient;
    }
    if (k > 0) {
      m.gyro += total_bias_g + sigma_g * random_vec();
      m.accel += total_bias_a + sigma_a * random_vec();
    } else if (errors) {
      m.gyro += total_bias_g;
      m.accel += total_bias_a;
    }
    samples.push_back(m);
    if (biases) biases->push_back({t, total_bias_g, total_bias_a});
    if (k > 0) {
      bias_g += walk_g * random_vec();
      bias_a += walk_a * random_vec();
    }
  }
  return samples;
}

}  // namespace sim
}  // namespace lisfm
