#include "lio/pose_slam/pose_graph.h"

#include <ceres/covariance.h>
#include <ceres/manifold_test_utils.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <iostream>
#include <memory>
#include <vector>

#include "core/errors.h"
#include "lio/pose_slam/pose_graph_factors.h"
#include "lio/pose_slam/pose_manifold.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using Block = Eigen::Matrix<double, 7, 1>;

Block ToBlock(const SE3& pose) {
  Block block;
  PoseManifold::ToBlock(pose, block.data());
  return block;
}

Vec6 RandomTangent(double scale) {
  std::normal_distribution<double> normal(0.0, scale);
  Vec6 xi;
  for (int k = 0; k < 6; ++k) xi(k) = normal(test::Rng());
  return xi;
}

Mat6 RandomInformation() {
  std::normal_distribution<double> normal(0.0, 1.0);
  Mat6 a;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) a(r, c) = normal(test::Rng());
  }
  return 10.0 * (a * a.transpose() + Mat6::Identity());
}

// (R Exp(omega), t + R v): PoseManifold's retraction, spelled out.
SE3 Retract(const SE3& pose, const Vec6& xi) {
  return SE3(pose.rotation() * so3::Exp(xi.head<3>()),
             pose.translation() + pose.rotation() * xi.tail<3>());
}

TEST(PoseManifold, InvariantsHold) {
  using namespace ceres;  // NOLINT: the macro names Ceres' matchers unqualified
  PoseManifold manifold;
  for (int trial = 0; trial < 20; ++trial) {
    const VecX x = ToBlock(test::RandomPose());
    const VecX delta = RandomTangent(0.3);
    VecX y = ToBlock(test::RandomPose());
    // Plus(x, Minus(y, x)) returns the quaternion nearest x: take y's sign in x's hemisphere.
    if (x.head<4>().dot(y.head<4>()) < 0.0) y.head<4>() *= -1.0;
    // 1e-9: Ceres' numeric checks of Plus(x, Minus(y, x)) == y etc. in doubles.
    EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, 1e-9);
  }
}

TEST(PoseManifold, PlusIsTheRightPerturbation) {
  PoseManifold manifold;
  const SE3 pose = test::RandomPose();
  const Vec6 xi = RandomTangent(0.5);
  Block out;
  manifold.Plus(ToBlock(pose).data(), xi.data(), out.data());
  EXPECT_TRUE(
      test::PosesNear(PoseManifold::FromBlock(out.data()), Retract(pose, xi), 1e-14, 1e-14));
  // First order agreement with T * Exp(xi) on SE(3): the difference is O(|xi|^2).
  const Vec6 small = 1e-4 * xi / xi.norm();
  manifold.Plus(ToBlock(pose).data(), small.data(), out.data());
  EXPECT_TRUE(
      test::PosesNear(PoseManifold::FromBlock(out.data()), pose * SE3::Exp(small), 1e-14, 1e-7));
}

// Ceres' covariance lives in the tangent space through PlusJacobian /
// MinusJacobian; both against central differences.
TEST(PoseManifold, JacobiansMatchNumericDifferences) {
  PoseManifold manifold;
  for (int trial = 0; trial < 10; ++trial) {
    const Block x = ToBlock(test::RandomPose());
    Eigen::Matrix<double, 7, 6, Eigen::RowMajor> plus_jacobian;
    ASSERT_TRUE(manifold.PlusJacobian(x.data(), plus_jacobian.data()));
    const MatX numeric_plus = test::NumericJacobian(
        [&](const VecX& delta) {
          Block out;
          manifold.Plus(x.data(), delta.data(), out.data());
          return VecX(out);
        },
        VecX::Zero(6));
    // Central differences with step 1e-6: truncation O(1e-12), rounding O(1e-10).
    EXPECT_LT((MatX(plus_jacobian) - numeric_plus).cwiseAbs().maxCoeff(), 1e-8);

    Eigen::Matrix<double, 6, 7, Eigen::RowMajor> minus_jacobian;
    ASSERT_TRUE(manifold.MinusJacobian(x.data(), minus_jacobian.data()));
    const MatX numeric_minus = test::NumericJacobian(
        [&](const VecX& y) {
          Vec6 out;
          manifold.Minus(y.data(), x.data(), out.data());
          return VecX(out);
        },
        VecX(x));
    EXPECT_LT((MatX(minus_jacobian) - numeric_minus).cwiseAbs().maxCoeff(), 1e-8);
  }
}

