#include "sim/imu_simulator.h"

#include <gtest/gtest.h>

#include "sim/motion.h"
#include "sim/scene.h"
#include "tests/common/sim_walks.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

SplineTrajectory Walk(double duration) {
  const auto scene = Scene::Generate(DefaultSceneOptions("office"));
  return GenerateWalking(scene->route(), duration, 0, 5, ThreeStopWalk(), nullptr);
}

// Cubic (4-point Lagrange) interpolation of the samples, 4th-order accurate.
ImuSample Interp(const std::vector<ImuSample>& m, size_t i, double u) {
  const size_t i0 = std::max<size_t>(i, 1) - 1;
  const double x = u + (i - i0);
  ImuSample out;
  for (size_t a = 0; a < 4; ++a) {
    double w = 1;
    for (size_t b = 0; b < 4; ++b) {
      if (a != b) w *= (x - double(b)) / (double(a) - double(b));
    }
    out.gyro += w * m[i0 + a].gyro;
    out.accel += w * m[i0 + a].accel;
  }
  return out;
}

// Integrating exact samples with RK4 must reproduce the ground truth: the
// error budget is the integrator's O(dt^4) truncation, far below 1 mm / 0.01
// deg over 10 s at 400 Hz. A wrong sign, frame (R vs R^T), gravity or angular
// velocity definition gives errors of metres.
TEST(ImuSimulator, NoiseFreeIntegrationReproducesGroundTruth) {
  const SplineTrajectory walk = Walk(30.0);
  const TimestampNs t0 = SecondsToNs(5.0), t1 = SecondsToNs(15.0);
  ImuSimOptions options;
  options.noise_scale = 0.0;
  const std::vector<ImuSample> m = SimulateImu(walk, ImuNoise(), t0 - SecondsToNs(0.01),
                                               t1 + SecondsToNs(0.01), options);
  // m[4] is at t0.
  ASSERT_EQ(m[4].t_ns, t0);
  const TrajectorySample start = walk.Evaluate(t0);
  Quat q = start.world_from_imu.rotation();
  Vec3 p = start.world_from_imu.translation(), v = start.velocity_world;
  const Vec3 g(0, 0, -kGravity);
  const double dt = 1.0 / 400;
  struct State {
    Quat q;
    Vec3 v, p;
  };
  auto deriv = [&](const State& s, const ImuSample& u, Vec3* dtheta, Vec3* dv, Vec3* dp) {
    *dtheta = u.gyro;
    *dv = s.q * u.accel + g;
    *dp = s.v;
  };
  size_t i = 4;
  for (; m[i].t_ns < t1; ++i) {
    // RK4; rotation updates as q * Exp(dt * k) (right perturbation, body rates).
    const State s0{q, v, p};
    Vec3 k1r, k1v, k1p, k2r, k2v, k2p, k3r, k3v, k3p, k4r, k4v, k4p;
    deriv(s0, m[i], &k1r, &k1v, &k1p);
    const ImuSample mid = Interp(m, i, 0.5);
    const State s1{q * so3::Exp(0.5 * dt * k1r), v + 0.5 * dt * k1v, p + 0.5 * dt * k1p};
    deriv(s1, mid, &k2r, &k2v, &k2p);
    const State s2{q * so3::Exp(0.5 * dt * k2r), v + 0.5 * dt * k2v, p + 0.5 * dt * k2p};
    deriv(s2, mid, &k3r, &k3v, &k3p);
    const State s3{q * so3::Exp(dt * k3r), v + dt * k3v, p + dt * k3p};
    deriv(s3, m[i + 1], &k4r, &k4v, &k4p);
    q = (q * so3::Exp(dt / 6 * (k1r + 2 * k2r + 2 * k3r + k4r))).normalized();
    v += dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
    p += dt / 6 * (k1p + 2 * k2p + 2 * k3p + k4p);
  }
  ASSERT_EQ(m[i].t_ns, t1);
  const SE3 truth = walk.Pose(t1);
  EXPECT_TRUE(test::PosesNear(SE3(q, p), truth, 0.01 * M_PI / 180, 1e-3));
  // The motion is not trivial: it moved several metres and turned.
  EXPECT_GT((truth.translation() - start.world_from_imu.translation()).norm(), 5.0);
}

