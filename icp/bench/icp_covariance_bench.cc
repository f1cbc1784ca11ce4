// Covariance calibration study (issue 5 item 6, scripts/bench_icp_covariance.sh).
//
// Simulated spinning-LiDAR scan pairs with exactly known relative pose
// (icp/icp_sim_pairs.h: static poses, 1 cm range noise, initial-guess error 2 deg /
// 10 cm per axis) in three procedural scenes: office (tuning set), hall and
// staircase (held out; the staircase is the narrow, LiDAR-degenerate stairwell
// with corridors), plus a held-out straight corridor without end walls in range
// (translation along it unobservable: the degenerate case). For each pair: point-to-plane ICP, its closed-form covariance
// (sigma^2 H^-1), the Censi sandwich, and Bayesian ICP (SGLD, re-associated
// correspondences). Reported per method: coverage of the 95 % ellipsoid, mean and
// median NEES (ideal 0.95 / 6 / 5.35 for 6 DoF) and time per pair.
//
// Tuning: BayesianIcpOptions::noise_sigma_scale is fitted on the office pairs
// only (fixed-point iterations c <- c sqrt(mean NEES / 6)) for two noise models,
// A (constant scale) and B (one independent error per occupied cell of
// correlation_length_m, 1 m a priori); the hall and staircase numbers use those
// values unchanged. `--scale X` skips the tuning and uses X for both.
// Usage: lisfm_icp_covariance_bench [pairs_per_scene=100] [--scale X]
//        [--correlation_length L]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/errors.h"
#include "icp/bayesian_icp.h"
#include "icp/icp.h"
#include "icp/icp_covariance.h"
#include "icp/icp_sim_pairs.h"

