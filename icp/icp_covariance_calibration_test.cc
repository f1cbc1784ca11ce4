// Guards the calibration of the Bayesian ICP covariance on simulated scan pairs
// of scenes that were NOT used to tune it (hall and staircase; the two constants
// of the noise model were fitted on office pairs, see
// icp/bench/icp_covariance_bench.cc and scripts/bench_icp_covariance.sh).
#include <gtest/gtest.h>

#include <cstdio>

#include "core/errors.h"
#include "icp/bayesian_icp.h"
#include "icp/icp_covariance.h"
#include "icp/icp_sim_pairs.h"

namespace lisfm {
namespace {

struct HeldOutRuns {
  std::vector<CovarianceSample> bayes;     // library defaults (24-cell sandwich sigma x 1.049, block tempering)
  std::vector<CovarianceSample> session3;  // session-3 default: 24-cell sandwich sigma x 1.015 only (reported)
  std::vector<CovarianceSample> old_a;   // previous default: sigma = 3.15 x ICP residual sigma
  std::vector<CovarianceSample> closed;  // sigma^2 H^-1
};

// Same preprocessing and ICP options as icp/bench/icp_covariance_bench.cc.
void RunPairs(const std::string& type, int count, uint32_t seed, HeldOutRuns* runs) {
  sim::SceneOptions scene_options = sim::DefaultSceneOptions(type);
  try {
    scene_options.Check("scene");
  } catch (const InputError&) {
    scene_options.width = 6.0;  // as the benchmark: sim rejects the staircase default width
  }
  const std::unique_ptr<sim::Scene> scene = sim::Scene::Generate(scene_options);
  const std::vector<test::SimScanPair> pairs =
      test::SimulateScanPairs(*scene, count, seed, test::SimScanPairOptions());
  for (size_t k = 0; k < pairs.size(); ++k) {
    const PointSet source = VoxelDownsamplePoints(FinitePointsOf(pairs[k].source), 0.2);
    const KdTreeTarget target(VoxelDownsamplePoints(FinitePointsOf(pairs[k].target), 0.1),
                              NormalOptions{10, 1.0});
    BayesianIcpOptions options;  // library defaults: the noise model fitted on office
    options.icp.max_correspondence_distance_m = 1.0;
    options.icp.kernel_scale_m = 0.1;
    options.sgld.seed = 1000 + k;
    const BayesianIcpResult r = RegisterBayesian(source, target, pairs[k].initial, options);
    runs->bayes.push_back({r.posterior.mean, r.posterior.covariance, pairs[k].truth});
    runs->closed.push_back({r.icp.target_from_source, ClosedFormCovariance(r.icp), pairs[k].truth});
    BayesianIcpOptions s3 = options;
    s3.plane_fit_variance = false;
    s3.block_tempering = false;
    s3.num_correlation_cells = 24;
    s3.noise_sigma_scale = 1.015;
    const BayesianIcpResult t = RegisterBayesian(source, target, pairs[k].initial, s3);
    runs->session3.push_back({t.posterior.mean, t.posterior.covariance, pairs[k].truth});
    BayesianIcpOptions old = options;
    old.noise_sigma_m = std::max(1e-6, 3.15 * std::sqrt(r.icp.residual_variance_m2));
    const BayesianIcpResult o = RegisterBayesian(source, target, pairs[k].initial, old);
    runs->old_a.push_back({o.posterior.mean, o.posterior.covariance, pairs[k].truth});
  }
}

// Mean NEES over 12 held-out pairs (6 hall, 6 staircase) must lie in [2, 10].
// Over the benchmark's fresh held-out pairs (scripts/bench_icp_covariance.sh, 200
// pairs, seeds 32/33, session 4) the default (per-pair cluster-sandwich likelihood
// + block tempering) measures mean NEES 7.7 (median 5.0; seeds 12/13: 8.2), the
// session-3 default 8.2, the previous default "old model A" (likelihood sigma = 3.15
// x the ICP residual sigma, fitted on office) 12.7-12.8, the i.i.d. likelihood 130
// and the closed form 200-280. The upper limit 10 (tightened from 11 in session 4)
// lies between the default's and old model A's 200-pair means, so the test fails
// if the per-pair inflation is lost (i.i.d.: ~10x over) or falls back to a constant
// scale like the old model, while the spread of a 12-pair mean (NEES here is
// heavy-tailed, std of one pair ~ 8, so ~2.3 for the mean) leaves room above the
// default's 200-pair 7.7 of ~1 sigma: this is a regression guard for the
// deterministic pairs below (measured: default 5.20, coverage 12/12; session-3
// default 5.81, which this band cannot tell apart; old model A 13.21; closed form
// 227.6), not a statistical acceptance test. The lower limit 2 catches a covariance
// ~3x too large in variance.
TEST(CovarianceCalibration, BayesianIsCalibratedOnHeldOutScenes) {
  HeldOutRuns runs;
  // Seeds 99 / 98: different pairs from the benchmark's hall / staircase sets (12 / 13).
  RunPairs("hall", 6, 99, &runs);
  RunPairs("staircase", 6, 98, &runs);
  const CalibrationStats b = EvaluateCovarianceCalibration(runs.bayes);
  const CalibrationStats o = EvaluateCovarianceCalibration(runs.old_a);
  const CalibrationStats c = EvaluateCovarianceCalibration(runs.closed);
  const CalibrationStats s3 = EvaluateCovarianceCalibration(runs.session3);
  std::printf("12 held-out pairs: default mean NEES %.2f (coverage %.2f, median %.2f); session-3 "
              "default %.2f (%.2f); old model A %.2f; closed form %.2f\n",
              b.mean_nees, b.coverage_95, b.median_nees, s3.mean_nees, s3.coverage_95, o.mean_nees,
              c.mean_nees);
  EXPECT_GT(b.mean_nees, 2.0) << "coverage " << b.coverage_95 << " median " << b.median_nees;
  EXPECT_LT(b.mean_nees, 10.0) << "coverage " << b.coverage_95 << " median " << b.median_nees;
  // The band discriminates: the previous default and the closed form miss it on
  // the same pairs.
  EXPECT_GT(o.mean_nees, 10.0) << "old model coverage " << o.coverage_95 << " median "
                               << o.median_nees;
  EXPECT_GT(c.mean_nees, 10.0) << "closed form median " << c.median_nees;
}

}  // namespace
}  // namespace lisfm
