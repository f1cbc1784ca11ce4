#include "icp/icp_covariance.h"

#include <algorithm>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include "core/errors.h"

namespace lisfm {

namespace {
constexpr double kChi2Six95 = 12.591587243743977;
}  // namespace

Mat6 SafeInverse(const Mat6& information) {
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(information);
  const Vec6 l = eig.eigenvalues();
  const double floor = std::max(l(5), 0.0) * 1e-12;
  Vec6 inv;
  for (int i = 0; i < 6; ++i) inv(i) = l(i) > floor && l(i) > 0 ? 1.0 / l(i) : 1e12;
  return eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
}

Mat6 ClosedFormCovariance(const IcpResult& result) {
  return result.residual_variance_m2 * SafeInverse(result.hessian);
}

Mat6 CensiCovariance(const IcpResult& result) {
  const Mat6 h_inv = SafeInverse(result.hessian);
  return h_inv * result.gradient_outer * h_inv;
}

CalibrationStats EvaluateCovarianceCalibration(const std::vector<CovarianceSample>& samples) {
  if (samples.empty()) {
    throw InputError("covariance samples", "", "expected at least one sample, found none");
  }
  CalibrationStats stats;
  std::vector<double> nees;
  nees.reserve(samples.size());
  size_t inside = 0;
  for (size_t k = 0; k < samples.size(); ++k) {
    const Eigen::LLT<Mat6> llt(samples[k].covariance);
    if (llt.info() != Eigen::Success || !samples[k].covariance.allFinite()) {
      throw InputError("covariance samples", fmt::format("record {}", k),
                       "expected a positive-definite covariance, found one that is not");
    }
    const Vec6 xi = (samples[k].estimate.Inverse() * samples[k].truth).Log();
    const double e = xi.dot(llt.solve(xi));
    nees.push_back(e);
    inside += e <= kChi2Six95 ? 1 : 0;
  }
  stats.count = samples.size();
  stats.coverage_95 = static_cast<double>(inside) / static_cast<double>(samples.size());
  double sum = 0;
  for (const double e : nees) sum += e;
  stats.mean_nees = sum / static_cast<double>(nees.size());
  std::sort(nees.begin(), nees.end());
  const size_t m = nees.size() / 2;
  stats.median_nees = nees.size() % 2 == 1 ? nees[m] : 0.5 * (nees[m - 1] + nees[m]);
  return stats;
}

}  // namespace lisfm
