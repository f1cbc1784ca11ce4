// The IMU error source against its definition (sim/imu_errors.h): the
// temperature process's amplitude and autocorrelation, the spread of the drawn
// sizes, scale/misalignment recovered by regression against ExactImu, the
// drift entering the bias, and the truth file.
#include "sim/imu_errors.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "core/errors.h"
#include "sim/imu_simulator.h"
#include "sim/motion.h"
#include "sim/scene.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

double Correlation(double lag_over_tau) { return (1 + lag_over_tau) * std::exp(-lag_over_tau); }

// Pooled over 1500 independent 1500 s series (tau = 300 s). For a Gaussian
// process the variance estimate over a total time T has a relative variance
// 2 * integral(rho^2) / T = 5 tau / T (rho as above: integral 2.5 tau), i.e. a
// standard error of 2.6 % on sigma^2, 1.3 % on sigma: we allow 5 %. The
// correlation estimates (ratios of such sums) have standard errors <= 0.02;
// we allow 0.07 at lags tau and 2 tau. At 0.1 tau the smooth process has
// correlation 0.9953 (a first-order lag would have exp(-0.1) = 0.905): the
// ratio estimate there is far tighter, we allow 0.01.
TEST(TemperatureDrift, HasTheConfiguredSigmaAndAutocorrelation) {
  const double sigma = 2.0, tau = 300.0;
  const int lags[] = {30, 300, 600};
  double sum = 0, sum_sq = 0, n = 0;
  double lag_sum[3] = {0, 0, 0}, lag_n[3] = {0, 0, 0};
  for (uint64_t seed = 1; seed <= 1500; ++seed) {
    const TemperatureDrift drift(sigma, tau, 0, SecondsToNs(1499.0), seed);
    const std::vector<double>& x = drift.samples_k();
    ASSERT_EQ(x.size(), 1500u);
    for (size_t i = 0; i < x.size(); ++i) {
      sum += x[i];
      sum_sq += x[i] * x[i];
      n += 1;
      for (int k = 0; k < 3; ++k) {
        if (i + lags[k] < x.size()) {
          lag_sum[k] += x[i] * x[i + lags[k]];
          lag_n[k] += 1;
        }
      }
    }
  }
  const double var = sum_sq / n;
  std::printf("sigma %.4f K; correlation at 0.1, 1, 2 tau: %.4f %.4f %.4f (model %.4f %.4f %.4f)\n",
              std::sqrt(var),
              lag_sum[0] / lag_n[0] / var,
              lag_sum[1] / lag_n[1] / var,
              lag_sum[2] / lag_n[2] / var,
              Correlation(0.1),
              Correlation(1.0),
              Correlation(2.0));
  EXPECT_NEAR(std::sqrt(var), sigma, 0.05 * sigma);
  // Mean: standard error sigma * sqrt(2 * integral(rho) / T) = 0.023 sigma.
  EXPECT_LT(std::abs(sum / n), 0.1 * sigma);
  EXPECT_NEAR(lag_sum[0] / lag_n[0] / var, Correlation(0.1), 0.01);
  EXPECT_NEAR(lag_sum[1] / lag_n[1] / var, Correlation(1.0), 0.07);
  EXPECT_NEAR(lag_sum[2] / lag_n[2] / var, Correlation(2.0), 0.07);
}

TEST(TemperatureDrift, SamplesEverySecondAndInterpolatesLinearly) {
  const TimestampNs start = SecondsToNs(100.0);
  const TemperatureDrift drift(1.5, 60.0, start, start + SecondsToNs(10.5), 4);
  const std::vector<double>& x = drift.samples_k();
  ASSERT_EQ(x.size(), 12u);  // 0..11 s: the last sample is at or after the end
  EXPECT_EQ(drift.At(start), x[0]);
  EXPECT_EQ(drift.At(start + SecondsToNs(3.0)), x[3]);
  EXPECT_NEAR(drift.At(start + SecondsToNs(3.25)), 0.75 * x[3] + 0.25 * x[4], 1e-15);
  EXPECT_EQ(drift.At(start - 1), x[0]);
  EXPECT_EQ(drift.At(start + SecondsToNs(20.0)), x.back());
  EXPECT_EQ(TemperatureDrift().At(start), 0.0);
  const TemperatureDrift flat(0.0, 60.0, start, start + SecondsToNs(5.0), 4);
  for (double v : flat.samples_k()) EXPECT_EQ(v, 0.0);
}

