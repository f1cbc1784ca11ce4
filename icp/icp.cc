#include "icp/icp.h"

#include <algorithm>
#include <cmath>
#include <mutex>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "core/errors.h"
#include "core/option_check.h"
#include "icp/icp_internal.h"

namespace lisfm {

namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Sums of one Gauss-Newton linearisation.
struct Accumulator {
  Mat6 hessian = Mat6::Zero();  // upper triangle filled during the reduction
  Mat6 gradient_outer = Mat6::Zero();
  Vec6 gradient = Vec6::Zero();
  double weighted_sq = 0;  // sum w r^2
  double sq = 0;           // sum r^2
  Eigen::Vector3d point_sum = Eigen::Vector3d::Zero();
  double point_sq = 0;  // sum |p|^2
  size_t count = 0;

  // Upper triangle of m += alpha j^T j, element for element the arithmetic of
  // Eigen's selfadjointView<Upper>().rankUpdate (column c: (alpha j_c) j_r for
  // r <= c), hence bit-identical sums, without the general product machinery
  // (which costs more than the 21 multiply-adds themselves at this size).
  static void UpperRankUpdate(const Eigen::Matrix<double, 1, 6>& j, double alpha, Mat6* m) {
    for (int c = 0; c < 6; ++c) {
      const double a = alpha * j(c);
      for (int r = 0; r <= c; ++r) (*m)(r, c) += a * j(r);
    }
  }

  // full: also the statistics needed only at the returned estimate (Censi
  // "meat", point spread); the Gauss-Newton iterations need only H, g, counts.
  template <bool full>
  void Add(const internal::LinearizedTerm& t, const Eigen::Vector3f& p) {
    const double wr = t.weight * t.residual;
    UpperRankUpdate(t.jacobian, t.weight, &hessian);
    gradient += t.jacobian.transpose() * wr;
    weighted_sq += wr * t.residual;
    sq += t.residual * t.residual;
    ++count;
    if (full) {
      UpperRankUpdate(t.jacobian, wr * wr, &gradient_outer);
      const Eigen::Vector3d pd = p.cast<double>();
      point_sum += pd;
      point_sq += pd.squaredNorm();
    }
  }
  void Join(const Accumulator& o) {
    hessian += o.hessian;
    gradient_outer += o.gradient_outer;
    gradient += o.gradient;
    weighted_sq += o.weighted_sq;
    sq += o.sq;
    point_sum += o.point_sum;
    point_sq += o.point_sq;
    count += o.count;
  }
  // Fills the lower triangles from the upper ones accumulated by Add.
  void Symmetrize() {
    hessian = hessian.selfadjointView<Eigen::Upper>();
    gradient_outer = gradient_outer.selfadjointView<Eigen::Upper>();
  }
};

// The matches of the last association, by source index (only the indices of
// the current level's subset are meaningful).
struct MatchCache {
  std::vector<Eigen::Vector3f> target_point, target_normal;
  std::vector<uint8_t> valid;
  explicit MatchCache(size_t n) : target_point(n), target_normal(n), valid(n, 0) {}
};

// Associates (every stride-th source point) and linearises at ctx; records the
// matches in *cache when given.
template <bool full>
Accumulator Linearize(const PointSet& source,
                      const std::vector<Eigen::Vector3f>& source_normals,
                      const IcpTarget& target,
                      const internal::LinearizationContext& ctx,
                      size_t stride = 1,
                      MatchCache* cache = nullptr,
                      std::vector<IcpTarget::MatchState>* states = nullptr) {
  const bool with_normals = !source_normals.empty();
  const size_t num_used = (source.size() + stride - 1) / stride;
  Accumulator total = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, num_used, 512),
      Accumulator(),
      [&](const tbb::blocked_range<size_t>& range, Accumulator acc) {
        internal::LinearizedTerm term;
        Eigen::Vector3f q, nq;
        for (size_t k = range.begin(); k != range.end(); ++k) {
          const size_t i = k * stride;
          const Eigen::Vector3f n = with_normals ? source_normals[i] : Eigen::Vector3f::Zero();
          const bool matched = internal::LinearizePoint(
              target, ctx, source[i], n, &term, &q, &nq,
              states != nullptr ? &(*states)[i] : nullptr);
          if (matched) acc.template Add<full>(term, source[i]);
          if (cache != nullptr) {
            cache->valid[i] = matched ? 1 : 0;
            if (matched) {
              cache->target_point[i] = q;
              cache->target_normal[i] = nq;
            }
          }
        }
        return acc;
      },
      [](Accumulator a, const Accumulator& b) {
        a.Join(b);
        return a;
      });
  total.Symmetrize();
  return total;
}

