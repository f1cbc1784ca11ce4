// Calibration statistics of registration covariances against known truth, for
// the covariance tests and the calibration benchmark (header-only; tests and
// benchmarks only).
#pragma once

#include <algorithm>
#include <string>
#include <vector>

#include <Eigen/Cholesky>

#include "core/errors.h"
#include "core/geometry.h"

namespace lisfm {

// One registration outcome for calibration: estimate, its covariance (right
// perturbation) and the true transform.
struct CovarianceSample {
  SE3 estimate;
  Mat6 covariance = Mat6::Identity();
  SE3 truth;
};

struct CalibrationStats {
  size_t count = 0;
  double coverage_95 = 0;  // fraction with NEES <= chi2_6(0.95) = 12.592
  double mean_nees = 0;    // ideal 6
  double median_nees = 0;  // ideal chi2_6 median 5.348
};

// NEES_k = xi^T Sigma^-1 xi with truth = estimate Exp(xi). Throws InputError for an
// empty set or a covariance that is not positive definite (names the sample).
inline CalibrationStats EvaluateCovarianceCalibration(
    const std::vector<CovarianceSample>& samples) {
  constexpr double kChi2Six95 = 12.591587243743977;  // 95 % quantile of chi2 with 6 DoF
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
      throw InputError("covariance samples",
                       "record " + std::to_string(k),
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
