// LIO on simulated sequences (lisfm_sim) with exact ground truth.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

#include "core/errors.h"
#include "core/evaluation.h"
#include "core/io/cloud_io.h"
#include "core/io/trajectory_io.h"
#include "importers/lidar_frames.h"
#include "importers/sequence.h"
#include "lio/imu_feeder.h"
#include "lio/lio_odometry.h"
#include "sim/imu_errors.h"
#include "sim/simulator.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// Simulates `duration` s of the office walk (no cameras) into dir/name.
Sequence SimulateSequence(const test::TempDir& dir,
                          const std::string& name,
                          double duration,
                          double noise_scale,
                          const std::string& lidars) {
  sim::SimulatorOptions options;
  options.scene = "office";
  options.duration = duration;
  options.camera_rate = 0;
  options.lidars = lidars;
  options.noise_scale = noise_scale;
  options.seed = 3;
  options.walk.num_stops = 3;      // the data these bounds were set on
  options.error_sources = "none";  // white noise and bias random walk only
  options.output_path = dir.File(name);
  Rig rig;  // the simulator's default rig: the HILTI 2022 LiDAR mounting
  sim::Simulate(options, sim::PrepareRig(rig, lidars));
  return ReadSequence(options.output_path);
}

struct LioRun {
  Trajectory trajectory;
  std::vector<LioFrameResult> results;
  std::vector<Keyframe> keyframes;
  std::vector<LidarCalibrationEstimate> calibration;  // at the end
};

LioRun RunLio(const Sequence& seq, const LioOptions& options, const std::vector<int>& lidars) {
  std::vector<SE3> extrinsics;
  std::vector<double> offsets;
  for (const auto& l : seq.rig.lidars) {
    extrinsics.push_back(l.imu_from_lidar);
    offsets.push_back(l.time_offset_s);
  }
  LioOdometry odom(options, seq.rig.imu, extrinsics, offsets);
  LioRun run;
  LidarFrameReader reader(seq, lidars);
  ImuFeeder imu_feeder(seq.imu);
  LidarFrame frame;
  while (reader.Next(&frame)) {
    imu_feeder.FeedUntil(frame.end_ns, &odom);
    const LioFrameResult r = odom.ProcessFrame(frame.Inputs());
    run.results.push_back(r);
    if (r.processed) {
      EXPECT_TRUE(r.world_from_imu.translation().allFinite());
      run.trajectory.PushBack({r.t_ns, r.world_from_imu});
    }
    for (auto& k : odom.TakeKeyframes()) run.keyframes.push_back(std::move(k));
  }
  run.calibration = odom.LidarCalibration();
  return run;
}

double WeakFraction(const LioRun& run) {
  int weak = 0, n = 0;
  for (const auto& r : run.results) {
    if (!r.processed || r.degeneracy.eigenvalues(0) == 0) continue;  // skip the map start
    ++n;
    if (r.degeneracy.num_weak > 0) ++weak;
  }
  return n > 0 ? static_cast<double>(weak) / n : 0.0;
}

double AteRmse(const Sequence& seq, const Trajectory& estimate) {
  const Trajectory gt = ReadTum(seq.groundtruth_path);
  TrajectoryEvaluationOptions options;
  options.max_dt_ns = 6000000;  // GT is 100 Hz; scan ends are within 5 ms of a sample
  const TrajectoryEvaluation ev = EvaluateTrajectory(gt, estimate, options);
  EXPECT_GT(ev.pairs.size(), estimate.size() * 9 / 10);
  return ev.ate_translation_m.rmse;
}

