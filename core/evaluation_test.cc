// Trajectory evaluation on constructed cases with known answers (rigid and
// similarity transforms, seeded noise checked against a straightforward
// computation, constant per-step drift, hand-made HILTI error bands) and the
// HILTI 2022 score of the real dense ground truth against the control points.
#include "core/evaluation.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>

#include "core/errors.h"
#include "core/io/trajectory_io.h"
#include "tests/common/option_check_test.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

constexpr int64_t kMs = 1000000;
constexpr TimestampNs kT0 = 1646304541627162000LL;

// A smooth 3D handheld-like path with changing orientation, 10 Hz.
Trajectory CurvedTrajectory(int n) {
  std::vector<StampedPose> poses;
  for (int k = 0; k < n; ++k) {
    const double t = 0.1 * k;
    const Vec3 p(5 * std::cos(0.2 * t) + 0.3 * t,
                 3 * std::sin(0.3 * t),
                 0.5 * std::sin(0.5 * t));
    const Quat q =
        so3::Exp(Vec3(0.1 * std::sin(t), 0.2 * std::cos(0.7 * t), 0.3 * t));
    poses.push_back({kT0 + k * 100 * kMs, SE3(q, p)});
  }
  return Trajectory(poses);
}

// world_from_body poses re-expressed in another world: new_world_from_world *
// pose.
Trajectory Transformed(const Trajectory& traj, const Sim3& new_from_old) {
  std::vector<StampedPose> poses;
  for (const auto& p : traj.poses())
    poses.push_back({p.t_ns, new_from_old.Transform(p.pose)});
  return Trajectory(poses);
}

TrajectoryEvaluationOptions Options(AlignmentType alignment) {
  TrajectoryEvaluationOptions o;
  o.alignment = alignment;
  return o;
}

TEST(ErrorStats, KnownValues) {
  const ErrorStats s = ComputeErrorStats({3, 1, 2, 4});
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(30.0 / 4));
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(5.0 / 4));
  EXPECT_EQ(s.min, 1);
  EXPECT_EQ(s.max, 4);
  EXPECT_DOUBLE_EQ(ComputeErrorStats({5, 1, 2}).median, 2);
  const ErrorStats empty = ComputeErrorStats({});
  EXPECT_EQ(empty.count, 0u);
  EXPECT_TRUE(std::isnan(empty.rmse));
  EXPECT_TRUE(std::isnan(empty.median));
}

TEST(AlignmentType, NamesRoundTrip) {
  for (const auto t :
       {AlignmentType::kNone, AlignmentType::kSE3, AlignmentType::kSim3}) {
    AlignmentType parsed = AlignmentType::kNone;
    ASSERT_TRUE(ParseAlignmentType(AlignmentTypeName(t), &parsed));
    EXPECT_EQ(parsed, t);
  }
  AlignmentType parsed;
  EXPECT_FALSE(ParseAlignmentType("foo", &parsed));
  EXPECT_FALSE(ParseAlignmentType("SE3", &parsed));
}

TEST(Association, NearestWithinToleranceOneToOne) {
  const Trajectory estimate({{kT0 + 12 * kMs, SE3()}, {kT0 + 50 * kMs, SE3()}});
  // References at 0, 10, 20, 48 ms: 10 and 20 both pick the sample at 12 ms;
  // the closer one (10 ms, |dt| = 2 ms) is kept. 0 ms is 12 ms away (> 11 ms).
  const std::vector<TimestampNs> refs = {
      kT0, kT0 + 10 * kMs, kT0 + 20 * kMs, kT0 + 48 * kMs};
  const auto pairs = AssociateByTime(refs, estimate, 11 * kMs);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].reference_index, 1u);
  EXPECT_EQ(pairs[0].estimate_index, 0u);
  EXPECT_EQ(pairs[0].dt_ns, 2 * kMs);
  EXPECT_EQ(pairs[1].reference_index, 3u);
  EXPECT_EQ(pairs[1].estimate_index, 1u);
  EXPECT_EQ(pairs[1].dt_ns, 2 * kMs);
  EXPECT_TRUE(AssociateByTime(refs, estimate, 1 * kMs).empty());
}

