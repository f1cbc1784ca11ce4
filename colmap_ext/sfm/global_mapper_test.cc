// End-to-end tests of RunGlobalMapper on synthetic databases with exact
// ground truth (colmap_ext/testing/synthetic.h): all stages together.
#include "colmap_ext/sfm/global_mapper.h"

#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "colmap_ext/testing/synthetic.h"
#include "core/errors.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/rig_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

struct PoseErrors {
  size_t num_images = 0;
  double max_rotation_deg = 0.0;
  double max_position = 0.0;  // after the alignment, in GT units (m)
  double mean_position = 0.0;
  double scale = 1.0;
};

// Aligns the model's camera centres to the truth (Sim3 or SE3) and measures
// per-image rotation and position errors.
PoseErrors Evaluate(const Reconstruction& model,
                    const SyntheticDataset& dataset,
                    bool estimate_scale) {
  PoseErrors e;
  std::vector<image_t> ids;
  for (const Image& image : model.Images()) ids.push_back(image.image_id);
  e.num_images = ids.size();
  Eigen::Matrix3Xd source(3, ids.size()), target(3, ids.size());
  for (size_t i = 0; i < ids.size(); ++i) {
    source.col(i) = model.GetImage(ids[i]).ProjectionCenter();
    target.col(i) = dataset.GetImage(ids[i]).gt_cam_from_world.Inverse().translation();
  }
  const Sim3 world_from_model = AlignUmeyama(source, target, estimate_scale);
  e.scale = world_from_model.scale;
  for (size_t i = 0; i < ids.size(); ++i) {
    const Vec3 aligned = world_from_model * source.col(i);
    const double d = (aligned - target.col(i)).norm();
    e.max_position = std::max(e.max_position, d);
    e.mean_position += d / ids.size();
    // Rotation: R_est_aligned = R_est * R_align^T.
    const Quat est = model.GetImage(ids[i]).CamFromWorld().rotation() *
                     world_from_model.pose.rotation().conjugate();
    const Quat gt = dataset.GetImage(ids[i]).gt_cam_from_world.rotation();
    e.max_rotation_deg = std::max(e.max_rotation_deg, so3::AngularDistance(est, gt) * kRadToDeg);
  }
  return e;
}

// Writes the scene's database into `dir` (db.db) and, with a rig, the rig and
// LiDAR-constraint files the mapper reads (rig.yaml, constraints.txt).
SyntheticDataset WriteScene(const SyntheticDatasetOptions& options, const test::TempDir& dir) {
  SyntheticDataset dataset = SynthesizeDataset(options);
  WriteSyntheticDatabase(dataset, dir.File("db.db"));
  if (options.with_rig) {
    WriteRigYaml(dir.File("rig.yaml"), dataset.rig);
    WriteLidarConstraints(dataset.constraints, dir.File("constraints.txt"));
  }
  return dataset;
}

// One line per component for failure messages.
std::string Describe(const GlobalMapperSummary& summary) {
  std::string s = std::to_string(summary.num_models) + " model(s);";
  for (const MapperComponentSummary& c : summary.components) {
    s += " component of " + std::to_string(c.frames) + " frames: " +
         std::to_string(c.model.registered_frames) + " registered, " +
         std::to_string(c.model.points) + " points;";
  }
  return s;
}

// 24 frames on a ring, 0.5 px noise, 10 % outlier matches and pairs.
SyntheticDatasetOptions RingSceneOptions() {
  SyntheticDatasetOptions o;
  o.num_frames = 24;
  o.num_points = 1500;
  o.pixel_noise = 0.5;
  o.outlier_match_ratio = 0.1;
  o.outlier_pair_ratio = 0.1;
  o.seed = 7;
  return o;
}

// A 5-camera rig in a room, with the pose priors and LiDAR constraints a LiDAR
// stage gives: priors 2 cm / 0.5 deg, constraints 5 mm / 0.1 deg.
SyntheticDatasetOptions RigSceneOptions() {
  SyntheticDatasetOptions o;
  o.num_frames = 20;
  o.with_rig = true;
  o.num_cameras = 5;
  o.trajectory = SyntheticTrajectory::kRoom;
  o.camera_models = {"OPENCV_FISHEYE"};
  o.num_points = 3000;
  o.pixel_noise = 0.5;
  o.max_frame_gap = 3;
  o.outlier_match_ratio = 0.05;
  o.prior_position_noise = 0.02;
  o.prior_rotation_noise = 0.5 * M_PI / 180.0;
  o.num_lidar_neighbors = 2;
  o.lidar_translation_noise = 0.005;
  o.lidar_rotation_noise = 0.1 * M_PI / 180.0;
  o.seed = 11;
  return o;
}

