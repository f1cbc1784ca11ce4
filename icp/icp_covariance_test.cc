#include "icp/icp_covariance.h"

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

std::vector<CovarianceSample> GaussianSamples(const Mat6& true_cov, const Mat6& reported_cov, int n) {
  const Mat6 L = true_cov.llt().matrixL();
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<CovarianceSample> out;
  for (int k = 0; k < n; ++k) {
    Vec6 eta;
    for (int i = 0; i < 6; ++i) eta(i) = g(test::Rng());
    CovarianceSample s;
    s.estimate = test::RandomPose(1.0, 3.0);
    s.truth = s.estimate * SE3::Exp(L * eta);
    s.covariance = reported_cov;
    out.push_back(s);
  }
  return out;
}

Mat6 SomeCovariance() {
  Mat6 A = Mat6::Random();
  Vec6 scale;
  scale << 1e-3, 2e-3, 5e-4, 1e-2, 3e-2, 5e-3;
  return scale.asDiagonal() * (A * A.transpose() + Mat6::Identity()) * scale.asDiagonal();
}

// Errors drawn from the reported covariance: coverage ~95 % and mean NEES ~6.
// With 4000 samples the binomial std of the coverage is 0.34 % (tolerance 1.5 %),
// and the std of the mean NEES is sqrt(12/4000) = 0.055 (tolerance 0.3).
TEST(EvaluateCovarianceCalibration, CalibratedGaussian) {
  const Mat6 cov = SomeCovariance();
  const CalibrationStats s = EvaluateCovarianceCalibration(GaussianSamples(cov, cov, 4000));
  EXPECT_EQ(s.count, 4000u);
  EXPECT_NEAR(s.coverage_95, 0.95, 0.015);
  EXPECT_NEAR(s.mean_nees, 6.0, 0.3);
  EXPECT_NEAR(s.median_nees, 5.348, 0.35);
}

// A 4x over-confident covariance gives NEES ~24 and a low coverage.
TEST(EvaluateCovarianceCalibration, OverconfidentIsDetected) {
  const Mat6 cov = SomeCovariance();
  const CalibrationStats s = EvaluateCovarianceCalibration(GaussianSamples(cov, cov / 4.0, 2000));
  EXPECT_NEAR(s.mean_nees, 24.0, 1.5);
  EXPECT_LT(s.coverage_95, 0.5);
}

TEST(EvaluateCovarianceCalibration, BadInput) {
  EXPECT_THROW(EvaluateCovarianceCalibration({}), InputError);
  std::vector<CovarianceSample> bad(2);
  bad[1].covariance = -Mat6::Identity();
  EXPECT_THROW(EvaluateCovarianceCalibration(bad), InputError);
}

// SafeInverse: exact on a regular matrix, 1e12 on a null direction.
TEST(SafeInverse, RegularAndSingular) {
  const Mat6 cov = SomeCovariance();
  const Mat6 info = cov.inverse();
  EXPECT_LT((SafeInverse(info) - cov).norm() / cov.norm(), 1e-8);
  Mat6 singular = Mat6::Identity();
  singular(3, 3) = 0;
  const Mat6 inv = SafeInverse(singular);
  EXPECT_DOUBLE_EQ(inv(3, 3), 1e12);
  EXPECT_NEAR(inv(0, 0), 1.0, 1e-12);
}

}  // namespace
}  // namespace lisfm