TEST(Evaluation, NoOverlapInTimeIsInputError) {
  const Trajectory ref = CurvedTrajectory(50);
  std::vector<StampedPose> later;
  for (const auto& p : ref.poses())
    later.push_back({p.t_ns + 3600 * kNsPerSecond, p.pose});
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { EvaluateTrajectory(ref, Trajectory(later), Options(AlignmentType::kSE3)); },
      {"no estimate pose lies within max_dt"}));
}

TEST(Evaluation, RigidMotionIsRecoveredBySe3) {
  const Trajectory ref = CurvedTrajectory(600);
  test::Rng().seed(test::kTestSeed);
  Sim3 moved;
  moved.pose =
      test::RandomPose(3.0, 20.0);  // estimate_world_from_reference_world
  const Trajectory est = Transformed(ref, moved);

  const TrajectoryEvaluation ev =
      EvaluateTrajectory(ref, est, Options(AlignmentType::kSE3));
  EXPECT_EQ(ev.pairs.size(), 600u);
  EXPECT_EQ(ev.reference_from_estimate.scale, 1.0);
  // The recovered alignment is the inverse of the applied motion. Tolerances:
  // an exact-data Umeyama fit on ~10 m coordinates is accurate to ~1e-12.
  EXPECT_TRUE(test::PosesNear(
      ev.reference_from_estimate.pose, moved.pose.Inverse(), 1e-9, 1e-9));
  EXPECT_LT(ev.ate_translation_m.max, 1e-9);
  EXPECT_LT(ev.ate_rotation_deg.max, 1e-6);
  EXPECT_LT(ev.rpe_translation_m.max, 1e-9);
  EXPECT_EQ(ev.rpe_distance.size(), 3u);
  EXPECT_GT(ev.rpe_distance[2].translation_m.count, 0u);
  EXPECT_LT(ev.rpe_distance[2].translation_m.max, 1e-9);

  // Without alignment the same estimate is far off (the motion is metres).
  const TrajectoryEvaluation none =
      EvaluateTrajectory(ref, est, Options(AlignmentType::kNone));
  EXPECT_GT(none.ate_translation_m.rmse, 1.0);
  // RPE does not depend on a rigid change of world frame.
  EXPECT_LT(none.rpe_translation_m.max, 1e-9);
}

TEST(Evaluation, ScaleIsRecoveredBySim3Only) {
  const Trajectory ref = CurvedTrajectory(600);
  test::Rng().seed(test::kTestSeed);
  Sim3 shrink;  // estimate = reference shrunk by 1.3 in a moved frame
  shrink.scale = 1.0 / 1.3;
  shrink.pose = test::RandomPose(3.0, 5.0);
  const Trajectory est = Transformed(ref, shrink);

  const TrajectoryEvaluation sim3 =
      EvaluateTrajectory(ref, est, Options(AlignmentType::kSim3));
  EXPECT_NEAR(sim3.reference_from_estimate.scale, 1.3, 1e-9);
  EXPECT_LT(sim3.ate_translation_m.max, 1e-9);
  // With Sim(3), RPE is measured in reference metres and vanishes too.
  EXPECT_LT(sim3.rpe_distance[0].translation_m.max, 1e-9);

  const TrajectoryEvaluation se3 =
      EvaluateTrajectory(ref, est, Options(AlignmentType::kSE3));
  EXPECT_EQ(se3.reference_from_estimate.scale, 1.0);
  // A 23 % scale error over a path of several metres: ATE of at least
  // decimetres.
  EXPECT_GT(se3.ate_translation_m.rmse, 0.1);
}

