#include "icp/icp_covariance.h"

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <unordered_map>

#include "core/errors.h"
#include "icp/testing/covariance_calibration.h"
#include "icp/testing/scenes.h"
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

// With every point its own cluster, CR1 is the Censi form times N/(N-1).
// A noise-free box room as target, a noisy (5 mm) resampling of it as source, and
// the converged default ICP between them.
struct RoomPair {
  PointSet source;
  std::unique_ptr<KdTreeTarget> model;
  IcpResult result;
};
RoomPair RegisteredRoomPair(size_t target_points, size_t source_points) {
  const Eigen::Vector3d room(3.0, 2.0, 4.0);
  RoomPair pair;
  pair.model = std::make_unique<KdTreeTarget>(
      test::SampleBoxRoom(room, target_points, 0.0, test::Rng()), NormalOptions());
  pair.source = test::SampleBoxRoom(room, source_points, 0.005, test::Rng());
  pair.result = RegisterPointToPlane(pair.source, *pair.model, SE3(), IcpOptions());
  return pair;
}

TEST(ComputeClusterSandwich, PointClustersGiveCensi) {
  const RoomPair pair = RegisteredRoomPair(1500, 1500);
  const PointSet& source = pair.source;
  const KdTreeTarget& model = *pair.model;
  const IcpResult& r = pair.result;
  const IcpOptions options;
  ASSERT_TRUE(r.converged) << r.message;
  const ClusterSandwich s =
      ComputeClusterSandwich(source, model, r.target_from_source, options, 0.0);
  EXPECT_EQ(s.num_clusters, s.num_terms);
  const double n = static_cast<double>(s.num_terms);
  // IcpResult's sums come from the last linearisation, one step (< 1e-4 rad / m,
  // the convergence thresholds) before the returned pose, so a few of the ~9000
  // associations and all residuals (~5 mm noise) shift slightly: 2 % on the
  // matrices (a step of 1e-4 m changes a 5 mm residual by at most 2 %).
  EXPECT_LT((s.covariance - n / (n - 1) * CensiCovariance(r)).norm(), 0.02 * s.covariance.norm());
  EXPECT_LT((s.hessian - r.hessian).norm(), 0.02 * r.hessian.norm());
  EXPECT_THROW(ComputeClusterSandwich(PointSet{}, model, SE3(), options, 1.0), InputError);
}

// leverage_power selects the cluster deltas: 0 gives the centred CR1 sandwich,
// (G-1)/G H^-1 sum_c (g_c - mean g)(g_c - mean g)^T H^-1, which at the optimum
// (sum g_c ~ 0) is ((G-1)/G)^2 times CR1; 1 (CR3) inflates every cell's delta by
// (I - A_c)^-1, so its effective variance is larger; the deltas returned are the
// centred ones the jackknife covariance is built from.
TEST(ComputeClusterSandwich, LeveragePowerZeroIsCentredCr1) {
  const RoomPair pair = RegisteredRoomPair(3000, 2000);
  ASSERT_TRUE(pair.result.converged) << pair.result.message;
  auto sandwich = [&](double leverage_power) {
    return ComputeClusterSandwich(pair.source, *pair.model, pair.result.target_from_source,
                                  IcpOptions(), 1.0, {}, nullptr, nullptr, leverage_power);
  };
  const ClusterSandwich cr0 = sandwich(0.0);
  const ClusterSandwich cr3 = sandwich(1.0);
  ASSERT_GT(cr0.num_clusters, 10u);
  const double g = static_cast<double>(cr0.num_clusters);
  // The sum of the cell scores is the gradient at the returned pose: one
  // convergence step (1e-4) from zero, so a few % of the score spread.
  EXPECT_LT((cr0.jackknife_covariance - std::pow((g - 1) / g, 2) * cr0.covariance).norm(),
            0.05 * cr0.covariance.norm());
  EXPECT_GT(cr3.effective_variance_m2, cr0.effective_variance_m2);
  EXPECT_NEAR(cr0.effective_variance_cr1_m2, cr3.effective_variance_cr1_m2, 1e-15);
  Mat6 rebuilt = Mat6::Zero();
  Vec6 sum = Vec6::Zero();
  for (const Vec6& d : cr0.jackknife_deltas) {
    rebuilt += d * d.transpose();
    sum += d;
  }
  EXPECT_LT(sum.norm(), 1e-9 * std::sqrt(cr0.jackknife_covariance.trace()));
  EXPECT_LT(((g - 1) / g * rebuilt - cr0.jackknife_covariance).norm(),
            1e-9 * cr0.jackknife_covariance.norm());
}