TEST(LioOdometry, ImuOnlyPropagationMatchesGroundTruth) {
  test::TempDir dir;
  const Sequence seq = SimulateSequence(dir, "seq", 8.0, 0.0, "spinning");
  const Trajectory gt = ReadTum(seq.groundtruth_path);
  LioOdometry odom(LioOptions(), seq.rig.imu, {seq.rig.lidars[0].imu_from_lidar}, {0.0});
  std::optional<SE3> start;
  TimestampNs t_start = 0;
  double max_dt_err = 0, max_rot_err = 0;
  for (const auto& s : seq.imu) {
    odom.AddImu(s);
    if (!odom.initialized()) continue;
    if (!start) {
      t_start = odom.initialization().t_ns;
      start = odom.Predict(t_start);
      ASSERT_TRUE(start.has_value());
      continue;
    }
    // Every 0.5 s: relative motion since the start, estimate vs ground truth.
    if ((s.t_ns - t_start) % 500000000LL != 0) continue;
    const auto pose = odom.Predict(s.t_ns);
    ASSERT_TRUE(pose.has_value());
    const SE3 rel_est = start->Inverse() * *pose;
    const SE3 rel_gt = gt.Interpolate(t_start)->Inverse() * *gt.Interpolate(s.t_ns);
    max_dt_err = std::max(max_dt_err, (rel_est.translation() - rel_gt.translation()).norm());
    max_rot_err = std::max(max_rot_err, so3::AngularDistance(rel_est.rotation(), rel_gt.rotation()));
  }
  ASSERT_TRUE(start.has_value());
  // Noise-free 400 Hz samples, mid-point integration: over ~7 s of walking the
  // discretisation error stays at a few mm (4 mm measured); a wrong gravity sign,
  // frame or bias handling gives metres.
  std::printf("IMU-only over %.1f s: max position error %.4f m, rotation %.4f deg\n",
              NsToSeconds(seq.imu.back().t_ns - t_start), max_dt_err, max_rot_err * 180 / M_PI);
  EXPECT_LT(max_dt_err, 0.01);
  EXPECT_LT(max_rot_err * 180 / M_PI, 0.05);
}

TEST(LioOdometry, DeskewRemovesMotionDistortion) {
  test::TempDir dir;
  const Sequence seq = SimulateSequence(dir, "seq", 6.0, 0.0, "spinning");
  const Trajectory gt = ReadTum(seq.groundtruth_path);
  LioOptions options;
  options.keyframe_distance = 1e-6;  // every frame is a keyframe: keep every de-skewed cloud
  const LioRun run = RunLio(seq, options, {0});
  ASSERT_GT(run.keyframes.size(), 20u);
  const SE3& T_il = seq.rig.lidars[0].imu_from_lidar;
  // The frame with the fastest motion (rotation + translation within the scan).
  double worst_motion = 0, worst_err = 0, worst_raw = 0;
  for (const Keyframe& k : run.keyframes) {
    const auto it = std::find_if(seq.lidar_scans[0].begin(), seq.lidar_scans[0].end(),
                                 [&](const SensorFile& f) { return f.t_ns <= k.t_ns && k.t_ns - f.t_ns < 100000000LL; });
    ASSERT_NE(it, seq.lidar_scans[0].end());
    PointCloud raw = ReadPointCloud(it->path);
    const SE3 end_from_world = gt.Interpolate(k.t_ns)->Inverse();
    const SE3 start_pose = *gt.Interpolate(it->t_ns);
    const double motion = (start_pose.translation() - gt.Interpolate(k.t_ns)->translation()).norm() +
                          so3::AngularDistance(start_pose.rotation(), gt.Interpolate(k.t_ns)->rotation());
    // Raw points in range, same order as the keyframe cloud.
    std::vector<Vec3> truth, distorted;
    for (const auto& p : raw.points) {
      const double r = p.xyzd().norm();
      if (r < options.min_range || r > options.max_range) continue;
      const SE3 world_from_imu_t = *gt.Interpolate(it->t_ns + SecondsToNs(p.t));
      truth.push_back(end_from_world * (world_from_imu_t * (T_il * p.xyzd())));
      distorted.push_back(T_il * p.xyzd());  // what no de-skew would give
    }
    ASSERT_EQ(truth.size(), k.cloud_in_imu.size());
    double err = 0, raw_err = 0;
    for (size_t i = 0; i < truth.size(); ++i) {
      err = std::max(err, (k.cloud_in_imu.points[i].xyzd() - truth[i]).norm());
      raw_err = std::max(raw_err, (distorted[i] - truth[i]).norm());
    }
    if (motion > worst_motion) {
      worst_motion = motion;
      worst_err = err;
      worst_raw = raw_err;
    }
  }
  // Walking with turns: without de-skew the points move by several cm; after
  // de-skew every point is within 5 mm of where it truly is at the scan end.
  std::printf("de-skew: worst frame motion %.3f, raw error %.4f m, de-skewed error %.5f m\n",
              worst_motion, worst_raw, worst_err);
  EXPECT_GT(worst_raw, 0.03) << "the test sequence should have real motion distortion";
  EXPECT_LT(worst_err, 0.005) << "motion in the worst frame " << worst_motion;
}

