#include "icp/bayesian_icp.h"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "core/errors.h"
#include "icp/icp_covariance.h"
#include "icp/testing/scenes.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// Linear-Gaussian toy: r_i = a_i^T Log(T) - b_i with Gaussian noise sigma. The
// posterior over xi = Log(T) is N(xi_ls, sigma^2 (A^T A)^-1) (flat prior). The
// Jacobian a_i^T ignores the SE(3) right-Jacobian J_r^-1(xi) = I + O(|xi|); with
// |xi| ~ 1e-3 that is a 0.1 % effect.
class LinearGaussianModel : public SgldModel {
 public:
  LinearGaussianModel(Eigen::MatrixXd A, Eigen::VectorXd b) : A_(std::move(A)), b_(std::move(b)) {}
  size_t NumTerms() const override { return static_cast<size_t>(A_.rows()); }
  bool Term(size_t i, const SE3& T, double* residual, Eigen::Matrix<double, 1, 6>* J,
            double* weight) const override {
    *J = A_.row(static_cast<Eigen::Index>(i));
    *residual = J->dot(T.Log()) - b_(static_cast<Eigen::Index>(i));
    *weight = 1.0;
    return true;
  }
  const Eigen::MatrixXd& A() const { return A_; }
  const Eigen::VectorXd& b() const { return b_; }

 private:
  Eigen::MatrixXd A_;
  Eigen::VectorXd b_;
};

// The sampled covariance equals the analytic posterior within 10 % in every
// direction: the eigenvalues of S^-1/2 C S^-1/2 (C sampled, S true) lie in
// [0.9, 1.1]. 80k iterations at step 1 (lag-1 autocorrelation 0.5) give ~25k
// effective samples, i.e. a +-3 % sampling spread of those eigenvalues; the
// correlated, badly scaled A exercises the preconditioner and the mini-batches
// of 50 out of 2000 terms exercise the control variate.
// A long chain (80k iterations, every sample kept) with a negligible damping
// (100 rad / 100 m next to the toy models' information of ~1e6): its sample
// covariance is the exact posterior's within the tests' 10 %.
SgldOptions LongChainOptions() {
  SgldOptions options;
  options.num_iterations = 80000;
  options.burn_in = 1000;
  options.thinning = 1;
  options.batch_size = 50;
  options.step_size = 1.0;
  options.damping_sigma_rotation_rad = 100.0;
  options.damping_sigma_translation_m = 100.0;
  return options;
}

TEST(SampleSgld, LinearGaussianPosteriorCovariance) {
  const int n = 2000;
  const double sigma = 0.05;
  Mat6 mix = Mat6::Random();
  mix.diagonal().array() += 2.0;
  Vec6 col_scale;
  col_scale << 1.0, 3.0, 10.0, 0.5, 2.0, 5.0;
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd A(n, 6);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) {
    Vec6 a;
    for (int k = 0; k < 6; ++k) a(k) = g(test::Rng());
    A.row(i) = (mix * a).cwiseProduct(col_scale).transpose();
    b(i) = sigma * g(test::Rng());  // true xi = 0
  }
  const LinearGaussianModel model(A, b);
  const Mat6 info = A.transpose() * A / (sigma * sigma);
  const Mat6 true_cov = info.inverse();
  const Vec6 xi_ls = info.ldlt().solve(A.transpose() * b / (sigma * sigma));
  const SgldOptions options = LongChainOptions();
  const SgldResult r = SampleSgld(model, SE3::Exp(xi_ls), sigma, options);
  EXPECT_EQ(r.num_samples, 79000u);
  const Eigen::SelfAdjointEigenSolver<Mat6> s(true_cov);
  const Mat6 w = s.operatorInverseSqrt() * r.covariance * s.operatorInverseSqrt();
  const Vec6 ratios = Eigen::SelfAdjointEigenSolver<Mat6>(w).eigenvalues();
  EXPECT_GT(ratios.minCoeff(), 0.9) << ratios.transpose();
  EXPECT_LT(ratios.maxCoeff(), 1.1) << ratios.transpose();
  // The mean is the least-squares solution within 5 posterior standard deviations
  // of the mean estimate (~25k effective samples -> std/160).
  const Vec6 d = r.mean.Log() - xi_ls;
  EXPECT_LT(std::sqrt(d.dot(info * d)), 5.0 / 160.0 * 6.0);
}