// CellSizeForClusterCount returns an edge where the occupied-cell count crosses
// the requested number: at least that many cells, fewer at an edge 0.1 % larger
// (the bisection's precision is ~0.01 %). 3372 points: below the 4096-point
// subsampling, so the count here is exactly the one bisected.
TEST(CellSizeForClusterCount, EdgeWhereTheCountCrosses) {
  const PointSet pts = test::SampleBoxRoom(Eigen::Vector3d(3.0, 2.0, 4.0), 500, 0.0, test::Rng());
  ASSERT_LT(pts.size(), 4096u);
  for (const size_t g : {12u, 24u, 100u}) {
    const double edge = CellSizeForClusterCount(pts, g);
    auto cells = [&](double e) {
      std::unordered_map<int64_t, int> seen;
      for (const auto& p : pts) {
        const Eigen::Vector3i c = (p.cast<double>() / e).array().floor().cast<int>();
        seen[(int64_t{c.x()} + 1000) * 4000000 + (c.y() + 1000) * 2000 + (c.z() + 1000)] = 1;
      }
      return seen.size();
    };
    EXPECT_GE(cells(edge), g);
    EXPECT_LT(cells(edge * 1.001), g);
  }
  // The room is centred at the origin: every grid has its 8 octants, so 8 cells
  // are reached at the largest edge tried, the bounding-box diagonal.
  EXPECT_NEAR(CellSizeForClusterCount(pts, 8), std::sqrt(6.0 * 6.0 + 4.0 * 4.0 + 8.0 * 8.0), 0.05);
  EXPECT_THROW(CellSizeForClusterCount(PointSet{}, 8), InputError);
}

// Block-correlated errors: every source point is displaced by its 1 m cell's
// common offset (5 mm per axis) plus 1 mm of independent noise, so the ~30 points
// of a cell share one error. Over 40 independent registrations the closed form
// (i.i.d. residuals) is grossly over-confident, while the Laplace covariance with
// the jackknife sandwich's effective variance, sigma_eff^2 H^-1 (what
// RegisterBayesian tempers its likelihood to), has mean NEES near 6. Band: for a
// calibrated covariance the mean of 40 chi2_6 values has std sqrt(12/40) = 0.55;
// the per-registration variance estimate from ~50 clusters adds roughly as much
// (its relative std is ~sqrt(2/(6*50)) ~ 8 % per trial plus the jackknife's
// small-sample conservatism), so [3.5, 9] is a 3-4 sigma band around 6 (measured
// 6.2, coverage 95 %). The closed form's mean NEES is of the order of the design
// effect 1 + (m - 1) rho with m ~ 30-60 points per cell and rho = 25 / 26 the
// within-cell correlation (measured 87); it must exceed 30.
TEST(ComputeClusterSandwich, CalibratedUnderBlockCorrelatedErrors) {
  const Eigen::Vector3d room(3.0, 2.0, 4.0);
  const PointSet target = test::SampleBoxRoom(room, 3000, 0.0, test::Rng());
  const KdTreeTarget model(target, NormalOptions());
  const SE3 truth(so3::Exp(Vec3(0.01, -0.02, 0.015)), Vec3(0.05, -0.03, 0.02));
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<CovarianceSample> tempered, closed;
  for (int trial = 0; trial < 40; ++trial) {
    PointSet world = test::SampleBoxRoom(room, 1500, 0.0, test::Rng());
    std::unordered_map<int64_t, Eigen::Vector3f> offsets;
    for (auto& p : world) {
      const Eigen::Vector3i c = (p.cast<double>()).array().floor().cast<int>();
      const int64_t key = (int64_t{c.x()} + 100) * 40000 + (c.y() + 100) * 200 + (c.z() + 100);
      auto it = offsets.find(key);
      if (it == offsets.end()) {
        const Eigen::Vector3f offset(g(test::Rng()), g(test::Rng()), g(test::Rng()));
        it = offsets.emplace(key, 0.005f * offset).first;
      }
      p += it->second + Eigen::Vector3f(g(test::Rng()), g(test::Rng()), g(test::Rng())) * 0.001f;
    }
    const PointSet source = test::Transformed(world, truth.Inverse());
    const IcpOptions options;
    const IcpResult r = RegisterPointToPlane(source, model, SE3(), options);
    ASSERT_TRUE(r.converged) << r.message;
    const ClusterSandwich s =
        ComputeClusterSandwich(source, model, r.target_from_source, options, 2.0);
    EXPECT_GT(s.num_clusters, 30u);
    const Mat6 laplace = s.effective_variance_m2 * SafeInverse(s.hessian);
    tempered.push_back({r.target_from_source, laplace, truth});
    closed.push_back({r.target_from_source, ClosedFormCovariance(r), truth});
  }
  const CalibrationStats t = EvaluateCovarianceCalibration(tempered);
  const CalibrationStats c = EvaluateCovarianceCalibration(closed);
  EXPECT_GT(t.mean_nees, 3.5) << "coverage " << t.coverage_95;
  EXPECT_LT(t.mean_nees, 9.0) << "coverage " << t.coverage_95;
  EXPECT_GT(c.mean_nees, 30.0) << "closed form coverage " << c.coverage_95;
}