TEST(ImuSimulator, NoiseFreeIsExact) {
  const SplineTrajectory walk = Walk(10.0);
  ImuSimOptions options;
  options.noise_scale = 0.0;
  const auto m = SimulateImu(walk, ImuNoise(), 0, SecondsToNs(5.0), options);
  ASSERT_EQ(m.size(), 2001u);
  for (size_t i = 0; i < m.size(); i += 97) {
    const ImuSample e = ExactImu(walk, m[i].t_ns);
    EXPECT_EQ(m[i].gyro, e.gyro);
    EXPECT_EQ(m[i].accel, e.accel);
  }
  // At rest the accelerometer reads -g in the IMU frame: +9.81 up, i.e. along -z_imu.
  EXPECT_NEAR(m[0].accel.z(), -kGravity, 0.2);
}

// With noise on, at rest: differences of consecutive samples remove the
// (slow) bias, var(diff) = 2 sigma_d^2 (+ 2e-7 relative from the random walk).
// 200 s at 400 Hz gives 80000 differences per axis: the standard error of the
// estimated sigma is 1 / sqrt(2 * 80000) = 0.25 %; we allow 3 %. The bias
// random walk increments have sigma_b * sqrt(dt) within 3 % likewise.
TEST(ImuSimulator, NoiseStatisticsMatchDensities) {
  std::vector<Quat> r(6, Quat(Eigen::AngleAxisd(0.3, Vec3(1, 2, 3).normalized())));
  std::vector<Vec3> p(6, Vec3(1, 2, 3));
  const SplineTrajectory still(0, 100.0, r, p);
  ImuNoise noise;
  ImuSimOptions options;
  options.seed = 9;
  std::vector<ImuBias> biases;
  const auto m = SimulateImu(still, noise, 0, SecondsToNs(200.0), options, nullptr, &biases);
  Eigen::Array3d sum_g = Eigen::Array3d::Zero(), sum_a = Eigen::Array3d::Zero();
  Eigen::Array3d sum_bg = Eigen::Array3d::Zero(), sum_ba = Eigen::Array3d::Zero();
  for (size_t i = 1; i < m.size(); ++i) {
    sum_g += (m[i].gyro - m[i - 1].gyro).array().square();
    sum_a += (m[i].accel - m[i - 1].accel).array().square();
    sum_bg += (biases[i].gyro - biases[i - 1].gyro).array().square();
    sum_ba += (biases[i].accel - biases[i - 1].accel).array().square();
  }
  const double n = static_cast<double>(m.size() - 1);
  const double sigma_g = noise.gyroscope_noise_density * std::sqrt(400.0);
  const double sigma_a = noise.accelerometer_noise_density * std::sqrt(400.0);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(std::sqrt(sum_g[k] / n / 2), sigma_g, 0.03 * sigma_g);
    EXPECT_NEAR(std::sqrt(sum_a[k] / n / 2), sigma_a, 0.03 * sigma_a);
    EXPECT_NEAR(std::sqrt(sum_bg[k] / n), noise.gyroscope_random_walk / 20, 0.03 * 1e-6);
    EXPECT_NEAR(std::sqrt(sum_ba[k] / n), noise.accelerometer_random_walk / 20, 0.03 * 2e-5);
  }
  // The mean of the samples minus the exact value is the (non-zero) bias.
  const ImuSample exact = ExactImu(still, 0);
  Vec3 mean_g = Vec3::Zero();
  for (size_t i = 0; i < 4000; ++i) mean_g += m[i].gyro - exact.gyro;
  mean_g /= 4000;
  // Standard error of a 4000-sample mean: sigma_g / 63 = 7.6e-5 rad/s; 5 sigma.
  EXPECT_LT((mean_g - biases[2000].gyro).norm(), 5 * sigma_g / std::sqrt(4000.0) * 1.8);
  EXPECT_GT(biases[0].gyro.norm(), 1e-5);
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