// A short straight path with 1 cm position noise: the positions fix the
// alignment's rotation about the path only through the noise, so the rotation
// ATE (here nothing but that alignment error) is flagged. A curved path with
// the same noise and real 1 deg orientation errors is not.
TEST(Evaluation, AlignmentConditioningFlagsNearlyStraightPaths) {
  test::Rng().seed(test::kTestSeed);
  std::normal_distribution<double> noise(0.0, 0.01);
  const auto noisy = [&](const Vec3& p) {
    return Vec3(p.x() + noise(test::Rng()), p.y() + noise(test::Rng()),
                p.z() + noise(test::Rng()));
  };
  std::vector<StampedPose> line_ref, line_est;
  for (int k = 0; k < 50; ++k) {
    const SE3 pose(so3::Exp(Vec3(0, 0, 0.01 * k)), Vec3(0.1 * k, 0.0, 1.0));  // 5 m along x
    line_ref.push_back({kT0 + k * 100 * kMs, pose});
    line_est.push_back({kT0 + k * 100 * kMs, SE3(pose.rotation(), noisy(pose.translation()))});
  }
  const TrajectoryEvaluation line = EvaluateTrajectory(
      Trajectory(line_ref), Trajectory(line_est), Options(AlignmentType::kSE3));
  const AlignmentConditioning& a = line.alignment_conditioning;
  EXPECT_TRUE(a.rotation_dominated) << a.rotation_sigma_rad << " rad vs ATE "
                                    << line.ate_rotation_deg.rmse << " deg";
  EXPECT_GT(std::abs(a.weak_axis.x()), 0.99) << a.weak_axis.transpose();  // about the path
  // σ = 1 cm across a cross-path spread of ~1 cm: σ / sqrt(50 * 2e-4) ~ 0.1 rad.
  EXPECT_GT(a.rotation_sigma_rad, 0.03);
  EXPECT_NEAR(a.position_sigma_m, 0.01, 0.003);

  const Trajectory curved = CurvedTrajectory(600);
  std::normal_distribution<double> tilt(0.0, 0.01);  // rad per axis, ~1 deg in all
  std::vector<StampedPose> curved_est;
  for (const StampedPose& p : curved.poses()) {
    const Quat q = p.pose.rotation() *
                   so3::Exp(Vec3(tilt(test::Rng()), tilt(test::Rng()), tilt(test::Rng())));
    curved_est.push_back({p.t_ns, SE3(q, noisy(p.pose.translation()))});
  }
  const TrajectoryEvaluation good =
      EvaluateTrajectory(curved, Trajectory(curved_est), Options(AlignmentType::kSE3));
  EXPECT_FALSE(good.alignment_conditioning.rotation_dominated);
  EXPECT_LT(good.alignment_conditioning.rotation_sigma_rad, 1e-3);
  // No alignment, nothing to flag.
  const TrajectoryEvaluation none = EvaluateTrajectory(
      Trajectory(line_ref), Trajectory(line_est), Options(AlignmentType::kNone));
  EXPECT_FALSE(none.alignment_conditioning.rotation_dominated);
  EXPECT_EQ(none.alignment_conditioning.rotation_sigma_rad, 0.0);
}