// The autodiff Jacobians in the tangent space (ambient Jacobian times
// PlusJacobian, as Ceres forms them) against central differences of the
// residual along Plus(x, delta).
TEST(PoseGraphFactors, TangentJacobiansMatchNumericDifferences) {
  PoseManifold manifold;
  for (int trial = 0; trial < 5; ++trial) {
    const SE3 z = test::RandomPose();
    const std::vector<Block> blocks = {ToBlock(test::RandomPose()), ToBlock(test::RandomPose())};
    const std::unique_ptr<ceres::CostFunction> chordal(ChordalFactor3::Create(z, 2.0, 3.0));
    const std::unique_ptr<ceres::CostFunction> relative(
        RelativePoseFactor::Create(z, RandomInformation().llt().matrixL().transpose()));
    for (const ceres::CostFunction* cost : {chordal.get(), relative.get()}) {
      const int m = cost->num_residuals();
      const auto evaluate = [&](const std::vector<Block>& x, double** jacobians) {
        const double* parameters[2] = {x[0].data(), x[1].data()};
        VecX r(m);
        EXPECT_TRUE(cost->Evaluate(parameters, r.data(), jacobians));
        return r;
      };
      std::vector<Eigen::Matrix<double, Eigen::Dynamic, 7, Eigen::RowMajor>> ambient(
          2, Eigen::Matrix<double, Eigen::Dynamic, 7, Eigen::RowMajor>(m, 7));
      double* jacobians[2] = {ambient[0].data(), ambient[1].data()};
      evaluate(blocks, jacobians);
      for (int b = 0; b < 2; ++b) {
        Eigen::Matrix<double, 7, 6, Eigen::RowMajor> plus_jacobian;
        manifold.PlusJacobian(blocks[b].data(), plus_jacobian.data());
        const MatX analytic = ambient[b] * plus_jacobian;
        const MatX numeric = test::NumericJacobian(
            [&](const VecX& delta) {
              std::vector<Block> moved = blocks;
              manifold.Plus(blocks[b].data(), delta.data(), moved[b].data());
              return evaluate(moved, nullptr);
            },
            VecX::Zero(6));
        // Step 1e-6 central differences: O(1e-12) truncation, O(1e-10) rounding
        // relative to the largest entry.
        EXPECT_LT((analytic - numeric).cwiseAbs().maxCoeff(), 1e-7 * analytic.cwiseAbs().maxCoeff())
            << "block " << b << "\nanalytic\n"
            << analytic << "\nnumeric\n"
            << numeric;
      }
    }
  }
}