// Monte Carlo of plane fits: k Gaussian points with spreads 0.2 m (x), 0.05 m (y)
// and 5 mm (z, the noise), `trials` fits. Returns the empirical variances of the
// normal's tilts towards x and y (its x, y components, sign fixed by n_z > 0) over
// the mean of the variances PlaneFitNormalCovariance predicts from each fit's own
// eigenvalues; *anisotropy: predicted y-tilt over x-tilt variance.
Eigen::Vector2d TiltVarianceRatios(int k, int trials, double* anisotropy) {
  std::normal_distribution<double> g(0.0, 1.0);
  double sum_x = 0, sum_y = 0, pred_x = 0, pred_y = 0;
  for (int t = 0; t < trials; ++t) {
    std::vector<Eigen::Vector3d> pts(k);
    for (auto& p : pts) p = Eigen::Vector3d(0.2 * g(test::Rng()), 0.05 * g(test::Rng()), 0.005 * g(test::Rng()));
    const PlaneFit fit = FitPlane(pts);
    EXPECT_EQ(fit.count, k);
    Eigen::Vector3d n = fit.eigenvectors.col(0);
    if (n.z() < 0) n = -n;
    sum_x += n.x() * n.x();
    sum_y += n.y() * n.y();
    const Eigen::Matrix3d c = PlaneFitNormalCovariance(fit, 1.0);
    // Tilts only: nothing along the fitted normal itself.
    EXPECT_LT((c * fit.eigenvectors.col(0)).norm(), 1e-12 * c.norm());
    pred_x += c(0, 0);
    pred_y += c(1, 1);
  }
  *anisotropy = pred_y / pred_x;
  return Eigen::Vector2d(sum_x / pred_x, sum_y / pred_y);
}

// Cov(n) (Anderson's asymptotic eigenvector covariance with plug-in eigenvalues)
// against a Monte Carlo of plane fits. With k = 200 points the asymptotics hold:
// empirical / predicted tilt variance within 10 % (Monte Carlo error on a variance
// sqrt(2/3000) = 2.6 %, O(1/k) plug-in bias ~1-2 %). With the LiDAR case's small k
// the formula is biased LOW (the sample l0 of few points underestimates the
// scatter): measured ratios 1.47 / 1.40 at k = 10 (1.03 / 1.01 at k = 200); the
// band [1.2, 1.8] (+-8 Monte Carlo sigmas) documents that bias and catches a
// change of the formula's scale (a lost factor 1/k would give ~0.1). The 16x
// anisotropy (spread ratio 4) is what gives ring-like neighbourhoods their large
// variance across the ring.
TEST(PlaneFitNormalCovariance, MatchesMonteCarloOfPlaneFits) {
  double anisotropy = 0;
  const Eigen::Vector2d large = TiltVarianceRatios(200, 3000, &anisotropy);
  EXPECT_NEAR(large(0), 1.0, 0.1);
  EXPECT_NEAR(large(1), 1.0, 0.1);
  EXPECT_GT(anisotropy, 12.0);
  const Eigen::Vector2d small = TiltVarianceRatios(10, 3000, &anisotropy);
  std::printf("empirical / predicted tilt variance: k=200 %.3f %.3f, k=10 %.3f %.3f\n", large(0),
              large(1), small(0), small(1));
  EXPECT_GT(small.minCoeff(), 1.2);
  EXPECT_LT(small.maxCoeff(), 1.8);
}

// A line of points (one LiDAR ring): the tilt about the line is capped at
// max_tilt_variance; fewer than 3 points give zero.
TEST(PlaneFitNormalCovariance, LineIsCappedAndTooFewIsZero) {
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 10; ++i) line.emplace_back(0.1 * i, 1e-6 * (i % 2), 1e-6 * ((i / 2) % 2));
  const Eigen::Matrix3d c = PlaneFitNormalCovariance(FitPlane(line), 0.25);
  EXPECT_NEAR(c.trace(), 0.25, 1e-3);  // one tilt (about the line) capped, the other ~0
  EXPECT_LT(c(0, 0), 1e-6);            // no tilt towards the line direction
  EXPECT_TRUE(PlaneFitNormalCovariance(FitPlane({Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX()}), 0.25)
                  .isZero());
}