// Linearises the cached matches at ctx (no association): the Gauss-Newton /
// IRLS re-solves on fixed correspondences.
template <bool full>
Accumulator LinearizeCached(const PointSet& source,
                            const MatchCache& cache,
                            const internal::LinearizationContext& ctx,
                            size_t stride) {
  const size_t num_used = (source.size() + stride - 1) / stride;
  Accumulator total = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, num_used, 1024),
      Accumulator(),
      [&](const tbb::blocked_range<size_t>& range, Accumulator acc) {
        internal::LinearizedTerm term;
        for (size_t k = range.begin(); k != range.end(); ++k) {
          const size_t i = k * stride;
          if (!cache.valid[i]) continue;
          internal::LinearizeMatch(ctx, source[i], cache.target_point[i], cache.target_normal[i], &term);
          acc.template Add<full>(term, source[i]);
        }
        return acc;
      },
      [](Accumulator a, const Accumulator& b) {
        a.Join(b);
        return a;
      });
  total.Symmetrize();
  return total;
}

// Damped Gauss-Newton step from the sums; false when too few matches or the
// solve is not finite.
bool SolveStep(const Accumulator& acc, int min_inliers, Vec6* step) {
  if (acc.count < static_cast<size_t>(min_inliers)) return false;
  // Tiny Levenberg damping keeps degenerate directions from exploding; it is
  // 1e-9 of the mean diagonal, far below any observable direction.
  Mat6 damped = acc.hessian;
  damped.diagonal().array() += 1e-9 * acc.hessian.trace() / 6.0 + 1e-12;
  *step = -damped.ldlt().solve(acc.gradient);
  return step->allFinite();
}

}  // namespace

RobustKernel RobustKernelFromString(const std::string& name) {
  if (name == "none") return RobustKernel::kNone;
  if (name == "huber") return RobustKernel::kHuber;
  if (name == "cauchy") return RobustKernel::kCauchy;
  if (name == "geman_mcclure") return RobustKernel::kGemanMcClure;
  throw UsageError("unknown robust kernel '" + name +
                   "'; expected none, huber, cauchy or geman_mcclure");
}

std::string RobustKernelToString(RobustKernel kernel) {
  switch (kernel) {
    case RobustKernel::kNone: return "none";
    case RobustKernel::kHuber: return "huber";
    case RobustKernel::kCauchy: return "cauchy";
    case RobustKernel::kGemanMcClure: return "geman_mcclure";
  }
  return "none";
}

double RobustWeight(RobustKernel kernel, double r, double k) {
  const double a = std::abs(r);
  switch (kernel) {
    case RobustKernel::kNone: return 1.0;
    case RobustKernel::kHuber: return a <= k ? 1.0 : k / a;
    case RobustKernel::kCauchy: return 1.0 / (1.0 + (r * r) / (k * k));
    case RobustKernel::kGemanMcClure: {
      const double d = k * k + r * r;
      return (k * k * k * k) / (d * d);
    }
  }
  return 1.0;
}

double RobustLoss(RobustKernel kernel, double r, double k) {
  const double a = std::abs(r);
  switch (kernel) {
    case RobustKernel::kNone: return 0.5 * r * r;
    case RobustKernel::kHuber: return a <= k ? 0.5 * r * r : k * a - 0.5 * k * k;
    case RobustKernel::kCauchy: return 0.5 * k * k * std::log1p((r * r) / (k * k));
    case RobustKernel::kGemanMcClure: return 0.5 * r * r * k * k / (k * k + r * r);
  }
  return 0.5 * r * r;
}

namespace {

bool IsRobustKernelName(const std::string& name) {
  return name == "none" || name == "huber" || name == "cauchy" || name == "geman_mcclure";
}

}  // namespace

bool IcpOptions::Check() const {
  CHECK_OPTION_GE(max_iterations, 1);
  CHECK_OPTION_GE(max_inner_iterations, 0);
  CHECK_OPTION_GT(max_correspondence_distance_m, 0.0);
  CHECK_OPTION_MSG(max_normal_angle_deg, max_normal_angle_deg > 0 && max_normal_angle_deg <= 180,
                   "in (0, 180]");
  CHECK_OPTION_MSG(min_planarity, min_planarity >= 0 && min_planarity <= 1, "in [0, 1]");
  CHECK_OPTION_MSG(kernel, IsRobustKernelName(kernel), "one of none, huber, cauchy, geman_mcclure");
  CHECK_OPTION_GT(kernel_scale_m, 0.0);
  CHECK_OPTION_GE(convergence_rotation_rad, 0.0);
  CHECK_OPTION_GE(convergence_translation_m, 0.0);
  CHECK_OPTION_GE(min_inliers, 6);
  CHECK_OPTION_GE(coarse_stride, 1);
  CHECK_OPTION_MSG(coarse_levels, coarse_levels >= 0 && coarse_levels <= 8, "in [0, 8]");
  CHECK_OPTION_GE(coarse_min_points, 1);
  CHECK_OPTION_GE(degeneracy_threshold, 0.0);
  CHECK_OPTION_GE(visibility_gate_m, 0.0);
  CHECK_OPTION_MSG(
      min_normal_contrast, min_normal_contrast >= 0 && min_normal_contrast <= 1, "in [0, 1]");
  return true;
}