// ||r||^2 of the chordal factors is SE-Sync's term; the 2D factor equals the 3D
// one on planar poses.
TEST(PoseGraphFactors, ChordalResidualIsTheSeSyncTerm) {
  const double kappa = 2.5, tau = 0.7;
  const SE3 a = test::RandomPose(), b = test::RandomPose(), z = test::RandomPose();
  const Mat3 Ra = a.RotationMatrix();
  const double expected =
      kappa * (b.RotationMatrix() - Ra * z.RotationMatrix()).squaredNorm() +
      tau * (b.translation() - a.translation() - Ra * z.translation()).squaredNorm();
  const Block block_a = ToBlock(a), block_b = ToBlock(b);
  Eigen::Matrix<double, 6, 1> r3;
  ChordalFactor3(z, kappa, tau)(block_a.data(), block_b.data(), r3.data());
  EXPECT_NEAR(r3.squaredNorm(), expected, 1e-12 * expected);

  const double pa[3] = {1.0, -2.0, 0.3}, pb[3] = {0.5, 4.0, -2.9}, pz[3] = {0.2, 1.1, 2.8};
  const auto planar = [](const double* p) {
    return SE3(Quat(Eigen::AngleAxisd(p[2], Vec3::UnitZ())), Vec3(p[0], p[1], 0.0));
  };
  Eigen::Matrix<double, 3, 1> r2;
  ChordalFactor2(pz[0], pz[1], pz[2], kappa, tau)(pa, pb, r2.data());
  const Block planar_a = ToBlock(planar(pa)), planar_b = ToBlock(planar(pb));
  ChordalFactor3(planar(pz), kappa, tau)(planar_a.data(), planar_b.data(), r3.data());
  EXPECT_NEAR(r2.squaredNorm(), r3.squaredNorm(), 1e-12 * r3.squaredNorm());
}

// With T_i^-1 T_j = Z (+) e, the whitened error is L e.
TEST(PoseGraphFactors, RelativePoseErrorIsTheRightPerturbation) {
  const SE3 a = test::RandomPose(), z = test::RandomPose();
  const Vec6 e = RandomTangent(0.2);
  const SE3 b = a * Retract(z, e);
  const Mat6 information = RandomInformation();
  const Mat6 L = information.llt().matrixL().transpose();
  const Block block_a = ToBlock(a), block_b = ToBlock(b);
  Vec6 r;
  RelativePoseFactor(z, L)(block_a.data(), block_b.data(), r.data());
  EXPECT_LT((r - L * e).norm(), 1e-10 * (L * e).norm());
  EXPECT_NEAR(r.squaredNorm(), e.dot(information * e), 1e-9 * e.dot(information * e));
}

// Noise-free relative poses on a loop: LM from a perturbed start returns the
// true poses (pose 0 is the gauge, held at the truth).
TEST(PoseGraph, RecoversConsistentPosesFromPerturbedStart) {
  const int n = 12;
  std::vector<SE3> truth;
  for (int k = 0; k < n; ++k) {
    const double angle = 2.0 * M_PI * k / n;
    truth.push_back(SE3(so3::Exp(Vec3(0.1 * std::sin(angle), 0.05, angle)),
                        Vec3(5.0 * std::cos(angle), 5.0 * std::sin(angle), 0.3 * k)));
  }
  PoseGraph graph;
  for (int k = 0; k < n; ++k)
    graph.AddPose(k == 0 ? truth[0] : Retract(truth[k], RandomTangent(0.1)));
  for (int k = 0; k < n; ++k) {
    for (const int step : {1, 3}) {
      const int j = (k + step) % n;
      graph.AddRelativePoseFactor(k, j, truth[k].Inverse() * truth[j], RandomInformation());
    }
  }
  PoseGraphSolverOptions options;
  const PoseGraphSolveSummary summary = graph.Solve(options);
  EXPECT_TRUE(summary.converged) << summary.message;
  EXPECT_TRUE(graph.IsPoseConstant(0));  // the default gauge
  // Exact data: the optimum is the truth to solver precision.
  for (int k = 0; k < n; ++k) EXPECT_TRUE(test::PosesNear(graph.Pose(k), truth[k], 1e-8, 1e-8));
  EXPECT_LT(graph.Objective(), 1e-14);
  EXPECT_THAT(summary.linear_solver, ::testing::HasSubstr("SPARSE_NORMAL_CHOLESKY"));
}

