#include "icp/icp_covariance.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"
#include "core/option_check.h"
#include "icp/icp_internal.h"

namespace lisfm {

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

namespace {

uint64_t CellKey(const Eigen::Vector3f& p, double cell_size_m) {
  // 21 bits per axis (cells within +-1e6 cell edges of the origin).
  uint64_t key = 0;
  for (int k = 0; k < 3; ++k) {
    const int64_t v = static_cast<int64_t>(std::floor(p(k) / cell_size_m));
    key = (key << 21) | (static_cast<uint64_t>(v + (int64_t{1} << 20)) & ((uint64_t{1} << 21) - 1));
  }
  return key;
}

size_t CountCells(const PointSet& points, double cell_size_m, std::vector<uint64_t>* keys) {
  keys->resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) (*keys)[i] = CellKey(points[i], cell_size_m);
  std::sort(keys->begin(), keys->end());
  return static_cast<size_t>(std::unique(keys->begin(), keys->end()) - keys->begin());
}

}  // namespace

double CellSizeForClusterCount(const PointSet& points, size_t num_cells) {
  if (points.empty()) throw InputError("points", "", "expected a non-empty cloud, found none");
  Eigen::Vector3f lo = points[0], hi = points[0];
  for (const Eigen::Vector3f& p : points) {
    if (!p.allFinite()) {
      throw InputError("points", "", "expected finite coordinates, found NaN/inf");
    }
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // Counting on at most ~4096 evenly strided points: the occupancy of a grid with a
  // few dozen cells (hundreds of points each) is the same, at a fraction of the cost.
  const size_t stride = std::max<size_t>(1, points.size() / 4096);
  PointSet subset;
  subset.reserve(points.size() / stride + 1);
  for (size_t i = 0; i < points.size(); i += stride) subset.push_back(points[i]);
  std::vector<uint64_t> keys;
  double small = 0.01, large = std::max(0.02, static_cast<double>((hi - lo).norm()));
  if (CountCells(subset, small, &keys) < num_cells) return small;
  if (CountCells(subset, large, &keys) >= num_cells) return large;
  // Invariant: cells(small) >= num_cells > cells(large) (one or a few cells at the diagonal).
  for (int it = 0; it < 16; ++it) {
    const double mid = std::sqrt(small * large);
    (CountCells(subset, mid, &keys) >= num_cells ? small : large) = mid;
  }
  return small;
}

PlaneFit FitPlane(const std::vector<Eigen::Vector3d>& points) {
  PlaneFit fit;
  fit.count = static_cast<int>(points.size());
  if (points.size() < 3) return fit;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d d = p - points[0];
    sum += d;
    outer.noalias() += d * d.transpose();
  }
  const double n = static_cast<double>(points.size());
  const Eigen::Vector3d mean = sum / n;
  const Eigen::Matrix3d cov = outer / n - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(cov);
  if (!(eig.eigenvalues()(2) > 0)) return fit;
  fit.eigenvalues = eig.eigenvalues().cwiseMax(0.0);
  fit.eigenvectors = eig.eigenvectors();
  return fit;
}

Eigen::Matrix3d PlaneFitNormalCovariance(const PlaneFit& fit, double max_tilt_variance_rad2) {
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  if (fit.count < 3 || !(fit.eigenvalues(2) > 0)) return cov;
  const double l0 = fit.eigenvalues(0);
  for (int j = 1; j < 3; ++j) {
    const double lj = fit.eigenvalues(j);
    const double gap = lj - l0;
    const double num = l0 * lj;
    // min(t_max, l0 lj / (k gap^2)) without dividing by a vanishing gap.
    const double tilt = num >= max_tilt_variance_rad2 * fit.count * gap * gap
                            ? max_tilt_variance_rad2
                            : num / (fit.count * gap * gap);
    cov.noalias() += tilt * fit.eigenvectors.col(j) * fit.eigenvectors.col(j).transpose();
  }
  return cov;
}

bool CorrespondenceVarianceOptions::Check() const {
  CHECK_OPTION_GE(plane_variance_weight, 0.0);
  CHECK_OPTION_GE(max_tilt_variance_rad2, 0.0);
  CHECK_OPTION_GT(floor_m2, 0.0);
  return true;
}

namespace {
constexpr uint8_t kStatsUnknown = 0, kStatsBusy = 1, kStatsReady = 2;
}  // namespace

CorrespondenceVarianceModel::CorrespondenceVarianceModel(const KdTreeTarget& target,
                                                         const CorrespondenceVarianceOptions& options)
    : target_(target), options_(options), stats_(target.size()) {
  THROW_CHECK_OPTIONS(options);
  state_ = std::make_unique<std::atomic<uint8_t>[]>(target.size());  // value-initialised: 0
}

CorrespondenceVarianceModel::~CorrespondenceVarianceModel() = default;