// ---- targets ----

namespace {
constexpr uint8_t kNormalUnknown = 0;
constexpr uint8_t kNormalBusy = 1;
constexpr uint8_t kNormalReady = 2;
}  // namespace

struct KdTreeTarget::FieldOfView {
  std::once_flag once;
  float min_sin_elevation = -1.f, max_sin_elevation = 1.f;
  float max_range_m = 0.f;
  // Visibility (range image): per bin the range of the nearest target point, 0 if
  // the bin holds none, and that point's index.
  static constexpr int kAzimuthBins = 720;    // 0.5 deg
  static constexpr int kElevationBins = 180;  // 1 deg, -90..+90 deg
  std::once_flag image_once;
  std::vector<float> nearest_range;
  std::vector<uint32_t> nearest_index;
  // Bin of a direction d != 0 (seen from the viewpoint) of norm r.
  static int Bin(const Eigen::Vector3f& d, float r) {
    constexpr float kToDeg = 180.f / static_cast<float>(M_PI);
    const float azimuth = std::atan2(d.y(), d.x()) * kToDeg;  // -180..180
    const float elevation = std::asin(std::clamp(d.z() / r, -1.f, 1.f)) * kToDeg;
    const int a = std::clamp(static_cast<int>((azimuth + 180.f) * 2.f), 0, kAzimuthBins - 1);
    const int e = std::clamp(static_cast<int>(std::floor(elevation)) + 90, 0, kElevationBins - 1);
    return e * kAzimuthBins + a;
  }
};

bool KdTreeTarget::Visible(const Eigen::Vector3f& point,
                           float tolerance_m,
                           bool follow_surface) const {
  FieldOfView& fov = *field_of_view_;
  std::call_once(fov.image_once, [&] {
    constexpr size_t kBins = FieldOfView::kAzimuthBins * FieldOfView::kElevationBins;
    fov.nearest_range.assign(kBins, 0.f);
    fov.nearest_index.assign(kBins, 0);
    const PointSet& pts = tree_.points();
    for (size_t i = 0; i < pts.size(); ++i) {
      const Eigen::Vector3f d = pts[i] - viewpoint_;
      const float r = d.norm();
      if (!(r > 0)) continue;
      const int bin = FieldOfView::Bin(d, r);
      float& nearest = fov.nearest_range[bin];
      if (nearest == 0.f || r < nearest) {
        nearest = r;
        fov.nearest_index[bin] = static_cast<uint32_t>(i);
      }
    }
  });
  const Eigen::Vector3f d = point - viewpoint_;
  const float r = d.norm();
  if (!(r > 0)) return true;
  const int bin = FieldOfView::Bin(d, r);
  const float nearest = fov.nearest_range[bin];
  if (nearest == 0.f || r <= nearest * 1.02f + tolerance_m) return true;
  if (!follow_surface) return false;
  // The ray x = viewpoint + t d / r meets the plane n^T (x - q) = 0 of the nearest
  // point q (normal n, oriented towards the viewpoint) at t = n^T (q - viewpoint) /
  // (n^T d / r); from the front only when n^T d < 0 (then t > 0 as n^T (q - viewpoint) < 0).
  const uint32_t index = fov.nearest_index[bin];
  Eigen::Vector3f n;
  float planarity = 0.f;
  NormalAt(index, &n, &planarity);
  if (planarity <= 0.f) return false;  // no normal: the nearest range decides
  const float n_dot_d = n.dot(d);
  if (!(n_dot_d < 0.f)) return true;  // the ray does not meet the plane from the front
  const float t = n.dot(tree_.points()[index] - viewpoint_) * r / n_dot_d;
  return r <= t * 1.02f + tolerance_m;
}

bool KdTreeTarget::InFieldOfView(const Eigen::Vector3f& point) const {
  FieldOfView& fov = *field_of_view_;
  std::call_once(fov.once, [&] {
    // Elevations as sines (no trigonometry), seen from the viewpoint; the extreme
    // 0.1 % on either side are left out (stray returns).
    const PointSet& pts = tree_.points();
    std::vector<float> sin_elevation;
    sin_elevation.reserve(pts.size());
    for (const Eigen::Vector3f& q : pts) {
      const Eigen::Vector3f d = q - viewpoint_;
      const float r = d.norm();
      if (!(r > 0)) continue;
      sin_elevation.push_back(d.z() / r);
      fov.max_range_m = std::max(fov.max_range_m, r);
    }
    if (sin_elevation.empty()) return;
    const size_t tail = sin_elevation.size() / 1000;
    std::nth_element(sin_elevation.begin(), sin_elevation.begin() + tail, sin_elevation.end());
    fov.min_sin_elevation = sin_elevation[tail];
    const size_t top = sin_elevation.size() - 1 - tail;
    std::nth_element(sin_elevation.begin(), sin_elevation.begin() + top, sin_elevation.end());
    fov.max_sin_elevation = sin_elevation[top];
  });
  const Eigen::Vector3f d = point - viewpoint_;
  const float r = d.norm();
  if (!(r > 0) || r > fov.max_range_m) return false;
  const float s = d.z() / r;
  return s >= fov.min_sin_elevation && s <= fov.max_sin_elevation;
}