// One factor from the fixed pose 0: pose 1's covariance on the right
// perturbation is exactly the measurement's covariance (the error's Jacobian
// with respect to pose 1's tangent is the identity at the optimum).
TEST(PoseGraph, CovarianceOfOneHopIsTheMeasurementCovariance) {
  const SE3 a = test::RandomPose(), z = test::RandomPose();
  const Mat6 information = RandomInformation();
  PoseGraph graph;
  graph.AddPose(a);
  graph.AddPose(a * z);
  graph.SetPoseConstant(0);
  graph.AddRelativePoseFactor(0, 1, z, information);
  const std::vector<MatX> covariances = graph.PoseCovariances({0, 1});
  ASSERT_EQ(covariances.size(), 2u);
  EXPECT_EQ(covariances[0], MatX::Zero(6, 6));
  const Mat6 expected = information.inverse();
  EXPECT_LT((covariances[1] - expected).cwiseAbs().maxCoeff(),
            1e-9 * expected.cwiseAbs().maxCoeff());
}

// The covariances are the same bits whatever the heap's state. The heap is
// perturbed by live blocks of 16 to 1024 bytes before each computation (the
// addresses, hence the alignment, of SuiteSparse's later allocations move).
// Control: ceres::Covariance with SuiteSparseQR called directly on the same
// problem under the same perturbations; where its bits move, this machine's
// BLAS is alignment-sensitive and the test shows PoseCovariances is not.
TEST(PoseGraph, CovariancesDoNotDependOnTheHeap) {
  const int n = 300;
  std::vector<SE3> truth;
  for (int k = 0; k < n; ++k) {
    const double angle = 2.0 * M_PI * k / n;
    truth.push_back(SE3(so3::Exp(Vec3(0.1 * std::sin(3 * angle), 0.05, angle)),
                        Vec3(20.0 * std::cos(angle), 20.0 * std::sin(angle), 0.1 * k)));
  }
  PoseGraph graph;
  for (int k = 0; k < n; ++k) graph.AddPose(Retract(truth[k], RandomTangent(0.01)));
  graph.SetPoseConstant(0);
  for (int k = 0; k < n; ++k) {
    for (const int step : {1, 2, 5, 37}) {
      const int j = (k + step) % n;
      graph.AddRelativePoseFactor(k, j, truth[k].Inverse() * truth[j], RandomInformation());
    }
  }
  const std::vector<int> probes = {n / 2, n - 1};
  auto direct = [&] {
    ceres::Covariance::Options options;
    options.algorithm_type = ceres::SPARSE_QR;
    ceres::Covariance covariance(options);
    const double* block = graph.PoseBlock(n - 1);
    const std::vector<std::pair<const double*, const double*>> blocks = {{block, block}};
    EXPECT_TRUE(covariance.Compute(blocks, &graph.problem()));
    Eigen::Matrix<double, 6, 6, Eigen::RowMajor> c;
    EXPECT_TRUE(covariance.GetCovarianceBlockInTangentSpace(block, block, c.data()));
    return c;
  };
  const std::vector<MatX> reference = graph.PoseCovariances(probes);
  const auto direct_reference = direct();
  std::vector<std::unique_ptr<char[]>> held;
  bool direct_moved = false;
  for (int trial = 1; trial <= 12; ++trial) {
    held.emplace_back(new char[16 * (trial % 4 + 1) + 64 * (trial % 16)]);
    const std::vector<MatX> covariances = graph.PoseCovariances(probes);
    ASSERT_EQ(covariances.size(), reference.size());
    for (size_t k = 0; k < probes.size(); ++k) {
      ASSERT_EQ(std::memcmp(covariances[k].data(), reference[k].data(), 36 * sizeof(double)), 0)
          << "trial " << trial << ", pose " << probes[k];
    }
    const auto d = direct();
    direct_moved |= std::memcmp(d.data(), direct_reference.data(), 36 * sizeof(double)) != 0;
  }
  std::cout << "ceres::Covariance without the aligned allocation "
            << (direct_moved ? "moved" : "did not move") << " with the heap\n";
}

