#include "lio/pose_slam/imu_factors.h"

#include <ceres/gradient_checker.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/product_manifold.h>
#include <ceres/solver.h>
#include <ceres/sphere_manifold.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <vector>

#include "lio/pose_slam/imu_preintegration.h"
#include "lio/pose_slam/stationary_detection.h"
#include "sim/imu_simulator.h"
#include "sim/motion.h"
#include "tests/common/sim_walks.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

const Vec3 kGravity(0, 0, -sim::kGravity);
constexpr TimestampNs kStartNs = 1'000'000'000'000LL;  // 1000 s
constexpr double kRate = 400.0;                        // Hz

// The pose block's manifold in these tests: unit quaternion (Eigen order) and
// translation. The factors do not depend on the choice of retraction.
using PoseManifold =
    ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>;

// A closed 12 m x 8 m walk of 30 s with exact rests at the start, middle and end.
sim::SplineTrajectory Walk(std::vector<sim::StationaryPeriod>* rests = nullptr) {
  sim::WalkingRoute route;
  route.waypoints = {Vec3(0, 0, 1.4), Vec3(12, 0, 1.4), Vec3(12, 8, 1.4), Vec3(0, 8, 1.4)};
  route.closed = true;
  return sim::GenerateWalking(route, 30.0, kStartNs, 7, ThreeStopWalk(), rests);
}

// Samples at 400 Hz: exact, plus a constant bias and BMI085 white noise when asked.
std::vector<ImuSample> Samples(const sim::SplineTrajectory& trajectory,
                               const ImuBias& bias,
                               bool noisy) {
  const ImuNoise noise;
  std::normal_distribution<double> normal(0.0, 1.0);
  const double sigma_g = noise.gyroscope_noise_density * std::sqrt(kRate);
  const double sigma_a = noise.accelerometer_noise_density * std::sqrt(kRate);
  std::vector<ImuSample> samples;
  for (int64_t k = 0;; ++k) {
    const TimestampNs t = trajectory.start_ns() + k * 2'500'000;
    if (t > trajectory.end_ns()) break;
    ImuSample m = sim::ExactImu(trajectory, t);
    m.gyro += bias.gyro;
    m.accel += bias.accel;
    if (noisy) {
      for (int a = 0; a < 3; ++a) m.gyro(a) += sigma_g * normal(test::Rng());
      for (int a = 0; a < 3; ++a) m.accel(a) += sigma_a * normal(test::Rng());
    }
    samples.push_back(m);
  }
  return samples;
}

// The parameter blocks of one keyframe.
struct State {
  double pose[7];
  double velocity[3];
};

void ToBlock(const SE3& pose, double* block) {
  Eigen::Map<Eigen::Vector4d> quaternion(block);
  Eigen::Map<Vec3> translation(block + 4);
  quaternion = pose.rotation().coeffs();
  translation = pose.translation();
}

State TrueState(const sim::SplineTrajectory& trajectory, TimestampNs t_ns) {
  const sim::TrajectorySample s = trajectory.Evaluate(t_ns);
  State state;
  ToBlock(s.world_from_imu, state.pose);
  Eigen::Map<Vec3>(state.velocity) = s.velocity_world;
  return state;
}

SE3 PoseOf(const State& state) {
  return SE3(Quat(state.pose[3], state.pose[0], state.pose[1], state.pose[2]),
             Vec3(state.pose[4], state.pose[5], state.pose[6]));
}

Eigen::VectorXd Evaluate(const ceres::CostFunction& cost, const std::vector<double*>& blocks) {
  Eigen::VectorXd residuals(cost.num_residuals());
  EXPECT_TRUE(cost.Evaluate(blocks.data(), residuals.data(), nullptr));
  return residuals;
}

// Autodiff Jacobians against Ceres' numeric differentiation in the tangent
// spaces (relative precision 1e-6: central differences of smooth residuals).
void ExpectJacobiansMatchNumeric(const ceres::CostFunction& cost,
                                 const std::vector<const ceres::Manifold*>& manifolds,
                                 const std::vector<double*>& blocks) {
  const ceres::GradientChecker checker(&cost, &manifolds, ceres::NumericDiffOptions());
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(blocks.data(), 1e-6, &results)) << results.error_log;
}