// The Gaussian pose prior: with the data blind along one direction (the column of
// translation x zeroed, as along a corridor's axis), the posterior is
// N(S (A^T b / sigma^2 + Lambda xi0), S), S = (A^T A / sigma^2 + Lambda)^-1 (flat
// directions get the prior's variance, the others the data's). Same sampler
// settings and 10 % band as above (S here has condition ~1e4, which the
// preconditioner absorbs); the prior residual Log(mean^-1 T) differs from
// xi - xi0 by O(|xi| |xi0|) ~ 1e-6, far below the prior sigma 0.01.
TEST(SampleSgld, GaussianPriorFillsUnobservedDirection) {
  const int n = 2000;
  const double sigma = 0.05;
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd A(n, 6);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 6; ++k) A(i, k) = k == 3 ? 0.0 : g(test::Rng());
    b(i) = sigma * g(test::Rng());
  }
  const LinearGaussianModel model(A, b);
  Vec6 xi0;
  xi0 << 1e-3, -2e-3, 5e-4, 4e-3, -1e-3, 2e-3;
  PosePrior prior;
  prior.mean = SE3::Exp(xi0);
  prior.information = Vec6::Constant(1.0 / (0.01 * 0.01)).asDiagonal();
  const Mat6 info = A.transpose() * A / (sigma * sigma) + prior.information;
  const Mat6 true_cov = info.inverse();
  const Vec6 xi_map =
      info.ldlt().solve(A.transpose() * b / (sigma * sigma) + prior.information * xi0);
  const SgldOptions options = LongChainOptions();
  const SgldResult r = SampleSgld(model, SE3::Exp(xi_map), sigma, options, prior);
  const Eigen::SelfAdjointEigenSolver<Mat6> s(true_cov);
  const Mat6 w = s.operatorInverseSqrt() * r.covariance * s.operatorInverseSqrt();
  const Vec6 ratios = Eigen::SelfAdjointEigenSolver<Mat6>(w).eigenvalues();
  EXPECT_GT(ratios.minCoeff(), 0.9) << ratios.transpose();
  EXPECT_LT(ratios.maxCoeff(), 1.1) << ratios.transpose();
  // Along the unobserved axis: the prior's variance (1e-4 m^2), within 10 %.
  EXPECT_NEAR(r.covariance(3, 3), 1e-4, 1e-5);
  const Vec6 d = r.mean.Log() - xi_map;
  EXPECT_LT(std::sqrt(d.dot(info * d)), 5.0 / 160.0 * 6.0);
  // A prior that is not positive semi-definite is a programming error.
  PosePrior bad = prior;
  bad.information(0, 0) = -1.0;
  EXPECT_THROW(SampleSgld(model, SE3(), sigma, options, bad), InternalError);
}