CorrespondenceVarianceModel::Stats CorrespondenceVarianceModel::StatsAt(uint32_t index) const {
  THROW_CHECK_LT(static_cast<size_t>(index), stats_.size());
  std::atomic<uint8_t>& state = state_[index];
  uint8_t s = state.load(std::memory_order_acquire);
  if (s == kStatsReady) return stats_[index];
  // The same neighbourhood as KdTreeTarget's normal (EstimateNormalAt).
  constexpr size_t kMaxNeighbors = 64;
  const NormalOptions& no = target_.normal_options();
  const PointSet& pts = target_.tree().points();
  const size_t k = std::min(static_cast<size_t>(no.num_neighbors), kMaxNeighbors);
  const float max_sq = static_cast<float>(no.max_radius_m * no.max_radius_m);
  uint32_t idx[kMaxNeighbors];
  float d2[kMaxNeighbors];
  const size_t n = target_.tree().Knn(pts[index], k, idx, d2);
  std::vector<Eigen::Vector3d> neighbours;
  neighbours.reserve(n);
  for (size_t j = 0; j < n && d2[j] <= max_sq; ++j) {
    neighbours.push_back((pts[idx[j]] - pts[index]).cast<double>());
  }
  const PlaneFit fit = FitPlane(neighbours);
  const Eigen::Matrix3d c = PlaneFitNormalCovariance(fit, options_.max_tilt_variance_rad2);
  Stats st;
  st.l0 = static_cast<float>(fit.eigenvalues(0));
  const float values[6] = {static_cast<float>(c(0, 0)), static_cast<float>(c(0, 1)),
                           static_cast<float>(c(0, 2)), static_cast<float>(c(1, 1)),
                           static_cast<float>(c(1, 2)), static_cast<float>(c(2, 2))};
  std::copy(values, values + 6, st.cov);
  if (s == kStatsUnknown &&
      state.compare_exchange_strong(s, kStatsBusy, std::memory_order_acquire)) {
    stats_[index] = st;
    state.store(kStatsReady, std::memory_order_release);
  }
  // (A thread that finds the slot busy keeps its own, identical, result.)
  return st;
}

double CorrespondenceVarianceModel::Variance(uint32_t target_index, const Eigen::Vector3f& normal,
                                             const Eigen::Vector3f& offset) const {
  const Stats st = StatsAt(target_index);
  const Eigen::Vector3f d = offset - normal * normal.dot(offset);
  const float* c = st.cov;
  const double quad = c[0] * d.x() * d.x() + c[3] * d.y() * d.y() + c[5] * d.z() * d.z() +
                      2.0f * (c[1] * d.x() * d.y() + c[2] * d.x() * d.z() + c[4] * d.y() * d.z());
  return options_.plane_variance_weight * st.l0 + std::max(quad, 0.0) + options_.floor_m2;
}

