#include "colmap_ext/sfm/bundle_adjustment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <vector>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

// Synthetic scene with exact ground truth: `num_frames` rig frames on a ring
// of radius 8 m around a 4 m cube of points, each frame looking at the centre;
// 1 camera per frame (no rig) or 3 cameras on a rig (yaw -20, 0, +20 deg,
// 10 cm apart). 640 x 480 images, f = 500 px, SIMPLE_RADIAL k = -0.05. Every
// point visible in an image is observed there, with Gaussian pixel noise.
struct Scene {
  MapperState state;  // ground truth values (tests perturb a copy)
  std::map<frame_t, SE3> rig_from_world;
  std::vector<Vec3> points;
  std::map<camera_t, SE3> cam_from_rig;
  std::vector<double> params;
};

struct SceneOptions {
  int num_frames = 10;
  int num_points = 300;
  bool rig = false;
  double noise_px = 0.5;
  double outlier_ratio = 0.0;  // observations replaced by uniform random pixels
  // Roll of frame f about its viewing axis: roll_rad * sin(2 * ring angle),
  // so that relative rotations turn about more than the vertical axis.
  double roll_rad = 0.0;
  // Pan of frame f about its vertical (rig y): pan_rad * cos(3 * ring angle),
  // so that the views do not all meet at the ring's centre.
  double pan_rad = 0.0;
  double height_amplitude_m = 1.0;  // frame heights: amplitude * sin(3 * ring angle)
};

SE3 LookAt(const Vec3& center, const Vec3& target) {
  const Vec3 z = (target - center).normalized();
  const Vec3 x = Vec3::UnitZ().cross(z).normalized();  // world up is +z
  const Vec3 y = z.cross(x);
  Mat3 world_from_cam;
  world_from_cam << x, y, z;
  return SE3(world_from_cam, center).Inverse();
}

Scene MakeScene(const SceneOptions& options) {
  std::mt19937& rng = test::Rng();
  std::normal_distribution<double> noise(0.0, options.noise_px);
  std::uniform_real_distribution<double> cube(-2.0, 2.0), unit(0.0, 1.0);
  Scene scene;
  MapperState& state = scene.state;
  scene.params = {500.0, 320.0, 240.0, -0.05};
  const int cameras_per_frame = options.rig ? 3 : 1;
  state.has_rig = options.rig;
  for (int c = 0; c < cameras_per_frame; ++c) {
    Camera camera;
    camera.camera_id = static_cast<camera_t>(c + 1);
    camera.model_id = static_cast<int>(CameraModelId::kSimpleRadial);
    camera.width = 640;
    camera.height = 480;
    camera.params = scene.params;
    state.cameras[camera.camera_id] = camera;
    SE3 cam_from_rig;
    if (options.rig) {
      const double yaw =
          (c - 1) * 20.0 * M_PI / 180.0;  // about the camera y axis
      cam_from_rig = SE3(Quat(Eigen::AngleAxisd(yaw, Vec3::UnitY())),
                         Vec3((c - 1) * 0.1, 0.0, 0.0));
    }
    state.cam_from_rig[camera.camera_id] = cam_from_rig;
    scene.cam_from_rig[camera.camera_id] = cam_from_rig;
  }
  for (int i = 0; i < options.num_points; ++i) {
    scene.points.emplace_back(cube(rng), cube(rng), cube(rng));
  }
  image_t next_image_id = 1;
  for (int f = 0; f < options.num_frames; ++f) {
    const double angle = 2.0 * M_PI * f / options.num_frames;
    const Vec3 center(8.0 * std::cos(angle),
                      8.0 * std::sin(angle),
                      options.height_amplitude_m * std::sin(3.0 * angle));
    SE3 rig_from_world =
        SE3::Exp(
            (Vec6() << 0.02 * (unit(rng) - 0.5), 0.02 * (unit(rng) - 0.5), 0, 0, 0, 0).finished()) *
        LookAt(center, Vec3::Zero());
    if (options.roll_rad != 0.0) {
      rig_from_world =
          SE3(Quat(Eigen::AngleAxisd(options.roll_rad * std::sin(2.0 * angle), Vec3::UnitZ())),
              Vec3::Zero()) *
          rig_from_world;
    }
    if (options.pan_rad != 0.0) {
      rig_from_world =
          SE3(Quat(Eigen::AngleAxisd(options.pan_rad * std::cos(3.0 * angle), Vec3::UnitY())),
              Vec3::Zero()) *
          rig_from_world;
    }
    SfmFrame frame;
    frame.frame_id = static_cast<frame_t>(f + 1);
    frame.rig_from_world = rig_from_world;
    frame.registered = true;
    scene.rig_from_world[frame.frame_id] = rig_from_world;
    for (int c = 0; c < cameras_per_frame; ++c) {
      SfmImage image;
      image.image_id = next_image_id++;
      image.camera_id = static_cast<camera_t>(c + 1);
      image.frame_id = frame.frame_id;
      image.name = "img" + std::to_string(image.image_id);
      frame.image_ids.push_back(image.image_id);
      state.images[image.image_id] = image;
    }
    state.frames[frame.frame_id] = frame;
  }
  state.tracks.resize(scene.points.size());
  for (size_t k = 0; k < scene.points.size(); ++k) {
    Track& track = state.tracks[k];
    track.xyz = scene.points[k];
    track.triangulated = true;
    for (auto& [image_id, image] : state.images) {
      const SE3 cam_from_world = scene.cam_from_rig.at(image.camera_id) *
                                 scene.rig_from_world.at(image.frame_id);
      Vec2 pixel;
      if (!state.cameras.at(image.camera_id)
               .Project(cam_from_world * scene.points[k], &pixel)) {
        continue;
      }
      if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() > 640 || pixel.y() > 480)
        continue;
      if (unit(rng) < options.outlier_ratio) {
        pixel = Vec2(640.0 * unit(rng), 480.0 * unit(rng));
      } else {
        pixel += Vec2(noise(rng), noise(rng));
      }
      track.elements.push_back(
          {image_id, static_cast<point2D_t>(image.keypoints.size())});
      image.keypoints.push_back(pixel);
      image.track_ids.push_back(static_cast<int>(k));
    }
  }
  return scene;
}

// Perturbs poses (rotation ~angle_rad, translation ~translation_m per axis,
// uniform) and points (~point_m per axis); frames listed in `keep` untouched.
void Perturb(MapperState* state,
             double angle_rad,
             double translation_m,
             double point_m,
             const std::set<frame_t>& keep = {}) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::mt19937& rng = test::Rng();
  for (auto& [frame_id, frame] : state->frames) {
    if (keep.count(frame_id)) continue;
    // Rotation and translation perturbed independently (so a pure rotation
    // perturbation moves the frame centre too).
    const Vec3 omega(
        angle_rad * u(rng), angle_rad * u(rng), angle_rad * u(rng));
    const Vec3 dt(
        translation_m * u(rng), translation_m * u(rng), translation_m * u(rng));
    frame.rig_from_world =
        SE3(so3::Exp(omega) * frame.rig_from_world.rotation(),
            frame.rig_from_world.translation() + dt);
  }
  for (Track& track : state->tracks) {
    track.xyz += point_m * Vec3(u(rng), u(rng), u(rng));
  }
}