// At the true states and bias the whitened residual is at the integration
// error (~1e-6 relative against ~1e-4 noise): far below one sigma. With a
// constant bias in the samples and bias_hat = 0, Eq. (44) corrects the
// measurement to the true bias (first order; measured whitened residuals
// ~0.01, bound 0.1), while leaving the bias block at zero costs ~42 sigmas.
TEST(ImuFactor, VanishesAtTheTrueStatesAndBias) {
  const sim::SplineTrajectory trajectory = Walk();
  ImuBias true_bias;
  true_bias.gyro = Vec3(2e-3, -1.5e-3, 1e-3);  // rad/s
  true_bias.accel = Vec3(0.05, -0.04, 0.03);   // m/s^2
  const std::vector<ImuSample> exact = Samples(trajectory, ImuBias(), false);
  const std::vector<ImuSample> biased = Samples(trajectory, true_bias, false);
  for (double t_s = 3.3; t_s < 26.0; t_s += 2.9) {
    SCOPED_TRACE("t " + std::to_string(t_s));
    const TimestampNs t_i = kStartNs + SecondsToNs(t_s), t_j = t_i + SecondsToNs(1.1);
    State i = TrueState(trajectory, t_i), j = TrueState(trajectory, t_j);
    {
      const Preintegration pim = Preintegration::Integrate(exact, t_i, t_j, ImuBias(), ImuNoise());
      std::unique_ptr<ceres::CostFunction> cost(ImuFactor::Create(pim, kGravity));
      Vec6 bias = Vec6::Zero();
      EXPECT_LT(Evaluate(*cost, {i.pose, i.velocity, j.pose, j.velocity, bias.data()}).norm(),
                0.01);
    }
    const Preintegration pim = Preintegration::Integrate(biased, t_i, t_j, ImuBias(), ImuNoise());
    std::unique_ptr<ceres::CostFunction> cost(ImuFactor::Create(pim, kGravity));
    Vec6 bias = true_bias.Vector();
    EXPECT_LT(Evaluate(*cost, {i.pose, i.velocity, j.pose, j.velocity, bias.data()}).norm(), 0.1);
    bias.setZero();
    EXPECT_GT(Evaluate(*cost, {i.pose, i.velocity, j.pose, j.velocity, bias.data()}).norm(), 10.0);
  }
}

TEST(ImuFactor, JacobiansMatchNumericDifferentiation) {
  const sim::SplineTrajectory trajectory = Walk();
  const std::vector<ImuSample> samples = Samples(trajectory, ImuBias(), true);
  const PoseManifold pose_manifold;
  ImuBias bias_hat;
  bias_hat.gyro = Vec3(1e-3, 2e-3, -1e-3);
  bias_hat.accel = Vec3(0.02, -0.03, 0.01);
  for (double t_s = 4.0; t_s < 26.0; t_s += 5.3) {
    const TimestampNs t_i = kStartNs + SecondsToNs(t_s), t_j = t_i + SecondsToNs(0.9);
    const Preintegration pim = Preintegration::Integrate(samples, t_i, t_j, bias_hat, ImuNoise());
    std::unique_ptr<ceres::CostFunction> cost(ImuFactor::Create(pim, kGravity));
    // Away from the optimum (random pose, velocity and bias offsets), where
    // every residual and Jacobian entry is non-trivial.
    State i = TrueState(trajectory, t_i), j = TrueState(trajectory, t_j);
    for (State* s : {&i, &j}) {
      ToBlock(PoseOf(*s) * test::RandomPose(0.05, 0.1), s->pose);
      Eigen::Map<Vec3>(s->velocity) += 0.1 * Vec3::Random();
    }
    Vec6 bias = bias_hat.Vector() + 0.01 * Vec6::Random();
    ExpectJacobiansMatchNumeric(*cost,
                                {&pose_manifold, nullptr, &pose_manifold, nullptr, nullptr},
                                {i.pose, i.velocity, j.pose, j.velocity, bias.data()});
  }
}