TEST(LioOdometry, ShortSequenceOneLidarMeetsAteBound) {
  test::TempDir dir;
  const Sequence seq = SimulateSequence(dir, "seq", 15.0, 1.0, "spinning");
  const LioRun run = RunLio(seq, LioOptions(), {0});
  ASSERT_GT(run.trajectory.size(), 130u);
  const double ate = AteRmse(seq, run.trajectory);
  // The office target is 2 cm; with sensor noise on we measure ~2 mm, so 1 cm keeps a
  // margin and still fails on any real regression.
  std::printf("one LiDAR: ATE %.4f m over %zu poses, weak-direction scans %.2f\n", ate,
              run.trajectory.size(), WeakFraction(run));
  EXPECT_LT(ate, 0.01) << "ATE " << ate;
  // Rooms and corridors constrain every direction: (almost) no scan is flagged.
  EXPECT_LT(WeakFraction(run), 0.05);
}

// The filter does not depend on the thread schedule: 1, 2, 3 and 8 threads
// give bit-identical poses (TBB's default partitioner splits the per-point
// sums by the arena's concurrency and by work stealing, so a
// scheduling-dependent reduction differs in the last bits here), with and
// without the online calibration.
TEST(LioOdometry, BitIdenticalForAnyThreadCount) {
  test::TempDir dir;
  const Sequence seq = SimulateSequence(dir, "seq", 6.0, 1.0, "spinning");
  LioOptions calibrating;
  calibrating.estimate_extrinsic = true;
  calibrating.estimate_time_offset = true;
  for (const LioOptions& options : {LioOptions(), calibrating}) {
    LioRun one;
    tbb::task_arena(1).execute([&] { one = RunLio(seq, options, {0}); });
    ASSERT_GT(one.trajectory.size(), 30u);
    for (const int threads : {2, 3, 8}) {
      LioRun many;
      tbb::task_arena(threads).execute([&] { many = RunLio(seq, options, {0}); });
      ASSERT_EQ(one.trajectory.size(), many.trajectory.size());
      for (size_t i = 0; i < one.trajectory.size(); ++i) {
        const SE3& a = one.trajectory[i].pose;
        const SE3& b = many.trajectory[i].pose;
        ASSERT_EQ(one.trajectory[i].t_ns, many.trajectory[i].t_ns);
        ASSERT_TRUE(a.translation() == b.translation() &&
                    a.rotation().coeffs() == b.rotation().coeffs())
            << threads << " threads, calibrating " << options.estimate_extrinsic << ": pose " << i
            << " differs by " << (a.translation() - b.translation()).norm() << " m";
      }
      const LidarCalibrationEstimate &c1 = one.calibration[0], &cn = many.calibration[0];
      ASSERT_TRUE(c1.imu_from_lidar.translation() == cn.imu_from_lidar.translation() &&
                  c1.time_offset_s == cn.time_offset_s);
    }
  }
}