KdTreeTarget::KdTreeTarget(PointSet points,
                           const NormalOptions& normal_options,
                           const Eigen::Vector3f& viewpoint)
    : tree_(std::move(points), "target"), normal_options_(normal_options), viewpoint_(viewpoint) {
  if (tree_.size() < 3) {
    throw InputError("target", "", fmt::format("expected at least 3 points, found {}", tree_.size()));
  }
  THROW_CHECK_OPTIONS(normal_options);
  normals_.normals.assign(tree_.size(), Eigen::Vector3f::Zero());
  normals_.planarity.assign(tree_.size(), 0.f);
  contrast_.assign(tree_.size(), 0.f);
  state_ = std::make_unique<std::atomic<uint8_t>[]>(tree_.size());  // value-initialised: 0
  field_of_view_ = std::make_unique<FieldOfView>();
}

KdTreeTarget::KdTreeTarget(PointSet points, std::vector<Eigen::Vector3f> normals)
    : tree_(std::move(points), "target") {
  if (tree_.size() < 3) {
    throw InputError("target", "", fmt::format("expected at least 3 points, found {}", tree_.size()));
  }
  if (normals.size() != tree_.size()) {
    throw InputError("target normals", "",
                     fmt::format("expected {} normals (one per point), found {}", tree_.size(),
                                 normals.size()));
  }
  normals_.planarity.assign(normals.size(), 1.f);
  contrast_.assign(normals.size(), 1.f);
  for (size_t i = 0; i < normals.size(); ++i) {
    const float norm = normals[i].norm();
    if (!std::isfinite(norm)) {
      throw InputError("target normals", fmt::format("normal {}", i), "expected finite values, found NaN/inf");
    }
    if (norm > 0) {
      normals[i] /= norm;
    } else {
      normals_.planarity[i] = 0.f;
    }
  }
  normals_.normals = std::move(normals);
  state_ = std::make_unique<std::atomic<uint8_t>[]>(tree_.size());
  for (size_t i = 0; i < tree_.size(); ++i) state_[i].store(kNormalReady, std::memory_order_relaxed);
  field_of_view_ = std::make_unique<FieldOfView>();
}

KdTreeTarget::~KdTreeTarget() = default;

void KdTreeTarget::NormalAt(size_t index, Eigen::Vector3f* normal, float* planarity) const {
  float contrast = 0.f;
  NormalAt(index, normal, planarity, &contrast);
}

void KdTreeTarget::NormalAt(size_t index,
                            Eigen::Vector3f* normal,
                            float* planarity,
                            float* contrast) const {
  THROW_CHECK_LT(index, tree_.size());
  std::atomic<uint8_t>& state = state_[index];
  uint8_t s = state.load(std::memory_order_acquire);
  if (s == kNormalReady) {
    *normal = normals_.normals[index];
    *planarity = normals_.planarity[index];
    *contrast = contrast_[index];
    return;
  }
  Eigen::Vector3f n = Eigen::Vector3f::Zero();
  float p = 0.f;
  float c = 0.f;
  EstimateNormalAt(tree_, index, normal_options_, viewpoint_, &n, &p, &c);
  // One thread publishes; a thread that finds the slot busy keeps its own
  // (identical) result instead of waiting.
  if (s == kNormalUnknown &&
      state.compare_exchange_strong(s, kNormalBusy, std::memory_order_acquire)) {
    normals_.normals[index] = n;
    normals_.planarity[index] = p;
    contrast_[index] = c;
    state.store(kNormalReady, std::memory_order_release);
  }
  *normal = n;
  *planarity = p;
  *contrast = c;
}

size_t KdTreeTarget::NumNormalsEstimated() const {
  size_t count = 0;
  for (size_t i = 0; i < tree_.size(); ++i) {
    count += state_[i].load(std::memory_order_relaxed) == kNormalReady ? 1 : 0;
  }
  return count;
}

bool KdTreeTarget::AcceptMatch(uint32_t index,
                               const Eigen::Vector3f& normal,
                               const MatchCriteria& criteria,
                               Eigen::Vector3f* target_point,
                               Eigen::Vector3f* target_normal) const {
  Eigen::Vector3f n;
  float planarity = 0.f;
  float contrast = 0.f;
  NormalAt(index, &n, &planarity, &contrast);
  if (planarity <= 0.f || planarity < criteria.min_planarity) return false;
  if (contrast < criteria.min_normal_contrast) return false;
  if (!normal.isZero() && std::abs(n.dot(normal)) < criteria.min_cos_normal_angle) return false;
  *target_point = tree_.points()[index];
  *target_normal = n;
  return true;
}