TEST(GlobalMapper, RingWithOutliersRecoversCamerasUpToSimilarity) {
  test::TempDir dir;
  const SyntheticDataset dataset = WriteScene(RingSceneOptions(), dir);
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  GlobalMapperOptions options;
  const GlobalMapperResult result = RunGlobalMapper(database, nullptr, {}, "", options);
  ASSERT_EQ(result.models.size(), 1u) << Describe(result.summary);
  const Reconstruction& model = result.models.front();
  model.Validate("global_mapper");
  EXPECT_EQ(model.NumImages(), dataset.images.size());
  const PoseErrors e = Evaluate(model, dataset, /*estimate_scale=*/true);
  // 0.5 px noise at f = 350 px over ~1000 points per image: the pose
  // uncertainty is a few thousandths of a degree; 0.05 deg leaves margin
  // while still failing for any mis-registered camera.
  EXPECT_LT(e.max_rotation_deg, 0.05);
  // Ring radius 6 m: 5 mm is below 0.1 % of the scene scale.
  EXPECT_LT(e.max_position, 0.005);
  // The final points reproject at the noise level (0.5 px per axis gives a
  // mean 2D error of 0.5 * sqrt(pi/2) = 0.63 px).
  EXPECT_LT(model.ComputeMeanReprojectionError(), 0.8);
  EXPECT_GT(model.ComputeMeanReprojectionError(), 0.3);
  // Most true observations are kept: each point is seen by many images.
  EXPECT_GT(model.NumPoints3D(), 1000u);
  // By default every stage runs: one refinement round (adjustment, filter,
  // retriangulation), then the final adjustment.
  ASSERT_EQ(result.summary.components.size(), 1u);
  const MapperComponentSummary& c = result.summary.components.front();
  EXPECT_FALSE(c.rotation_averaging_skipped);
  EXPECT_FALSE(c.translation_averaging_skipped);
  ASSERT_EQ(c.refinement.size(), 2u);
  for (const MapperRoundSummary& r : c.refinement) {
    EXPECT_FALSE(r.bundle_adjustment_skipped);
    EXPECT_GT(r.bundle_adjustment.num_iterations, 0);
    EXPECT_FALSE(r.retriangulation_skipped);
  }
  EXPECT_FALSE(c.refinement.front().final_round);
  EXPECT_TRUE(c.refinement.back().final_round);
  // Every stage that ran has its own wall time (s), and the stages, which run
  // one after the other, add up to no more than the whole run.
  const GlobalMapperSummary& s = result.summary;
  double stages = s.load_seconds + s.view_graph_seconds;
  for (const double seconds : {c.rotation_averaging_seconds, c.translation_averaging_seconds,
                               c.tracks_seconds, c.to_model_seconds}) {
    EXPECT_GT(seconds, 0.0);
    stages += seconds;
  }
  for (const MapperRoundSummary& r : c.refinement) {
    EXPECT_GT(r.bundle_adjustment_seconds, 0.0);
    EXPECT_GT(r.filter_retriangulate_seconds, 0.0);
    stages += r.bundle_adjustment_seconds + r.filter_retriangulate_seconds;
  }
  EXPECT_GT(s.load_seconds, 0.0);
  EXPECT_GT(s.view_graph_seconds, 0.0);
  EXPECT_LE(stages, s.total_seconds);
}