// A gross outlier among consistent factors: with a Cauchy loss the estimate
// stays near the truth, and its squared residual (without the loss) flags it;
// removing it restores the exact solution.
TEST(PoseGraph, RobustLossAndFactorRemoval) {
  const int n = 8;
  std::vector<SE3> truth;
  for (int k = 0; k < n; ++k) truth.push_back(SE3(so3::Exp(Vec3(0, 0, 0.2 * k)), Vec3(k, 0, 0)));
  PoseGraph graph;
  for (const SE3& pose : truth) graph.AddPose(pose);
  const Mat6 information = 1e4 * Mat6::Identity();  // 1 cm, 0.01 rad
  RobustLossOptions cauchy;
  cauchy.kernel = "cauchy";
  cauchy.scale = 3.0;
  for (int k = 0; k < n; ++k) {
    for (const int step : {1, 2}) {
      if (k + step < n) {
        graph.AddRelativePoseFactor(
            k, k + step, truth[k].Inverse() * truth[k + step], information, cauchy);
      }
    }
  }
  const SE3 wrong = truth[2].Inverse() * truth[6] * SE3(Quat::Identity(), Vec3(1.0, 0.5, 0.0));
  const PoseGraph::FactorId outlier = graph.AddRelativePoseFactor(2, 6, wrong, information, cauchy);
  EXPECT_EQ(graph.num_factors(), 14);
  graph.Solve(PoseGraphSolverOptions());
  // 1.1 m of error against 14 factors of 1 cm: Cauchy keeps the poses within 2 cm.
  for (int k = 0; k < n; ++k) EXPECT_TRUE(test::PosesNear(graph.Pose(k), truth[k], 0.02, 0.02));
  EXPECT_GT(graph.SquaredResidual(outlier), 1e3);  // ~ (1 m / 1 cm)^2
  graph.RemoveFactor(outlier);
  EXPECT_EQ(graph.num_factors(), 13);
  graph.Solve(PoseGraphSolverOptions());
  for (int k = 0; k < n; ++k) EXPECT_TRUE(test::PosesNear(graph.Pose(k), truth[k], 1e-8, 1e-8));
}

TEST(PoseGraph, PlanarGraph) {
  PoseGraph graph(2);
  const auto planar = [](double x, double y, double theta) {
    return SE3(Quat(Eigen::AngleAxisd(theta, Vec3::UnitZ())), Vec3(x, y, 0.0));
  };
  const std::vector<SE3> truth = {
      planar(0, 0, 0), planar(1, 0, 1.5), planar(1, 2, 3.0), planar(-1, 2, -1.6)};
  graph.AddPose(truth[0]);
  graph.AddPose(planar(1.2, 0.1, 1.3));
  graph.AddPose(planar(0.8, 2.3, 2.8));
  graph.AddPose(planar(-1.1, 1.7, -1.9));
  for (int k = 0; k < 4; ++k) {
    const int j = (k + 1) % 4;
    graph.AddChordalFactor(k, j, truth[k].Inverse() * truth[j], 10.0, 5.0);
  }
  const PoseGraphSolveSummary summary = graph.Solve(PoseGraphSolverOptions());
  EXPECT_TRUE(summary.usable) << summary.message;
  for (int k = 0; k < 4; ++k) EXPECT_TRUE(test::PosesNear(graph.Pose(k), truth[k], 1e-8, 1e-8));
  // Planar graphs take no full-information 3D factor; a non-planar pose is a bug.
  EXPECT_THROW(graph.AddRelativePoseFactor(0, 1, truth[1], Mat6::Identity()), InternalError);
  EXPECT_THROW(graph.AddPose(test::RandomPose()), InternalError);
}

TEST(PoseGraph, OptionsCheck) {
  PoseGraphSolverOptions options;
  EXPECT_TRUE(options.Check());
  options.num_threads = 0;
  EXPECT_FALSE(options.Check());
  options.num_threads = -1;
  options.max_num_iterations = 0;
  EXPECT_FALSE(options.Check());
  RobustLossOptions loss;
  EXPECT_TRUE(loss.Check());
  loss.kernel = "tukey";
  EXPECT_FALSE(loss.Check());
}

}  // namespace
}  // namespace lisfm