namespace lisfm {
namespace {

using Clock = std::chrono::steady_clock;
double Ms(Clock::time_point a) {
  return std::chrono::duration<double, std::milli>(Clock::now() - a).count();
}

// Same preprocessing as the real-data benchmark (scripts/bench_icp.sh).
constexpr double kSourceVoxel = 0.2;
constexpr double kTargetVoxel = 0.1;

struct PreparedPair {
  PointSet source;
  std::unique_ptr<KdTreeTarget> target;
  SE3 truth, initial;
};

struct MethodRun {
  std::vector<CovarianceSample> samples;
  double total_ms = 0;
};

std::vector<PreparedPair> Prepare(const std::string& type, int count, uint32_t seed,
                                  double* sim_ms) {
  const auto t0 = Clock::now();
  sim::SceneOptions scene_options = sim::DefaultSceneOptions(type == "corridor" ? "office" : type);
  try {
    scene_options.Check("scene");
  } catch (const InputError& e) {
    // sim's own Check rejects the staircase default width 2.8 m (lower bound 6 m,
    // a sim bug at the time of writing): use the narrowest width it accepts.
    std::printf("note: default %s scene rejected (%s); using width 6 m\n", type.c_str(), e.what());
    scene_options.width = 6.0;
  }
  const bool corridor = type == "corridor";
  const std::unique_ptr<sim::Scene> scene = corridor ? test::CorridorScene(300, 3, 3)
                                                     : sim::Scene::Generate(scene_options);
  const std::vector<test::SimScanPair> pairs =
      corridor ? test::SimulateCorridorPairs(*scene, count, seed, test::SimScanPairOptions())
               : test::SimulateScanPairs(*scene, count, seed, test::SimScanPairOptions());
  std::vector<PreparedPair> out;
  for (const test::SimScanPair& p : pairs) {
    PreparedPair q;
    q.source = VoxelDownsamplePoints(FinitePointsOf(p.source), kSourceVoxel);
    q.target = std::make_unique<KdTreeTarget>(
        VoxelDownsamplePoints(FinitePointsOf(p.target), kTargetVoxel),
        NormalOptions{10, 10 * kTargetVoxel});
    q.truth = p.truth;
    q.initial = p.initial;
    out.push_back(std::move(q));
  }
  *sim_ms = Ms(t0);
  return out;
}

IcpOptions BenchIcpOptions() {
  IcpOptions o;
  o.max_correspondence_distance_m = 1.0;
  o.kernel_scale_m = 0.1;
  return o;
}

void RunIcp(const std::vector<PreparedPair>& pairs, MethodRun* closed, MethodRun* censi,
            MethodRun* icp_only, size_t* num_degenerate, double* rot_err_deg,
            double* trans_err_m) {
  *num_degenerate = 0;
  std::vector<double> rot, trans;
  for (const PreparedPair& p : pairs) {
    const auto t0 = Clock::now();
    const IcpResult r = RegisterPointToPlane(p.source, *p.target, p.initial, BenchIcpOptions());
    icp_only->total_ms += Ms(t0);
    *num_degenerate += r.degenerate ? 1 : 0;
    const auto t1 = Clock::now();
    const Mat6 c = ClosedFormCovariance(r);
    closed->total_ms += Ms(t1);
    const auto t2 = Clock::now();
    const Mat6 s = CensiCovariance(r);
    censi->total_ms += Ms(t2);
    closed->samples.push_back({r.target_from_source, c, p.truth});
    censi->samples.push_back({r.target_from_source, s, p.truth});
    const Vec6 e = (r.target_from_source.Inverse() * p.truth).Log();
    rot.push_back(e.head<3>().norm() * 180.0 / M_PI);
    trans.push_back(e.tail<3>().norm());
  }
  std::sort(rot.begin(), rot.end());
  std::sort(trans.begin(), trans.end());
  *rot_err_deg = rot[rot.size() / 2];
  *trans_err_m = trans[trans.size() / 2];
}

double g_correlation_length = 1.0;

MethodRun RunBayesian(const std::vector<PreparedPair>& pairs, double scale, double corr) {
  MethodRun run;
  for (size_t k = 0; k < pairs.size(); ++k) {
    BayesianIcpOptions b;
    b.icp = BenchIcpOptions();
    b.noise_sigma_scale = scale;
    b.correlation_length_m = corr;
    b.sgld.seed = 1000 + k;
    const auto t0 = Clock::now();
    const BayesianIcpResult r = RegisterBayesian(pairs[k].source, *pairs[k].target, pairs[k].initial, b);
    run.total_ms += Ms(t0);
    run.samples.push_back({r.posterior.mean, r.posterior.covariance, pairs[k].truth});
  }
  return run;
}

void Row(const std::string& set, const std::string& method, const MethodRun& run) {
  if (run.samples.empty()) {  // timing-only row
    std::printf("| %s | %s | | | | | %.2f |\n", set.c_str(), method.c_str(), run.total_ms);
    return;
  }
  const CalibrationStats s = EvaluateCovarianceCalibration(run.samples);
  std::printf("| %s | %s | %zu | %.1f %% | %.2f | %.2f | %.2f |\n", set.c_str(), method.c_str(),
              s.count, 100.0 * s.coverage_95, s.mean_nees, s.median_nees,
              run.total_ms / static_cast<double>(s.count));
  std::fflush(stdout);
}

MethodRun Concat(const MethodRun& a, const MethodRun& b) {
  MethodRun c = a;
  c.samples.insert(c.samples.end(), b.samples.begin(), b.samples.end());
  c.total_ms += b.total_ms;
  return c;
}

int Main(int argc, char** argv) {
  int count = 100;
  double fixed_scale = 0;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--scale") == 0 && i + 1 < argc) {
      fixed_scale = std::atof(argv[++i]);
    } else if (std::strcmp(argv[i], "--correlation_length") == 0 && i + 1 < argc) {
      g_correlation_length = std::atof(argv[++i]);
    } else {
      count = std::atoi(argv[i]);
    }
  }
  struct SceneSet {
    std::string type;
    uint32_t seed;
    std::vector<PreparedPair> pairs;
  };
  std::vector<SceneSet> sets(4);
  sets[0].type = "office";
  sets[0].seed = 11;
  sets[1].type = "hall";
  sets[1].seed = 12;
  sets[2].type = "staircase";
  sets[2].seed = 13;
  sets[3].type = "corridor";  // straight 3 m corridor, no end walls in range: degenerate
  sets[3].seed = 14;
  for (SceneSet& s : sets) {
    double ms = 0;
    s.pairs = Prepare(s.type, count, s.seed, &ms);
    size_t ns = 0, nt = 0;
    for (const PreparedPair& p : s.pairs) {
      ns += p.source.size();
      nt += p.target->size();
    }
    std::printf("%s: %d pairs simulated in %.1f s; mean %zu source / %zu target points\n",
                s.type.c_str(), count, ms / 1e3, ns / s.pairs.size(), nt / s.pairs.size());
  }

