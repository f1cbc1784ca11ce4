// End-to-end tests of RunGlobalMapper on synthetic databases with exact
// ground truth (colmap_ext/testing/synthetic.h): all stages together.
#include "colmap_ext/sfm/global_mapper.h"

#include <cmath>

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

TEST(GlobalMapper, RingWithOutliersRecoversCamerasUpToSimilarity) {
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 24;
  o.num_points = 1500;
  o.pixel_noise = 0.5;
  o.outlier_match_ratio = 0.1;
  o.outlier_pair_ratio = 0.1;
  o.seed = 7;
  const SyntheticDataset dataset = SynthesizeDataset(o);
  WriteSyntheticDatabase(dataset, dir.File("db.db"));
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  GlobalMapperOptions options;
  const GlobalMapperResult result = RunGlobalMapper(database, nullptr, {}, "", options);
  ASSERT_EQ(result.models.size(), 1u) << result.summary.dump(2);
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
}

TEST(GlobalMapper, RigWithPriorsAndLidarConstraintsIsMetric) {
  test::TempDir dir;
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
  // What a LiDAR stage gives: priors 2 cm / 0.5 deg, constraints
  // 5 mm / 0.1 deg.
  o.prior_position_noise = 0.02;
  o.prior_rotation_noise = 0.5 * M_PI / 180.0;
  o.num_lidar_neighbors = 2;
  o.lidar_translation_noise = 0.005;
  o.lidar_rotation_noise = 0.1 * M_PI / 180.0;
  o.seed = 11;
  const SyntheticDataset dataset = SynthesizeDataset(o);
  WriteSyntheticDatabase(dataset, dir.File("db.db"));
  // The mapper reads the rig and the constraints back from their files.
  WriteRigYaml(dir.File("rig.yaml"), dataset.rig);
  WriteLidarConstraints(dataset.constraints, dir.File("constraints.txt"));
  const Rig rig = ReadRigYaml(dir.File("rig.yaml"));
  const std::vector<LidarConstraintRecord> constraints =
      ReadLidarConstraints(dir.File("constraints.txt"));
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  GlobalMapperOptions options;
  options.load.prior_position_sigma = 0.02;
  options.load.prior_rotation_sigma = 0.5 * M_PI / 180.0;
  const GlobalMapperResult result = RunGlobalMapper(database, &rig, constraints, "", options);
  ASSERT_EQ(result.models.size(), 1u) << result.summary.dump(2);
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
  WriteSyntheticDatabase(SynthesizeDataset(o), dir.File("db.db"));
  {
    Database database(dir.File("db.db"), Database::OpenMode::kReadWrite);
    // Images 1..16; cut every pair that links {1..8} with {9..16}.
    for (image_t a = 1; a <= 8; ++a) {
      for (image_t b = 9; b <= 16; ++b) database.DeleteMatchesAndGeometry(a, b);
    }
  }
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  const GlobalMapperResult result = RunGlobalMapper(database, nullptr, {}, "", {});
  ASSERT_EQ(result.models.size(), 2u) << result.summary.dump(2);
  EXPECT_EQ(result.models[0].NumImages() + result.models[1].NumImages(), 16u);
  for (const Reconstruction& model : result.models) model.Validate("component");
}

TEST(GlobalMapper, DatabaseWithoutTwoViewGeometriesIsAnInputError) {
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 5;
  WriteSyntheticDatabase(SynthesizeDataset(o), dir.File("db.db"));
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
  WriteSyntheticDatabase(SynthesizeDataset(o), dir.File("db.db"));
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
  const SyntheticDataset dataset = SynthesizeDataset(o);
  WriteSyntheticDatabase(dataset, dir.File("db.db"));
  Rig rig = dataset.rig;
  rig.cameras.pop_back();  // images of cam2 now name a camera the rig lacks
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  EXPECT_TRUE(
      test::ThrowsInputError([&] { RunGlobalMapper(database, &rig, {}, "", {}); }, {"cam2"}));
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