TEST(Evaluation, NoisyAteMatchesStraightforwardComputation) {
  const Trajectory ref = CurvedTrajectory(400);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.05);
  std::vector<Vec3> offsets;
  std::vector<StampedPose> noisy;
  for (const auto& p : ref.poses()) {
    offsets.emplace_back(noise(rng), noise(rng), noise(rng));
    noisy.push_back(
        {p.t_ns,
         SE3(p.pose.rotation(), p.pose.translation() + offsets.back())});
  }

  // (a) No alignment: the ATE errors are the offsets' norms.
  const TrajectoryEvaluation none =
      EvaluateTrajectory(ref, Trajectory(noisy), Options(AlignmentType::kNone));
  double sum_sq = 0;
  double sum = 0;
  double max = 0;
  for (const Vec3& o : offsets) {
    sum_sq += o.squaredNorm();
    sum += o.norm();
    max = std::max(max, o.norm());
  }
  const double n = static_cast<double>(offsets.size());
  // Sums of 400 terms in a different order: agreement to ~1e-15 relative.
  EXPECT_NEAR(none.ate_translation_m.rmse, std::sqrt(sum_sq / n), 1e-12);
  EXPECT_NEAR(none.ate_translation_m.mean, sum / n, 1e-12);
  EXPECT_DOUBLE_EQ(none.ate_translation_m.max, max);
  EXPECT_EQ(none.ate_translation_m.count, 400u);

  // (b) The noisy estimate in a moved frame, SE(3)-aligned: compare with a
  // direct Eigen::umeyama fit and a plain RMSE loop.
  test::Rng().seed(test::kTestSeed);
  Sim3 moved;
  moved.pose = test::RandomPose(2.0, 10.0);
  const Trajectory est = Transformed(Trajectory(noisy), moved);
  Eigen::Matrix3Xd src(3, 400);
  Eigen::Matrix3Xd dst(3, 400);
  for (int k = 0; k < 400; ++k) {
    src.col(k) = est[static_cast<size_t>(k)].pose.translation();
    dst.col(k) = ref[static_cast<size_t>(k)].pose.translation();
  }
  const Eigen::Matrix4d T = Eigen::umeyama(src, dst, false);
  double expected_sq = 0;
  for (int k = 0; k < 400; ++k) {
    const Vec3 aligned = T.block<3, 3>(0, 0) * src.col(k) + T.block<3, 1>(0, 3);
    expected_sq += (aligned - dst.col(k)).squaredNorm();
  }
  const TrajectoryEvaluation se3 =
      EvaluateTrajectory(ref, est, Options(AlignmentType::kSE3));
  // Same least-squares problem solved twice: ~1e-12 m agreement on 5 cm errors.
  EXPECT_NEAR(se3.ate_translation_m.rmse, std::sqrt(expected_sq / 400), 1e-10);
  // The optimal alignment can only lower the error of the identity alignment
  // of the un-moved noisy estimate, and stays close to it (noise is isotropic).
  EXPECT_LE(se3.ate_translation_m.rmse, none.ate_translation_m.rmse + 1e-12);
  EXPECT_GT(se3.ate_translation_m.rmse, 0.9 * none.ate_translation_m.rmse);
}

TEST(Evaluation, RpeOfConstantPerStepDriftEqualsTheDrift) {
  // Reference: steps D_k along a curve; estimate: each step followed by the
  // same small error delta, est_{k+1} = est_k * D_k * delta, so every per-frame
  // RPE (ref step)^-1 (est step) is exactly delta.
  const SE3 delta(so3::Exp(Vec3(0.001, -0.002, 0.003)),
                  Vec3(0.002, -0.001, 0.0005));
  std::vector<StampedPose> ref;
  std::vector<StampedPose> est;
  SE3 r;
  SE3 e;
  for (int k = 0; k < 300; ++k) {
    ref.push_back({kT0 + k * 100 * kMs, r});
    est.push_back({kT0 + k * 100 * kMs, e});
    const SE3 step(so3::Exp(Vec3(0.0, 0.01 * std::sin(0.1 * k), 0.05)),
                   Vec3(0.2, 0.01 * (k % 3), 0));
    r = r * step;
    e = e * step * delta;
  }
  const double drift_t = delta.translation().norm();
  const double drift_deg = so3::Log(delta.rotation()).norm() * 180.0 / M_PI;
  for (const auto alignment : {AlignmentType::kNone, AlignmentType::kSE3}) {
    const TrajectoryEvaluation ev = EvaluateTrajectory(
        Trajectory(ref), Trajectory(est), Options(alignment));
    EXPECT_EQ(ev.rpe_translation_m.count, 299u);
    // Composition of 300 poses accumulates ~1e-13 rounding.
    EXPECT_NEAR(ev.rpe_translation_m.min, drift_t, 1e-9);
    EXPECT_NEAR(ev.rpe_translation_m.max, drift_t, 1e-9);
    EXPECT_NEAR(ev.rpe_rotation_deg.min, drift_deg, 1e-7);
    EXPECT_NEAR(ev.rpe_rotation_deg.max, drift_deg, 1e-7);
  }
}

