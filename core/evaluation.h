// Trajectory evaluation against ground truth: time association, alignment,
// absolute trajectory error (ATE), relative pose error (RPE) per frame and over
// travelled distance, and the HILTI SLAM Challenge 2022 control-point score.
//
// Pure math on in-memory trajectories; file formats live in core/io
// (trajectory_io.h) and the command in apps/evaluate_command.cc.
//
// Frames and units: both trajectories hold world_from_body poses (body = IMU
// frame), each in its own world frame. The alignment maps the estimate's world
// into the reference's world (reference_from_estimate, DESIGN.md "Alignment in
// evaluation"). Positions and translation errors are in metres, rotation errors
// in degrees, times in ns.
//
// Association: every reference pose is paired with the *nearest* estimate
// sample in time when that sample is within max_dt (binary search, no
// interpolation of the estimate, like TUM's associate.py and evo). The pairing
// is one-to-one: when two reference poses pick the same estimate sample, the
// pair with the smaller time difference is kept. Pairs are ordered by time.
//
// Failures: too few associated pairs (0, or < 3 for an SE(3)/Sim(3) alignment)
// and degenerate (collinear) positions throw InputError; callers add the file
// names. Invalid options throw InternalError (THROW_CHECK).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "core/time.h"
#include "core/trajectory.h"

namespace lisfm {

enum class AlignmentType {
  kNone,  // compare in the given frames
  kSE3,   // rigid: rotation + translation (metric estimates)
  kSim3,  // similarity: rotation + translation + scale (scale-free estimates)
};

// "none", "se3", "sim3".
std::string AlignmentTypeName(AlignmentType type);
// Parses "none" / "se3" / "sim3"; false for anything else.
bool ParseAlignmentType(const std::string& name, AlignmentType* type);

// Summary statistics of a list of non-negative errors. With count == 0 every
// value is NaN (undefined), never 0.
struct ErrorStats {
  double rmse = 0;
  double mean = 0;
  double median = 0;  // mean of the two middle values for an even count
  double std = 0;     // population standard deviation (divides by count)
  double min = 0;
  double max = 0;
  size_t count = 0;
};
ErrorStats ComputeErrorStats(const std::vector<double>& values);

// One associated pair: reference pose `reference_index` and estimate sample
// `estimate_index`, whose stamps differ by `dt_ns` = t_estimate - t_reference.
struct AssociatedPair {
  size_t reference_index = 0;
  size_t estimate_index = 0;
  int64_t dt_ns = 0;
};

// Nearest-in-time, one-to-one association (see the file comment). Both inputs
// are strictly increasing (Trajectory's invariant), so the result is strictly
// increasing in both indices. max_dt_ns must be >= 0.
std::vector<AssociatedPair> AssociateByTime(
    const std::vector<TimestampNs>& reference_ns,
    const Trajectory& estimate,
    int64_t max_dt_ns);
std::vector<AssociatedPair> AssociateByTime(const Trajectory& reference,
                                            const Trajectory& estimate,
                                            int64_t max_dt_ns);

// Least-squares alignment reference ~= T * estimate of corresponding positions
// (Umeyama 1991 via AlignUmeyama). kNone returns the identity. Throws
// InputError for < 3 or collinear positions when an alignment is requested.
Sim3 AlignPositions(const std::vector<Vec3>& estimate_positions,
                    const std::vector<Vec3>& reference_positions,
                    AlignmentType type);

// How well corresponding positions determine the rotation of a position-only
// alignment (Umeyama / Horn), and whether that uncertainty dominates the
// rotation ATE.
//
// Criterion. The alignment minimises sum_k |p_ref_k - T p_est_k|^2. For a small
// rotation error dθ of T about the aligned centroid, the Gauss-Newton
// information of that cost is H = sum_k [c_k]x^T [c_k]x = sum_k (|c_k|^2 I -
// c_k c_k^T), c_k the centred aligned estimate positions; with isotropic
// position errors of variance σ² per axis, cov(dθ) = σ² H^-1. σ² is taken from
// the ATE residuals r_k: σ² = sum_k |r_k|^2 / (3n - d), d = 6 (SE(3)) or 7
// (Sim(3)). The worst direction is H's smallest eigenvector, with
//   rotation_sigma = σ / sqrt(λ_min(H))   (rad).
// For a nearly straight path λ_min is the positions' spread across the path
// (summed over both cross axes) and its eigenvector the path direction: the
// rotation about the path is then barely determined; for a short path every
// λ is small. The alignment's rotation error adds to every pair's rotation
// error, so the rotation ATE is `dominated` by the alignment when
//   ATE rotation rmse <= 3 * rotation_sigma,
// i.e. the measured rotation error lies within what the alignment alone
// produces at three standard deviations and cannot be told apart from it.
// Zero (not dominated) without alignment or with exact positions (σ = 0).
struct AlignmentConditioning {
  double rotation_sigma_rad = 0;   // σ / sqrt(λ_min(H)) as above
  Vec3 weak_axis = Vec3::Zero();   // unit eigenvector of λ_min(H), reference world
  double position_sigma_m = 0;     // σ from the residuals
  bool rotation_dominated = false;  // rmse_rot <= 3 rotation_sigma
};

// The criterion above for aligned estimate positions, reference positions,
// the rotation ATE rmse (deg) and the number of alignment parameters d.
AlignmentConditioning ComputeAlignmentConditioning(
    const std::vector<Vec3>& aligned_estimate_positions,
    const std::vector<Vec3>& reference_positions,
    double ate_rotation_rmse_deg,
    int num_alignment_parameters);

// RPE statistics over pose pairs that are `distance_m` apart along the
// reference path. For each associated start pose i the end pose is the first
// later associated pose j whose reference path length from i reaches
// distance_m; starts with no such j are skipped.
struct DistanceRpe {
  double distance_m = 0;
  ErrorStats
      translation_m;  // |translation of (ref_i^-1 ref_j)^-1 (est_i^-1 est_j)|
  ErrorStats rotation_deg;  // angle of the same relative error
  // 100 * mean over segments of translation error / reference path length of
  // the segment (>= distance_m); NaN when there is no segment.
  double drift_percent = 0;
};

struct TrajectoryEvaluationOptions {
  AlignmentType alignment = AlignmentType::kSE3;  // how the estimate is aligned
  int64_t max_dt_ns = 10000000;  // association tolerance (ns), 10 ms
  std::vector<double> rpe_distances_m = {
      1.0, 5.0, 10.0};  // RPE windows (m), each > 0
  bool Check() const;
};

struct TrajectoryEvaluation {
  size_t num_reference = 0;
  size_t num_estimate = 0;
  std::vector<AssociatedPair> pairs;
  AlignmentType alignment = AlignmentType::kSE3;
  // reference_world_from_estimate_world; scale is 1 unless alignment is kSim3.
  Sim3 reference_from_estimate;

