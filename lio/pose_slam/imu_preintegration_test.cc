#include "lio/pose_slam/imu_preintegration.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "core/errors.h"
#include "sim/imu_simulator.h"
#include "sim/motion.h"
#include "tests/common/sim_walks.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

const Vec3 kGravity(0, 0, -sim::kGravity);
constexpr TimestampNs kStartNs = 1'000'000'000'000LL;  // 1000 s

// A closed 12 m x 8 m walk with rests at the start, middle and end
// (sim/motion.h: exact rests, gait bob, sway and turns).
sim::SplineTrajectory Walk(double duration_s, std::vector<sim::StationaryPeriod>* rests = nullptr) {
  sim::WalkingRoute route;
  route.waypoints = {Vec3(0, 0, 1.4), Vec3(12, 0, 1.4), Vec3(12, 8, 1.4), Vec3(0, 8, 1.4)};
  route.closed = true;
  return sim::GenerateWalking(route, duration_s, kStartNs, 7, ThreeStopWalk(), rests);
}

// Noise-free samples at `rate` Hz over the whole trajectory.
std::vector<ImuSample> ExactSamples(const sim::SplineTrajectory& trajectory, double rate) {
  std::vector<ImuSample> samples;
  const double period_ns = 1e9 / rate;
  for (int64_t k = 0;; ++k) {
    const TimestampNs t = trajectory.start_ns() + std::llround(k * period_ns);
    if (t > trajectory.end_ns()) break;
    samples.push_back(sim::ExactImu(trajectory, t));
  }
  return samples;
}

// The preintegrated measurement the trajectory defines between t_i and t_j.
struct TrueDelta {
  Quat rotation;
  Vec3 velocity;
  Vec3 position;
};

TrueDelta TrueDeltaBetween(const sim::SplineTrajectory& trajectory,
                           TimestampNs t_i,
                           TimestampNs t_j) {
  const sim::TrajectorySample i = trajectory.Evaluate(t_i), j = trajectory.Evaluate(t_j);
  const double dt = NsToSeconds(t_j - t_i);
  const Quat R_i_inverse = i.world_from_imu.rotation().conjugate();
  TrueDelta d;
  d.rotation = R_i_inverse * j.world_from_imu.rotation();
  d.velocity = R_i_inverse * (j.velocity_world - i.velocity_world - kGravity * dt);
  d.position = R_i_inverse * (j.world_from_imu.translation() - i.world_from_imu.translation() -
                              i.velocity_world * dt - 0.5 * kGravity * dt * dt);
  return d;
}

// Keyframe times every ~0.73 s, off the IMU sample grid.
std::vector<TimestampNs> KeyframeTimes(const sim::SplineTrajectory& trajectory) {
  std::vector<TimestampNs> times;
  for (TimestampNs t = trajectory.start_ns() + 123'456'789; t < trajectory.end_ns() - 100'000'000;
       t += 731'234'567) {
    times.push_back(t);
  }
  return times;
}

// The measurement error e = [Log(dR_ref^T dR); dv - dv_ref; dp - dp_ref].
Eigen::Matrix<double, 9, 1> MeasurementError(const Preintegration& reference,
                                             const Quat& rotation,
                                             const Vec3& velocity,
                                             const Vec3& position) {
  Eigen::Matrix<double, 9, 1> e;
  e << so3::Log(reference.delta_rotation().conjugate() * rotation),
      velocity - reference.delta_velocity(), position - reference.delta_position();
  return e;
}

// Adds white noise of the densities of `noise` (discrete sigma = density *
// sqrt(rate), Kalibr) to every sample.
std::vector<ImuSample> AddWhiteNoise(std::vector<ImuSample> samples,
                                     const ImuNoise& noise,
                                     double rate,
                                     std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const double sigma_g = noise.gyroscope_noise_density * std::sqrt(rate);
  const double sigma_a = noise.accelerometer_noise_density * std::sqrt(rate);
  for (ImuSample& m : samples) {
    for (int a = 0; a < 3; ++a) m.gyro(a) += sigma_g * normal(rng);
    for (int a = 0; a < 3; ++a) m.accel(a) += sigma_a * normal(rng);
  }
  return samples;
}

