// Deterministic IMU errors beyond white noise and bias random walk (error
// source `imu`): per-axis scale-factor error, axis misalignment / cross-axis
// sensitivity, and a slow temperature-driven bias drift. Measurement model of
// one triad (gyroscope or accelerometer), IMU frame, at time t:
//
//   measured = M * true + b_rw(t) + c * dT(t) + n,
//   M = diag(1 + scale) * (I + misalignment)   (misalignment: zero diagonal)
//
// with b_rw the random-walk bias and n the white noise of sim/imu_simulator.h,
// c the per-axis temperature coefficient of the bias (rad/s/K, m/s^2/K) and
// dT(t) one temperature deviation (K) shared by both triads. dT is a
// stationary Gaussian process with standard deviation sigma and time constant
// tau: two cascaded first-order lags driven by white noise, so that its paths
// are smooth (differentiable) and its autocorrelation is
//   E[dT(t) dT(t + l)] = sigma^2 (1 + |l| / tau) exp(-|l| / tau).
// It is sampled exactly (discrete-time transition of the 2-state lag chain)
// every second and interpolated linearly in between.
//
// Sizes (datasheet "typ" values, read as 1 sigma over parts, Bosch's
// convention) are drawn per recording from the seed and multiplied by the
// simulator's noise_scale; truth/imu_errors.yaml records the drawn values.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "core/time.h"

namespace lisfm {
namespace sim {

// Sizes of the IMU errors (1-sigma over parts; 0 turns that part off).
// Scale, cross-axis and temperature coefficients: Bosch BMI085 datasheet typ
// values (the IMU of the HILTI 2022 rig). The temperature process (a few K
// over minutes: a handheld device warming up and carried between rooms) is a
// modelling choice, not a datasheet value.
struct ImuErrorOptions {
  double gyro_scale_sigma_percent = 1.0;                  // %, per axis (sensitivity tolerance)
  double accel_scale_sigma_percent = 0.5;                 // %, per axis (sensitivity tolerance)
  double gyro_cross_axis_sigma_percent = 1.0;             // %, per off-diagonal entry
  double accel_cross_axis_sigma_percent = 0.5;            // %, per off-diagonal entry
  double gyro_temperature_coefficient_dps_per_k = 0.015;  // deg/s/K, zero-rate offset drift
  double accel_temperature_coefficient_mg_per_k = 0.2;    // mg/K, zero-g offset drift
  double temperature_sigma_k = 2.0;                       // K, std of the temperature deviation
  double temperature_time_constant_s = 300.0;             // s, tau of the temperature process

  bool Check() const;
};

// A sampled temperature deviation dT(t) (model above).
class TemperatureDrift {
 public:
  static constexpr TimestampNs kPeriodNs = kNsPerSecond;  // sample spacing

  // dT == 0 everywhere.
  TemperatureDrift() = default;
  // Samples at start_ns + i s for every i with start_ns + (i - 1) s < end_ns
  // (the last sample is at or after end_ns), the first from the stationary
  // distribution. Deterministic in `seed`.
  TemperatureDrift(double sigma_k,
                   double time_constant_s,
                   TimestampNs start_ns,
                   TimestampNs end_ns,
                   uint64_t seed);
  // From recorded samples (truth/imu_errors.yaml).
  TemperatureDrift(double sigma_k,
                   double time_constant_s,
                   TimestampNs start_ns,
                   std::vector<double> samples_k);

  // dT at t_ns (K): linear between samples, the end samples outside.
  double At(TimestampNs t_ns) const;

  double sigma_k() const { return sigma_k_; }
  double time_constant_s() const { return time_constant_s_; }
  TimestampNs start_ns() const { return start_ns_; }
  const std::vector<double>& samples_k() const { return samples_k_; }

 private:
  double sigma_k_ = 0.0;
  double time_constant_s_ = 1.0;
  TimestampNs start_ns_ = 0;
  std::vector<double> samples_k_;
};

// The errors of one triad (model above).
struct ImuTriadErrors {
  Vec3 scale = Vec3::Zero();                    // fraction (0.01 = +1 %)
  Mat3 misalignment = Mat3::Zero();             // zero diagonal
  Vec3 temperature_coefficient = Vec3::Zero();  // rad/s/K (gyro), m/s^2/K (accel)

  // M = diag(1 + scale) * (I + misalignment).
  Mat3 Matrix() const;
};

struct ImuErrors {
  ImuTriadErrors gyro;
  ImuTriadErrors accel;
  TemperatureDrift temperature;
};

// Draws the errors of one recording covering [start_ns, end_ns]: sizes times
// `noise_scale` (the temperature coefficients are scaled, dT keeps its sigma).
ImuErrors DrawImuErrors(const ImuErrorOptions& options,
                        double noise_scale,
                        uint64_t seed,
                        TimestampNs start_ns,
                        TimestampNs end_ns);

// truth/imu_errors.yaml: the model as a comment, then
//   gyro: {scale: [3], misalignment: [[3]x3], matrix: [[3]x3],
//          temperature_coefficient: [3]}          (rad/s/K)
//   accel: likewise                                (m/s^2/K)
//   temperature: {sigma_k, time_constant_s, start_ns, period_s: 1, samples_k: [...]}
// Numbers in shortest round-trip form, so reading gives the same doubles.
// Written atomically.
void WriteImuErrorsYaml(const std::string& path, const ImuErrors& errors);
// Reads the file above; InputError naming the file and field on bad input.
ImuErrors ReadImuErrorsYaml(const std::string& path);

}  // namespace sim
}  // namespace lisfm