// docs/FORMATS.md: lio's world frame is gravity-aligned with its origin at the
// IMU position at the initialisation time (the end of the first
// Init.min_duration_s of IMU data). Against exact ground truth, every pose is
// the ground truth moved by one rotation about z and that origin shift.
TEST(LioOdometry, WorldFrameIsGravityAlignedAtTheInitialisationPose) {
  test::TempDir dir;
  const Sequence seq = SimulateSequence(dir, "seq", 6.0, 0.0, "spinning");
  const Trajectory gt = ReadTum(seq.groundtruth_path);
  LioOdometry odom(LioOptions(), seq.rig.imu, {seq.rig.lidars[0].imu_from_lidar}, {0.0});
  LidarFrameReader reader(seq, {0});
  ImuFeeder imu_feeder(seq.imu);
  LidarFrame frame;
  std::vector<StampedPose> poses;
  while (reader.Next(&frame)) {
    imu_feeder.FeedUntil(frame.end_ns, &odom);
    const LioFrameResult r = odom.ProcessFrame(frame.Inputs());
    if (r.processed) poses.push_back({r.t_ns, r.world_from_imu});
  }
  ASSERT_TRUE(odom.initialized());
  ASSERT_GT(poses.size(), 30u);
  const TimestampNs t_init = odom.initialization().t_ns;
  EXPECT_LE(t_init - seq.imu.front().t_ns, SecondsToNs(LioOptions().init.min_duration_s));
  const SE3 gt_init = *gt.Interpolate(t_init);
  // lio_from_gt_world from the initial rotation (lio position 0 at t_init).
  const Quat lio_from_gt = odom.initialization().world_from_imu * gt_init.rotation().conjugate();
  EXPECT_LT(so3::AngularDistance(Quat::FromTwoVectors(lio_from_gt * Vec3::UnitZ(), Vec3::UnitZ()),
                                 Quat::Identity()),
            1e-3);  // a rotation about z: the tilt of the static mean is exact without noise
  double max_error = 0;
  for (const StampedPose& p : poses) {
    const Vec3 expected = lio_from_gt * (gt.Interpolate(p.t_ns)->translation() -
                                         gt_init.translation());
    max_error = std::max(max_error, (p.pose.translation() - expected).norm());
  }
  // Noise-free data: the odometry's own error over 6 s stays at the mm level.
  EXPECT_LT(max_error, 0.01);
}

TEST(LioOdometry, ShortSequenceTwoLidarsMeetsAteBound) {
  test::TempDir dir;
  const Sequence seq = SimulateSequence(dir, "seq", 15.0, 1.0, "spinning,livox");
  ASSERT_EQ(seq.rig.lidars.size(), 2u);
  const LioRun both = RunLio(seq, LioOptions(), {0, 1});
  const double ate_both = AteRmse(seq, both.trajectory);
  EXPECT_LT(ate_both, 0.01) << "ATE " << ate_both;
  // Livox alone (70° field of view) also works.
  const LioRun livox = RunLio(seq, LioOptions(), {1});
  ASSERT_GT(livox.trajectory.size(), 130u);
  const double ate_livox = AteRmse(seq, livox.trajectory);
  std::printf("two LiDARs: ATE %.4f m; Livox alone: ATE %.4f m\n", ate_both, ate_livox);
  EXPECT_LT(ate_livox, 0.05) << "ATE " << ate_livox;
}

