// Guards the calibration of the Bayesian ICP covariance on simulated scan pairs
// of scenes that were NOT used to tune it (hall and staircase; the two constants
// of the noise model were fitted on office pairs, see
// bench/icp_covariance_bench.cc and scripts/bench_icp_covariance.sh).
#include <gtest/gtest.h>

#include <cstdio>

#include "core/errors.h"
#include "icp/bayesian_icp.h"
#include "icp/icp_covariance.h"
#include "icp/testing/covariance_calibration.h"
#include "icp/testing/sim_pairs.h"

namespace lisfm {
namespace {

struct HeldOutRuns {
  // Library defaults (BayesianIcpOptions: Cauchy 0.05 m with a planarity gate of 0.1
  // and the field-of-view and visibility gates, normals of 20 neighbours, 48-cell CR3
  // sandwich sigma x 1.063, block tempering).
  std::vector<CovarianceSample> bayes;
  // A baseline on the ICP's association: Huber 0.1 m, normals of 10 neighbours,
  // 24-cell CR3 sandwich sigma x 1.049, block tempering (reported, not asserted).
  std::vector<CovarianceSample> huber_24_cells;
  std::vector<CovarianceSample> old_a;   // "old model A": sigma = 3.15 x ICP residual sigma
  std::vector<CovarianceSample> closed;  // sigma^2 H^-1 (Huber, k = 10)
};

// Same preprocessing and ICP options as bench/icp_covariance_bench.cc.
void RunPairs(const std::string& type, int count, uint32_t seed, HeldOutRuns* runs) {
  sim::SceneOptions scene_options = sim::DefaultSceneOptions(type);
  try {
    scene_options.CheckOrThrow("scene");
  } catch (const InputError&) {
    scene_options.width = 6.0;  // as the benchmark, should sim reject the default width
  }
  const std::unique_ptr<sim::Scene> scene = sim::Scene::Generate(scene_options);
  const std::vector<test::SimScanPair> pairs =
      test::SimulateScanPairs(*scene, count, seed, test::SimScanPairOptions());
  for (size_t k = 0; k < pairs.size(); ++k) {
    const PointSet source = VoxelDownsamplePoints(FinitePointsOf(pairs[k].source), 0.2);
    const PointSet target_points = VoxelDownsamplePoints(FinitePointsOf(pairs[k].target), 0.1);
    BayesianIcpOptions options;  // library defaults: the noise model fitted on office
    options.sgld.seed = 1000 + k;
    const KdTreeTarget target(target_points, NormalOptions{options.normal_neighbors, 1.0});
    const BayesianIcpResult r = RegisterBayesian(source, target, pairs[k].initial, options);
    runs->bayes.push_back({r.posterior.mean, r.posterior.covariance, pairs[k].truth});
    {
      const Vec6 xi = (r.posterior.mean.Inverse() * pairs[k].truth).Log();
      const Vec6 xi_icp = (r.icp.target_from_source.Inverse() * pairs[k].truth).Log();
      const Mat6& c = r.posterior.covariance;
      std::printf("%s pair %zu: NEES %.2f (rotation %.2f, translation %.2f), error %.3f deg / %.1f mm, "
                  "ICP %.3f deg / %.1f mm, %d iterations, sd %.3f deg / %.1f mm\n",
                  type.c_str(), k, xi.dot(c.llt().solve(xi)),
                  xi.head<3>().dot(c.topLeftCorner<3, 3>().llt().solve(xi.head<3>())),
                  xi.tail<3>().dot(c.bottomRightCorner<3, 3>().llt().solve(xi.tail<3>())),
                  xi.head<3>().norm() * 180 / M_PI, 1e3 * xi.tail<3>().norm(),
                  xi_icp.head<3>().norm() * 180 / M_PI, 1e3 * xi_icp.tail<3>().norm(),
                  r.icp.iterations, std::sqrt(c.topLeftCorner<3, 3>().trace()) * 180 / M_PI,
                  1e3 * std::sqrt(c.bottomRightCorner<3, 3>().trace()));
    }
    // The baseline models on their own association (Huber 0.1 m, k = 10).
    const KdTreeTarget target10(target_points, NormalOptions{10, 1.0});
    BayesianIcpOptions huber = options;
    huber.icp = IcpOptions();
    huber.icp.kernel_scale_m = 0.1;
    huber.noise_sigma_scale = 1.049;
    huber.num_correlation_cells = 24;
    huber.jackknife_leverage_power = 1.0;  // CR3
    const BayesianIcpResult t = RegisterBayesian(source, target10, pairs[k].initial, huber);
    runs->huber_24_cells.push_back({t.posterior.mean, t.posterior.covariance, pairs[k].truth});
    runs->closed.push_back({t.icp.target_from_source, ClosedFormCovariance(t.icp), pairs[k].truth});
    BayesianIcpOptions old = huber;
    old.block_tempering = false;
    old.noise_sigma_m = std::max(1e-6, 3.15 * std::sqrt(t.icp.residual_variance_m2));
    const BayesianIcpResult o = RegisterBayesian(source, target10, pairs[k].initial, old);
    runs->old_a.push_back({o.posterior.mean, o.posterior.covariance, pairs[k].truth});
  }
}

// Mean NEES over 40 held-out pairs (20 hall, 20 staircase) must lie in [2, 10].
// On these pairs the default measures 8.94 (coverage 82 %, median 5.90; one staircase
// pair slid 0.9 m along its corridor has NEES 39). Over 200 fresh held-out pairs of the
// benchmark (docs/BENCHMARKS.md, "Bayesian ICP covariance calibration") the default
// measures 6.72, the baseline 7.35-8.9, "old model A" (likelihood sigma = 3.15 x the ICP
// residual sigma, fitted on office) 11.9-14.0, the i.i.d. likelihood 130-150 and the
// closed form 180-280. The upper limit 10 lies between the default's and old model A's
// 200-pair means, so the test fails if the per-pair inflation is lost (i.i.d.: ~10x
// over) or falls back to a constant scale like old model A. NEES is heavy-tailed (one
// pair reaches 30-40), so this is a regression guard for the deterministic pairs below,
// not a statistical acceptance test; 40 pairs rather than 12 because on 12 of them two
// noise models ranked in the reverse order of their 200-pair means.
// The lower limit 2 catches a covariance ~3x too large in variance.
TEST(CovarianceCalibration, BayesianIsCalibratedOnHeldOutScenes) {
  HeldOutRuns runs;
  // Seeds 99 / 98: different pairs from the benchmark's hall / staircase sets (12 / 13).
  RunPairs("hall", 20, 99, &runs);
  RunPairs("staircase", 20, 98, &runs);
  const CalibrationStats b = EvaluateCovarianceCalibration(runs.bayes);
  const CalibrationStats o = EvaluateCovarianceCalibration(runs.old_a);
  const CalibrationStats c = EvaluateCovarianceCalibration(runs.closed);
  const CalibrationStats h = EvaluateCovarianceCalibration(runs.huber_24_cells);
  std::printf("%zu held-out pairs: default mean NEES %.2f (coverage %.2f, median %.2f); "
              "Huber 0.1 m, k = 10, 24 cells CR3, 1.049 %.2f (%.2f); old model A %.2f; "
              "closed form %.2f\n",
              runs.bayes.size(), b.mean_nees, b.coverage_95, b.median_nees, h.mean_nees,
              h.coverage_95, o.mean_nees, c.mean_nees);
  EXPECT_GT(b.mean_nees, 2.0) << "coverage " << b.coverage_95 << " median " << b.median_nees;
  EXPECT_LT(b.mean_nees, 10.0) << "coverage " << b.coverage_95 << " median " << b.median_nees;
  // The band discriminates: old model A and the closed form miss it on the same
  // pairs.
  EXPECT_GT(o.mean_nees, 10.0) << "old model coverage " << o.coverage_95 << " median "
                               << o.median_nees;
  EXPECT_GT(c.mean_nees, 10.0) << "closed form median " << c.median_nees;
}

}  // namespace
}  // namespace lisfm