Vec3 Center(const SE3& rig_from_world) {
  return rig_from_world.Inverse().translation();
}

struct Errors {
  double max_rotation_rad = 0.0;
  double max_position_m = 0.0;
  double rms_point_m = 0.0;
};

// Errors of frames and points against the truth, after applying `align`
// (estimate -> truth) to the estimate.
Errors ComputeErrors(const Scene& scene,
                     const MapperState& state,
                     const Sim3& align = Sim3()) {
  Errors errors;
  for (const auto& [frame_id, truth] : scene.rig_from_world) {
    const SE3 world_from_rig =
        align.Transform(state.frames.at(frame_id).rig_from_world.Inverse());
    errors.max_rotation_rad =
        std::max(errors.max_rotation_rad,
                 so3::AngularDistance(world_from_rig.rotation(),
                                      truth.Inverse().rotation()));
    errors.max_position_m =
        std::max(errors.max_position_m,
                 (world_from_rig.translation() - Center(truth)).norm());
  }
  double sum = 0.0;
  for (size_t k = 0; k < scene.points.size(); ++k) {
    sum += (align * state.tracks[k].xyz - scene.points[k]).squaredNorm();
  }
  errors.rms_point_m = std::sqrt(sum / scene.points.size());
  return errors;
}

// Similarity estimate -> truth from the frame centres.
Sim3 AlignToTruth(const Scene& scene, const MapperState& state) {
  Eigen::Matrix3Xd source(3, scene.rig_from_world.size()),
      target(3, scene.rig_from_world.size());
  int i = 0;
  for (const auto& [frame_id, truth] : scene.rig_from_world) {
    source.col(i) = Center(state.frames.at(frame_id).rig_from_world);
    target.col(i) = Center(truth);
    ++i;
  }
  return AlignUmeyama(source, target, /*estimate_scale=*/true);
}

BundleAdjustmentOptions FixedIntrinsicsOptions() {
  BundleAdjustmentOptions options;
  options.refine_focal_length = false;
  options.refine_extra_params = false;
  options.num_threads = 2;
  return options;
}

// Accuracy implied by the injected noise (0.5 px at f = 500 px, i.e. 1e-3 rad
// per observation, or 8 mm laterally at the 8 m viewing distance). The points
// cover only +-15 deg (0.26 rad) of each view, so a lateral shift d of a frame
// and a rotation d / 8 m are nearly interchangeable: with ~300 points per view
// the lateral position is known to ~8 mm / sqrt(300) / 0.26^2 ~ 7 mm and the
// rotation to ~7 mm / 8 m ~ 1e-3 rad. Points are seen by ~10 frames at 8 m:
// ~8 mm / sqrt(10) ~ 3 mm plus the frames' error. The bounds are ~3 sigma for
// the worst of 10 frames, and 5-100x below the perturbations.
constexpr double kMaxPositionErrorM = 0.02;
constexpr double kMaxRotationErrorRad = kMaxPositionErrorM / 8.0;
constexpr double kMaxPointRmsM = 0.02;

TEST(BundleAdjustment, ConvergesToTruthFromPerturbedStart) {
  const Scene scene = MakeScene(SceneOptions());
  MapperState state = scene.state;
  Perturb(&state, 0.02, 0.1, 0.1);
  const Errors initial =
      ComputeErrors(scene, state, AlignToTruth(scene, state));
  const SE3 first_before = state.frames.begin()->second.rig_from_world;

  const BundleAdjustmentStats stats =
      RunBundleAdjustment(FixedIntrinsicsOptions(), &state);
  EXPECT_TRUE(stats.usable) << stats.termination;
  EXPECT_EQ(stats.num_frames, 10u);
  EXPECT_EQ(stats.num_points, 300u);
  EXPECT_GT(stats.num_reprojection_residuals, 2500u);
  EXPECT_EQ(stats.num_lidar_residuals, 0u);
  EXPECT_LT(stats.final_cost, stats.initial_cost);
  // Gauge: the first frame is held exactly.
  EXPECT_TRUE(test::PosesNear(
      state.frames.begin()->second.rig_from_world, first_before, 1e-12, 1e-12));
  EXPECT_NE(stats.gauge.find("frame 1 fixed"), std::string::npos)
      << stats.gauge;

  // Scale is a gauge here: compare after a similarity alignment.
  const Errors final = ComputeErrors(scene, state, AlignToTruth(scene, state));
  EXPECT_GT(initial.rms_point_m, 5 * kMaxPointRmsM);  // the test can fail
  EXPECT_LT(final.max_rotation_rad, kMaxRotationErrorRad);
  EXPECT_LT(final.max_position_m, kMaxPositionErrorM);
  EXPECT_LT(final.rms_point_m, kMaxPointRmsM);
  // Mean |noise| of a 2D Gaussian with sigma 0.5 px is 0.5 sqrt(pi/2) = 0.63
  // px; the fit absorbs a small fraction of it.
  EXPECT_GT(stats.final_mean_reprojection_error_px, 0.45);
  EXPECT_LT(stats.final_mean_reprojection_error_px, 0.70);
  for (const Track& track : state.tracks) {
    EXPECT_GE(track.error, 0.0);
    EXPECT_LT(track.error, 3.0);  // mean of ~10 observations, sigma 0.5 px
  }
}

// Without noise the truth is the exact optimum (first frame held at the
// truth, the scale coordinate keeps its true value since translations are not
// perturbed): BA must reach it to solver precision.
TEST(BundleAdjustment, NoiseFreeSceneConvergesExactly) {
  SceneOptions scene_options;
  scene_options.noise_px = 0.0;
  const Scene scene = MakeScene(scene_options);
  MapperState state = scene.state;
  Perturb(&state, 0.02, 0.0, 0.1, {1});
  const BundleAdjustmentStats stats =
      RunBundleAdjustment(FixedIntrinsicsOptions(), &state);
  EXPECT_TRUE(stats.converged) << stats.termination;
  const Errors final = ComputeErrors(scene, state);
  // Ceres stops at a relative cost change of 1e-6 on a cost that falls
  // quadratically to ~0; 1e-6 rad / 1e-5 m is far below any noise level.
  EXPECT_LT(final.max_rotation_rad, 1e-6);
  EXPECT_LT(final.max_position_m, 1e-5);
  EXPECT_LT(final.rms_point_m, 1e-5);
  EXPECT_LT(stats.final_mean_reprojection_error_px, 1e-4);
  // 10 frames <= dense_schur_max_frames: lisfm's dense-Schur LM by default.
  EXPECT_EQ(stats.linear_solver, "lisfm dense Schur LM");

  // Ceres' dense and sparse Schur paths reach the same optimum.
  for (const std::string solver_path : {"dense", "sparse"}) {
    MapperState ceres_state = scene.state;
    Perturb(&ceres_state, 0.02, 0.0, 0.1, {1});
    BundleAdjustmentOptions ceres_options = FixedIntrinsicsOptions();
    ceres_options.solver = "ceres";
    if (solver_path == "sparse") ceres_options.dense_schur_max_frames = 0;
    const BundleAdjustmentStats ceres_stats = RunBundleAdjustment(ceres_options, &ceres_state);
    EXPECT_TRUE(ceres_stats.converged) << ceres_stats.termination;
    EXPECT_EQ(ceres_stats.linear_solver, solver_path == "sparse" ? "SPARSE_SCHUR" : "DENSE_SCHUR");
    const Errors ceres_errors = ComputeErrors(scene, ceres_state);
    EXPECT_LT(ceres_errors.max_rotation_rad, 1e-6) << solver_path;
    EXPECT_LT(ceres_errors.max_position_m, 1e-5) << solver_path;
  }
}