TEST(Evaluation, RpeOverDistanceOnAStraightLine) {
  // Straight reference with 0.125 m steps (exact in binary, so 1/5/10 m are
  // reached after exactly 8/40/80 steps) and a sideways drift of 2 mm per step.
  std::vector<StampedPose> ref;
  std::vector<StampedPose> est;
  const int n = 200;
  for (int k = 0; k < n; ++k) {
    ref.push_back(
        {kT0 + k * 100 * kMs, SE3(Quat::Identity(), Vec3(0.125 * k, 0, 0))});
    est.push_back({kT0 + k * 100 * kMs,
                   SE3(Quat::Identity(), Vec3(0.125 * k, 0.002 * k, 0))});
  }
  const TrajectoryEvaluation ev = EvaluateTrajectory(
      Trajectory(ref), Trajectory(est), Options(AlignmentType::kNone));
  ASSERT_EQ(ev.rpe_distance.size(), 3u);
  const int steps[3] = {8, 40, 80};
  for (int w = 0; w < 3; ++w) {
    const DistanceRpe& d = ev.rpe_distance[static_cast<size_t>(w)];
    EXPECT_EQ(d.translation_m.count, static_cast<size_t>(n - steps[w]));
    EXPECT_NEAR(d.translation_m.mean, 0.002 * steps[w], 1e-12);
    EXPECT_NEAR(d.translation_m.max, 0.002 * steps[w], 1e-12);
    // Drift: 2 mm per 0.125 m = 1.6 %.
    EXPECT_NEAR(d.drift_percent, 100 * 0.002 / 0.125, 1e-9);
    EXPECT_NEAR(d.rotation_deg.max, 0.0, 1e-12);
  }
  EXPECT_NEAR(ev.rpe_translation_m.mean, 0.002, 1e-12);
  // A window longer than the path has no segment.
  TrajectoryEvaluationOptions long_window = Options(AlignmentType::kNone);
  long_window.rpe_distances_m = {100.0};
  const TrajectoryEvaluation none =
      EvaluateTrajectory(Trajectory(ref), Trajectory(est), long_window);
  EXPECT_EQ(none.rpe_distance[0].translation_m.count, 0u);
  EXPECT_TRUE(std::isnan(none.rpe_distance[0].drift_percent));
  // Collinear positions cannot fix a rotation: SE(3) alignment is an input
  // error.
  EXPECT_THROW(
      EvaluateTrajectory(
          Trajectory(ref), Trajectory(est), Options(AlignmentType::kSE3)),
      InputError);
}

TEST(EvaluationOptions, CheckRejectsEachFieldOutOfRange) {
  using T = TrajectoryEvaluationOptions;
  test::ExpectCheckRejects<T>({
      {"max_dt_ns", [](T* o) { o->max_dt_ns = -1; }},
      {"rpe_distances_m",
       [](T* o) {
         o->rpe_distances_m = {1.0, 0.0};
       }},
      {"rpe_distances_m", [](T* o) { o->rpe_distances_m = {std::nan("")}; }},
  });
  using H = HiltiScoreOptions;
  test::ExpectCheckRejects<H>({
      {"tip_in_imu", [](H* o) { o->tip_in_imu.x() = std::nan(""); }},
      {"max_dt_ns", [](H* o) { o->max_dt_ns = -1; }},
      {"thresholds_m", [](H* o) { o->thresholds_m.clear(); }},
      {"thresholds_m",
       [](H* o) { o->thresholds_m.pop_back(); }},  // one per band
      {"thresholds_m", [](H* o) { o->thresholds_m[0] = 0.0; }},
      {"thresholds_m",
       [](H* o) { o->thresholds_m[1] = o->thresholds_m[0]; }},  // increasing
      {"thresholds_m",
       [](H* o) { o->band_points[1] = 11; }},  // points non-increasing
      {"thresholds_m", [](H* o) { o->band_points.back() = 0; }},
  });
}