  // Tuning on the office pairs only, for two noise models (BayesianIcpOptions):
  // A: constant noise_sigma_scale (correlation_length_m = 0, the library default);
  // B: one independent error per occupied 1 m cell (correlation_length_m = 1,
  //    fixed a priori) and noise_sigma_scale fitted.
  auto tune = [&](double corr) {
    double scale = fixed_scale > 0 ? fixed_scale : 1.0;
    if (fixed_scale > 0) return scale;
    for (int iter = 0; iter < 2; ++iter) {
      const MethodRun run = RunBayesian(sets[0].pairs, scale, corr);
      const CalibrationStats st = EvaluateCovarianceCalibration(run.samples);
      std::printf("tuning on office (correlation_length_m %.1f): noise_sigma_scale %.3f -> "
                  "coverage %.1f %%, mean NEES %.2f, median %.2f\n",
                  corr, scale, 100 * st.coverage_95, st.mean_nees, st.median_nees);
      scale *= std::sqrt(st.mean_nees / 6.0);
    }
    return scale;
  };
  const double scale_a = tune(0.0);
  const double scale_b = tune(g_correlation_length);
  std::printf("Bayesian ICP A: noise_sigma_scale %.3f; B: noise_sigma_scale %.3f with "
              "correlation_length_m %.2f\n\n", scale_a, scale_b, g_correlation_length);

  std::printf("| pairs | method | n | coverage 95 %% | mean NEES | median NEES | ms per pair |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  MethodRun held_closed, held_censi, held_bayes, held_raw, held_cells;
  for (size_t i = 0; i < sets.size(); ++i) {
    const std::string name = sets[i].type + (i == 0 ? " (tuning)" : " (held out)");
    MethodRun closed, censi, icp_only;
    size_t degenerate = 0;
    double rot_med = 0, trans_med = 0;
    RunIcp(sets[i].pairs, &closed, &censi, &icp_only, &degenerate, &rot_med, &trans_med);
    const MethodRun bayes = RunBayesian(sets[i].pairs, scale_a, 0.0);
    const MethodRun cells = RunBayesian(sets[i].pairs, scale_b, g_correlation_length);
    const MethodRun raw = RunBayesian(sets[i].pairs, 1.0, 0.0);
    icp_only.total_ms /= static_cast<double>(sets[i].pairs.size());
    Row(name, "point-to-plane ICP alone (no covariance)", icp_only);
    Row(name, "closed form sigma^2 H^-1 (on top of ICP)", closed);
    Row(name, "Censi sandwich (on top of ICP)", censi);
    Row(name, "Bayesian ICP, noise_sigma_scale 1 (untuned)", raw);
    Row(name, "Bayesian ICP A, tuned noise_sigma_scale (default)", bayes);
    Row(name, "Bayesian ICP B, tuned scale + 1 m correlation cells", cells);
    std::printf("| %s | (ICP median error %.3f deg / %.1f mm; %zu of %zu flagged degenerate) | | | | | |\n",
                name.c_str(), rot_med, 1e3 * trans_med, degenerate, sets[i].pairs.size());
    if (i == 1 || i == 2) {
      held_closed = Concat(held_closed, closed);
      held_censi = Concat(held_censi, censi);
      held_bayes = Concat(held_bayes, bayes);
      held_raw = Concat(held_raw, raw);
      held_cells = Concat(held_cells, cells);
    }
  }
  Row("hall + staircase (held out)", "closed form sigma^2 H^-1", held_closed);
  Row("hall + staircase (held out)", "Censi sandwich", held_censi);
  Row("hall + staircase (held out)", "Bayesian ICP, noise_sigma_scale 1 (untuned)", held_raw);
  Row("hall + staircase (held out)", "Bayesian ICP A, tuned noise_sigma_scale (default)", held_bayes);
  Row("hall + staircase (held out)", "Bayesian ICP B, tuned scale + 1 m correlation cells", held_cells);
  return 0;
}

}  // namespace
}  // namespace lisfm

int main(int argc, char** argv) { return lisfm::Main(argc, argv); }