ClusterSandwich ComputeClusterSandwich(const PointSet& source,
                                       const IcpTarget& target,
                                       const SE3& target_from_source,
                                       const IcpOptions& options,
                                       double cell_size_m,
                                       const std::vector<Eigen::Vector3f>& source_normals,
                                       const CorrespondenceVarianceModel* variance_model,
                                       std::vector<uint32_t>* matched_target_indices,
                                       double leverage_power) {
  CheckIcpSource(source, source_normals);
  THROW_CHECK_OPTIONS(options);
  THROW_CHECK_GE(cell_size_m, 0.0);
  THROW_CHECK_GE(leverage_power, 0.0);
  THROW_CHECK_MSG(variance_model == nullptr || &variance_model->target() == &target,
                  "CorrespondenceVarianceModel built for another target");
  const size_t n = source.size();
  const internal::LinearizationContext ctx(target_from_source, options);
  std::vector<internal::LinearizedTerm> terms(n);
  std::vector<uint8_t> valid(n, 0);
  std::vector<double> variances(variance_model != nullptr ? n : 0, 0.0);
  if (matched_target_indices != nullptr) matched_target_indices->assign(n, IcpTarget::kNoHint);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 512), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const Eigen::Vector3f nrm =
          source_normals.empty() ? Eigen::Vector3f::Zero() : source_normals[i];
      if (variance_model == nullptr) {
        valid[i] = internal::LinearizePoint(target, ctx, source[i], nrm, &terms[i]) ? 1 : 0;
        continue;
      }
      // MatchWithHint without a hint: Match()'s result, and the matched index.
      const Eigen::Vector3f p_t = ctx.rotation_f * source[i] + ctx.translation_f;
      Eigen::Vector3f q, nq;
      uint32_t index = IcpTarget::kNoHint;
      valid[i] = target.MatchWithHint(p_t, ctx.rotation_f * nrm, ctx.criteria, &q, &nq, &index)
                     ? 1
                     : 0;
      if (valid[i]) {
        internal::LinearizeMatch(ctx, source[i], q, nq, &terms[i]);
        variances[i] = variance_model->Variance(index, nq, p_t - q);
        if (matched_target_indices != nullptr) (*matched_target_indices)[i] = index;
      }
    }
  });
  double variance_reference = 0;
  if (variance_model != nullptr) {
    size_t count = 0;
    for (size_t i = 0; i < n; ++i) {
      if (valid[i]) {
        variance_reference += variances[i];
        ++count;
      }
    }
    variance_reference = count > 0 ? variance_reference / static_cast<double>(count) : 0.0;
    for (size_t i = 0; i < n; ++i) {
      if (valid[i]) terms[i].weight *= variance_reference / variances[i];
    }
  }
  // Serial accumulation in point order: deterministic, independent of threads.
  ClusterSandwich out;
  std::unordered_map<uint64_t, size_t> cell_index;
  std::vector<Vec6> cell_scores;
  std::vector<Mat6> cell_hessians;
  double weighted_sq = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!valid[i]) continue;
    const internal::LinearizedTerm& t = terms[i];
    out.hessian.noalias() += t.jacobian.transpose() * t.jacobian * t.weight;
    weighted_sq += t.weight * t.residual * t.residual;
    ++out.num_terms;
    size_t c = cell_scores.size();
    if (cell_size_m > 0) {
      c = cell_index.emplace(CellKey(source[i], cell_size_m), cell_scores.size()).first->second;
    }
    if (c == cell_scores.size()) {
      cell_scores.push_back(Vec6::Zero());
      cell_hessians.push_back(Mat6::Zero());
    }
    cell_scores[c] += t.jacobian.transpose() * (t.weight * t.residual);
    cell_hessians[c].noalias() += t.jacobian.transpose() * t.jacobian * t.weight;
  }
  out.num_clusters = cell_scores.size();
  out.variance_reference_m2 = variance_reference;
  if (out.num_terms < 7 || out.num_clusters < 2) {
    throw InputError("ICP correspondences", "",
                     fmt::format("expected at least 7 matches in 2 cells for a cluster sandwich, "
                                 "found {} matches in {} cells",
                                 out.num_terms, out.num_clusters));
  }
  for (const Vec6& g : cell_scores) out.meat.noalias() += g * g.transpose();
  const double g = static_cast<double>(out.num_clusters);
  out.meat *= g / (g - 1.0);
  out.residual_variance_m2 = weighted_sq / (static_cast<double>(out.num_terms) - 6.0);
  const Mat6 h_inv = SafeInverse(out.hessian);
  out.covariance = h_inv * out.meat * h_inv;
  // Whitening H = B B^T, B = V diag(sqrt l), W = B^-1 = diag(1/sqrt l) V^T (rows of
  // directions without curvature, as SafeInverse, set to zero): H^-1 = W^T W.
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(out.hessian);
  const Vec6 l = eig.eigenvalues();
  const double floor = std::max(l(5), 0.0) * 1e-12;
  Mat6 W = Mat6::Zero();
  Mat6 null_space = Mat6::Zero();
  int used = 0;
  for (int k = 0; k < 6; ++k) {
    if (l(k) > floor && l(k) > 0) {
      W.row(k) = eig.eigenvectors().col(k).transpose() / std::sqrt(l(k));
      ++used;
    } else {
      null_space += 1e12 * eig.eigenvectors().col(k) * eig.eigenvectors().col(k).transpose();
    }
  }
  const Mat6 meat_w = W * out.meat * W.transpose();
  // Cluster jackknife (CR3): delta_c = (H - H_c)^-1 g_c = W^T (I - A_c)^-1 W g_c with the
  // cluster's leverage A_c = W H_c W^T (exact for a linear model; CR3 in Cameron &
  // Miller 2015, the few-clusters section); eigenvalues of A_c are capped at kMaxLeverage so that a cell
  // that alone determines a direction gives a large, finite delta.
  constexpr double kMaxLeverage = 0.95;
  std::vector<Vec6> deltas(out.num_clusters);
  Vec6 delta_mean = Vec6::Zero();
  for (size_t c = 0; c < out.num_clusters; ++c) {
    if (leverage_power == 0) {
      deltas[c] = W * cell_scores[c];
    } else {
      const Eigen::SelfAdjointEigenSolver<Mat6> a(W * cell_hessians[c] * W.transpose());
      const Vec6 keep =
          (1.0 - a.eigenvalues().array().min(kMaxLeverage)).pow(-leverage_power).matrix();
      deltas[c] = a.eigenvectors() * keep.asDiagonal() * a.eigenvectors().transpose() *
                  (W * cell_scores[c]);
    }
    delta_mean += deltas[c];
  }
  delta_mean /= g;
  Mat6 jack_w = Mat6::Zero();
  for (const Vec6& d : deltas) jack_w.noalias() += (d - delta_mean) * (d - delta_mean).transpose();
  jack_w *= (g - 1.0) / g;
  out.jackknife_covariance = W.transpose() * jack_w * W + null_space;
  out.jackknife_deltas.reserve(deltas.size());
  for (const Vec6& d : deltas) out.jackknife_deltas.push_back(W.transpose() * (d - delta_mean));
  const int n_used = std::max(used, 1);
  out.effective_variance_cr1_m2 = meat_w.trace() / n_used;
  out.effective_variance_m2 = jack_w.trace() / n_used;
  return out;
}

}  // namespace lisfm