// The Schur solver and Ceres minimise the same objective: from the same start
// with tight tolerances they reach the same optimum (poses, points, refined
// intrinsics, cost) on a problem with everything at once: Cauchy loss with
// outliers, focal length + distortion refined (free indices 0 and 3 of
// SIMPLE_RADIAL), position + rotation priors on some frames and LiDAR
// constraints between consecutive frames.
TEST(BundleAdjustment, SchurSolverMatchesCeres) {
  SceneOptions scene_options;
  scene_options.outlier_ratio = 0.03;
  const Scene scene = MakeScene(scene_options);
  MapperState start = scene.state;
  std::normal_distribution<double> n01(0.0, 1.0);
  for (frame_t f : {2, 5, 9}) {
    SfmFrame& frame = start.frames.at(f);
    frame.has_prior_position = true;
    frame.prior_position = Center(scene.rig_from_world.at(f)) +
                           0.05 * Vec3(n01(test::Rng()), n01(test::Rng()), n01(test::Rng()));
    frame.prior_position_covariance = Mat3::Identity() * 0.05 * 0.05;
    frame.has_prior_rotation = true;
    frame.prior_rig_from_world_rotation =
        so3::Exp(Vec3(0.01, -0.005, 0.002)) * scene.rig_from_world.at(f).rotation();
    frame.prior_rotation_sigma = 0.01;
  }
  Mat6 covariance = Mat6::Identity() * 1e-4;
  for (frame_t f = 1; f < 10; ++f) {
    LidarConstraint constraint;
    constraint.frame_id1 = f;
    constraint.frame_id2 = f + 1;
    Vec6 xi;
    for (int i = 0; i < 6; ++i) xi[i] = 0.01 * n01(test::Rng());
    constraint.rig1_from_rig2 = scene.rig_from_world.at(f) *
                                scene.rig_from_world.at(f + 1).Inverse() * SE3::Exp(xi);
    constraint.covariance = covariance;
    start.lidar_constraints.push_back(constraint);
  }
  Perturb(&start, 0.01, 0.05, 0.05);
  start.cameras.begin()->second.params[0] *= 1.02;  // focal length 2 % off

  BundleAdjustmentOptions options;
  options.num_threads = 2;
  options.loss_type = "cauchy";
  options.max_num_iterations = 200;
  options.function_tolerance = 1e-14;
  options.gradient_tolerance = 1e-14;
  options.parameter_tolerance = 1e-14;
  MapperState schur_state = start;
  MapperState ceres_state = start;
  options.solver = "schur";
  const BundleAdjustmentStats schur = RunBundleAdjustment(options, &schur_state);
  options.solver = "ceres";
  const BundleAdjustmentStats ceres = RunBundleAdjustment(options, &ceres_state);
  EXPECT_EQ(schur.linear_solver, "lisfm dense Schur LM");
  EXPECT_EQ(ceres.linear_solver, "DENSE_SCHUR");
  EXPECT_EQ(schur.gauge, ceres.gauge);
  EXPECT_EQ(schur.num_lidar_residuals, 9u);
  EXPECT_EQ(schur.num_position_prior_residuals, 3u);
  EXPECT_NEAR(schur.initial_cost, ceres.initial_cost, 1e-9 * ceres.initial_cost);
  // Both run to machine-precision convergence of the same smooth objective.
  EXPECT_NEAR(schur.final_cost, ceres.final_cost, 1e-8 * ceres.final_cost);
  EXPECT_LT(schur.final_cost, schur.initial_cost);
  // It did move: the start is perturbed by up to 5 cm per frame.
  double max_move = 0.0;
  for (const auto& [frame_id, frame] : schur_state.frames) {
    max_move = std::max(max_move, (Center(frame.rig_from_world) -
                                   Center(start.frames.at(frame_id).rig_from_world))
                                      .norm());
  }
  EXPECT_GT(max_move, 0.01);
  for (const auto& [frame_id, frame] : schur_state.frames) {
    EXPECT_TRUE(test::PosesNear(frame.rig_from_world,
                                ceres_state.frames.at(frame_id).rig_from_world, 1e-7, 1e-6))
        << "frame " << frame_id;
  }
  const std::vector<double>& p_schur = schur_state.cameras.begin()->second.params;
  const std::vector<double>& p_ceres = ceres_state.cameras.begin()->second.params;
  const std::vector<double>& p_start = start.cameras.begin()->second.params;
  for (size_t i = 0; i < p_schur.size(); ++i) {
    EXPECT_NEAR(p_schur[i], p_ceres[i], 1e-6 * std::max(1.0, std::abs(p_ceres[i]))) << i;
  }
  EXPECT_NE(p_schur[0], p_start[0]);   // focal length refined
  EXPECT_EQ(p_schur[1], p_start[1]);   // principal point held
  EXPECT_EQ(p_schur[2], p_start[2]);
  double max_point_diff = 0.0;
  for (size_t k = 0; k < schur_state.tracks.size(); ++k) {
    max_point_diff = std::max(max_point_diff,
                              (schur_state.tracks[k].xyz - ceres_state.tracks[k].xyz).norm());
  }
  EXPECT_LT(max_point_diff, 1e-5);
  EXPECT_NEAR(schur.final_mean_reprojection_error_px, ceres.final_mean_reprojection_error_px, 1e-6);
}

// Both solvers keep the gauge: the first frame exactly, and the far frame's
// largest translation coordinate.
TEST(BundleAdjustment, SchurSolverKeepsTheGauge) {
  const Scene scene = MakeScene(SceneOptions());
  MapperState state = scene.state;
  Perturb(&state, 0.02, 0.1, 0.1);
  const MapperState before = state;
  BundleAdjustmentOptions options = FixedIntrinsicsOptions();
  options.solver = "schur";
  const BundleAdjustmentStats stats = RunBundleAdjustment(options, &state);
  EXPECT_TRUE(stats.converged) << stats.termination;
  EXPECT_TRUE(test::PosesNear(state.frames.at(1).rig_from_world,
                              before.frames.at(1).rig_from_world, 0.0, 0.0));
  // "scale: frame F t[i] fixed"
  const size_t at = stats.gauge.find("scale: frame ");
  ASSERT_NE(at, std::string::npos) << stats.gauge;
  const frame_t far = static_cast<frame_t>(std::stoul(stats.gauge.substr(at + 13)));
  const int coordinate = stats.gauge[stats.gauge.find("t[", at) + 2] - '0';
  EXPECT_EQ(state.frames.at(far).rig_from_world.translation()[coordinate],
            before.frames.at(far).rig_from_world.translation()[coordinate]);
  EXPECT_NE(state.frames.at(far).rig_from_world.translation()[(coordinate + 1) % 3],
            before.frames.at(far).rig_from_world.translation()[(coordinate + 1) % 3]);
  // The cam_from_rig refinement is Ceres' job: "auto" switches, "schur" refuses.
  SceneOptions rig_options;
  rig_options.rig = true;
  const Scene rig_scene = MakeScene(rig_options);
  MapperState rig_state = rig_scene.state;
  BundleAdjustmentOptions rig_ba = FixedIntrinsicsOptions();
  rig_ba.refine_cam_from_rig = true;
  rig_ba.max_num_iterations = 2;
  EXPECT_EQ(RunBundleAdjustment(rig_ba, &rig_state).linear_solver, "DENSE_SCHUR");
  rig_ba.solver = "schur";
  EXPECT_THROW(RunBundleAdjustment(rig_ba, &rig_state), InternalError);
}

