// Closed-form ICP covariances and covariance calibration statistics.
//
// Both closed forms use the point-to-plane linearisation at the ICP optimum
// (IcpResult::hessian H = sum w J^T J, xi = [omega; v] on the right, DESIGN.md):
//  - ClosedFormCovariance = sigma^2 H^-1 with sigma^2 = sum w r^2 / (N - 6): the
//    Gauss-Newton / Laplace covariance. It treats correspondences as fixed and
//    residuals as independent, hence over-confident (REFERENCES.md section 4).
//  - CensiCovariance = H^-1 (sum w^2 r_i^2 J_i^T J_i) H^-1: the sandwich form of
//    Censi (ICRA 2007) with each correspondence's own squared residual as its
//    variance (heteroscedasticity-consistent); valid for point-to-plane
//    (Bonnabel et al. 2016).
// Unobservable directions (eigenvalues of H below 1e-12 of the largest) are given
// a variance of 1e12 (m^2 / rad^2) instead of an exception: "unknown".
#pragma once

#include <vector>

#include "core/geometry.h"
#include "icp/icp.h"

namespace lisfm {

Mat6 ClosedFormCovariance(const IcpResult& result);
Mat6 CensiCovariance(const IcpResult& result);

// Inverse of a symmetric PSD 6x6 with the 1e12 rule above.
Mat6 SafeInverse(const Mat6& information);

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
CalibrationStats EvaluateCovarianceCalibration(const std::vector<CovarianceSample>& samples);

}  // namespace lisfm