// In a corridor the Bayesian posterior is wide along the axis (translation x)
// and tight across it, and wider along the axis than the closed form, which
// takes the accidental curvature of noisy normals for information. Measured with a
// Huber 0.1 m association and 24 cells (block tempering on: factors 0.67 / 1.33): axial
// variance 0.10 m^2 (Bayesian) vs 2.6e-6 m^2 (closed form), across 7e-7 m^2.
TEST(RegisterBayesian, CorridorAxisIsUncertain) {
  const PointSet target = test::SampleCorridor(10.0, 3000, 0.005, test::Rng());
  const PointSet source = test::SampleCorridor(10.0, 3000, 0.005, test::Rng());
  const KdTreeTarget model(target, NormalOptions());
  BayesianIcpOptions options;
  options.noise_sigma_scale = 1.0;  // i.i.d. synthetic noise: sandwich = residual variance, no office scale
  options.sgld.num_iterations = 2000;
  const BayesianIcpResult r = RegisterBayesian(source, model, SE3(), options);
  EXPECT_TRUE(r.icp.degenerate);
  const Mat6& c = r.posterior.covariance;
  const Mat6 closed = ClosedFormCovariance(r.icp);
  EXPECT_GT(c(3, 3), 100.0 * c(4, 4));
  EXPECT_GT(c(3, 3), 100.0 * c(5, 5));
  EXPECT_GT(c(3, 3), 10.0 * closed(3, 3));
}

// A well-conditioned room: the posterior mean is at the ICP optimum (within 3
// posterior standard deviations per axis) and the chain really re-associates.
TEST(RegisterBayesian, RoomPosteriorIsConsistent) {
  const Eigen::Vector3d room(3.0, 2.0, 4.0);
  const SE3 truth(so3::Exp(Vec3(0.02, -0.01, 0.03)), Vec3(0.1, -0.05, 0.02));
  const PointSet target = test::SampleBoxRoom(room, 3000, 0.005, test::Rng());
  const PointSet source =
      test::Transformed(test::SampleBoxRoom(room, 3000, 0.005, test::Rng()), truth.Inverse());
  const KdTreeTarget model(target, NormalOptions());
  BayesianIcpOptions options;
  options.noise_sigma_scale = 1.0;  // i.i.d. synthetic noise: sandwich = residual variance, no office scale
  options.sgld.keep_samples = true;
  const BayesianIcpResult r = RegisterBayesian(source, model, SE3(), options);
  ASSERT_TRUE(r.icp.converged) << r.icp.message;
  EXPECT_EQ(r.posterior.samples.size(), r.posterior.num_samples);
  EXPECT_EQ(r.posterior.num_term_evaluations, 1000u * 100u);
  const Vec6 d = (r.icp.target_from_source.Inverse() * r.posterior.mean).Log();
  for (int i = 0; i < 6; ++i) {
    EXPECT_LT(std::abs(d(i)), 3.0 * std::sqrt(r.posterior.covariance(i, i))) << i;
  }
  EXPECT_TRUE(test::PosesNear(r.posterior.mean, truth, 0.002, 0.005));
}

// Block tempering is a deterministic rescaling of the same chain: with the same
// seed, the tempered covariance is D C D (D = diag(sqrt f_rot I3, sqrt f_trans I3))
// of the untempered one, and every kept sample is moved about the mean by D. The
// plane-fit variance model changes the likelihood weights (a different chain) but
// still re-associates at every sample.
TEST(RegisterBayesian, BlockTemperingRescalesTheChain) {
  const Eigen::Vector3d room(3.0, 2.0, 4.0);
  const PointSet target = test::SampleBoxRoom(room, 3000, 0.005, test::Rng());
  const PointSet source = test::SampleBoxRoom(room, 3000, 0.005, test::Rng());
  const KdTreeTarget model(target, NormalOptions());
  BayesianIcpOptions options;
  options.sgld.keep_samples = true;
  options.block_tempering = false;
  const BayesianIcpResult plain = RegisterBayesian(source, model, SE3(), options);
  options.block_tempering = true;
  const BayesianIcpResult tempered = RegisterBayesian(source, model, SE3(), options);
  EXPECT_EQ(plain.block_factors, Eigen::Vector2d::Ones());
  ASSERT_GT(tempered.block_factors.minCoeff(), 0.0);
  EXPECT_NE(tempered.block_factors, Eigen::Vector2d::Ones());
  Vec6 d;
  d << Eigen::Vector3d::Constant(std::sqrt(tempered.block_factors(0))),
      Eigen::Vector3d::Constant(std::sqrt(tempered.block_factors(1)));
  const Mat6 expected = d.asDiagonal() * plain.posterior.covariance * d.asDiagonal();
  EXPECT_LT((tempered.posterior.covariance - expected).norm(), 1e-9 * expected.norm());
  ASSERT_EQ(tempered.posterior.samples.size(), plain.posterior.samples.size());
  const Vec6 xi_plain = (plain.posterior.mean.Inverse() * plain.posterior.samples[7]).Log();
  const Vec6 xi_tempered = (tempered.posterior.mean.Inverse() * tempered.posterior.samples[7]).Log();
  EXPECT_LT((xi_tempered - d.asDiagonal() * xi_plain).norm(), 1e-9 + 1e-6 * xi_plain.norm());
  EXPECT_EQ(tempered.posterior.num_term_evaluations, 1000u * 100u);
  options.plane_fit_variance = !options.plane_fit_variance;  // the other likelihood
  const BayesianIcpResult other = RegisterBayesian(source, model, SE3(), options);
  EXPECT_NE(other.noise_sigma_m, tempered.noise_sigma_m);
  EXPECT_EQ(other.posterior.num_term_evaluations, 1000u * 100u);
}

