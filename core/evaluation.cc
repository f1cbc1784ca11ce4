#include "core/evaluation.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

#include <Eigen/Eigenvalues>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

double RotationErrorDeg(const Quat& a, const Quat& b) {
  return so3::AngularDistance(a, b) * kRadToDeg;
}

Eigen::Matrix3Xd ToMatrix(const std::vector<Vec3>& points) {
  Eigen::Matrix3Xd m(3, static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i)
    m.col(static_cast<Eigen::Index>(i)) = points[i];
  return m;
}

std::string SpanText(const Trajectory& t) {
  return fmt::format("[{}, {}] s",
                     FormatNsAsSeconds(t.start_ns()),
                     FormatNsAsSeconds(t.end_ns()));
}

}  // namespace

std::string AlignmentTypeName(AlignmentType type) {
  switch (type) {
    case AlignmentType::kNone:
      return "none";
    case AlignmentType::kSE3:
      return "se3";
    case AlignmentType::kSim3:
      return "sim3";
  }
  return "unknown";
}

bool ParseAlignmentType(const std::string& name, AlignmentType* type) {
  if (name == "none") {
    *type = AlignmentType::kNone;
  } else if (name == "se3") {
    *type = AlignmentType::kSE3;
  } else if (name == "sim3") {
    *type = AlignmentType::kSim3;
  } else {
    return false;
  }
  return true;
}

ErrorStats ComputeErrorStats(const std::vector<double>& values) {
  ErrorStats s;
  s.count = values.size();
  if (values.empty()) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    s.rmse = s.mean = s.median = s.std = s.min = s.max = nan;
    return s;
  }
  const double n = static_cast<double>(values.size());
  double sum = 0;
  double sum_sq = 0;
  for (const double v : values) {
    sum += v;
    sum_sq += v * v;
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  // Two-pass variance: numerically safer than sum_sq / n - mean^2.
  double var = 0;
  for (const double v : values) var += (v - s.mean) * (v - s.mean);
  s.std = std::sqrt(var / n);
  std::vector<double> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  s.min = sorted.front();
  s.max = sorted.back();
  const size_t mid = sorted.size() / 2;
  s.median = sorted.size() % 2 == 1 ? sorted[mid]
                                    : 0.5 * (sorted[mid - 1] + sorted[mid]);
  return s;
}

std::vector<AssociatedPair> AssociateByTime(
    const std::vector<TimestampNs>& reference_ns,
    const Trajectory& estimate,
    int64_t max_dt_ns) {
  THROW_CHECK_GE(max_dt_ns, 0);
  std::vector<AssociatedPair> pairs;
  for (size_t r = 0; r < reference_ns.size(); ++r) {
    if (r > 0) THROW_CHECK_GT(reference_ns[r], reference_ns[r - 1]);
    const int j = estimate.Nearest(reference_ns[r], max_dt_ns);
    if (j < 0) continue;
    AssociatedPair pair;
    pair.reference_index = r;
    pair.estimate_index = static_cast<size_t>(j);
    pair.dt_ns = estimate[pair.estimate_index].t_ns - reference_ns[r];
    // Increasing inputs give non-decreasing nearest indices, so a shared
    // estimate sample can only be the previous pair's: keep the closer one.
    if (!pairs.empty() && pairs.back().estimate_index == pair.estimate_index) {
      if (std::llabs(pair.dt_ns) < std::llabs(pairs.back().dt_ns))
        pairs.back() = pair;
      continue;
    }
    pairs.push_back(pair);
  }
  return pairs;
}

std::vector<AssociatedPair> AssociateByTime(const Trajectory& reference,
                                            const Trajectory& estimate,
                                            int64_t max_dt_ns) {
  std::vector<TimestampNs> stamps;
  stamps.reserve(reference.size());
  for (const auto& p : reference.poses()) stamps.push_back(p.t_ns);
  return AssociateByTime(stamps, estimate, max_dt_ns);
}