TEST(HiltiScore, PointsPerBand) {
  const HiltiScoreOptions o;
  EXPECT_TRUE(o.Check());
  EXPECT_EQ(HiltiPointsForError(0.0, o), 10);
  EXPECT_EQ(HiltiPointsForError(0.0099, o), 10);
  EXPECT_EQ(HiltiPointsForError(0.01, o), 6);  // "below 1 cm" is strict
  EXPECT_EQ(HiltiPointsForError(0.0299, o), 6);
  EXPECT_EQ(HiltiPointsForError(0.05, o), 3);
  EXPECT_EQ(HiltiPointsForError(0.0999, o), 1);
  EXPECT_EQ(HiltiPointsForError(0.10, o), 0);
  EXPECT_EQ(HiltiPointsForError(3.0, o), 0);
}

// Control points in symmetric pairs around a centre, each estimated tip pushed
// outwards along its own direction from the centre by a chosen error. The
// offsets sum to zero and their cross-covariance with the points is symmetric
// positive definite, so the least-squares SE(3) alignment is exactly the
// identity and every point keeps its chosen error.
TEST(HiltiScore, HandMadeBandsGiveTheExactScore) {
  const Vec3 centre(3, -2, 1.5);
  const std::vector<std::pair<Vec3, double>> directions_and_errors = {
      {Vec3(4, 0, 0), 0.005},  // 10 points each
      {Vec3(0, 5, 0), 0.02},   // 6
      {Vec3(0, 0, 3), 0.045},  // 3
      {Vec3(2, 2, 0), 0.08},   // 1
      {Vec3(0, 3, 3), 0.2},    // 0
  };
  std::vector<ControlPoint> control_points;
  std::vector<Vec3> tips;
  std::vector<double> errors;
  for (const auto& [d, err] : directions_and_errors) {
    for (const double sign : {1.0, -1.0}) {
      ControlPoint c;
      c.position = centre + sign * d;
      control_points.push_back(c);
      tips.push_back(c.position + sign * err * d.normalized());
      errors.push_back(err);
    }
  }
  // Times 10 s apart; estimate samples 0.7 s after each control point.
  const HiltiScoreOptions options;
  test::Rng().seed(test::kTestSeed);
  std::vector<StampedPose> estimate;
  for (size_t i = 0; i < control_points.size(); ++i) {
    control_points[i].t_ns = kT0 + static_cast<int64_t>(i) * 10 * kNsPerSecond;
    // world_from_imu with a random orientation such that the tip lands on
    // tips[i].
    const Quat q = test::RandomPose(3.0, 0.0).rotation();
    estimate.push_back({control_points[i].t_ns + 700 * kMs,
                        SE3(q, tips[i] - q * options.tip_in_imu)});
  }
  // One more control point 5 s after the last estimate sample: missing.
  ControlPoint missing;
  missing.t_ns = estimate.back().t_ns + 5 * kNsPerSecond;
  missing.position = centre;
  control_points.push_back(missing);

  const HiltiScore score =
      ComputeHiltiScore(control_points, Trajectory(estimate), options);
  ASSERT_EQ(score.points.size(), 11u);
  EXPECT_EQ(score.num_associated, 10u);
  // The alignment is the identity up to rounding (~1e-15 on these coordinates).
  EXPECT_TRUE(
      test::PosesNear(score.reference_from_estimate.pose, SE3(), 1e-12, 1e-12));
  const int expected_points[5] = {10, 6, 3, 1, 0};
  for (size_t i = 0; i < 10; ++i) {
    EXPECT_TRUE(score.points[i].associated);
    EXPECT_EQ(score.points[i].dt_ns, 700 * kMs);
    EXPECT_NEAR(score.points[i].error_m, errors[i], 1e-12) << "point " << i;
    EXPECT_EQ(score.points[i].points, expected_points[i / 2]) << "point " << i;
  }
  EXPECT_FALSE(score.points[10].associated);
  EXPECT_EQ(score.points[10].points, 0);
  // 2 * (10 + 6 + 3 + 1 + 0) = 40 of 11 * 10 possible points.
  EXPECT_DOUBLE_EQ(score.score, 100.0 * 40.0 / 110.0);
  EXPECT_EQ(score.errors_m.count, 10u);

  // With a 0.5 s tolerance nothing associates: an input error, not a score.
  HiltiScoreOptions tight = options;
  tight.max_dt_ns = 500 * kMs;
  EXPECT_THROW(ComputeHiltiScore(control_points, Trajectory(estimate), tight),
               InputError);
  EXPECT_THROW(ComputeHiltiScore({}, Trajectory(estimate), options),
               InputError);
}