// The rig.yaml of a recording is off by HILTI-sized calibration errors
// (0.2 deg, 5 mm, 3 ms); the data were made with the true calibration. With
// the online estimation (LioOptions::estimate_extrinsic, estimate_time_offset)
// the time offset and the extrinsic rotation converge within 30 s of walking.
// The extrinsic translation is seen only through the IMU (a LiDAR-only fit
// absorbs it in the position), weakly at the filter's IMU noise
// (docs/BENCHMARKS.md): its error must stay within 3 of its reported sigmas.
TEST(LioOdometry, OnlineCalibrationMovesTowardTheTruth) {
  test::TempDir dir;
  Sequence seq = SimulateSequence(dir, "seq", 30.0, 1.0, "spinning");
  const RigLidar truth = seq.rig.lidars[0];
  const Quat rotation_error = so3::Exp(Vec3(1.0, -2.0, 0.5).normalized() * (0.2 * M_PI / 180));
  const Vec3 translation_error = Vec3(3.0, -4.0, 0.0) * 1e-3;  // 5 mm
  seq.rig.lidars[0].imu_from_lidar = SE3(truth.imu_from_lidar.rotation() * rotation_error,
                                         truth.imu_from_lidar.translation() + translation_error);
  seq.rig.lidars[0].time_offset_s = truth.time_offset_s + 0.003;
  // Errors in mm, deg, ms.
  auto errors = [&](const SE3& imu_from_lidar, double time_offset_s) {
    return Vec3(1e3 * (imu_from_lidar.translation() - truth.imu_from_lidar.translation()).norm(),
                so3::AngularDistance(imu_from_lidar.rotation(), truth.imu_from_lidar.rotation()) *
                    180 / M_PI,
                1e3 * std::abs(time_offset_s - truth.time_offset_s));
  };
  const Vec3 before = errors(seq.rig.lidars[0].imu_from_lidar, seq.rig.lidars[0].time_offset_s);

  const LioRun fixed = RunLio(seq, LioOptions(), {0});
  LioOptions options;
  options.estimate_extrinsic = true;
  options.estimate_time_offset = true;
  // The LiDAR calibration alone (this recording has no gyro scale error). With
  // the gyro intrinsics E also estimated, the attitude corrections after turns
  // are shared between E and the extrinsic rotation, which then stays at
  // 0.22 deg here (measured; docs/notes/lio_stairwell.md).
  options.estimate_gyro_scale = false;
  const LioRun estimated = RunLio(seq, options, {0});
  ASSERT_GT(estimated.trajectory.size(), 270u);
  const LidarCalibrationEstimate& c = estimated.calibration[0];
  ASSERT_TRUE(c.extrinsic_estimated && c.time_offset_estimated);
  const Vec3 after = errors(c.imu_from_lidar, c.time_offset_s);
  const double ate_fixed = AteRmse(seq, fixed.trajectory);
  const double ate_estimated = AteRmse(seq, estimated.trajectory);
  std::printf("calibration error before: %.2f mm / %.3f deg / %.2f ms; after: %.2f mm / %.3f "
              "deg / %.2f ms (1-sigma %.2f mm / %.3f deg / %.3f ms); ATE fixed %.4f m, "
              "estimated %.4f m\n",
              before(0), before(1), before(2), after(0), after(1), after(2),
              1e3 * c.translation_std_m.norm(), c.rotation_std_rad.norm() * 180 / M_PI,
              1e3 * c.time_offset_std_s, ate_fixed, ate_estimated);
  // Measured: 0.07 ms and 0.12 deg after 30 s; a sign error in the time-offset
  // or the rotation columns of lio/point_to_plane.h gives > 100 ms or ~0.6 deg.
  EXPECT_LT(after(2), 0.1 * before(2));
  EXPECT_LT(after(1), 0.75 * before(1));
  EXPECT_LT(after(0), 3 * 1e3 * c.translation_std_m.norm());
  // Not worse than keeping the wrong calibration (max(1 mm, 5 %), the tolerance).
  EXPECT_LT(ate_estimated, std::max(ate_fixed + 0.001, 1.05 * ate_fixed));
}

// The simulated staircase (seed 3, one spinning LiDAR, no cameras).
Sequence SimulateStaircase(const test::TempDir& dir, double duration) {
  sim::SimulatorOptions options;
  options.scene = "staircase";
  options.duration = duration;
  options.camera_rate = 0;
  options.seed = 3;
  options.walk.num_stops = 3;  // the data these bounds were set on
  options.error_sources = "none";
  options.output_path = dir.File("stairs");
  sim::Simulate(options, sim::PrepareRig(Rig(), "spinning"));
  return ReadSequence(options.output_path);
}

TEST(LioOdometry, StaircaseIsFlaggedDegenerateAndDoesNotDiverge) {
  test::TempDir dir;
  const Sequence seq = SimulateStaircase(dir, 15.0);
  const LioRun run = RunLio(seq, LioOptions(), {0});
  ASSERT_GT(run.trajectory.size(), 130u);
  const double ate = AteRmse(seq, run.trajectory);
  std::printf("staircase: ATE %.4f m, weak-direction scans %.2f\n", ate, WeakFraction(run));
  // The staircase bound is 10 cm; we measure < 1 cm.
  EXPECT_LT(ate, 0.05);
  // The narrow stair shaft constrains some direction weakly in most scans.
  EXPECT_GT(WeakFraction(run), 0.3);
}