// A surface seen in the source scan only (a 1.6 x 1.6 m table top 0.4 m above the
// floor, a third of the source points): with the ICP's 1 m correspondence distance
// its points match the floor and pull the estimate down through the Cauchy kernel's
// tail; a refinement within 0.2 m leaves them unmatched, in the ICP
// estimate the chain starts from and in the likelihood.
TEST(RegisterBayesian, RefinementDropsMatchesWithoutCounterpart) {
  const Eigen::Vector3d room(3.0, 2.0, 1.5);
  const SE3 truth(so3::Exp(Vec3(0.01, -0.01, 0.02)), Vec3(0.05, -0.03, 0.02));
  const PointSet target = test::SampleBoxRoom(room, 1500, 0.003, test::Rng());
  PointSet source_world = test::SampleBoxRoom(room, 1500, 0.003, test::Rng());
  test::SamplePlane(2, -room.z() + 0.4, Eigen::Vector3d(-0.8, -0.8, 0), Eigen::Vector3d(0.8, 0.8, 0),
                    4500, 0.003, test::Rng(), &source_world);
  const PointSet source = test::Transformed(source_world, truth.Inverse());
  const KdTreeTarget model(target, NormalOptions());
  BayesianIcpOptions options;
  options.sgld.num_iterations = 300;
  options.sgld.burn_in = 30;
  options.refine_max_correspondence_distance_m = 0.2;
  const BayesianIcpResult refined = RegisterBayesian(source, model, SE3(), options);
  options.refine_max_correspondence_distance_m = 0;
  const BayesianIcpResult plain = RegisterBayesian(source, model, SE3(), options);
  const auto z_error = [&](const SE3& estimate) {
    return std::abs((estimate.Inverse() * truth).Log()(5));
  };
  const double plain_z = z_error(plain.icp.target_from_source);
  const double refined_z = z_error(refined.icp.target_from_source);
  EXPECT_GT(plain_z, 3e-3) << "the table top should bias the 1 m association";
  EXPECT_LT(refined_z, 1e-3);
  EXPECT_LT(z_error(refined.posterior.mean), 1e-3);
  EXPECT_GT(refined.icp.iterations, 0);
}

TEST(RegisterBayesian, BadInputsThrow) {
  const PointSet room = test::SampleBoxRoom(Eigen::Vector3d(3, 2, 4), 300, 0.0, test::Rng());
  const KdTreeTarget model(room, NormalOptions());
  EXPECT_THROW(RegisterBayesian(PointSet{}, model, SE3(), BayesianIcpOptions()), InputError);
  BayesianIcpOptions bad;
  bad.sgld.step_size = 3.0;
  EXPECT_THROW(RegisterBayesian(room, model, SE3(), bad), InternalError);
}

}  // namespace
}  // namespace lisfm