// With the gravity direction u as a block: at u = g / |g| the residuals are
// ImuFactor's; a tilted u changes them (gravity enters e_v and e_p); an extra
// covariance weakens them; the Jacobians (u on the sphere) match numeric ones.
TEST(ImuGravityFactor, MatchesImuFactorAndItsJacobians) {
  const sim::SplineTrajectory trajectory = Walk();
  const std::vector<ImuSample> samples = Samples(trajectory, ImuBias(), true);
  const PoseManifold pose_manifold;
  const ceres::SphereManifold<3> sphere;
  const TimestampNs t_i = kStartNs + SecondsToNs(6.0), t_j = t_i + SecondsToNs(0.8);
  const Preintegration pim = Preintegration::Integrate(samples, t_i, t_j, ImuBias(), ImuNoise());
  std::unique_ptr<ceres::CostFunction> plain(ImuFactor::Create(pim, kGravity));
  std::unique_ptr<ceres::CostFunction> with_gravity(
      ImuGravityFactor::Create(pim, sim::kGravity));
  State i = TrueState(trajectory, t_i), j = TrueState(trajectory, t_j);
  ToBlock(PoseOf(j) * test::RandomPose(0.02, 0.05), j.pose);
  Vec6 bias = 0.01 * Vec6::Random();
  Vec3 down(0, 0, -1);
  const Eigen::VectorXd r_plain =
      Evaluate(*plain, {i.pose, i.velocity, j.pose, j.velocity, bias.data()});
  const Eigen::VectorXd r_gravity =
      Evaluate(*with_gravity, {i.pose, i.velocity, j.pose, j.velocity, bias.data(), down.data()});
  EXPECT_LT((r_plain - r_gravity).norm(), 1e-9 * r_plain.norm());
  Vec3 tilted = Vec3(0.01, 0, -1).normalized();
  EXPECT_GT((Evaluate(*with_gravity,
                      {i.pose, i.velocity, j.pose, j.velocity, bias.data(), tilted.data()}) -
             r_gravity)
                .norm(),
            1.0);
  Mat9 extra = Mat9::Zero();
  extra.diagonal().setConstant(1e-2);
  std::unique_ptr<ceres::CostFunction> weak(ImuGravityFactor::Create(pim, sim::kGravity, extra));
  EXPECT_LT(
      Evaluate(*weak, {i.pose, i.velocity, j.pose, j.velocity, bias.data(), down.data()}).norm(),
      0.1 * r_gravity.norm());
  ExpectJacobiansMatchNumeric(
      *with_gravity,
      {&pose_manifold, nullptr, &pose_manifold, nullptr, nullptr, &sphere},
      {i.pose, i.velocity, j.pose, j.velocity, bias.data(), tilted.data()});
}

TEST(BiasRandomWalkFactor, WhitensTheBiasChangeByTheRandomWalk) {
  ImuNoise noise;
  noise.gyroscope_random_walk = 2e-5;
  noise.accelerometer_random_walk = 4e-4;
  std::unique_ptr<ceres::CostFunction> cost(BiasRandomWalkFactor::Create(noise, 4.0));
  Vec6 b_k, b_k1;
  b_k << 1e-3, 2e-3, 3e-3, 0.1, 0.2, 0.3;
  b_k1 = b_k;
  b_k1(1) += 4e-5;    // one sigma of the gyro walk over 4 s: 2e-5 * sqrt(4)
  b_k1(5) -= 1.6e-3;  // two sigma of the accelerometer walk: 2 * 4e-4 * sqrt(4)
  Vec6 expected = Vec6::Zero();
  expected(1) = 1.0;
  expected(5) = -2.0;
  EXPECT_LT((Evaluate(*cost, {b_k.data(), b_k1.data()}) - expected).norm(), 1e-9);
  ExpectJacobiansMatchNumeric(*cost, {nullptr, nullptr}, {b_k.data(), b_k1.data()});
}

TEST(ZeroVelocityFactors, ResidualsAndJacobians) {
  ZeroVelocityOptions options;
  options.velocity_sigma = 1e-3;
  options.rotation_sigma = 1e-4;
  options.translation_sigma = 2e-4;
  ASSERT_TRUE(options.Check());
  std::unique_ptr<ceres::CostFunction> velocity_cost(ZeroVelocityFactor::Create(options));
  Vec3 velocity(2e-3, 0, -1e-3);
  EXPECT_LT((Evaluate(*velocity_cost, {velocity.data()}) - Vec3(2, 0, -1)).norm(), 1e-12);
  ExpectJacobiansMatchNumeric(*velocity_cost, {nullptr}, {velocity.data()});

  // Pose j = pose i moved by [0.5, -1, 1] 1e-4 rad and [4, -2, 1] 1e-4 m in the body frame.
  std::unique_ptr<ceres::CostFunction> pose_cost(StationaryPoseFactor::Create(options));
  const SE3 pose_i = test::RandomPose();
  const SE3 pose_j = pose_i * SE3(so3::Exp(Vec3(0.5e-4, -1e-4, 1e-4)), Vec3(4e-4, -2e-4, 1e-4));
  double block_i[7], block_j[7];
  ToBlock(pose_i, block_i);
  ToBlock(pose_j, block_j);
  Vec6 expected;
  expected << 0.5, -1, 1, 2, -1, 0.5;
  EXPECT_LT((Evaluate(*pose_cost, {block_i, block_j}) - expected).norm(), 1e-6);
  const PoseManifold pose_manifold;
  ExpectJacobiansMatchNumeric(*pose_cost, {&pose_manifold, &pose_manifold}, {block_i, block_j});

  ZeroVelocityOptions bad;
  bad.rotation_sigma = 0.0;
  EXPECT_FALSE(bad.Check());
}