// The first climb, the landing and the start of the second flight (t < 22 s),
// where the horizontal LiDAR (±16°) sees almost no floor or ceiling, so the
// height rests on step edges and the IMU. Matches across a riser (a point on
// a tread not yet in the map against the tread below) and planes fitted across
// a step edge pull the pose 8-14 cm down here unless the residual gates reject
// them (LioOptions::max_point_residual, max_plane_residual); the error is measured
// without alignment (world = the first pose, DESIGN.md), where such an offset
// cannot be absorbed.
TEST(LioOdometry, StaircaseClimbKeepsItsHeight) {
  test::TempDir dir;
  const Sequence seq = SimulateStaircase(dir, 22.0);
  const LioRun run = RunLio(seq, LioOptions(), {0});
  ASSERT_GT(run.trajectory.size(), 200u);
  const Trajectory gt = ReadTum(seq.groundtruth_path);
  // scene_from_world of the odometry, from its first pose.
  const std::optional<SE3> gt_first = gt.Interpolate(run.trajectory[0].t_ns, 20000000);
  ASSERT_TRUE(gt_first.has_value());
  const SE3 scene_from_world = *gt_first * run.trajectory[0].pose.Inverse();
  double max_error = 0, max_dz = 0;
  for (const StampedPose& p : run.trajectory.poses()) {
    const std::optional<SE3> truth = gt.Interpolate(p.t_ns, 20000000);
    ASSERT_TRUE(truth.has_value());
    const Vec3 d = (scene_from_world * p.pose).translation() - truth->translation();
    max_error = std::max(max_error, d.norm());
    max_dz = std::max(max_dz, std::abs(d.z()));
  }
  std::printf("staircase climb: max position error %.4f m (height %.4f m)\n", max_error, max_dz);
  // 1 cm range noise and the IMU noise give ~1.3 cm here (measured); 4 cm
  // leaves margin for them and is far below the 8-14 cm of the biased matches.
  EXPECT_LT(max_error, 0.04);
}

// The staircase with the `imu` error source: the gyro's scale-factor and
// cross-axis errors (BMI085 datasheet sizes; seed 4 draws E_xz = -2.2 %, the
// yaw rate leaking into roll) tilt the attitude by ~4 deg over the 180 deg turn
// at the top of the shaft (t ~ 28 s). The shaft constrains pitch and the
// along-shaft position weakly, so unmodelled (LioOptions::estimate_gyro_scale
// off) the tilt leaks gravity into the velocity and lio diverges (28 m at 40 s,
// measured); with E in the state the LiDAR calibrates it on the earlier turns
// (5.4 cm). The same mechanism diverged the 900 s site walk in its stairwell
// (docs/notes/lio_stairwell.md).
TEST(LioOdometry, StaircaseWithGyroScaleErrorsDoesNotDiverge) {
  test::TempDir dir;
  sim::SimulatorOptions sim_options;
  sim_options.scene = "staircase";
  sim_options.duration = 40.0;
  sim_options.camera_rate = 0;
  sim_options.seed = 4;
  sim_options.walk.num_stops = 2;
  sim_options.error_sources = "imu";
  sim_options.output_path = dir.File("stairs_imu");
  sim::Simulate(sim_options, sim::PrepareRig(Rig(), "spinning"));
  const Sequence seq = ReadSequence(sim_options.output_path);
  LioOptions options;
  options.estimate_gyro_scale = true;
  LioOdometry odom(
      options, seq.rig.imu, {seq.rig.lidars[0].imu_from_lidar}, {seq.rig.lidars[0].time_offset_s});
  Trajectory trajectory;
  LidarFrameReader reader(seq, {0});
  ImuFeeder imu_feeder(seq.imu);
  LidarFrame frame;
  while (reader.Next(&frame)) {
    imu_feeder.FeedUntil(frame.end_ns, &odom);
    const LioFrameResult r = odom.ProcessFrame(frame.Inputs());
    if (r.processed) trajectory.PushBack({r.t_ns, r.world_from_imu});
    odom.TakeKeyframes();
  }
  ASSERT_GT(trajectory.size(), 350u);
  // Position error without alignment (world = the first pose).
  const Trajectory gt = ReadTum(seq.groundtruth_path);
  const std::optional<SE3> gt_first = gt.Interpolate(trajectory[0].t_ns, 20000000);
  ASSERT_TRUE(gt_first.has_value());
  const SE3 scene_from_world = *gt_first * trajectory[0].pose.Inverse();
  double max_error = 0;
  for (const StampedPose& p : trajectory.poses()) {
    const std::optional<SE3> truth = gt.Interpolate(p.t_ns, 20000000);
    ASSERT_TRUE(truth.has_value());
    max_error = std::max(max_error,
                         ((scene_from_world * p.pose).translation() - truth->translation()).norm());
  }
  // The estimate of E against the drawn truth (M = I + E).
  const sim::ImuErrors truth =
      sim::ReadImuErrorsYaml(sim_options.output_path + "/truth/imu_errors.yaml");
  const Mat3 E_true = truth.gyro.Matrix() - Mat3::Identity();
  const Mat3& E = odom.gyro_scale_error();
  std::printf(
      "staircase with gyro errors: max position error %.4f m; E_xz %.3f %% (true %.3f %%), "
      "|E - E_true| %.3f %% (|E_true| %.3f %%)\n",
      max_error,
      100 * E(0, 2),
      100 * E_true(0, 2),
      100 * (E - E_true).norm(),
      100 * E_true.norm());
  EXPECT_LT(max_error, 0.15);
  // The dominant entry converges (-2.0 % against -2.2 %, measured) and the
  // estimate is closer to the truth than the prior E = 0.
  EXPECT_NEAR(E(0, 2), E_true(0, 2), 0.005);
  EXPECT_LT((E - E_true).norm(), 0.5 * E_true.norm());
}