Sim3 AlignPositions(const std::vector<Vec3>& estimate_positions,
                    const std::vector<Vec3>& reference_positions,
                    AlignmentType type) {
  THROW_CHECK_EQ(estimate_positions.size(), reference_positions.size());
  if (type == AlignmentType::kNone) return Sim3();
  return AlignUmeyama(ToMatrix(estimate_positions),
                      ToMatrix(reference_positions),
                      type == AlignmentType::kSim3);
}

AlignmentConditioning ComputeAlignmentConditioning(
    const std::vector<Vec3>& aligned_estimate_positions,
    const std::vector<Vec3>& reference_positions,
    double ate_rotation_rmse_deg,
    int num_alignment_parameters) {
  THROW_CHECK_EQ(aligned_estimate_positions.size(), reference_positions.size());
  AlignmentConditioning c;
  const size_t n = aligned_estimate_positions.size();
  const double dof = 3.0 * static_cast<double>(n) - num_alignment_parameters;
  if (n < 3 || dof <= 0) return c;
  Vec3 centroid = Vec3::Zero();
  double sum_sq_residual = 0;
  for (size_t k = 0; k < n; ++k) {
    centroid += aligned_estimate_positions[k];
    sum_sq_residual += (reference_positions[k] - aligned_estimate_positions[k]).squaredNorm();
  }
  centroid /= static_cast<double>(n);
  Mat3 H = Mat3::Zero();
  for (const Vec3& p : aligned_estimate_positions) {
    const Vec3 q = p - centroid;
    H += q.squaredNorm() * Mat3::Identity() - q * q.transpose();
  }
  c.position_sigma_m = std::sqrt(sum_sq_residual / dof);
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(H);
  const double lambda_min = eig.eigenvalues()(0);  // ascending
  c.weak_axis = eig.eigenvectors().col(0);
  if (c.position_sigma_m == 0) return c;
  c.rotation_sigma_rad = lambda_min > 0 ? c.position_sigma_m / std::sqrt(lambda_min)
                                        : std::numeric_limits<double>::infinity();
  c.rotation_dominated = ate_rotation_rmse_deg / kRadToDeg <= 3.0 * c.rotation_sigma_rad;
  return c;
}

bool TrajectoryEvaluationOptions::Check() const {
  CHECK_OPTION_GE(max_dt_ns, 0);
  CHECK_OPTION_MSG(
      rpe_distances_m,
      std::all_of(rpe_distances_m.begin(),
                  rpe_distances_m.end(),
                  [](double d) { return d > 0 && std::isfinite(d); }),
      "a list of distances > 0");
  return true;
}