// Two parallel "rings" 0.3 m apart on the plane z = 0 (points every 5 cm along x,
// 2 mm of deterministic scatter across and 1 mm off the plane): a point's 10
// neighbours lie on its own ring, so its normal is poorly determined about the
// ring direction. A match offset 0.15 m across the ring then has a residual
// variance far above one offset along the ring (the along-ring spread of 0.45 m
// pins that tilt), which is above the plane scatter alone (offset 0).
TEST(CorrespondenceVarianceModel, RingNeighbourhoodIsUncertainAcrossTheRing) {
  PointSet pts;
  for (int ring = 0; ring < 2; ++ring) {
    for (int i = 0; i < 60; ++i) {
      const float jitter = (i % 3 == 0 ? 1.f : (i % 3 == 1 ? -1.f : 0.f));
      pts.emplace_back(0.05f * i, 0.3f * ring + 0.002f * jitter, 0.001f * ((i % 2) ? 1.f : -1.f));
    }
  }
  const KdTreeTarget target(pts, NormalOptions{10, 1.0});
  CorrespondenceVarianceOptions options;
  const CorrespondenceVarianceModel model(target, options);
  Eigen::Vector3f n;
  float planarity = 0;
  const uint32_t index = 30;  // middle of ring 0
  target.NormalAt(index, &n, &planarity);
  ASSERT_GT(planarity, 0.f);
  const double across = model.Variance(index, n, Eigen::Vector3f(0, 0.15f, 0));
  const double along = model.Variance(index, n, Eigen::Vector3f(0.15f, 0, 0));
  const double zero = model.Variance(index, n, Eigen::Vector3f::Zero());
  EXPECT_GT(across, 100.0 * along) << across << " " << along;
  EXPECT_GE(along, zero);
  // The offset along the normal is not tangential: it adds nothing.
  EXPECT_NEAR(model.Variance(index, n, 0.1f * n), zero, 1e-12);
  EXPECT_GT(zero, options.floor_m2);  // 2 l0 + floor
  // Same value on the second call (cached).
  EXPECT_EQ(model.Variance(index, n, Eigen::Vector3f(0, 0.15f, 0)), across);
}

// Planar patches on a 5 cm grid (every neighbourhood an exact plane, l0 = 0, and
// the same Cov(n) = 0), source = target points displaced along their normals by
// i.i.d. 1 mm noise (no tangential offset): every v_i is the same, so the
// heteroscedastic sandwich reduces to the unweighted one (up to float rounding,
// 1e-6 relative) with the mean variance as reference.
TEST(ComputeClusterSandwich, PlaneFitVarianceReducesToIidOnExactPlanes) {
  PointSet target, source;
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Vector3f normals[6] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1},
                                      Eigen::Vector3f(1, 1, 0).normalized(),
                                      Eigen::Vector3f(0, 1, 1).normalized(),
                                      Eigen::Vector3f(1, 0, 1).normalized()};
  const Eigen::Vector3f centres[6] = {{3, 1, 0}, {-1, 3, 0.5}, {0.5, -1, -2},
                                      {-2, -2, 1}, {2, -2, -1}, {-2, 1, -2}};
  for (int f = 0; f < 6; ++f) {
    const Eigen::Vector3f u = normals[f].unitOrthogonal();
    const Eigen::Vector3f v = normals[f].cross(u);
    for (int i = -20; i <= 20; ++i) {
      for (int j = -20; j <= 20; ++j) {
        const Eigen::Vector3f q = centres[f] + 0.05f * (i * u + j * v);
        target.push_back(q);
        source.push_back(q + static_cast<float>(0.001 * g(test::Rng())) * normals[f]);
      }
    }
  }
  const KdTreeTarget kd(target, NormalOptions{10, 1.0});
  const IcpOptions options;
  const CorrespondenceVarianceModel model(kd, CorrespondenceVarianceOptions());
  const double cell = CellSizeForClusterCount(source, 24);
  const ClusterSandwich plain = ComputeClusterSandwich(source, kd, SE3(), options, cell);
  std::vector<uint32_t> matches;
  const ClusterSandwich weighted =
      ComputeClusterSandwich(source, kd, SE3(), options, cell, {}, &model, &matches);
  ASSERT_EQ(plain.num_terms, source.size());
  EXPECT_EQ(weighted.num_terms, plain.num_terms);
  EXPECT_NEAR(weighted.variance_reference_m2, CorrespondenceVarianceOptions().floor_m2, 1e-9);
  EXPECT_NEAR(weighted.effective_variance_m2 / plain.effective_variance_m2, 1.0, 1e-6);
  EXPECT_NEAR(weighted.residual_variance_m2 / plain.residual_variance_m2, 1.0, 1e-6);
  EXPECT_LT((weighted.hessian - plain.hessian).norm(), 1e-6 * plain.hessian.norm());
  ASSERT_EQ(matches.size(), source.size());
  for (size_t i = 0; i < source.size(); i += 97) EXPECT_EQ(matches[i], i);  // each point's own target
}

}  // namespace
}  // namespace lisfm