constexpr const char* kExp04Dense =
    "hilti2022_groundtruth/"
    "exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt";
constexpr const char* kExp04Points =
    "hilti2022_groundtruth/exp04_construction_upper_level.txt";
constexpr const char* kExp05Dense =
    "hilti2022_groundtruth/"
    "exp_05_construction_upper_level_easy_2022-03-03-11-46-10_imu.txt";
constexpr const char* kExp05Points =
    "hilti2022_groundtruth/exp05_construction_upper_level_2.txt";

TEST(HiltiScore, DenseGroundTruthAgainstControlPoints) {
  LISFM_REQUIRE_SHARED_DATA(kExp04Dense);
  LISFM_REQUIRE_SHARED_DATA(kExp05Dense);
  const HiltiScoreOptions options;
  for (const auto& [dense, points] :
       {std::make_pair(kExp04Dense, kExp04Points),
        std::make_pair(kExp05Dense, kExp05Points)}) {
    const Trajectory gt = ReadTum(test::SharedData(dense));
    const std::vector<ControlPoint> cps =
        ReadControlPoints(test::SharedData(points));
    const HiltiScore score = ComputeHiltiScore(cps, gt, options);
    std::cout << "[ HILTI   ] " << points << ": dense ground truth scores "
              << score.score << " / 100, tip errors " << score.errors_m.min
              << " .. " << score.errors_m.max << " m\n";
    // Every control point lies inside the 10 Hz ground truth (<= 50 ms away).
    EXPECT_EQ(score.num_associated, cps.size());
    for (const auto& p : score.points) EXPECT_LE(std::llabs(p.dt_ns), 50 * kMs);
    // The dense ground truth and the survey differ by about 1-6 cm after
    // alignment (see the brief), so the score is neither 0 nor 100.
    EXPECT_GT(score.score, 0.0);
    EXPECT_LT(score.score, 100.0);
    EXPECT_LT(score.errors_m.max, 0.10);

    // 5 cm of seeded position noise per axis lowers the score.
    std::mt19937 rng(11);
    std::normal_distribution<double> noise(0.0, 0.05);
    std::vector<StampedPose> noisy;
    for (const auto& p : gt.poses()) {
      noisy.push_back({p.t_ns,
                       SE3(p.pose.rotation(),
                           p.pose.translation() +
                               Vec3(noise(rng), noise(rng), noise(rng)))});
    }
    const HiltiScore worse = ComputeHiltiScore(cps, Trajectory(noisy), options);
    std::cout << "[ HILTI   ] with 5 cm noise: " << worse.score << " / 100\n";
    EXPECT_LT(worse.score, score.score);
  }
}

}  // namespace
}  // namespace lisfm