TrajectoryEvaluation EvaluateTrajectory(
    const Trajectory& reference,
    const Trajectory& estimate,
    const TrajectoryEvaluationOptions& options) {
  THROW_CHECK(options.Check());
  if (reference.empty())
    throw InputError("evaluation: the reference trajectory is empty");
  if (estimate.empty())
    throw InputError("evaluation: the estimated trajectory is empty");

  TrajectoryEvaluation ev;
  ev.num_reference = reference.size();
  ev.num_estimate = estimate.size();
  ev.alignment = options.alignment;
  ev.pairs = AssociateByTime(reference, estimate, options.max_dt_ns);
  if (ev.pairs.empty()) {
    throw InputError(
        fmt::format("no estimate pose lies within max_dt = {} s of a reference "
                    "pose (reference spans {}, "
                    "estimate spans {})",
                    NsToSeconds(options.max_dt_ns),
                    SpanText(reference),
                    SpanText(estimate)));
  }

  const size_t n = ev.pairs.size();
  std::vector<Vec3> estimate_positions;
  std::vector<SE3> reference_poses;
  std::vector<SE3> estimate_poses;
  for (const auto& pair : ev.pairs) {
    const StampedPose& r = reference[pair.reference_index];
    const StampedPose& e = estimate[pair.estimate_index];
    ev.t_ns.push_back(r.t_ns);
    ev.reference_positions.push_back(r.pose.translation());
    estimate_positions.push_back(e.pose.translation());
    reference_poses.push_back(r.pose);
    estimate_poses.push_back(e.pose);
  }
  ev.reference_from_estimate = AlignPositions(
      estimate_positions, ev.reference_positions, options.alignment);

  // ATE on the aligned estimate.
  std::vector<SE3> aligned(n);
  std::vector<double> rotation_errors(n);
  ev.translation_errors_m.resize(n);
  ev.aligned_estimate_positions.resize(n);
  for (size_t k = 0; k < n; ++k) {
    aligned[k] = ev.reference_from_estimate.Transform(estimate_poses[k]);
    ev.aligned_estimate_positions[k] = aligned[k].translation();
    ev.translation_errors_m[k] =
        (ev.reference_positions[k] - aligned[k].translation()).norm();
    rotation_errors[k] =
        RotationErrorDeg(reference_poses[k].rotation(), aligned[k].rotation());
  }
  ev.ate_translation_m = ComputeErrorStats(ev.translation_errors_m);
  ev.ate_rotation_deg = ComputeErrorStats(rotation_errors);
  if (options.alignment != AlignmentType::kNone) {
    ev.alignment_conditioning = ComputeAlignmentConditioning(
        ev.aligned_estimate_positions, ev.reference_positions, ev.ate_rotation_deg.rmse,
        options.alignment == AlignmentType::kSim3 ? 7 : 6);
  }

  // Relative error of the motion i -> j: (ref_i^-1 ref_j)^-1 (est_i^-1 est_j).
  auto relative_error = [&](size_t i, size_t j) {
    const SE3 ref_ij = reference_poses[i].Inverse() * reference_poses[j];
    const SE3 est_ij = aligned[i].Inverse() * aligned[j];
    return ref_ij.Inverse() * est_ij;
  };

  std::vector<double> rpe_t;
  std::vector<double> rpe_r;
  for (size_t k = 1; k < n; ++k) {
    const SE3 err = relative_error(k - 1, k);
    rpe_t.push_back(err.translation().norm());
    rpe_r.push_back(RotationErrorDeg(Quat::Identity(), err.rotation()));
  }
  ev.rpe_translation_m = ComputeErrorStats(rpe_t);
  ev.rpe_rotation_deg = ComputeErrorStats(rpe_r);

  // Cumulative path length along the associated reference poses.
  std::vector<double> path(n, 0.0);
  for (size_t k = 1; k < n; ++k) {
    path[k] =
        path[k - 1] +
        (ev.reference_positions[k] - ev.reference_positions[k - 1]).norm();
  }
  for (const double d : options.rpe_distances_m) {
    DistanceRpe window;
    window.distance_m = d;
    std::vector<double> t_err;
    std::vector<double> r_err;
    double drift_sum = 0;
    for (size_t i = 0; i + 1 < n; ++i) {
      // First j > i with path[j] >= path[i] + d (path is non-decreasing).
      const auto it =
          std::lower_bound(path.begin() + static_cast<std::ptrdiff_t>(i) + 1,
                           path.end(),
                           path[i] + d);
      if (it == path.end()) break;  // later starts cannot reach d either
      const size_t j = static_cast<size_t>(it - path.begin());
      const SE3 err = relative_error(i, j);
      t_err.push_back(err.translation().norm());
      r_err.push_back(RotationErrorDeg(Quat::Identity(), err.rotation()));
      drift_sum += t_err.back() / (path[j] - path[i]);
    }
    window.translation_m = ComputeErrorStats(t_err);
    window.rotation_deg = ComputeErrorStats(r_err);
    window.drift_percent =
        t_err.empty() ? std::numeric_limits<double>::quiet_NaN()
                      : 100.0 * drift_sum / static_cast<double>(t_err.size());
    ev.rpe_distance.push_back(window);
  }
  return ev;
}