bool KdTreeTarget::Match(const Eigen::Vector3f& point,
                         const Eigen::Vector3f& normal,
                         const MatchCriteria& criteria,
                         Eigen::Vector3f* target_point,
                         Eigen::Vector3f* target_normal) const {
  uint32_t hint = kNoHint;
  return MatchWithHint(point, normal, criteria, target_point, target_normal, &hint);
}

bool KdTreeTarget::MatchWithHint(const Eigen::Vector3f& point,
                                 const Eigen::Vector3f& normal,
                                 const MatchCriteria& criteria,
                                 Eigen::Vector3f* target_point,
                                 Eigen::Vector3f* target_normal,
                                 uint32_t* hint) const {
  if (!InView(point, criteria)) return false;
  // The nearest point is at most as far as the previous match: a tighter bound
  // prunes most of the tree walk once the estimate settles (same result).
  float bound = criteria.max_distance_m * criteria.max_distance_m;
  // (Relaxed by 1e-4 relative so that rounding differences between this distance
  // and the tree's own cannot exclude the previous match itself.)
  if (*hint < tree_.size()) {
    bound = std::min(bound, (tree_.points()[*hint] - point).squaredNorm() * 1.0001f + 1e-12f);
  }
  uint32_t index = 0;
  float sq_dist = 0;
  if (!tree_.NearestWithin(point, bound, &index, &sq_dist)) return false;
  *hint = index;
  return AcceptMatch(index, normal, criteria, target_point, target_normal);
}

bool KdTreeTarget::MatchTracked(const Eigen::Vector3f& point,
                                const Eigen::Vector3f& normal,
                                const MatchCriteria& criteria,
                                Eigen::Vector3f* target_point,
                                Eigen::Vector3f* target_normal,
                                MatchState* state) const {
  if (criteria.HasViewGates()) {
    if (state->in_view < 0) state->in_view = InView(point, criteria) ? 1 : 0;
    if (state->in_view == 0) return false;
  }
  const float max_sq = criteria.max_distance_m * criteria.max_distance_m;
  uint32_t index = 0;
  if (state->index < tree_.size() && state->margin_m > 0 &&
      (point - state->anchor).squaredNorm() < state->margin_m * state->margin_m) {
    // Within the margin of the last search: the nearest point is unchanged.
    index = state->index;
    if ((tree_.points()[index] - point).squaredNorm() > max_sq) return false;
  } else {
    // Two nearest points within max distance, or within twice the distance of
    // the previous match when that is less (it bounds the nearest; a missing
    // second point only means a smaller margin).
    float bound = max_sq;
    if (state->index < tree_.size()) {
      const float previous_sq = (tree_.points()[state->index] - point).squaredNorm();
      bound = std::min(bound, 4.f * previous_sq * 1.0001f + 1e-12f);
    }
    uint32_t idx[2];
    float d2[2];
    const size_t n = tree_.KnnWithin(point, 2, bound, idx, d2);
    if (n == 0) return false;
    index = idx[0];
    const float d_first = std::sqrt(d2[0]);
    const float d_second = n == 2 ? std::sqrt(d2[1]) : std::sqrt(bound);
    // Half the gap, less 2 % and 1 um: far above the rounding of float
    // distances, so that the tree search would return the same nearest point.
    state->index = index;
    state->anchor = point;
    state->margin_m = 0.49f * (d_second - d_first) - 1e-6f;
  }
  return AcceptMatch(index, normal, criteria, target_point, target_normal);
}

ProjectiveTarget::ProjectiveTarget(PointSet vertex_map, const PinholeIntrinsics& intrinsics)
    : vertex_map_(std::move(vertex_map)), intrinsics_(intrinsics) {
  if (!(intrinsics.fx > 0 && intrinsics.fy > 0 && intrinsics.width > 2 && intrinsics.height > 2)) {
    throw InputError("intrinsics", "",
                     fmt::format("expected fx, fy > 0 and an image larger than 2x2, found fx={} "
                                 "fy={} {}x{}",
                                 intrinsics.fx, intrinsics.fy, intrinsics.width, intrinsics.height));
  }
  const size_t expected = static_cast<size_t>(intrinsics.width) * intrinsics.height;
  if (vertex_map_.size() != expected) {
    throw InputError("vertex map", "",
                     fmt::format("expected {}x{} = {} vertices, found {}", intrinsics.width,
                                 intrinsics.height, expected, vertex_map_.size()));
  }
  normals_ = EstimateOrganizedNormals(vertex_map_, intrinsics.width, intrinsics.height);
  size_t valid = 0;
  for (const float p : normals_.planarity) valid += p > 0 ? 1 : 0;
  if (valid < 3) {
    throw InputError("vertex map", "",
                     fmt::format("expected at least 3 pixels with depth and a normal, found {}", valid));
  }
}