// A small problem on the first 18 s of the walk (start rest 0-2.8 s, walking,
// middle rest 13.7-16.3 s, walking), keyframes every 0.5 s: IMU factors with
// one constant bias, zero-velocity factors at the rest keyframes, the first
// pose held at the truth (gauge, gravity direction). Samples carry BMI085
// white noise and a constant bias. The states start from the truth perturbed
// (2 deg, 10 cm, 0.1 m/s) and the bias from zero.
//  - The rest keyframes stay together: within a rest the poses differ by less
//    than 1e-3 rad and 1 mm (the zero-velocity sigmas are 1e-4 rad / 1e-4 m
//    per interval, sqrt(5) 1e-4 over a rest's 5 intervals: the bounds are
//    ~4.5 sigma) and the velocities are below 5 sigma_v.
//  - The bias comes back: the start rest alone fixes it to sigma_g / sqrt(T)
//    = 2.4e-4 / sqrt(2.8) = 1.4e-4 rad/s and 1.7e-3 / sqrt(2.8) = 1.0e-3
//    m/s^2 per axis; the bounds are ~4 sigma of that.
TEST(ImuProblem, ZeroVelocityHoldsTheRestsAndRecoversAConstantBias) {
  std::vector<sim::StationaryPeriod> rests;
  const sim::SplineTrajectory trajectory = Walk(&rests);
  ASSERT_EQ(rests.size(), 3u);
  ImuBias true_bias;
  true_bias.gyro = Vec3(3e-3, -2e-3, 4e-3);
  true_bias.accel = Vec3(0.05, -0.08, 0.06);
  const std::vector<ImuSample> samples = Samples(trajectory, true_bias, true);
  std::vector<StationaryPeriod> periods;
  for (const sim::StationaryPeriod& r : rests) periods.push_back({r.start_ns, r.end_ns});

  std::vector<TimestampNs> times;
  for (int k = 0; k <= 36; ++k) times.push_back(kStartNs + k * 500'000'000LL);
  std::vector<State> states;
  for (const TimestampNs t : times) {
    State s = TrueState(trajectory, t);
    if (!states.empty()) {
      ToBlock(PoseOf(s) * test::RandomPose(0.035, 0.1), s.pose);
      Eigen::Map<Vec3>(s.velocity) += 0.1 * Vec3::Random();
    }
    states.push_back(s);
  }
  Vec6 bias = Vec6::Zero();

  ceres::Problem problem;
  const ZeroVelocityOptions zero_velocity;
  for (size_t k = 0; k + 1 < times.size(); ++k) {
    const Preintegration pim =
        Preintegration::Integrate(samples, times[k], times[k + 1], ImuBias(), ImuNoise());
    problem.AddResidualBlock(ImuFactor::Create(pim, kGravity),
                             nullptr,
                             states[k].pose,
                             states[k].velocity,
                             states[k + 1].pose,
                             states[k + 1].velocity,
                             bias.data());
    if (PairInsideStationaryPeriod(periods, times[k], times[k + 1])) {
      problem.AddResidualBlock(
          StationaryPoseFactor::Create(zero_velocity), nullptr, states[k].pose, states[k + 1].pose);
    }
  }
  int num_zero_velocity = 0;
  for (size_t k = 0; k < times.size(); ++k) {
    problem.SetManifold(states[k].pose, new PoseManifold);
    if (StationaryPeriodIndex(periods, times[k]) >= 0) {
      problem.AddResidualBlock(
          ZeroVelocityFactor::Create(zero_velocity), nullptr, states[k].velocity);
      ++num_zero_velocity;
    }
  }
  EXPECT_EQ(num_zero_velocity, 6 + 5);  // 0-2.5 s and 14-16 s
  problem.SetParameterBlockConstant(states[0].pose);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.max_num_iterations = 100;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.FullReport();

  EXPECT_LT((bias.head<3>() - true_bias.gyro).cwiseAbs().maxCoeff(), 6e-4);
  EXPECT_LT((bias.tail<3>() - true_bias.accel).cwiseAbs().maxCoeff(), 4e-3);
  for (const StationaryPeriod& period : periods) {
    int first = -1;
    for (size_t k = 0; k < times.size(); ++k) {
      if (!period.Contains(times[k])) continue;
      EXPECT_LT(Eigen::Map<const Vec3>(states[k].velocity).norm(), 5e-3);
      if (first < 0) {
        first = static_cast<int>(k);
        continue;
      }
      EXPECT_TRUE(test::PosesNear(PoseOf(states[k]), PoseOf(states[first]), 1e-3, 1e-3))
          << "keyframe " << k << " against " << first;
    }
  }
}

}  // namespace
}  // namespace lisfm