// Noise-free samples at the rig's 400 Hz over a walk with turns, gait and
// rests; keyframes ~0.73 s apart, off the sample grid (interpolated boundary
// samples) and on it. Relative errors: |dv - dv_true| / |dv_true| and the same
// for dp (gravity keeps both away from zero); the rotation error angle over
// the rotation travelled in the interval (integral of |omega|, since the net
// angle vanishes at rests). The integration is second order in the sample
// spacing (fourth for the rotation): measured 1.7e-7 (dv), 6.9e-7 (dp) and
// 5e-7 (dR) at 400 Hz, each 100x smaller at 4 kHz.
TEST(Preintegration, NoiseFreeMatchesTrajectoryWithin1e6Relative) {
  const sim::SplineTrajectory trajectory = Walk(30.0);
  const double rate = 400.0;
  const std::vector<ImuSample> samples = ExactSamples(trajectory, rate);
  std::vector<TimestampNs> off_grid = KeyframeTimes(trajectory);
  std::vector<TimestampNs> on_grid;
  for (const TimestampNs t : off_grid) on_grid.push_back(t - (t - kStartNs) % 2'500'000);
  for (const std::vector<TimestampNs>& keyframes : {off_grid, on_grid}) {
    ASSERT_GE(keyframes.size(), 35u);
    for (size_t k = 0; k + 1 < keyframes.size(); ++k) {
      SCOPED_TRACE("interval " + std::to_string(k));
      const Preintegration pim =
          Preintegration::Integrate(samples, keyframes[k], keyframes[k + 1], ImuBias(), ImuNoise());
      EXPECT_NEAR(pim.dt_s(), NsToSeconds(keyframes[k + 1] - keyframes[k]), 1e-12);
      const TrueDelta truth = TrueDeltaBetween(trajectory, keyframes[k], keyframes[k + 1]);
      double travelled = 0;  // rad, exact rates on the sample grid (trapezoidal sum)
      for (size_t m = 0; m + 1 < samples.size(); ++m) {
        if (samples[m].t_ns >= keyframes[k] && samples[m + 1].t_ns <= keyframes[k + 1]) {
          travelled += 0.5 * (samples[m].gyro.norm() + samples[m + 1].gyro.norm()) / rate;
        }
      }
      EXPECT_LE(so3::AngularDistance(pim.delta_rotation(), truth.rotation), 1e-6 * travelled);
      EXPECT_LE((pim.delta_velocity() - truth.velocity).norm(), 1e-6 * truth.velocity.norm());
      EXPECT_LE((pim.delta_position() - truth.position).norm(), 1e-6 * truth.position.norm());
    }
  }
}

// Predict() applies the measurement to the state at t_i with gravity along
// -z: it reproduces the state at t_j.
TEST(Preintegration, PredictReproducesTheNextState) {
  const sim::SplineTrajectory trajectory = Walk(30.0);
  const std::vector<ImuSample> samples = ExactSamples(trajectory, 400.0);
  const TimestampNs t_i = kStartNs + SecondsToNs(6.1), t_j = kStartNs + SecondsToNs(7.3);
  const Preintegration pim = Preintegration::Integrate(samples, t_i, t_j, ImuBias(), ImuNoise());
  const sim::TrajectorySample i = trajectory.Evaluate(t_i), j = trajectory.Evaluate(t_j);
  SE3 predicted_pose;
  Vec3 predicted_velocity;
  pim.Predict(i.world_from_imu,
              i.velocity_world,
              ImuBias(),
              kGravity,
              &predicted_pose,
              &predicted_velocity);
  EXPECT_TRUE(test::PosesNear(predicted_pose, j.world_from_imu, 1e-6, 1e-6));
  EXPECT_LT((predicted_velocity - j.velocity_world).norm(), 1e-5);
}