bool ProjectiveTarget::Match(const Eigen::Vector3f& point,
                             const Eigen::Vector3f& normal,
                             const MatchCriteria& criteria,
                             Eigen::Vector3f* target_point,
                             Eigen::Vector3f* target_normal) const {
  if (!(point.z() > 0)) return false;
  const double u = intrinsics_.fx * point.x() / point.z() + intrinsics_.cx;
  const double v = intrinsics_.fy * point.y() / point.z() + intrinsics_.cy;
  const long ui = std::lround(u);
  const long vi = std::lround(v);
  if (ui < 0 || vi < 0 || ui >= intrinsics_.width || vi >= intrinsics_.height) return false;
  const size_t i = static_cast<size_t>(vi) * intrinsics_.width + static_cast<size_t>(ui);
  if (normals_.planarity[i] <= 0.f) return false;  // no depth or no normal
  const Eigen::Vector3f& q = vertex_map_[i];
  if ((q - point).squaredNorm() > criteria.max_distance_m * criteria.max_distance_m) return false;
  const Eigen::Vector3f& n = normals_.normals[i];
  if (!normal.isZero() && std::abs(n.dot(normal)) < criteria.min_cos_normal_angle) return false;
  *target_point = q;
  *target_normal = n;
  return true;
}

// ---- linearisation ----

namespace internal {

LinearizationContext::LinearizationContext(const SE3& T, const IcpOptions& options)
    : target_from_source(T),
      rotation_f(T.RotationMatrix().cast<float>()),
      translation_f(T.translation().cast<float>()),
      criteria{static_cast<float>(options.max_correspondence_distance_m),
               static_cast<float>(std::cos(options.max_normal_angle_deg * kDegToRad)),
               static_cast<float>(options.min_planarity), options.field_of_view_gate,
               static_cast<float>(options.visibility_gate_m), options.visibility_follows_surface,
               static_cast<float>(options.min_normal_contrast)},
      kernel(RobustKernelFromString(options.kernel)),
      kernel_scale_m(options.kernel_scale_m) {}

void LinearizeMatch(const LinearizationContext& ctx,
                    const Eigen::Vector3f& p,
                    const Eigen::Vector3f& q,
                    const Eigen::Vector3f& nq,
                    LinearizedTerm* term) {
  const Eigen::Vector3f p_t = ctx.rotation_f * p + ctx.translation_f;
  // Residual in double from float inputs: r = n^T (T p - q), J = [(p x m)^T, m^T].
  const Eigen::Vector3d nd = nq.cast<double>();
  term->residual = nd.dot((p_t - q).cast<double>());
  const Eigen::Vector3f m = ctx.rotation_f.transpose() * nq;
  const Eigen::Vector3f pxm = p.cross(m);
  term->jacobian << pxm.x(), pxm.y(), pxm.z(), m.x(), m.y(), m.z();
  term->weight = RobustWeight(ctx.kernel, term->residual, ctx.kernel_scale_m);
}

bool LinearizePoint(const IcpTarget& target,
                    const LinearizationContext& ctx,
                    const Eigen::Vector3f& p,
                    const Eigen::Vector3f& n,
                    LinearizedTerm* term,
                    Eigen::Vector3f* target_point,
                    Eigen::Vector3f* target_normal,
                    IcpTarget::MatchState* state) {
  const Eigen::Vector3f p_t = ctx.rotation_f * p + ctx.translation_f;
  const Eigen::Vector3f n_t = ctx.rotation_f * n;
  Eigen::Vector3f q, nq;
  const bool matched =
      state != nullptr
          ? target.MatchTracked(p_t, n_t, ctx.criteria, &q, &nq, state)
          : target.Match(p_t, n_t, ctx.criteria, &q, &nq);
  if (!matched) return false;
  LinearizeMatch(ctx, p, q, nq, term);
  if (target_point != nullptr) *target_point = q;
  if (target_normal != nullptr) *target_normal = nq;
  return true;
}

}  // namespace internal

double PointToPlaneResidual(const SE3& T,
                            const Vec3& p,
                            const Vec3& q,
                            const Vec3& n,
                            Eigen::Matrix<double, 1, 6>* jacobian) {
  if (jacobian != nullptr) {
    const Vec3 m = T.rotation().conjugate() * n;
    jacobian->head<3>() = p.cross(m).transpose();
    jacobian->tail<3>() = m.transpose();
  }
  return n.dot(T * p - q);
}

void CheckIcpSource(const PointSet& source, const std::vector<Eigen::Vector3f>& source_normals) {
  if (source.size() < 6) {
    throw InputError("source", "",
                     fmt::format("expected at least 6 points for a 6-DoF registration, found {}",
                                 source.size()));
  }
  CheckFinitePoints(source, "source");
  if (!source_normals.empty()) {
    if (source_normals.size() != source.size()) {
      throw InputError("source normals", "",
                       fmt::format("expected {} normals (one per source point), found {}",
                                   source.size(), source_normals.size()));
    }
    CheckFinitePoints(source_normals, "source normals");
  }
}