TEST(GlobalMapper, RigWithPriorsAndLidarConstraintsIsMetric) {
  test::TempDir dir;
  const SyntheticDatasetOptions o = RigSceneOptions();
  const SyntheticDataset dataset = WriteScene(o, dir);
  const Rig rig = ReadRigYaml(dir.File("rig.yaml"));
  const std::vector<LidarConstraintRecord> constraints =
      ReadLidarConstraints(dir.File("constraints.txt"));
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  GlobalMapperOptions options;
  options.load.prior_position_sigma = 0.02;
  options.load.prior_rotation_sigma = 0.5 * M_PI / 180.0;
  const GlobalMapperResult result = RunGlobalMapper(database, &rig, constraints, "", options);
  ASSERT_EQ(result.models.size(), 1u) << Describe(result.summary);
  const Reconstruction& model = result.models.front();
  model.Validate("global_mapper");
  EXPECT_EQ(model.NumImages(), dataset.images.size());
  EXPECT_EQ(model.Frames().size(), static_cast<size_t>(o.num_frames));
  EXPECT_EQ(model.Rigs().size(), 1u);
  // Accuracy targets after an SE(3) alignment: 0.05 deg, 5 mm.
  const PoseErrors se3 = Evaluate(model, dataset, /*estimate_scale=*/false);
  EXPECT_LT(se3.max_rotation_deg, 0.05);
  EXPECT_LT(se3.max_position, 0.005);
  // Metric: the free Sim3 alignment finds scale 1 within 0.2 %.
  const PoseErrors sim3 = Evaluate(model, dataset, /*estimate_scale=*/true);
  EXPECT_NEAR(sim3.scale, 1.0, 0.002);
  // Gauge: the priors put the model in their world frame without alignment;
  // 20 frames of 2 cm priors average to well under 2 cm.
  double max_offset = 0.0;
  for (const Image& image : model.Images()) {
    const Vec3 gt = dataset.GetImage(image.image_id).gt_cam_from_world.Inverse().translation();
    max_offset = std::max(max_offset, (image.ProjectionCenter() - gt).norm());
  }
  EXPECT_LT(max_offset, 0.02);
}

TEST(GlobalMapper, DisconnectedViewGraphGivesOneModelPerComponent) {
  test::TempDir dir;
  // A forward loop with pairs only between close frames, then the pairs that
  // bridge the two halves are deleted.
  SyntheticDatasetOptions o;
  o.num_frames = 16;
  o.trajectory = SyntheticTrajectory::kRoom;
  o.num_points = 2500;
  o.max_frame_gap = 2;
  o.pixel_noise = 0.3;
  const SyntheticDataset dataset = WriteScene(o, dir);
  (void)dataset;
  {
    Database database(dir.File("db.db"), Database::OpenMode::kReadWrite);
    // Images 1..16; cut every pair that links {1..8} with {9..16}.
    for (image_t a = 1; a <= 8; ++a) {
      for (image_t b = 9; b <= 16; ++b) database.DeleteMatchesAndGeometry(a, b);
    }
  }
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  const GlobalMapperResult result = RunGlobalMapper(database, nullptr, {}, "", {});
  ASSERT_EQ(result.models.size(), 2u) << Describe(result.summary);
  EXPECT_EQ(result.models[0].NumImages() + result.models[1].NumImages(), 16u);
  for (const Reconstruction& model : result.models) model.Validate("component");
}

TEST(GlobalMapper, DatabaseWithoutTwoViewGeometriesIsAnInputError) {
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 5;
  WriteScene(o, dir);
  {
    Database database(dir.File("db.db"), Database::OpenMode::kReadWrite);
    database.ClearTwoViewGeometries();
  }
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  EXPECT_THROW(RunGlobalMapper(database, nullptr, {}, "", {}), InputError);
}

TEST(GlobalMapper, CameraWithoutUsableIntrinsicsIsAnInputError) {
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 4;
  WriteScene(o, dir);
  {
    Database database(dir.File("db.db"), Database::OpenMode::kReadWrite);
    Camera camera = database.ReadAllCameras().front();
    camera.params[0] = 0.0;  // focal length 0
    database.UpdateCamera(camera);
  }
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  EXPECT_TRUE(test::ThrowsInputError([&] { RunGlobalMapper(database, nullptr, {}, "", {}); },
                                     {"camera_id=1"}));
}

TEST(GlobalMapper, RigThatLacksACameraOfTheDatabaseIsAnInputError) {
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 4;
  o.with_rig = true;
  o.num_cameras = 3;
  o.trajectory = SyntheticTrajectory::kRoom;
  WriteScene(o, dir);
  Rig rig = ReadRigYaml(dir.File("rig.yaml"));
  rig.cameras.pop_back();  // images of cam2 now name a camera the rig lacks
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  EXPECT_TRUE(
      test::ThrowsInputError([&] { RunGlobalMapper(database, &rig, {}, "", {}); }, {"cam2"}));
}