// The bias Jacobians are the derivatives of the discrete integration: central
// differences of re-integrations with perturbed biases (step 1e-6 in rad/s and
// m/s^2; truncation error ~1e-12, rounding ~1e-10) agree to 1e-7 of the
// largest entry.
TEST(Preintegration, BiasJacobiansMatchFiniteDifferences) {
  const sim::SplineTrajectory trajectory = Walk(30.0);
  const std::vector<ImuSample> samples =
      AddWhiteNoise(ExactSamples(trajectory, 400.0), ImuNoise(), 400.0, test::Rng());
  const TimestampNs t_i = kStartNs + SecondsToNs(5.03), t_j = kStartNs + SecondsToNs(6.21);
  ImuBias bias_hat;
  bias_hat.gyro = Vec3(0.01, -0.02, 0.005);
  bias_hat.accel = Vec3(0.1, -0.05, 0.2);
  const Preintegration pim = Preintegration::Integrate(samples, t_i, t_j, bias_hat, ImuNoise());
  const auto measurement = [&](const Eigen::VectorXd& bias) -> Eigen::VectorXd {
    const Preintegration p =
        Preintegration::Integrate(samples, t_i, t_j, ImuBias::FromVector(Vec6(bias)), ImuNoise());
    return MeasurementError(pim, p.delta_rotation(), p.delta_velocity(), p.delta_position());
  };
  const Eigen::MatrixXd numeric = test::NumericJacobian(measurement, bias_hat.Vector(), 1e-6);
  const PreintegrationBiasJacobian& analytic = pim.bias_jacobian();
  EXPECT_TRUE((analytic.block<3, 3>(0, 3).isZero()));
  EXPECT_LT((numeric - analytic).cwiseAbs().maxCoeff(), 1e-7 * analytic.cwiseAbs().maxCoeff())
      << "numeric\n"
      << numeric << "\nanalytic\n"
      << analytic;
}

// Eq. (44) is the first-order correction: against re-integration with the
// changed bias, its error is quadratic in the change (a 10x smaller change
// leaves a ~100x smaller error) and small against the correction itself.
TEST(Preintegration, FirstOrderBiasCorrectionIsSecondOrderAccurate) {
  const sim::SplineTrajectory trajectory = Walk(30.0);
  const std::vector<ImuSample> samples = ExactSamples(trajectory, 400.0);
  const TimestampNs t_i = kStartNs + SecondsToNs(8.0), t_j = kStartNs + SecondsToNs(9.0);
  const Preintegration pim = Preintegration::Integrate(samples, t_i, t_j, ImuBias(), ImuNoise());
  Vec6 change;
  change << 0.02, -0.03, 0.01, 0.2, 0.1, -0.3;  // BMI085-class offsets (rad/s, m/s^2)
  double previous_error = 0;
  for (const double scale : {1.0, 0.1}) {
    const ImuBias bias = ImuBias::FromVector(scale * change);
    const Preintegration exact = Preintegration::Integrate(samples, t_i, t_j, bias, ImuNoise());
    const Eigen::Matrix<double, 9, 1> correction =
        MeasurementError(pim,
                         pim.CorrectedDeltaRotation(bias),
                         pim.CorrectedDeltaVelocity(bias),
                         pim.CorrectedDeltaPosition(bias));
    const Eigen::Matrix<double, 9, 1> error = MeasurementError(exact,
                                                               pim.CorrectedDeltaRotation(bias),
                                                               pim.CorrectedDeltaVelocity(bias),
                                                               pim.CorrectedDeltaPosition(bias));
    EXPECT_LT(error.norm(), 0.02 * correction.norm()) << "scale " << scale;
    if (scale < 1.0) {
      EXPECT_GT(previous_error / error.norm(), 50.0);
      EXPECT_LT(previous_error / error.norm(), 200.0);
    }
    previous_error = error.norm();
  }
}