  // Per associated pair, in time order: reference stamp, reference position,
  // aligned estimate position and the ATE translation error |p_ref - T p_est|.
  std::vector<TimestampNs> t_ns;
  std::vector<Vec3> reference_positions;
  std::vector<Vec3> aligned_estimate_positions;
  std::vector<double> translation_errors_m;

  ErrorStats ate_translation_m;  // absolute position error after alignment
  ErrorStats ate_rotation_deg;   // angle of R_ref^T * R_aligned_est
  // How much of ate_rotation_deg the position-only alignment may explain
  // (default-initialised, never dominated, for AlignmentType::kNone).
  AlignmentConditioning alignment_conditioning;
  // RPE between consecutive associated pairs (one "frame" step each).
  ErrorStats rpe_translation_m;
  ErrorStats rpe_rotation_deg;
  // One entry per options.rpe_distances_m, same order.
  std::vector<DistanceRpe> rpe_distance;
};

// Associates, aligns and scores `estimate` against `reference`. RPE uses the
// aligned estimate poses, so with Sim(3) its translations are in reference
// metres (RPE does not depend on an SE(3) alignment). Throws InputError when
// no pair (or, for SE(3)/Sim(3), fewer than 3) associates.
TrajectoryEvaluation EvaluateTrajectory(
    const Trajectory& reference,
    const Trajectory& estimate,
    const TrajectoryEvaluationOptions& options);

// A surveyed point (HILTI 2022 control point) that the tool tip touched at
// t_ns.
struct ControlPoint {
  TimestampNs t_ns = 0;
  Vec3 position = Vec3::Zero();  // in the reference world frame (m)
  std::string id;                // optional label from the file ("" when none)
};

struct HiltiScoreOptions {
  // Lever arm T_imu_tip translation: the pole tip in the IMU frame (m), from
  // the HILTI 2022 handheld device. The scored point is world_from_imu *
  // tip_in_imu.
  Vec3 tip_in_imu = Vec3(0.059, -0.00855, 0.1964);
  int64_t max_dt_ns = 2 * kNsPerSecond;  // association tolerance (ns), 2 s
  // Error bands (m) and points per band: error < 1 cm -> 10, < 3 cm -> 6,
  // < 6 cm -> 3, < 10 cm -> 1, otherwise 0.
  std::vector<double> thresholds_m = {0.01, 0.03, 0.06, 0.10};
  std::vector<int> band_points = {10, 6, 3, 1};
  bool Check() const;
};

// Points of the first band whose threshold the error is below, 0 if none.
int HiltiPointsForError(double error_m, const HiltiScoreOptions& options);

struct ControlPointResult {
  ControlPoint control_point;
  bool associated = false;  // an estimate sample within max_dt exists
  int64_t dt_ns = 0;        // t_estimate - t_control_point when associated
  Vec3 aligned_tip =
      Vec3::Zero();    // estimated tip after alignment (reference world)
  double error_m = 0;  // |aligned_tip - position| when associated
  int points = 0;      // 0 when not associated
};

struct HiltiScore {
  std::vector<ControlPointResult> points;  // one per control point, input order
  size_t num_associated = 0;
  // reference_world_from_estimate_world from the tip positions (scale 1).
  Sim3 reference_from_estimate;
  ErrorStats errors_m;  // over associated points
  // 100 * sum(points) / (10 * number of control points); missing points count
  // 0.
  double score = 0;
};

// HILTI SLAM Challenge 2022 scoring: the estimate (IMU frame) is moved to the
// pole tip by the lever arm, each control point is associated with the nearest
// estimate sample within max_dt, the tips are SE(3)-aligned (no scale) to the
// associated control points, and each point scores by its error band. Each
// control point is associated on its own (not one-to-one: a point visited twice
// may share a sample), so the list need not be sorted. Throws InputError for an
// empty list or fewer than 3 associated, non-collinear points.
HiltiScore ComputeHiltiScore(const std::vector<ControlPoint>& control_points,
                             const Trajectory& estimate,
                             const HiltiScoreOptions& options);

}  // namespace lisfm