TEST(LioOdometry, BadInputIsSkippedOrRejectedNeverNan) {
  LioOptions options;
  LioOdometry odom(options, ImuNoise(), {SE3()}, {0.0});
  ImuSample s;
  s.accel = Vec3(0, 0, 9.81);
  for (int i = 0; i <= 400; ++i) {
    s.t_ns = 1000000000LL + i * 2500000LL;
    odom.AddImu(s);
  }
  ASSERT_TRUE(odom.initialized());
  // Unsorted IMU time stamps: a clear error.
  ImuSample old = s;
  old.t_ns -= 1000;
  EXPECT_THROW(odom.AddImu(old), InputError);
  ImuSample nan = s;
  nan.t_ns += 1000;
  nan.gyro.x() = std::nan("");
  EXPECT_THROW(odom.AddImu(nan), InputError);
  // Empty scan: skipped.
  PointCloud empty;
  empty.stamp_ns = s.t_ns - 200000000LL;
  auto r = odom.ProcessFrame({{0, &empty}});
  EXPECT_FALSE(r.processed);
  EXPECT_EQ(r.message, "empty scan");
  // A scan beyond the IMU data: skipped, not extrapolated.
  PointCloud future;
  future.stamp_ns = s.t_ns + 1000000000LL;
  LidarPoint p;
  p.x = 5;
  future.points.assign(100, p);
  r = odom.ProcessFrame({{0, &future}});
  EXPECT_FALSE(r.processed);
  EXPECT_NE(r.message.find("outside IMU coverage"), std::string::npos) << r.message;
  // An unknown LiDAR (no extrinsic): a clear error.
  EXPECT_THROW(odom.ProcessFrame({{3, &future}}), InputError);
  // An IMU gap > 0.1 s inside a frame: prediction only, finite pose.
  s.t_ns += 300000000LL;
  odom.AddImu(s);
  s.t_ns += 2500000LL;
  odom.AddImu(s);
  PointCloud gap;
  gap.stamp_ns = s.t_ns - 250000000LL;
  gap.points.assign(100, p);
  for (auto& q : gap.points) q.t = 0.2f;
  r = odom.ProcessFrame({{0, &gap}});
  EXPECT_FALSE(r.processed);
  EXPECT_NE(r.message.find("IMU gap"), std::string::npos) << r.message;
  EXPECT_TRUE(r.world_from_imu.translation().allFinite());
}

}  // namespace
}  // namespace lisfm