// The propagated covariance against Monte Carlo: 500 runs of noisy samples
// (BMI085 white noise, 400 Hz) over a 1.2 s walking interval. The error of each
// run against the noise-free preintegration has NEES e^T Sigma^-1 e with mean
// 9 if Sigma is right; the mean of 500 runs has standard deviation
// sqrt(2 * 9 / 500) = 0.19, so a 4-sigma band is +-0.76. Each diagonal sample
// variance has relative standard deviation sqrt(2 / 500) = 6.3%: 4 sigma is
// 25%.
TEST(Preintegration, CovarianceMatchesMonteCarlo) {
  const sim::SplineTrajectory trajectory = Walk(30.0);
  const double rate = 400.0;
  const ImuNoise noise;
  const std::vector<ImuSample> exact = ExactSamples(trajectory, rate);
  const TimestampNs t_i = kStartNs + SecondsToNs(20.02), t_j = kStartNs + SecondsToNs(21.23);
  const Preintegration reference = Preintegration::Integrate(exact, t_i, t_j, ImuBias(), noise);
  const Mat9 covariance = reference.covariance();
  const Mat9 information = covariance.inverse();
  constexpr int kRuns = 500;
  double nees_sum = 0;
  Mat9 scatter = Mat9::Zero();
  for (int run = 0; run < kRuns; ++run) {
    const std::vector<ImuSample> noisy = AddWhiteNoise(exact, noise, rate, test::Rng());
    const Preintegration pim = Preintegration::Integrate(noisy, t_i, t_j, ImuBias(), noise);
    const Eigen::Matrix<double, 9, 1> e = MeasurementError(
        reference, pim.delta_rotation(), pim.delta_velocity(), pim.delta_position());
    nees_sum += e.dot(information * e);
    scatter += e * e.transpose();
  }
  scatter /= kRuns;
  EXPECT_NEAR(nees_sum / kRuns, 9.0, 0.76);
  for (int d = 0; d < 9; ++d) {
    EXPECT_NEAR(scatter(d, d) / covariance(d, d), 1.0, 0.25) << "component " << d;
  }
}

TEST(Preintegration, BadSamplesThrowInputErrorNamingTheTimes) {
  const sim::SplineTrajectory trajectory = Walk(30.0);
  std::vector<ImuSample> samples = ExactSamples(trajectory, 400.0);
  const TimestampNs t_i = kStartNs + SecondsToNs(5.0), t_j = kStartNs + SecondsToNs(6.0);
  // Not covered: the interval runs past the last sample.
  EXPECT_TRUE(test::ThrowsInputError(
      [&] {
        Preintegration::Integrate(samples, t_i, trajectory.end_ns() + 1, ImuBias(), ImuNoise());
      },
      {"do not cover", FormatNsAsSeconds(trajectory.end_ns() + 1)}));
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { Preintegration::Integrate({}, t_i, t_j, ImuBias(), ImuNoise()); }, {"none"}));
  // A 0.1 s gap inside the interval.
  std::vector<ImuSample> gap;
  for (const ImuSample& m : samples) {
    if (m.t_ns <= kStartNs + SecondsToNs(5.4) || m.t_ns >= kStartNs + SecondsToNs(5.5)) {
      gap.push_back(m);
    }
  }
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { Preintegration::Integrate(gap, t_i, t_j, ImuBias(), ImuNoise()); },
      {"IMU gap of 0.1000 s",
       FormatNsAsSeconds(kStartNs + SecondsToNs(5.4)),
       FormatNsAsSeconds(t_i)}));
  // The same gap with a larger allowed gap integrates.
  PreintegrationOptions lenient;
  lenient.max_sample_gap_s = 0.2;
  EXPECT_NO_THROW(Preintegration::Integrate(gap, t_i, t_j, ImuBias(), ImuNoise(), lenient));
  // A repeated stamp.
  std::vector<ImuSample> repeated = samples;
  const size_t k = 2200;  // 5.5 s
  repeated[k + 1].t_ns = repeated[k].t_ns;
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { Preintegration::Integrate(repeated, t_i, t_j, ImuBias(), ImuNoise()); },
      {"not in increasing time order", FormatNsAsSeconds(repeated[k].t_ns)}));
}

}  // namespace
}  // namespace lisfm