// The typ values are 1 sigma over parts: over 3000 recordings each size has
// the configured spread (1 / sqrt(2 n) = 1.3 % standard error; 5 % allowed).
TEST(ImuErrors, SpreadOverSeedsIsTheConfiguredSigma) {
  const ImuErrorOptions options;
  std::vector<double> gs, as, gm, am, gt, at;
  for (uint64_t seed = 1; seed <= 3000; ++seed) {
    const ImuErrors e = DrawImuErrors(options, 1.0, seed, 0, 0);
    gs.push_back(e.gyro.scale.x());
    as.push_back(e.accel.scale.z());
    gm.push_back(e.gyro.misalignment(0, 2));
    am.push_back(e.accel.misalignment(2, 1));
    gt.push_back(e.gyro.temperature_coefficient.y());
    at.push_back(e.accel.temperature_coefficient.x());
    EXPECT_EQ(e.gyro.misalignment.diagonal(), Vec3::Zero());
    EXPECT_EQ(e.accel.misalignment.diagonal(), Vec3::Zero());
  }
  auto std_of = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x * x;
    return std::sqrt(s / static_cast<double>(v.size()));
  };
  auto expect = [&](const std::vector<double>& v, double sigma, const char* what) {
    EXPECT_NEAR(std_of(v), sigma, 0.05 * sigma) << what;
  };
  expect(gs, options.gyro_scale_sigma_percent / 100, "gyro scale");
  expect(as, options.accel_scale_sigma_percent / 100, "accel scale");
  expect(gm, options.gyro_cross_axis_sigma_percent / 100, "gyro misalignment");
  expect(am, options.accel_cross_axis_sigma_percent / 100, "accel misalignment");
  expect(gt,
         options.gyro_temperature_coefficient_dps_per_k * M_PI / 180,
         "gyro temperature coefficient (rad/s/K)");
  expect(at,
         options.accel_temperature_coefficient_mg_per_k * 9.80665e-3,
         "accel temperature coefficient (m/s^2/K)");
  // noise_scale scales the sizes; 0 turns them off.
  const ImuErrors one = DrawImuErrors(options, 1.0, 8, 0, 0);
  const ImuErrors half = DrawImuErrors(options, 0.5, 8, 0, 0);
  EXPECT_EQ(half.gyro.scale, 0.5 * one.gyro.scale);
  EXPECT_EQ(half.accel.temperature_coefficient, 0.5 * one.accel.temperature_coefficient);
  const ImuErrors zero = DrawImuErrors(options, 0.0, 8, 0, 0);
  EXPECT_EQ(zero.gyro.Matrix(), Mat3::Identity());
  EXPECT_EQ(zero.accel.temperature_coefficient, Vec3::Zero());
}

SplineTrajectory Walk(double duration) {
  const auto scene = Scene::Generate(DefaultSceneOptions("office"));
  WalkingOptions walk;
  walk.num_stops = 3;  // the walk these bounds were set on
  return GenerateWalking(scene->route(), duration, 0, 5, walk, nullptr);
}

// measured - bias = M * exact + white noise: least squares of the samples on
// ExactImu recovers M. Per entry (r, c) the estimate has standard error
// sigma_d * sqrt(inv(X^T X)(c, c)); every entry must be within 5 of them, and
// M must differ from I by far more (else the test could not fail).
TEST(ImuErrors, ScaleAndMisalignmentRecoveredByRegressionOnExactImu) {
  const SplineTrajectory walk = Walk(90.0);
  ImuErrorOptions options;
  const ImuErrors errors = DrawImuErrors(options, 1.0, 21, 0, SecondsToNs(90.0));
  const ImuNoise noise;
  ImuSimOptions imu;
  imu.seed = 21;
  std::vector<ImuBias> biases;
  const std::vector<ImuSample> m =
      SimulateImu(walk, noise, 0, SecondsToNs(90.0), imu, &errors, &biases);
  struct Triad {
    const char* name;
    Mat3 truth;
    double sigma_d;
    Mat3 yx = Mat3::Zero(), xx = Mat3::Zero();
  };
  Triad triads[2] = {
      {"gyro", errors.gyro.Matrix(), noise.gyroscope_noise_density * std::sqrt(400.0)},
      {"accel", errors.accel.Matrix(), noise.accelerometer_noise_density * std::sqrt(400.0)}};
  for (size_t i = 0; i < m.size(); ++i) {
    const ImuSample exact = ExactImu(walk, m[i].t_ns);
    const Vec3 yg = m[i].gyro - biases[i].gyro, ya = m[i].accel - biases[i].accel;
    triads[0].yx += yg * exact.gyro.transpose();
    triads[0].xx += exact.gyro * exact.gyro.transpose();
    triads[1].yx += ya * exact.accel.transpose();
    triads[1].xx += exact.accel * exact.accel.transpose();
  }
  for (const Triad& t : triads) {
    const Mat3 inv = t.xx.inverse();
    const Mat3 estimate = t.yx * inv;
    double max_stderr = 0;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        const double stderr_rc = t.sigma_d * std::sqrt(inv(c, c));
        max_stderr = std::max(max_stderr, stderr_rc);
        EXPECT_NEAR(estimate(r, c), t.truth(r, c), 5 * stderr_rc)
            << t.name << " (" << r << ", " << c << ")";
      }
    }
    EXPECT_GT((t.truth - Mat3::Identity()).cwiseAbs().maxCoeff(), 10 * max_stderr) << t.name;
    std::printf("%s: max |M - I| %.2e, max |estimate - M| %.2e, max standard error %.2e\n",
                t.name,
                (t.truth - Mat3::Identity()).cwiseAbs().maxCoeff(),
                (estimate - t.truth).cwiseAbs().maxCoeff(),
                max_stderr);
  }
}