// skip_bundle_adjustment: the poses are those of rotation and translation
// averaging; the tracks are still triangulated and filtered.
TEST(GlobalMapper, SkipBundleAdjustmentKeepsTheAveragedPoses) {
  test::TempDir dir;
  const SyntheticDataset dataset = WriteScene(RingSceneOptions(), dir);
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  GlobalMapperOptions options;
  options.skip_bundle_adjustment = true;
  const GlobalMapperResult result = RunGlobalMapper(database, nullptr, {}, "", options);
  ASSERT_EQ(result.models.size(), 1u) << Describe(result.summary);
  const MapperComponentSummary& c = result.summary.components.front();
  ASSERT_EQ(c.refinement.size(), 2u);
  for (const MapperRoundSummary& r : c.refinement) {
    EXPECT_TRUE(r.bundle_adjustment_skipped);
    EXPECT_EQ(r.bundle_adjustment.num_iterations, 0);
    EXPECT_EQ(r.bundle_adjustment.num_reprojection_residuals, 0u);
  }
  const Reconstruction& model = result.models.front();
  model.Validate("global_mapper");
  EXPECT_EQ(model.NumImages(), dataset.images.size());
  const PoseErrors e = Evaluate(model, dataset, /*estimate_scale=*/true);
  // Rotation and translation averaging alone: 0.052 deg and 6.2 mm (max) on
  // this scene, where the adjusted model stays below 0.05 deg and 5 mm
  // (RingWithOutliersRecoversCamerasUpToSimilarity). The bounds (0.2 deg,
  // 2 cm = 0.3 % of the 6 m ring radius) leave margin and still fail for a
  // mis-registered camera (errors of degrees / decimetres).
  EXPECT_LT(e.max_rotation_deg, 0.2);
  EXPECT_LT(e.max_position, 0.02);
  EXPECT_GT(model.NumPoints3D(), 1000u);
}

// skip_retriangulation: the refinement round re-adds no rejected observation;
// the final adjustment still reaches the accuracy of the full pipeline.
TEST(GlobalMapper, SkipRetriangulation) {
  test::TempDir dir;
  const SyntheticDataset dataset = WriteScene(RingSceneOptions(), dir);
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  GlobalMapperOptions options;
  options.skip_retriangulation = true;
  const GlobalMapperResult result = RunGlobalMapper(database, nullptr, {}, "", options);
  ASSERT_EQ(result.models.size(), 1u) << Describe(result.summary);
  const MapperComponentSummary& c = result.summary.components.front();
  ASSERT_EQ(c.refinement.size(), 2u);
  EXPECT_TRUE(c.refinement.front().retriangulation_skipped);
  EXPECT_EQ(c.refinement.front().retriangulated_observations, 0u);
  EXPECT_FALSE(c.refinement.front().bundle_adjustment_skipped);
  const Reconstruction& model = result.models.front();
  model.Validate("global_mapper");
  EXPECT_EQ(model.NumImages(), dataset.images.size());
  const PoseErrors e = Evaluate(model, dataset, /*estimate_scale=*/true);
  // The same bounds as the full pipeline (RingWithOutliersRecoversCamerasUpToSimilarity).
  EXPECT_LT(e.max_rotation_deg, 0.05);
  EXPECT_LT(e.max_position, 0.005);
  EXPECT_GT(model.NumPoints3D(), 1000u);
}

// skip_rotation_averaging + skip_translation_averaging: the pose priors stand
// in for both averaging stages; bundle adjustment starts from them.
TEST(GlobalMapper, SkipAveragingStartsFromThePriors) {
  test::TempDir dir;
  const SyntheticDatasetOptions o = RigSceneOptions();
  const SyntheticDataset dataset = WriteScene(o, dir);
  const Rig rig = ReadRigYaml(dir.File("rig.yaml"));
  const std::vector<LidarConstraintRecord> constraints =
      ReadLidarConstraints(dir.File("constraints.txt"));
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  GlobalMapperOptions options;
  options.load.prior_position_sigma = 0.02;
  options.load.prior_rotation_sigma = 0.5 * M_PI / 180.0;
  options.skip_rotation_averaging = true;
  options.skip_translation_averaging = true;
  const GlobalMapperResult result = RunGlobalMapper(database, &rig, constraints, "", options);
  ASSERT_EQ(result.models.size(), 1u) << Describe(result.summary);
  const MapperComponentSummary& c = result.summary.components.front();
  EXPECT_TRUE(c.rotation_averaging_skipped);
  EXPECT_EQ(c.rotation_averaging.num_prior_frames, static_cast<size_t>(o.num_frames));
  EXPECT_EQ(c.rotation_averaging.num_iterations, 0);
  EXPECT_TRUE(c.translation_averaging_skipped);
  EXPECT_EQ(c.translation_averaging.num_edges_input, 0u);
  EXPECT_EQ(c.translation_averaging_registered_frames, static_cast<size_t>(o.num_frames));
  const Reconstruction& model = result.models.front();
  model.Validate("global_mapper");
  EXPECT_EQ(model.NumImages(), dataset.images.size());
  const PoseErrors se3 = Evaluate(model, dataset, /*estimate_scale=*/false);
  // From 2 cm / 0.5 deg priors the adjustment reaches the accuracy of the full
  // pipeline (RigWithPriorsAndLidarConstraintsIsMetric): 0.05 deg, 5 mm.
  EXPECT_LT(se3.max_rotation_deg, 0.05);
  EXPECT_LT(se3.max_position, 0.005);
}