TEST(BundleAdjustment, RigSceneKeepsFixedCamFromRig) {
  SceneOptions scene_options;
  scene_options.rig = true;
  const Scene scene = MakeScene(scene_options);
  MapperState state = scene.state;
  // The first frame is the gauge and stays at the truth; other frames keep
  // their true translation t (so the scale coordinate is the true one) while
  // rotations (hence centres) and points are perturbed: the truth is then the
  // exact solution without any alignment.
  Perturb(&state, 0.02, 0.0, 0.1, {1});
  const Errors initial = ComputeErrors(scene, state);
  const BundleAdjustmentStats stats =
      RunBundleAdjustment(FixedIntrinsicsOptions(), &state);
  EXPECT_TRUE(stats.usable) << stats.termination;
  EXPECT_EQ(stats.num_frames, 10u);
  EXPECT_EQ(stats.num_images, 30u);
  for (const auto& [camera_id, cam_from_rig] : scene.cam_from_rig) {
    EXPECT_TRUE(test::PosesNear(
        state.cam_from_rig.at(camera_id), cam_from_rig, 0.0, 0.0));
  }
  const Errors final = ComputeErrors(scene, state);
  EXPECT_GT(initial.max_position_m, 5 * kMaxPositionErrorM);
  EXPECT_LT(final.max_rotation_rad, kMaxRotationErrorRad);
  EXPECT_LT(final.max_position_m, kMaxPositionErrorM);
  EXPECT_LT(final.rms_point_m, kMaxPointRmsM);
}

TEST(BundleAdjustment, RigRefinesCamFromRig) {
  SceneOptions scene_options;
  scene_options.rig = true;
  const Scene scene = MakeScene(scene_options);
  MapperState state = scene.state;
  Perturb(&state, 0.01, 0.0, 0.05, {1});
  // Rotate cameras 2 and 3 by 1 degree in the rig; camera 1 is the reference.
  for (camera_t camera_id : {2u, 3u}) {
    state.cam_from_rig[camera_id] =
        SE3(Quat(Eigen::AngleAxisd(0.0175, Vec3(1, 1, 0).normalized())),
            Vec3::Zero()) *
        state.cam_from_rig[camera_id];
  }
  BundleAdjustmentOptions options = FixedIntrinsicsOptions();
  options.refine_cam_from_rig = true;
  const BundleAdjustmentStats stats = RunBundleAdjustment(options, &state);
  EXPECT_TRUE(stats.usable) << stats.termination;
  EXPECT_TRUE(test::PosesNear(
      state.cam_from_rig.at(1), scene.cam_from_rig.at(1), 0.0, 0.0));
  for (camera_t camera_id : {2u, 3u}) {
    // cam_from_rig is shared by 10 frames, so it is known at least as well
    // as one frame's pose: the per-frame bounds (rotation) and 1 cm (half the
    // position bound: the offsets are 10 cm, not 8 m lever arms) apply.
    EXPECT_TRUE(test::PosesNear(state.cam_from_rig.at(camera_id),
                                scene.cam_from_rig.at(camera_id),
                                kMaxRotationErrorRad,
                                0.01))
        << "camera " << camera_id;
  }
  const Errors final = ComputeErrors(scene, state);
  EXPECT_LT(final.max_rotation_rad, kMaxRotationErrorRad);
  EXPECT_LT(final.max_position_m, kMaxPositionErrorM);
}

TEST(BundleAdjustment, PositionPriorsGiveMetricResultWithoutAlignment) {
  const Scene scene = MakeScene(SceneOptions());
  MapperState state = scene.state;
  const double kPriorSigma = 0.02;  // m
  std::normal_distribution<double> noise(0.0, kPriorSigma);
  for (auto& [frame_id, frame] : state.frames) {
    frame.has_prior_position = true;
    frame.prior_position =
        Center(scene.rig_from_world.at(frame_id)) +
        Vec3(noise(test::Rng()), noise(test::Rng()), noise(test::Rng()));
    frame.prior_position_covariance =
        Mat3::Identity() * kPriorSigma * kPriorSigma;
  }
  // Start far from the truth: scale 0.7, shifted by 1 m, plus perturbations
  // (what a scale-free averaging stage might hand over).
  for (auto& [frame_id, frame] : state.frames) {
    const Vec3 center =
        0.7 * Center(frame.rig_from_world) + Vec3(1.0, -0.5, 0.3);
    frame.rig_from_world.SetTranslation(
        -(frame.rig_from_world.rotation() * center));
  }
  for (Track& track : state.tracks)
    track.xyz = 0.7 * track.xyz + Vec3(1.0, -0.5, 0.3);
  Perturb(&state, 0.02, 0.1, 0.1);
  const BundleAdjustmentStats stats =
      RunBundleAdjustment(FixedIntrinsicsOptions(), &state);
  EXPECT_TRUE(stats.usable) << stats.termination;
  EXPECT_EQ(stats.num_position_prior_residuals, 10u);
  EXPECT_NE(stats.gauge.find("pose from priors"), std::string::npos)
      << stats.gauge;
  // No alignment: the priors fix the 7-dof similarity. A least-squares fit of
  // 7 parameters to 30 coordinates with sigma 2 cm leaves ~2 cm * sqrt(7/30)
  // ~ 1 cm per frame; the ring radius (8 m) turns this into ~1e-3 rad of
  // gauge rotation. 4 cm / 3e-3 rad bound the worst of 10 frames (> 3 sigma).
  const Errors final = ComputeErrors(scene, state);
  EXPECT_LT(final.max_position_m, 0.04);
  EXPECT_LT(final.max_rotation_rad, 3e-3);
  EXPECT_LT(final.rms_point_m, 0.04);
}