// Same seed with and without errors: the random draws are the same, so the
// samples differ by exactly (M - I) * exact + c * dT(t), and the recorded
// bias by c * dT(t).
TEST(ImuErrors, TemperatureDriftEntersTheBiasAndTheRestIsUnchanged) {
  const SplineTrajectory walk = Walk(30.0);
  ImuErrorOptions options;
  options.temperature_time_constant_s = 20.0;  // a visible drift within 30 s
  const ImuErrors errors = DrawImuErrors(options, 1.0, 3, 0, SecondsToNs(30.0));
  ImuSimOptions imu;
  imu.seed = 3;
  std::vector<ImuBias> b0, b1;
  const auto m0 = SimulateImu(walk, ImuNoise(), 0, SecondsToNs(30.0), imu, nullptr, &b0);
  const auto m1 = SimulateImu(walk, ImuNoise(), 0, SecondsToNs(30.0), imu, &errors, &b1);
  ASSERT_EQ(m0.size(), m1.size());
  double drift_range = 0;
  for (size_t i = 0; i < m0.size(); ++i) {
    const double dT = errors.temperature.At(m0[i].t_ns);
    const Vec3 drift_g = dT * errors.gyro.temperature_coefficient;
    const Vec3 drift_a = dT * errors.accel.temperature_coefficient;
    EXPECT_LT((b1[i].gyro - b0[i].gyro - drift_g).norm(), 1e-15);
    EXPECT_LT((b1[i].accel - b0[i].accel - drift_a).norm(), 1e-15);
    const ImuSample exact = ExactImu(walk, m0[i].t_ns);
    const Vec3 dg = (errors.gyro.Matrix() - Mat3::Identity()) * exact.gyro + drift_g;
    const Vec3 da = (errors.accel.Matrix() - Mat3::Identity()) * exact.accel + drift_a;
    EXPECT_LT((m1[i].gyro - m0[i].gyro - dg).norm(), 1e-13) << i;
    EXPECT_LT((m1[i].accel - m0[i].accel - da).norm(), 1e-12) << i;
    drift_range = std::max(drift_range, std::abs(dT));
  }
  EXPECT_GT(drift_range, 0.5);  // K: the drift was exercised
}

TEST(ImuErrors, TruthFileRoundTripsExactly) {
  test::TempDir dir;
  const ImuErrors e =
      DrawImuErrors(ImuErrorOptions(), 1.0, 17, SecondsToNs(5.0), SecondsToNs(65.5));
  WriteImuErrorsYaml(dir.File("imu_errors.yaml"), e);
  const ImuErrors r = ReadImuErrorsYaml(dir.File("imu_errors.yaml"));
  EXPECT_EQ(r.gyro.scale, e.gyro.scale);
  EXPECT_EQ(r.gyro.misalignment, e.gyro.misalignment);
  EXPECT_EQ(r.gyro.temperature_coefficient, e.gyro.temperature_coefficient);
  EXPECT_EQ(r.accel.scale, e.accel.scale);
  EXPECT_EQ(r.accel.misalignment, e.accel.misalignment);
  EXPECT_EQ(r.accel.temperature_coefficient, e.accel.temperature_coefficient);
  EXPECT_EQ(r.temperature.start_ns(), e.temperature.start_ns());
  EXPECT_EQ(r.temperature.samples_k(), e.temperature.samples_k());
  EXPECT_EQ(r.temperature.sigma_k(), e.temperature.sigma_k());
  EXPECT_EQ(r.temperature.time_constant_s(), e.temperature.time_constant_s());
  EXPECT_EQ(r.temperature.samples_k().size(), 62u);
  test::WriteText(dir.File("bad.yaml"), "gyro:\n  scale: [1, 2]\n");
  EXPECT_THROW(ReadImuErrorsYaml(dir.File("bad.yaml")), InputError);
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