IcpResult RegisterPointToPlane(const PointSet& source,
                               const IcpTarget& target,
                               const SE3& initial,
                               const IcpOptions& options,
                               const std::vector<Eigen::Vector3f>& source_normals) {
  THROW_CHECK_OPTIONS(options);
  CheckIcpSource(source, source_normals);
  IcpResult result;
  result.target_from_source = initial;
  Accumulator acc;
  bool small_step = false;
  // Coarse-to-fine: while far from the optimum, every coarse_stride-th source
  // point is enough to point the step the right way; the next finer level is used
  // once a step falls below 10x the convergence thresholds (the full set at once
  // when a subset has too few matches), and only full-set steps can end the
  // iteration.
  // Levels: every 2^(L-1) k-th, ..., 2k-th, k-th point (k = coarse_stride, L =
  // coarse_levels), each only if the subset keeps >= coarse_min_points points; then
  // all points.
  // Why L = 3 and 600 points: a coarse iteration far from the optimum matches mostly
  // target points it has not matched before, and each of them costs a lazy normal (a
  // 10-NN search and a 3x3 eigensolve), so the first iterations should use as few
  // points as still point the step the right way. The real pairs converge to the same
  // estimates (within the convergence thresholds) as with L = 2 and 1200 points, up to
  // 1.26x faster on BALM pairs (docs/BENCHMARKS.md, "ICP registration vs PCL and
  // Open3D").
  std::vector<size_t> strides;
  const size_t k = static_cast<size_t>(options.coarse_stride);
  for (int j = options.coarse_levels - 1; k > 1 && j >= 0; --j) {
    const size_t s = k << j;
    if (source.size() / s >= static_cast<size_t>(options.coarse_min_points)) strides.push_back(s);
  }
  strides.push_back(1);
  size_t level = 0;
  size_t stride = strides[0];
  SE3 last_linearized = initial;
  MatchCache cache(options.max_inner_iterations > 0 ? source.size() : 0);
  // Per source point: its last match and search (warm start, skipped searches).
  std::vector<IcpTarget::MatchState> match_states(source.size());
  constexpr double kMaxExtrapolation = 4.0;
  bool last_extrapolated = false;
  size_t prev_stride = 0;
  Vec6 prev_scaled_step = Vec6::Zero();
  // L: RMS distance of the source points from their centroid (m), scales rotations.
  double source_scale = 1.0;
  {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double sq = 0;
    for (const auto& p : source) {
      sum += p.cast<double>();
      sq += p.cast<double>().squaredNorm();
    }
    const double n = static_cast<double>(source.size());
    source_scale = std::sqrt(std::max(sq / n - (sum / n).squaredNorm(), 1e-12));
  }
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const internal::LinearizationContext ctx(result.target_from_source, options);
    last_linearized = result.target_from_source;
    acc = Linearize<false>(source, source_normals, target, ctx, stride,
                           options.max_inner_iterations > 0 ? &cache : nullptr,
                           &match_states);
    result.iterations = iteration + 1;
    Vec6 step;
    if (!SolveStep(acc, options.min_inliers, &step)) {
      if (acc.count < static_cast<size_t>(options.min_inliers) && stride > 1) {
        level = strides.size() - 1;
        stride = 1;
        continue;
      }
      break;
    }
    result.target_from_source = result.target_from_source * SE3::Exp(step);
    // Re-solves on the fixed matches (IRLS re-weighting and the rotation's
    // nonlinearity) until a step falls below the convergence thresholds: far
    // cheaper than an association, and the fixed point is unchanged.
    for (int inner = 0; inner < options.max_inner_iterations; ++inner) {
      if (step.head<3>().norm() < options.convergence_rotation_rad &&
          step.tail<3>().norm() < options.convergence_translation_m) {
        break;
      }
      const internal::LinearizationContext inner_ctx(result.target_from_source, options);
      if (!SolveStep(LinearizeCached<false>(source, cache, inner_ctx, stride), options.min_inliers,
                     &step)) {
        break;
      }
      result.target_from_source = result.target_from_source * SE3::Exp(step);
    }
    // The step of this association: from the linearisation point to the new estimate.
    const Vec6 total_step = (last_linearized.Inverse() * result.target_from_source).Log();
    const double rotation_step = total_step.head<3>().norm();
    const double translation_step = total_step.tail<3>().norm();
    // Besl & McKay (1992, Sec. IV-C) acceleration: ICP converges linearly, so
    // when two successive steps point the same way (within 10 deg, in the
    // scaled space [L omega; v]) and shrink by rho < 1, jump ahead by the rest of
    // the geometric series, rho / (1 - rho) steps (at most kMaxExtrapolation).
    // The jump is only taken after the convergence test (so convergence is
    // always decided by a plain step) and never twice in a row.
    Vec6 scaled_step;
    scaled_step << source_scale * total_step.head<3>(), total_step.tail<3>();
    bool extrapolated = false;
    const bool small = rotation_step < options.convergence_rotation_rad &&
                       translation_step < options.convergence_translation_m;
    if (!small && !last_extrapolated && prev_stride == stride && prev_scaled_step.norm() > 0) {
      const double cos_angle =
          scaled_step.dot(prev_scaled_step) / (scaled_step.norm() * prev_scaled_step.norm());
      const double rho = scaled_step.norm() / prev_scaled_step.norm();
      if (cos_angle > std::cos(10.0 * kDegToRad) && rho < 1.0) {
        const double factor = std::min(rho / (1.0 - rho), kMaxExtrapolation);
        result.target_from_source = result.target_from_source * SE3::Exp(factor * total_step);
        extrapolated = true;
      }
    }
    last_extrapolated = extrapolated;
    prev_scaled_step = scaled_step;
    prev_stride = stride;
    if (stride > 1) {
      if (rotation_step < 10 * options.convergence_rotation_rad &&
          translation_step < 10 * options.convergence_translation_m) {
        stride = strides[++level];
      }
      continue;
    }
    if (small) {
      small_step = true;
      break;
    }
  }
  // Statistics and the Hessian at the returned estimate. After convergence with
  // cached matches: over the matches of the last association, which was made
  // within the convergence thresholds of the estimate (re-associating there would
  // change almost no match, at the cost of a full nearest-neighbour pass).
  // Otherwise one more association at the estimate (or, after a loop that ended
  // without a small step at full resolution, at its last linearisation point).
  if (small_step && options.max_inner_iterations > 0) {
    acc = LinearizeCached<true>(source, cache,
                                internal::LinearizationContext(result.target_from_source, options), 1);
  } else {
    acc = Linearize<true>(source, source_normals, target,
                          internal::LinearizationContext(
                              small_step || stride > 1 ? result.target_from_source : last_linearized,
                              options),
                          1, nullptr, &match_states);
  }
  result.num_inliers = acc.count;
  result.hessian = acc.hessian;
  result.gradient_outer = acc.gradient_outer;
  if (acc.count > 0) {
    result.rmse_m = std::sqrt(acc.sq / acc.count);
    const Eigen::Vector3d mean = acc.point_sum / acc.count;
    const double spread = acc.point_sq / acc.count - mean.squaredNorm();
    result.characteristic_length_m = std::sqrt(std::max(spread, 1e-12));
  }
  if (acc.count > 6) result.residual_variance_m2 = acc.weighted_sq / (acc.count - 6.0);
  // Degeneracy: rotation columns scale with distance, so compare eigenvalues of
  // D H D with D = diag(1/L, 1/L, 1/L, 1, 1, 1) (dimensionless ratio). For the
  // translation block this ratio is the share of squared normal components along
  // the weakest direction; normal noise alone gives ~0.5-1 % in a corridor
  // (PCA over 10 neighbours with mm noise), hence the default threshold of 2 %.
  Vec6 d;
  d << Eigen::Vector3d::Constant(1.0 / result.characteristic_length_m), Eigen::Vector3d::Ones();
  const Mat6 scaled = d.asDiagonal() * acc.hessian * d.asDiagonal();
  result.scaled_eigenvalues = Eigen::SelfAdjointEigenSolver<Mat6>(scaled).eigenvalues();
  const double max_eig = result.scaled_eigenvalues(5);
  // Two tests: translation block (share of squared normal components along the
  // weakest direction; catches planes and corridors) against the threshold, and the
  // full scaled Hessian against a tenth of it (weak rotations, e.g. roll about a
  // camera's optical axis in a room, reach ~5e-3 while still well determined).
  const Eigen::Vector3d trans_eig =
      Eigen::SelfAdjointEigenSolver<Mat3>(acc.hessian.bottomRightCorner<3, 3>()).eigenvalues();
  const double trans_ratio = trans_eig(2) > 0 ? trans_eig(0) / trans_eig(2) : 0.0;
  const double full_ratio = max_eig > 0 ? result.scaled_eigenvalues(0) / max_eig : 0.0;
  result.degenerate = !(max_eig > 0) || trans_ratio < options.degeneracy_threshold ||
                      full_ratio < 0.1 * options.degeneracy_threshold;
  if (acc.count < static_cast<size_t>(options.min_inliers)) {
    result.message = fmt::format("too few correspondences: {} < min_inliers {}", acc.count,
                                 options.min_inliers);
  } else if (result.degenerate) {
    result.message = fmt::format(
        "degenerate geometry: Hessian eigenvalue ratios {:.2e} (translation) / {:.2e} (scaled, "
        "all) below {:.1e} / {:.1e} (e.g. a plane or a corridor); the estimate is unconstrained "
        "along some directions",
        trans_ratio, full_ratio, options.degeneracy_threshold, 0.1 * options.degeneracy_threshold);
  } else if (!small_step) {
    result.message = fmt::format("no convergence within {} iterations", options.max_iterations);
  } else {
    result.message = "converged";
  }
  result.converged = small_step && !result.degenerate &&
                     acc.count >= static_cast<size_t>(options.min_inliers);
  return result;
}

}  // namespace lisfm