bool HiltiScoreOptions::Check() const {
  CHECK_OPTION_MSG(tip_in_imu, tip_in_imu.allFinite(), "finite");
  CHECK_OPTION_GE(max_dt_ns, 0);
  bool bands_ok =
      !thresholds_m.empty() && thresholds_m.size() == band_points.size();
  for (size_t i = 0; bands_ok && i < thresholds_m.size(); ++i) {
    bands_ok = thresholds_m[i] > 0 && std::isfinite(thresholds_m[i]) &&
               band_points[i] > 0 &&
               (i == 0 || (thresholds_m[i] > thresholds_m[i - 1] &&
                           band_points[i] <= band_points[i - 1]));
  }
  CHECK_OPTION_MSG(
      thresholds_m,
      bands_ok,
      "increasing thresholds > 0, one per band_points entry (positive, "
      "non-increasing)");
  return true;
}

int HiltiPointsForError(double error_m, const HiltiScoreOptions& options) {
  for (size_t i = 0; i < options.thresholds_m.size(); ++i) {
    if (error_m < options.thresholds_m[i]) return options.band_points[i];
  }
  return 0;
}

HiltiScore ComputeHiltiScore(const std::vector<ControlPoint>& control_points,
                             const Trajectory& estimate,
                             const HiltiScoreOptions& options) {
  THROW_CHECK(options.Check());
  if (control_points.empty())
    throw InputError("HILTI score: no control points");
  if (estimate.empty())
    throw InputError("HILTI score: the estimated trajectory is empty");

  HiltiScore result;
  result.points.resize(control_points.size());
  std::vector<Vec3> tips;
  std::vector<Vec3> targets;
  std::vector<Vec3> tip_of_point(control_points.size(), Vec3::Zero());
  for (size_t i = 0; i < control_points.size(); ++i) {
    ControlPointResult& p = result.points[i];
    p.control_point = control_points[i];
    const int j = estimate.Nearest(control_points[i].t_ns, options.max_dt_ns);
    if (j < 0) continue;
    const StampedPose& e = estimate[static_cast<size_t>(j)];
    p.associated = true;
    p.dt_ns = e.t_ns - control_points[i].t_ns;
    tip_of_point[i] =
        e.pose * options.tip_in_imu;  // world_from_imu * tip_in_imu
    tips.push_back(tip_of_point[i]);
    targets.push_back(control_points[i].position);
  }
  result.num_associated = tips.size();
  if (tips.size() < 3) {
    throw InputError(
        fmt::format("HILTI score: only {} of {} control points have an "
                    "estimate pose within {} s "
                    "(estimate spans {}); the SE(3) alignment needs at least 3",
                    tips.size(),
                    control_points.size(),
                    NsToSeconds(options.max_dt_ns),
                    SpanText(estimate)));
  }
  result.reference_from_estimate =
      AlignPositions(tips, targets, AlignmentType::kSE3);

  int total = 0;
  std::vector<double> errors;
  for (size_t i = 0; i < result.points.size(); ++i) {
    ControlPointResult& p = result.points[i];
    if (!p.associated) continue;
    p.aligned_tip = result.reference_from_estimate * tip_of_point[i];
    p.error_m = (p.aligned_tip - p.control_point.position).norm();
    p.points = HiltiPointsForError(p.error_m, options);
    total += p.points;
    errors.push_back(p.error_m);
  }
  result.errors_m = ComputeErrorStats(errors);
  const int max_points =
      *std::max_element(options.band_points.begin(), options.band_points.end());
  result.score = 100.0 * static_cast<double>(total) /
                 (static_cast<double>(max_points) *
                  static_cast<double>(control_points.size()));
  return result;
}

}  // namespace lisfm
