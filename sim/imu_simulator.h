// IMU simulation from the trajectory's analytic derivatives (body = IMU frame):
//   gyro  = omega_body + b_g + n_g
//   accel = R^T (a_world - g) + b_a + n_a,   g = (0, 0, -kGravity) in the scene frame.
// Noise (Kalibr conventions, continuous-time densities from the rig's ImuNoise):
// white noise with discrete sigma_d = sigma_c * sqrt(rate); biases start at a
// constant random offset and follow a random walk with per-sample step
// sigma_bc * sqrt(1 / rate). All noise and biases scale with `noise_scale`
// (0 = exact samples). Optional deterministic errors (sim/imu_errors.h: scale,
// misalignment, temperature bias drift) enter as
//   measured = M * exact + (random-walk bias + temperature bias) + noise.
#pragma once

#include <vector>

#include "core/rig.h"
#include "core/sensor_data.h"
#include "sim/imu_errors.h"
#include "sim/spline_trajectory.h"

namespace lisfm {
namespace sim {

constexpr double kGravity = 9.81;  // m/s^2, along -z of the scene frame

struct ImuBias {
  TimestampNs t_ns = 0;
  Vec3 gyro = Vec3::Zero();   // rad/s
  Vec3 accel = Vec3::Zero();  // m/s^2
};

struct ImuSimOptions {
  double noise_scale = 1.0;             // 0 = noise-free, no biases
  double initial_gyro_bias_sigma = 2e-3;   // rad/s, per axis (BMI085 class offsets)
  double initial_accel_bias_sigma = 0.05;  // m/s^2, per axis
  uint64_t seed = 1;
  bool Check() const;
};

// Samples at start_ns + k / noise.update_rate for every such time <= end_ns.
// `errors` (optional) adds the errors of sim/imu_errors.h; without them the
// samples are exactly those of the model above (the same random draws either
// way). `biases` (optional) receives the true additive bias at every sample
// (random walk plus, with `errors`, the temperature drift).
std::vector<ImuSample> SimulateImu(const SplineTrajectory& trajectory,
                                   const ImuNoise& noise,
                                   TimestampNs start_ns,
                                   TimestampNs end_ns,
                                   const ImuSimOptions& options,
                                   const ImuErrors* errors = nullptr,
                                   std::vector<ImuBias>* biases = nullptr);

// Exact (noise-free) measurement at one time.
ImuSample ExactImu(const SplineTrajectory& trajectory, TimestampNs t_ns);

}  // namespace sim
}  // namespace lisfm