TEST(BundleAdjustment, LidarConstraintsAloneFixTheScale) {
  const Scene scene = MakeScene(SceneOptions());
  MapperState state = scene.state;
  // Constraints between consecutive frames, rig1_from_rig2 = truth * Exp(xi)
  // with xi ~ N(0, covariance): 0.1 deg and 5 mm per axis.
  const double kRotSigma = 0.1 * M_PI / 180.0, kTransSigma = 0.005;
  Mat6 covariance = Mat6::Zero();
  covariance.diagonal() << Vec3::Constant(kRotSigma * kRotSigma),
      Vec3::Constant(kTransSigma * kTransSigma);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (frame_t f = 1; f < 10; ++f) {
    LidarConstraint constraint;
    constraint.frame_id1 = f;
    constraint.frame_id2 = f + 1;
    Vec6 xi;
    for (int i = 0; i < 6; ++i)
      xi[i] = n01(test::Rng()) * std::sqrt(covariance(i, i));
    constraint.rig1_from_rig2 = scene.rig_from_world.at(f) *
                                scene.rig_from_world.at(f + 1).Inverse() *
                                SE3::Exp(xi);
    constraint.covariance = covariance;
    state.lidar_constraints.push_back(constraint);
  }
  // Scale-free start: the whole scene shrunk to half about the first frame
  // (which stays at its true pose, being the gauge), then perturbed.
  const Vec3 c1 = Center(scene.rig_from_world.at(1));
  for (auto& [frame_id, frame] : state.frames) {
    const Vec3 center = c1 + 0.5 * (Center(frame.rig_from_world) - c1);
    frame.rig_from_world.SetTranslation(
        -(frame.rig_from_world.rotation() * center));
  }
  for (Track& track : state.tracks) track.xyz = c1 + 0.5 * (track.xyz - c1);
  Perturb(&state, 0.01, 0.05, 0.05, {1});
  const Errors initial = ComputeErrors(scene, state);
  const BundleAdjustmentStats stats =
      RunBundleAdjustment(FixedIntrinsicsOptions(), &state);
  EXPECT_TRUE(stats.usable) << stats.termination;
  EXPECT_EQ(stats.num_lidar_residuals, 9u);
  EXPECT_NE(stats.gauge.find("frame 1 fixed"), std::string::npos)
      << stats.gauge;
  EXPECT_NE(stats.gauge.find("LiDAR"), std::string::npos) << stats.gauge;
  // Metric without alignment: 9 constraints of ~5 m with 5 mm noise give the
  // scale to ~1e-3 / sqrt(9) relative, i.e. ~3 mm over the 16 m ring; image
  // noise adds the few mm of the first test.
  const Errors final = ComputeErrors(scene, state);
  EXPECT_GT(initial.max_position_m, 1.0);
  EXPECT_LT(final.max_position_m, kMaxPositionErrorM);
  EXPECT_LT(final.max_rotation_rad, kMaxRotationErrorRad);
  EXPECT_LT(final.rms_point_m, kMaxPointRmsM);
}

TEST(BundleAdjustment, RefinesFocalLength) {
  const Scene scene = MakeScene(SceneOptions());
  MapperState state = scene.state;
  Perturb(&state, 0.005, 0.02, 0.02, {1});
  state.cameras.at(1).params[0] *= 1.05;
  BundleAdjustmentOptions
      options;  // defaults: focal + extra refined, principal point fixed
  options.num_threads = 2;
  const BundleAdjustmentStats stats = RunBundleAdjustment(options, &state);
  EXPECT_TRUE(stats.usable) << stats.termination;
  EXPECT_EQ(stats.num_cameras_refined, 1u);
  const std::vector<double>& params = state.cameras.at(1).params;
  // ~3000 observations with 0.5 px noise over a +-20 deg field: the focal
  // length is determined to well below 0.1 %; 0.5 % is 10x below the 5 %
  // initial error. The principal point is held constant exactly.
  EXPECT_NEAR(params[0], scene.params[0], 0.005 * scene.params[0]);
  EXPECT_EQ(params[1], scene.params[1]);
  EXPECT_EQ(params[2], scene.params[2]);
  EXPECT_NEAR(
      params[3], scene.params[3], 0.01);  // k on r^2 <= 0.1: weakly determined
  EXPECT_LT(stats.final_mean_reprojection_error_px, 0.70);
}

TEST(BundleAdjustment, RobustLossResistsOutliers) {
  SceneOptions scene_options;
  scene_options.outlier_ratio =
      0.05;  // uniform random pixels: errors of ~100 px
  const Scene scene = MakeScene(scene_options);
  MapperState robust_state = scene.state;
  Perturb(&robust_state, 0.005, 0.02, 0.02, {1});
  MapperState trivial_state = robust_state;

  BundleAdjustmentOptions options = FixedIntrinsicsOptions();
  options.loss_type = "cauchy";
  RunBundleAdjustment(options, &robust_state);
  const Errors robust =
      ComputeErrors(scene, robust_state, AlignToTruth(scene, robust_state));
  // Inliers carry the same noise as in the first test; the Cauchy loss
  // (scale 1 px) gives ~100 px outliers a weight of ~1e-4, so the same bounds
  // hold.
  EXPECT_LT(robust.max_rotation_rad, kMaxRotationErrorRad);
  EXPECT_LT(robust.max_position_m, kMaxPositionErrorM);
  EXPECT_LT(robust.rms_point_m, kMaxPointRmsM);

  options.loss_type = "trivial";
  RunBundleAdjustment(options, &trivial_state);
  const Errors trivial =
      ComputeErrors(scene, trivial_state, AlignToTruth(scene, trivial_state));
  // Without the robust loss the outliers drag the points (the comparison shows
  // that the scene does contain harmful outliers).
  EXPECT_GT(trivial.rms_point_m, 2.0 * robust.rms_point_m);
}

TEST(BundleAdjustment, NoObservationsLeavesStateUnchanged) {
  Scene scene = MakeScene(SceneOptions());
  for (auto& [frame_id, frame] : scene.state.frames) frame.registered = false;
  const SE3 before = scene.state.frames.at(3).rig_from_world;
  const BundleAdjustmentStats stats =
      RunBundleAdjustment(FixedIntrinsicsOptions(), &scene.state);
  EXPECT_EQ(stats.num_reprojection_residuals, 0u);
  EXPECT_FALSE(stats.usable);
  EXPECT_TRUE(test::PosesNear(
      scene.state.frames.at(3).rig_from_world, before, 0.0, 0.0));
}

TEST(BundleAdjustment, BadInputs) {
  Scene scene = MakeScene(SceneOptions());
  BundleAdjustmentOptions options = FixedIntrinsicsOptions();
  options.loss_type = "tukey";
  EXPECT_THROW(RunBundleAdjustment(options, &scene.state), InternalError);

  MapperState state = scene.state;
  state.frames.at(2).has_prior_position = true;
  state.frames.at(2).prior_position_covariance = -Mat3::Identity();
  EXPECT_THROW(RunBundleAdjustment(FixedIntrinsicsOptions(), &state),
               InputError);

  state = scene.state;
  LidarConstraint constraint;
  constraint.frame_id1 = 1;
  constraint.frame_id2 = 2;
  constraint.covariance = Mat6::Zero();
  state.lidar_constraints.push_back(constraint);
  EXPECT_THROW(RunBundleAdjustment(FixedIntrinsicsOptions(), &state),
               InputError);
}

// ---------------------------------------------------------------------------
// Residual functors against core/geometry.h.

Mat6 RandomSpd6() {
  std::normal_distribution<double> n01(0.0, 1.0);
  Mat6 a;
  for (int i = 0; i < 36; ++i) a(i) = n01(test::Rng());
  return a * a.transpose() + Mat6::Identity();
}