// The first triangulation runs on averaged poses, which are off by a few
// tenths of a degree: its threshold (initial_reprojection_error_factor) keeps
// the observations such pose errors push past the final 4 px, and the first
// bundle adjustment brings them back under it. Here the starting poses are
// priors 0.3 deg / 3 cm off (averaging skipped, priors not in the adjustment).
TEST(GlobalMapper, LooseFirstTriangulationKeepsObservationsOfRoughPoses) {
  test::TempDir dir;
  SyntheticDatasetOptions o = RingSceneOptions();
  o.num_frames = 8;
  o.outlier_match_ratio = 0.0;
  o.outlier_pair_ratio = 0.0;
  o.prior_position_noise = 0.03;
  o.prior_rotation_noise = 0.3 * M_PI / 180.0;
  const SyntheticDataset dataset = WriteScene(o, dir);
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  GlobalMapperOptions options;
  options.skip_rotation_averaging = true;
  options.skip_translation_averaging = true;
  options.bundle_adjustment.use_priors = false;
  options.num_refinement_rounds = 0;  // one adjustment, then the final filter
  const auto run = [&](double factor) {
    options.initial_reprojection_error_factor = factor;
    return RunGlobalMapper(database, nullptr, {}, "", options);
  };
  const GlobalMapperResult tight = run(1.0);  // 4 px
  const GlobalMapperResult loose = run(GlobalMapperOptions().initial_reprojection_error_factor);
  ASSERT_EQ(tight.models.size(), 1u) << Describe(tight.summary);
  ASSERT_EQ(loose.models.size(), 1u) << Describe(loose.summary);
  const TriangulationStats& t = tight.summary.components.front().triangulation;
  const TriangulationStats& l = loose.summary.components.front().triangulation;
  size_t num_true = 0;
  for (const SyntheticImage& image : dataset.images) {
    for (const SyntheticKeypoint& k : image.keypoints) num_true += k.point_index >= 0 ? 1 : 0;
  }
  std::cout << "first triangulation rejects " << t.num_observations_rejected_reprojection
            << " (4 px) vs " << l.num_observations_rejected_reprojection << " ("
            << 4.0 * options.initial_reprojection_error_factor << " px) of " << num_true
            << " true observations; final observations " << tight.models.front().ComputeNumObservations()
            << " vs " << loose.models.front().ComputeNumObservations() << "\n";
  EXPECT_LT(l.num_observations_rejected_reprojection, 0.01 * num_true);
  EXPECT_GT(t.num_observations_rejected_reprojection, 5 * l.num_observations_rejected_reprojection);
  EXPECT_GT(loose.models.front().ComputeNumObservations(),
            tight.models.front().ComputeNumObservations());
  const PoseErrors e = Evaluate(loose.models.front(), dataset, /*estimate_scale=*/true);
  EXPECT_LT(e.max_rotation_deg, 0.05);
  EXPECT_LT(e.max_position, 0.005);
}

// Without rotation priors skip_rotation_averaging registers no frame: no
// model, and the summary says why.
TEST(GlobalMapper, SkipRotationAveragingWithoutPriorsGivesNoModel) {
  test::TempDir dir;
  WriteScene(RingSceneOptions(), dir);
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  GlobalMapperOptions options;
  options.skip_rotation_averaging = true;
  const GlobalMapperResult result = RunGlobalMapper(database, nullptr, {}, "", options);
  EXPECT_TRUE(result.models.empty());
  ASSERT_EQ(result.summary.components.size(), 1u);
  EXPECT_TRUE(result.summary.components.front().lost_frames_in_averaging);
  EXPECT_EQ(result.summary.components.front().rotation_averaging.num_registered_frames, 0u);
}


}  // namespace
}  // namespace colmap
}  // namespace lisfm