// Priors and LiDAR constraints measured in a frame P rotated from the rig
// frame by a known X = rig_from_prior (0.2 deg), as lio's frame is offset by
// a LiDAR extrinsic calibration error: position priors on P's
// origin (sigma 2 cm), rotation priors on prior_from_world = X^-1
// rig_from_world (sigma 0.005 rad), LiDAR constraints prior_i_from_prior_j =
// X^-1 rig_i_from_rig_j X between frames 1-3 apart on the ring (rotation sigma
// 0.0005 rad, translation 3 mm), all with that noise. Rolled frames (0.3 rad)
// so that the relative rotations turn about different axes.
struct PriorFrameProblem {
  Scene scene;
  MapperState start;
  SE3 rig_from_prior;
};

PriorFrameProblem MakePriorFrameProblem(double roll_rad = 0.3,
                                        const Vec3& rig_from_prior_translation = Vec3::Zero(),
                                        double pan_rad = 0.0,
                                        double height_amplitude_m = 1.0) {
  SceneOptions scene_options;
  scene_options.rig = true;
  scene_options.roll_rad = roll_rad;
  scene_options.pan_rad = pan_rad;
  scene_options.height_amplitude_m = height_amplitude_m;
  PriorFrameProblem p;
  p.scene = MakeScene(scene_options);
  p.rig_from_prior =
      SE3(so3::Exp(Vec3(0.12, -0.08, 0.14) * M_PI / 180.0), rig_from_prior_translation);
  const SE3 prior_from_rig = p.rig_from_prior.Inverse();
  MapperState& state = p.start;
  state = p.scene.state;
  std::mt19937& rng = test::Rng();
  std::normal_distribution<double> n01(0.0, 1.0);
  auto noise3 = [&](double sigma) -> Vec3 { return Vec3(n01(rng), n01(rng), n01(rng)) * sigma; };
  const int n = static_cast<int>(p.scene.rig_from_world.size());
  for (auto& [frame_id, frame] : state.frames) {
    const SE3 prior_from_world = prior_from_rig * p.scene.rig_from_world.at(frame_id);
    frame.has_prior_position = true;
    frame.prior_position = Center(prior_from_world) + noise3(0.02);
    frame.prior_position_covariance = Mat3::Identity() * 0.02 * 0.02;
    frame.has_prior_rotation = true;
    frame.prior_rig_from_world_rotation = so3::Exp(noise3(0.005)) * prior_from_world.rotation();
    frame.prior_rotation_sigma = 0.005;
  }
  Mat6 covariance = Mat6::Zero();
  covariance.diagonal() << Vec3::Constant(0.0005 * 0.0005), Vec3::Constant(0.003 * 0.003);
  for (int i = 0; i < n; ++i) {
    for (int d = 1; d <= 3; ++d) {
      const frame_t f1 = static_cast<frame_t>(i + 1);
      const frame_t f2 = static_cast<frame_t>((i + d) % n + 1);
      LidarConstraint constraint;
      constraint.frame_id1 = f1;
      constraint.frame_id2 = f2;
      Vec6 xi;
      xi << noise3(0.0005), noise3(0.003);
      constraint.rig1_from_rig2 = prior_from_rig * p.scene.rig_from_world.at(f1) *
                                  p.scene.rig_from_world.at(f2).Inverse() * p.rig_from_prior *
                                  SE3::Exp(xi);
      constraint.covariance = covariance;
      state.lidar_constraints.push_back(constraint);
    }
  }
  Perturb(&state, 0.005, 0.02, 0.02);
  return p;
}

// Mean over frames of the rotation error Log(R_est * R_true^-1) of
// rig_from_world (rad, rig axes) after an SE(3) alignment of the frame
// centres: a rotation constant in the rig frame, which no world alignment
// removes.
Vec3 MeanRigFrameRotationError(const Scene& scene, const MapperState& state) {
  Eigen::Matrix3Xd source(3, scene.rig_from_world.size()), target(3, scene.rig_from_world.size());
  int i = 0;
  for (const auto& [frame_id, truth] : scene.rig_from_world) {
    source.col(i) = Center(state.frames.at(frame_id).rig_from_world);
    target.col(i) = Center(truth);
    ++i;
  }
  const Sim3 align = AlignUmeyama(source, target, /*estimate_scale=*/false);
  Vec3 sum = Vec3::Zero();
  for (const auto& [frame_id, truth] : scene.rig_from_world) {
    const SE3 world_from_rig = align.Transform(state.frames.at(frame_id).rig_from_world.Inverse());
    sum += so3::Log(world_from_rig.Inverse().rotation() * truth.rotation().conjugate());
  }
  return sum / static_cast<double>(scene.rig_from_world.size());
}

TEST(BundleAdjustment, RefinesPriorFrameWithBothSolvers) {
  const PriorFrameProblem p = MakePriorFrameProblem();
  const double offset_rad = so3::Log(p.rig_from_prior.rotation()).norm();
  for (const std::string solver : {"schur", "ceres"}) {
    SCOPED_TRACE(solver);
    BundleAdjustmentOptions options = FixedIntrinsicsOptions();
    options.solver = solver;

    // Without X the rig frames take on the prior frame's offset.
    MapperState plain = p.start;
    const BundleAdjustmentStats plain_stats = RunBundleAdjustment(options, &plain);
    EXPECT_TRUE(plain_stats.usable) << plain_stats.termination;
    EXPECT_FALSE(plain_stats.prior_frame_used);
    EXPECT_TRUE(test::PosesNear(plain.rig_from_prior, SE3(), 0.0, 0.0));
    const Vec3 plain_error = MeanRigFrameRotationError(p.scene, plain);

    options.refine_prior_frame = true;
    MapperState refined = p.start;
    const BundleAdjustmentStats stats = RunBundleAdjustment(options, &refined);
    EXPECT_TRUE(stats.usable) << stats.termination;
    EXPECT_TRUE(stats.prior_frame_used);
    // The rotation is determined (0.0005 rad LiDAR rotations over 30 terms
    // turning about different axes: predicted sigma ~0.006 deg).
    EXPECT_TRUE(stats.prior_frame_rotation_refined) << stats.prior_frame_note;
    EXPECT_LT(stats.prior_frame_rotation_sigma_deg, 0.02);
    const Vec3 refined_error = MeanRigFrameRotationError(p.scene, refined);
    const double x_rotation_error =
        so3::AngularDistance(refined.rig_from_prior.rotation(), p.rig_from_prior.rotation());
    const double x_translation_error =
        (refined.rig_from_prior.translation() - p.rig_from_prior.translation()).norm();
    // Without X most of the offset stays in the rig frames; with X, X and the
    // frames' mean rotation are known to a few predicted sigmas (0.006 deg),
    // well below a tenth of the 0.2 deg offset.
    EXPECT_GT(plain_error.norm(), 0.5 * offset_rad) << plain_error.transpose();
    EXPECT_LT(refined_error.norm(), 0.1 * offset_rad) << refined_error.transpose();
    EXPECT_LT(x_rotation_error, 0.1 * offset_rad);
    // At its true value, or refined along the directions the guard releases.
    EXPECT_LT(x_translation_error, 3.0 * stats.prior_frame_translation_sigmas_m(0) + 1e-9)
        << stats.prior_frame_note;
    EXPECT_TRUE(test::PosesNear(stats.rig_from_prior, refined.rig_from_prior, 0.0, 0.0));

    // Without LiDAR terms X is held (the guard needs them) and stays identity.
    options.use_lidar_constraints = false;
    MapperState no_lidar = p.start;
    const BundleAdjustmentStats no_lidar_stats = RunBundleAdjustment(options, &no_lidar);
    EXPECT_TRUE(no_lidar_stats.prior_frame_used);
    EXPECT_FALSE(no_lidar_stats.prior_frame_rotation_refined);
    EXPECT_FALSE(no_lidar_stats.prior_frame_translation_refined);
    EXPECT_EQ(no_lidar_stats.prior_frame_note, "held: no LiDAR terms");
    EXPECT_TRUE(test::PosesNear(no_lidar.rig_from_prior, SE3(), 0.0, 0.0));
  }
}

// X's translation, 8 / -3 / 14 mm like a LiDAR extrinsic calibration error,
// shows only through relative rotations, (I - R_ij) t_X. Frames panned by up
// to 0.15 rad, so that t_X along the viewing axes does not trade off against
// the scale (as it does when every view meets the ring's centre). Rolled by up
// to 0.6 rad, the relative rotations turn about the vertical and about the
// viewing axes: every direction is determined and the guard refines it. Flat
// ring without roll: every frame turns about the vertical only (rig y, world
// up; the scene's 0.01 rad tilts aside), so t_X along it is unseen and held
// while the two horizontal directions are refined.
TEST(BundleAdjustment, PriorFrameTranslationGuard) {
  const Vec3 t_x(0.008, -0.003, 0.014);
  for (const std::string solver : {"schur", "ceres"}) {
    SCOPED_TRACE(solver);
    BundleAdjustmentOptions options = FixedIntrinsicsOptions();
    options.solver = solver;
    options.refine_prior_frame = true;

    const PriorFrameProblem turns = MakePriorFrameProblem(0.6, t_x, 0.15);
    MapperState refined = turns.start;
    const BundleAdjustmentStats stats = RunBundleAdjustment(options, &refined);
    EXPECT_TRUE(stats.usable) << stats.termination;
    EXPECT_EQ(stats.prior_frame_translation_directions_refined, 3) << stats.prior_frame_note;
    EXPECT_TRUE(stats.prior_frame_translation_refined);
    // The guard's sigma (0.9-3.4 mm) takes the images' relative poses as
    // exact; the estimate is within a few of those sigmas of the truth, about
    // a third of the 16 mm offset that holding it would leave.
    const double error = (refined.rig_from_prior.translation() - t_x).norm();
    EXPECT_LT(error, 0.5 * t_x.norm()) << stats.prior_frame_note;
    EXPECT_LT(error, 4.0 * stats.prior_frame_translation_sigma_m) << stats.prior_frame_note;

    const PriorFrameProblem planar = MakePriorFrameProblem(0.0, t_x, 0.15, 0.0);
    MapperState planar_refined = planar.start;
    const BundleAdjustmentStats planar_stats = RunBundleAdjustment(options, &planar_refined);
    EXPECT_TRUE(planar_stats.usable) << planar_stats.termination;
    EXPECT_EQ(planar_stats.prior_frame_translation_directions_refined, 2)
        << planar_stats.prior_frame_note;
    EXPECT_GT(planar_stats.prior_frame_translation_sigmas_m(2), 0.05)
        << planar_stats.prior_frame_note;
    // The vertical component stays near its start (0): held, not estimated.
    const Vec3 t = planar_refined.rig_from_prior.translation();
    EXPECT_LT(std::abs(t.y()), 5e-4) << t.transpose() << "; " << planar_stats.prior_frame_note;
    // The horizontal ones are refined towards the truth (held: 16 mm off).
    EXPECT_LT(Vec2(t.x() - t_x.x(), t.z() - t_x.z()).norm(), 0.75 * Vec2(t_x.x(), t_x.z()).norm())
        << t.transpose() << "; " << planar_stats.prior_frame_note;
  }
}

TEST(BundleAdjustmentFunctors, SE3LogMatchesGeometry) {
  for (int trial = 0; trial < 20; ++trial) {
    const SE3 pose = test::RandomPose(3.0, 5.0);
    const Vec6 expected = pose.Log();
    const Vec6 actual = SE3LogT<double>(pose.rotation(), pose.translation());
    EXPECT_LT((actual - expected).norm(), 1e-9)
        << actual.transpose() << " vs " << expected.transpose();
  }
  // Small angles (series branches).
  for (double angle : {0.0, 1e-10, 1e-6, 1e-4}) {
    const SE3 pose = SE3::Exp(
        (Vec6() << angle, -2 * angle, 0.5 * angle, 0.3, -1.0, 2.0).finished());
    EXPECT_LT(
        (SE3LogT<double>(pose.rotation(), pose.translation()) - pose.Log())
            .norm(),
        1e-12)
        << angle;
  }
}

TEST(BundleAdjustmentFunctors, RelativePoseResidualIsWhitenedSE3Log) {
  for (int trial = 0; trial < 10; ++trial) {
    const SE3 rig1_from_world = test::RandomPose();
    const SE3 rig2_from_world = test::RandomPose();
    const SE3 meas = rig1_from_world * rig2_from_world.Inverse() *
                     test::RandomPose(0.2, 0.3);
    const Mat6 covariance = RandomSpd6();
    // S^T S = covariance^-1 (any such S whitens); the functor gets it from the
    // caller.
    const Mat6 information = covariance.inverse();
    const Mat6 sqrt_information =
        Eigen::LLT<Mat6>(information).matrixL().transpose();
    std::unique_ptr<ceres::CostFunction> cost(
        RelativePoseFunctor::Create(meas, sqrt_information));
    const Quat q1 = rig1_from_world.rotation(), q2 = rig2_from_world.rotation();
    const Vec3 t1 = rig1_from_world.translation(),
               t2 = rig2_from_world.translation();
    const double* params[] = {
        q1.coeffs().data(), t1.data(), q2.coeffs().data(), t2.data()};
    Vec6 residual;
    ASSERT_TRUE(cost->Evaluate(params, residual.data(), nullptr));
    const Vec6 xi =
        (meas.Inverse() * rig1_from_world * rig2_from_world.Inverse()).Log();
    EXPECT_LT((residual - sqrt_information * xi).norm(), 1e-9);
    // Whitening: |r|^2 is the Mahalanobis distance of xi.
    EXPECT_NEAR(residual.squaredNorm(),
                xi.dot(information * xi),
                1e-9 * residual.squaredNorm());
  }
}

// At a consistent measurement (residual 0, the small-angle branch) the
// autodiff Jacobian must still be right: compare with central differences.
TEST(BundleAdjustmentFunctors, RelativePoseJacobianAtZeroResidual) {
  const SE3 rig1_from_world = test::RandomPose();
  const SE3 rig2_from_world = test::RandomPose();
  const SE3 meas = rig1_from_world * rig2_from_world.Inverse();
  std::unique_ptr<ceres::CostFunction> cost(
      RelativePoseFunctor::Create(meas, Mat6::Identity()));
  std::vector<std::vector<double>> blocks = {
      {rig1_from_world.rotation().coeffs().data(),
       rig1_from_world.rotation().coeffs().data() + 4},
      {rig1_from_world.translation().data(),
       rig1_from_world.translation().data() + 3},
      {rig2_from_world.rotation().coeffs().data(),
       rig2_from_world.rotation().coeffs().data() + 4},
      {rig2_from_world.translation().data(),
       rig2_from_world.translation().data() + 3}};
  std::vector<const double*> ptrs;
  for (const auto& b : blocks) ptrs.push_back(b.data());
  std::vector<std::vector<double>> jac(4);
  std::vector<double*> jac_ptrs;
  for (size_t b = 0; b < 4; ++b) {
    jac[b].resize(6 * blocks[b].size());
    jac_ptrs.push_back(jac[b].data());
  }
  Vec6 residual;
  ASSERT_TRUE(cost->Evaluate(ptrs.data(), residual.data(), jac_ptrs.data()));
  EXPECT_LT(residual.norm(), 1e-9);
  for (size_t b = 0; b < 4; ++b) {
    const int n = static_cast<int>(blocks[b].size());
    auto f = [&](const VecX& x) -> VecX {
      auto perturbed = blocks;
      for (int i = 0; i < n; ++i) perturbed[b][i] = x[i];
      std::vector<const double*> p;
      for (const auto& pb : perturbed) p.push_back(pb.data());
      VecX r(6);
      EXPECT_TRUE(cost->Evaluate(p.data(), r.data(), nullptr));
      return r;
    };
    const VecX x0 = Eigen::Map<const VecX>(blocks[b].data(), n);
    const MatX numeric = test::NumericJacobian(f, x0);
    const Eigen::Map<
        const Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::RowMajor>>
        analytic(jac[b].data(), 6, n);
    // Central differences with step 1e-6 on O(1) values: error ~1e-9.
    EXPECT_LT((analytic - numeric).cwiseAbs().maxCoeff(), 1e-6)
        << "block " << b;
  }
}

// The terms through X = rig_from_prior: with X = identity they equal the plain
// terms; with X they vanish exactly at measurements made in the prior frame
// (prior_from_world = X^-1 rig_from_world).
TEST(BundleAdjustmentFunctors, PriorFrameResiduals) {
  const SE3 rig1_from_world = test::RandomPose();
  const SE3 rig2_from_world = test::RandomPose();
  Mat6 sqrt_information = Mat6::Identity();
  sqrt_information.diagonal() << 100, 200, 300, 10, 20, 30;
  const Mat3 sqrt_information3 = Vec3(2, 3, 4).asDiagonal();
  const SE3 meas = test::RandomPose();
  const Vec3 prior_position(1.0, -2.0, 0.5);
  const Quat prior_rotation = test::RandomPose().rotation();
  const Quat q1 = rig1_from_world.rotation(), q2 = rig2_from_world.rotation();
  const Vec3 t1 = rig1_from_world.translation(), t2 = rig2_from_world.translation();
  for (const bool identity : {true, false}) {
    SCOPED_TRACE(identity ? "X = identity" : "X");
    const SE3 x = identity ? SE3() : SE3(so3::Exp(Vec3(0.3, -0.2, 0.1)), Vec3(0.1, 0.2, -0.3));
    const Quat qx = x.rotation();
    const Vec3 tx = x.translation();
    // Relative pose.
    std::unique_ptr<ceres::CostFunction> relative(
        PriorFrameRelativePoseFunctor::Create(meas, sqrt_information));
    const double* params[] = {q1.coeffs().data(),
                              t1.data(),
                              q2.coeffs().data(),
                              t2.data(),
                              qx.coeffs().data(),
                              tx.data()};
    Vec6 r;
    ASSERT_TRUE(relative->Evaluate(params, r.data(), nullptr));
    const SE3 estimate = x.Inverse() * rig1_from_world * rig2_from_world.Inverse() * x;
    EXPECT_LT((r - sqrt_information * (meas.Inverse() * estimate).Log()).norm(), 1e-9);
    std::unique_ptr<ceres::CostFunction> exact(
        PriorFrameRelativePoseFunctor::Create(estimate, sqrt_information));
    ASSERT_TRUE(exact->Evaluate(params, r.data(), nullptr));
    EXPECT_LT(r.norm(), 1e-9);
    if (identity) {
      std::unique_ptr<ceres::CostFunction> plain(
          RelativePoseFunctor::Create(meas, sqrt_information));
      Vec6 r_plain, r_x;
      ASSERT_TRUE(plain->Evaluate(params, r_plain.data(), nullptr));
      ASSERT_TRUE(relative->Evaluate(params, r_x.data(), nullptr));
      EXPECT_LT((r_plain - r_x).norm(), 1e-12);
    }
    // Position prior on the origin of P.
    std::unique_ptr<ceres::CostFunction> position(
        PriorFramePositionPriorFunctor::Create(prior_position, sqrt_information3));
    const double* pparams[] = {q1.coeffs().data(), t1.data(), tx.data()};
    Vec3 rp;
    ASSERT_TRUE(position->Evaluate(pparams, rp.data(), nullptr));
    const Vec3 origin = (rig1_from_world.Inverse() * x).translation();
    EXPECT_LT((rp - sqrt_information3 * (origin - prior_position)).norm(), 1e-9);
    // Rotation prior on prior_from_world.
    std::unique_ptr<ceres::CostFunction> rotation(
        PriorFrameRotationPriorFunctor::Create(prior_rotation, 0.01));
    const double* rparams[] = {q1.coeffs().data(), qx.coeffs().data()};
    ASSERT_TRUE(rotation->Evaluate(rparams, rp.data(), nullptr));
    EXPECT_LT((rp - so3::Log(prior_rotation.conjugate() * qx.conjugate() * q1) / 0.01).norm(),
              1e-9);
  }
}

TEST(BundleAdjustmentFunctors, PriorResiduals) {
  const SE3 rig_from_world = test::RandomPose();
  const Vec3 prior(1.0, 2.0, 3.0);
  Mat3 sqrt_information;
  sqrt_information << 2, 0.1, 0, 0, 3, 0.2, 0, 0, 4;
  std::unique_ptr<ceres::CostFunction> position(
      PositionPriorFunctor::Create(prior, sqrt_information));
  const Quat q = rig_from_world.rotation();
  const Vec3 t = rig_from_world.translation();
  const double* params[] = {q.coeffs().data(), t.data()};
  Vec3 residual;
  ASSERT_TRUE(position->Evaluate(params, residual.data(), nullptr));
  EXPECT_LT(
      (residual - sqrt_information * (Center(rig_from_world) - prior)).norm(),
      1e-12);

  const Quat prior_rotation = test::RandomPose().rotation();
  std::unique_ptr<ceres::CostFunction> rotation(
      RotationPriorFunctor::Create(prior_rotation, 0.01));
  const double* rparams[] = {q.coeffs().data()};
  ASSERT_TRUE(rotation->Evaluate(rparams, residual.data(), nullptr));
  EXPECT_LT((residual - so3::Log(prior_rotation.conjugate() * q) / 0.01).norm(),
            1e-9);
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
