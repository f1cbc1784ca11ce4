#include "colmap_ext/testing/synthetic.h"

#include <unistd.h>

#include <cmath>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "colmap_ext/io/database.h"
#include "colmap_ext/sfm/lidar_constraints.h"
#include "colmap_ext/sfm/mapper_state.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/rig_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

// A Gaussian draw exceeds 6 sigma with probability 2e-9 per axis, and a 2D
// (3D) Gaussian vector exceeds 6 sigma in norm with probability 1.5e-8
// (1e-7): with the ~1e5 draws of these tests a tolerance of 6 sigma fails
// with probability < 1e-2 for some seed, and the seed is fixed.
constexpr double kSigmas = 6.0;
// Keypoints are stored as float32: ~6e-5 px at 720 px; 1e-3 px is ample.
constexpr double kFloatPx = 1e-3;

Vec3 Centre(const SE3& cam_from_world) { return cam_from_world.Inverse().translation(); }

// Checks every two-view geometry of the database against the dataset: true
// matches see the same GT point and the keypoints lie within `max_px` of the
// GT projections; outlier pairs hold no true match. Returns the number of
// wrong matches found outside the outlier pairs.
size_t CheckPairs(const Database& database,
                  const SyntheticDataset& dataset,
                  const SyntheticMatches& written,
                  double max_px,
                  size_t* num_true_matches) {
  size_t num_wrong = 0;
  *num_true_matches = 0;
  const auto geometries = database.ReadAllTwoViewGeometries();
  EXPECT_EQ(geometries.size(), written.num_pairs);
  size_t num_matches = 0;
  for (const auto& [pair_id, geometry] : geometries) {
    image_t id1 = 0, id2 = 0;
    PairIdToImagePair(pair_id, &id1, &id2);
    EXPECT_EQ(geometry.config, static_cast<int>(TwoViewConfig::kCalibrated));
    EXPECT_EQ(database.ReadMatches(id1, id2).rows(), geometry.inlier_matches.rows());
    const KeypointsBlob keypoints1 = database.ReadKeypoints(id1);
    const KeypointsBlob keypoints2 = database.ReadKeypoints(id2);
    const SyntheticImage& image1 = dataset.GetImage(id1);
    const SyntheticImage& image2 = dataset.GetImage(id2);
    EXPECT_EQ(static_cast<size_t>(keypoints1.rows()), image1.keypoints.size());
    const SE3& cam1 = image1.gt_cam_from_world;
    const SE3& cam2 = image2.gt_cam_from_world;
    const Camera& camera1 = dataset.cameras.at(image1.camera_id);
    const Camera& camera2 = dataset.cameras.at(image2.camera_id);
    const bool outlier_pair = written.outlier_pairs.count(pair_id) > 0;
    const SE3 gt_cam2_from_cam1 = cam2 * cam1.Inverse();
    const Quat stored_rotation(
        geometry.qvec(0), geometry.qvec(1), geometry.qvec(2), geometry.qvec(3));
    EXPECT_NEAR(geometry.tvec.norm(), 1.0, 1e-12);
    if (!outlier_pair) {
      // The stored relative pose is the exact one (unit translation).
      EXPECT_LT(so3::AngularDistance(stored_rotation, gt_cam2_from_cam1.rotation()), 1e-12);
      EXPECT_LT((geometry.tvec - gt_cam2_from_cam1.translation().normalized()).norm(), 1e-12);
    } else {
      EXPECT_GT(so3::AngularDistance(stored_rotation, gt_cam2_from_cam1.rotation()), 0.29);
    }
    for (Eigen::Index m = 0; m < geometry.inlier_matches.rows(); ++m) {
      ++num_matches;
      const uint32_t k1 = geometry.inlier_matches(m, 0);
      const uint32_t k2 = geometry.inlier_matches(m, 1);
      const int p1 = image1.keypoints.at(k1).point_index;
      const int p2 = image2.keypoints.at(k2).point_index;
      if (p1 < 0 || p1 != p2) {
        ++num_wrong;
        EXPECT_TRUE(written.num_outlier_matches > 0) << "unexpected wrong match";
        continue;
      }
      EXPECT_FALSE(outlier_pair) << "true match in an outlier pair";
      ++*num_true_matches;
      const Vec3& x = dataset.points[static_cast<size_t>(p1)];
      Vec2 pixel1, pixel2;
      if (!camera1.Project(cam1 * x, &pixel1) || !camera2.Project(cam2 * x, &pixel2)) {
        ADD_FAILURE() << "a matched point projects behind a camera";
        continue;
      }
      EXPECT_LE((Vec2(keypoints1(k1, 0), keypoints1(k1, 1)) - pixel1).norm(), max_px);
      EXPECT_LE((Vec2(keypoints2(k2, 0), keypoints2(k2, 1)) - pixel2).norm(), max_px);
      // Epipolar constraint on the exact normalised coordinates.
      const Vec3 n1 = (cam1 * x).normalized();
      const Vec3 n2 = (cam2 * x).normalized();
      EXPECT_NEAR(n2.dot(geometry.E * n1), 0.0, 1e-9);
    }
  }
  EXPECT_EQ(num_matches, written.num_matches);
  return num_wrong;
}

TEST(SyntheticDataset, RingWithoutRigReadsBack) {
  test::TempDir dir;
  SyntheticDatasetOptions options;
  options.num_frames = 8;
  options.num_points = 400;
  options.pixel_noise = 0.5;
  options.prior_position_noise = 0.02;
  options.prior_rotation_noise = 0.005;
  const std::string path = dir.File("db.db");
  const SyntheticDataset dataset = SynthesizeDataset(options);
  const SyntheticMatches written = WriteSyntheticDatabase(dataset, path);
  EXPECT_FALSE(FileExists(path + ".tmp-" + std::to_string(::getpid())));

  Database database(path, Database::OpenMode::kReadOnly);
  EXPECT_EQ(database.NumCameras(), 1u);
  EXPECT_EQ(database.NumImages(), 8u);
  EXPECT_TRUE(database.ReadCamera(1).has_prior_focal_length);
  EXPECT_EQ(database.ReadCamera(1).ModelName(), "PINHOLE");
  // 8 ring cameras all see the whole cube: every pair is written.
  EXPECT_EQ(written.num_pairs, 28u);
  ASSERT_EQ(dataset.frames.size(), 8u);

  size_t num_true = 0;
  EXPECT_EQ(CheckPairs(database, dataset, written, kSigmas * options.pixel_noise, &num_true), 0u);
  EXPECT_EQ(num_true, written.num_matches);

  double max_position_error = 0.0;
  for (const DbImage& image : database.ReadAllImages()) {
    EXPECT_EQ(image.name, "image_000" + std::to_string(image.image_id) + ".png");
    const SE3& gt = dataset.GetImage(image.image_id).gt_cam_from_world;
    // Without a rig the frame pose is the camera pose.
    EXPECT_TRUE(test::PosesNear(dataset.frames[image.image_id - 1].gt_rig_from_world, gt, 0, 0));
    ASSERT_TRUE(image.has_prior_position);
    ASSERT_TRUE(image.has_prior_rotation);
    const Vec3 error = image.prior_position - Centre(gt);
    EXPECT_LE(error.cwiseAbs().maxCoeff(), kSigmas * options.prior_position_noise);
    max_position_error = std::max(max_position_error, error.cwiseAbs().maxCoeff());
    const Quat prior(
        image.prior_qvec(0), image.prior_qvec(1), image.prior_qvec(2), image.prior_qvec(3));
    EXPECT_LE(so3::AngularDistance(prior, gt.rotation()), kSigmas * options.prior_rotation_noise);
    EXPECT_GT(so3::AngularDistance(prior, gt.rotation()), 0.0);
    EXPECT_NEAR(image.prior_position_covariance(0, 0), 0.02 * 0.02, 1e-15);
    EXPECT_EQ(image.prior_position_covariance(0, 1), 0.0);
  }
  // The priors are perturbed (24 draws of sigma 2 cm all below 2 mm: p < 1e-20).
  EXPECT_GT(max_position_error, 0.002);
  // Random keypoints exist and are not matched to points.
  size_t num_random = 0;
  for (const SyntheticKeypoint& keypoint : dataset.GetImage(1).keypoints) {
    num_random += keypoint.point_index < 0 ? 1 : 0;
  }
  EXPECT_EQ(num_random, static_cast<size_t>(options.num_random_keypoints));
}

TEST(SyntheticDataset, FisheyeRigInRoomWithConstraints) {
  test::TempDir dir;
  SyntheticDatasetOptions options;
  options.num_frames = 10;
  options.with_rig = true;
  options.num_cameras = 5;
  options.camera_models = {"OPENCV_FISHEYE"};
  options.trajectory = SyntheticTrajectory::kRoom;
  options.num_points = 3000;
  options.max_frame_gap = 3;
  options.num_lidar_neighbors = 2;
  options.lidar_translation_noise = 0.005;
  options.lidar_rotation_noise = 0.00175;
  const std::string path = dir.File("db.db");
  const SyntheticDataset dataset = SynthesizeDataset(options);
  const SyntheticMatches written = WriteSyntheticDatabase(dataset, path);
  WriteRigYaml(dir.File("rig.yaml"), dataset.rig);
  WriteLidarConstraints(dataset.constraints, dir.File("constraints.txt"));

  Database database(path, Database::OpenMode::kReadOnly);
  EXPECT_EQ(database.NumCameras(), 5u);
  EXPECT_EQ(database.NumImages(), 50u);
  for (const Camera& camera : database.ReadAllCameras()) {
    EXPECT_EQ(camera.ModelName(), "OPENCV_FISHEYE");
  }
  // No pixel noise: keypoints are the exact projections (float32 storage).
  size_t num_true = 0;
  EXPECT_EQ(CheckPairs(database, dataset, written, kFloatPx, &num_true), 0u);
  bool has_stereo_pair = false;
  for (const auto& [pair_id, geometry] : database.ReadAllTwoViewGeometries()) {
    image_t id1 = 0, id2 = 0;
    PairIdToImagePair(pair_id, &id1, &id2);
    const int frame1 = static_cast<int>(id1 - 1) / 5;
    const int frame2 = static_cast<int>(id2 - 1) / 5;
    EXPECT_LE(std::abs(frame1 - frame2), options.max_frame_gap);
    has_stereo_pair |= frame1 == frame2 && (id1 - 1) % 5 == 0 && (id2 - 1) % 5 == 1;
  }
  EXPECT_TRUE(has_stereo_pair);

  // Every camera (front, up, left, right) sees the room.
  for (const SyntheticImage& image : dataset.images) {
    EXPECT_GT(image.keypoints.size(), 50u + options.num_random_keypoints) << image.image_id;
  }

  // Names, rig and poses are consistent.
  const Rig rig = ReadRigYaml(dir.File("rig.yaml"));
  ASSERT_EQ(rig.cameras.size(), 5u);
  for (const SyntheticFrame& frame : dataset.frames) {
    ASSERT_EQ(frame.image_ids.size(), 5u);
    for (int k = 0; k < 5; ++k) {
      const image_t image_id = frame.image_ids[k];
      EXPECT_EQ(database.ReadImage(image_id).name,
                "cam" + std::to_string(k) + "/data/" + std::to_string(frame.stamp_ns) + ".png");
      EXPECT_FALSE(database.ReadImage(image_id).has_prior_position);
      EXPECT_TRUE(test::PosesNear(rig.cameras[k].cam_from_imu * frame.gt_rig_from_world,
                                  dataset.GetImage(image_id).gt_cam_from_world,
                                  1e-12,
                                  1e-12));
    }
  }
  // The stereo pair: 0.11 m baseline.
  EXPECT_NEAR((Centre(rig.cameras[0].cam_from_imu) - Centre(rig.cameras[1].cam_from_imu)).norm(),
              0.11,
              1e-12);

  // Constraints: written and read back; within their noise of the GT
  // relative poses, with a plausible normalised error.
  const auto records = ReadLidarConstraints(dir.File("constraints.txt"));
  ASSERT_EQ(records.size(), 9u + 8u);  // (k, k+1) and (k, k+2)
  ASSERT_EQ(dataset.constraints.size(), records.size());
  double nees_sum = 0.0;
  for (size_t c = 0; c < records.size(); ++c) {
    const auto& record = records[c];
    ASSERT_TRUE(record.has_stamps);
    EXPECT_EQ(record.t_i_ns, dataset.constraints[c].t_i_ns);
    const SyntheticFrame& frame_i = dataset.frames.at(
        static_cast<size_t>((record.t_i_ns - options.first_stamp_ns) / options.frame_period_ns));
    const SyntheticFrame& frame_j = dataset.frames.at(
        static_cast<size_t>((record.t_j_ns - options.first_stamp_ns) / options.frame_period_ns));
    ASSERT_EQ(frame_i.stamp_ns, record.t_i_ns);
    ASSERT_EQ(frame_j.stamp_ns, record.t_j_ns);
    const SE3 gt = frame_i.gt_rig_from_world * frame_j.gt_rig_from_world.Inverse();
    const Vec6 xi = (gt.Inverse() * record.i_from_j).Log();
    EXPECT_LE(xi.head<3>().cwiseAbs().maxCoeff(), kSigmas * options.lidar_rotation_noise);
    EXPECT_LE(xi.tail<3>().cwiseAbs().maxCoeff(), kSigmas * options.lidar_translation_noise);
    nees_sum += xi.dot(record.covariance.inverse() * xi);
  }
  // Mean NEES of 17 6-D Gaussian errors: chi2(102) / 17, mean 6, sd 0.84;
  // [3, 10] is beyond 3.5 sd, yet fails if the covariance were off by 2x.
  const double mean_nees = nees_sum / records.size();
  EXPECT_GT(mean_nees, 3.0);
  EXPECT_LT(mean_nees, 10.0);

  // The loader groups the images into the synthetic frames, and every
  // constraint attaches by stamp.
  MapperState state = LoadMapperState(database, &rig, LoadMapperStateOptions());
  ASSERT_EQ(state.frames.size(), 10u);
  EXPECT_EQ(AttachLidarConstraints(records, kDefaultLidarConstraintToleranceNs, &state),
            records.size());
  for (const LidarConstraint& constraint : state.lidar_constraints) {
    EXPECT_LT(state.frames.at(constraint.frame_id1).stamp_ns,
              state.frames.at(constraint.frame_id2).stamp_ns);
  }
}

TEST(SyntheticDataset, OpenCvOutliers) {
  test::TempDir dir;
  SyntheticDatasetOptions options;
  options.num_frames = 12;
  options.num_points = 300;
  options.camera_models = {"OPENCV"};
  options.outlier_match_ratio = 0.2;
  options.outlier_pair_ratio = 0.2;
  options.num_random_keypoints = 100;  // room for the wrong matches
  const SyntheticDataset dataset = SynthesizeDataset(options);
  const SyntheticMatches written = WriteSyntheticDatabase(dataset, dir.File("db.db"));
  Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  EXPECT_EQ(database.ReadCamera(1).ModelName(), "OPENCV");
  size_t num_true = 0;
  const size_t num_wrong = CheckPairs(database, dataset, written, kFloatPx, &num_true);
  EXPECT_EQ(num_wrong, written.num_outlier_matches);
  ASSERT_EQ(written.num_pairs, 66u);
  // Outlier pairs ~ Binomial(66, 0.2): mean 13.2, sd 3.2.
  EXPECT_GE(written.outlier_pairs.size(), 3u);
  EXPECT_LE(written.outlier_pairs.size(), 26u);
  // In the other pairs, round(0.2 n) wrong matches per n true ones (fewer
  // only when a random pairing happens to be right, which is rare).
  size_t wrong_in_good_pairs = 0;
  for (const auto& [pair_id, geometry] : database.ReadAllTwoViewGeometries()) {
    if (written.outlier_pairs.count(pair_id)) continue;
    image_t id1 = 0, id2 = 0;
    PairIdToImagePair(pair_id, &id1, &id2);
    for (Eigen::Index m = 0; m < geometry.inlier_matches.rows(); ++m) {
      const int p1 = dataset.GetImage(id1).keypoints.at(geometry.inlier_matches(m, 0)).point_index;
      const int p2 = dataset.GetImage(id2).keypoints.at(geometry.inlier_matches(m, 1)).point_index;
      wrong_in_good_pairs += (p1 < 0 || p1 != p2) ? 1 : 0;
    }
  }
  const double ratio = static_cast<double>(wrong_in_good_pairs) / num_true;
  EXPECT_NEAR(ratio, 0.2, 0.01);
}

TEST(SyntheticDataset, DeterministicPerSeedWithIndependentStreams) {
  test::TempDir dir;
  SyntheticDatasetOptions options;
  options.num_frames = 5;
  options.num_points = 200;
  options.pixel_noise = 1.0;
  options.outlier_match_ratio = 0.1;
  options.num_random_keypoints = 100;  // room for the wrong matches
  const SyntheticMatches a = WriteSyntheticDatabase(SynthesizeDataset(options), dir.File("a.db"));
  const SyntheticMatches b = WriteSyntheticDatabase(SynthesizeDataset(options), dir.File("b.db"));
  Database da(dir.File("a.db"), Database::OpenMode::kReadOnly);
  Database db(dir.File("b.db"), Database::OpenMode::kReadOnly);
  EXPECT_EQ(a.num_matches, b.num_matches);
  EXPECT_EQ(da.ReadKeypoints(3), db.ReadKeypoints(3));
  EXPECT_EQ(da.ReadMatches(1, 4), db.ReadMatches(1, 4));
  // Other outliers: the same keypoints, other matches.
  options.outlier_match_ratio = 0.3;
  WriteSyntheticDatabase(SynthesizeDataset(options), dir.File("more_outliers.db"));
  Database more(dir.File("more_outliers.db"), Database::OpenMode::kReadOnly);
  EXPECT_EQ(more.ReadKeypoints(3), da.ReadKeypoints(3));
  EXPECT_GT(more.ReadMatches(1, 4).rows(), da.ReadMatches(1, 4).rows());
  // Another seed: other keypoints.
  options.seed = 7;
  WriteSyntheticDatabase(SynthesizeDataset(options), dir.File("c.db"));
  Database dc(dir.File("c.db"), Database::OpenMode::kReadOnly);
  EXPECT_FALSE(da.ReadKeypoints(3).rows() == dc.ReadKeypoints(3).rows() &&
               da.ReadKeypoints(3) == dc.ReadKeypoints(3));
  // Rewriting replaces the file.
  WriteSyntheticDatabase(SynthesizeDataset(options), dir.File("a.db"));
  Database again(dir.File("a.db"), Database::OpenMode::kReadOnly);
  EXPECT_EQ(again.ReadKeypoints(3), dc.ReadKeypoints(3));
}

TEST(SyntheticDataset, NoRigConstraintsAttachByIndex) {
  test::TempDir dir;
  SyntheticDatasetOptions options;
  options.num_frames = 6;
  options.num_points = 200;
  options.num_lidar_neighbors = 1;
  const SyntheticDataset dataset = SynthesizeDataset(options);
  WriteSyntheticDatabase(dataset, dir.File("db.db"));
  WriteLidarConstraints(dataset.constraints, dir.File("c.txt"));
  const auto records = ReadLidarConstraints(dir.File("c.txt"));
  ASSERT_EQ(records.size(), 5u);
  EXPECT_FALSE(records[0].has_stamps);  // GTSFM layout: frames by index
  Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  MapperState state = LoadMapperState(database, nullptr, LoadMapperStateOptions());
  EXPECT_EQ(AttachLidarConstraints(records, kDefaultLidarConstraintToleranceNs, &state), 5u);
  for (size_t c = 0; c < state.lidar_constraints.size(); ++c) {
    const LidarConstraint& constraint = state.lidar_constraints[c];
    EXPECT_EQ(constraint.frame_id1, c + 1);
    EXPECT_EQ(constraint.frame_id2, c + 2);
    // Frame k is image k + 1; its pose is the camera pose.
    const SE3 gt = dataset.GetImage(constraint.frame_id1).gt_cam_from_world *
                   dataset.GetImage(constraint.frame_id2).gt_cam_from_world.Inverse();
    EXPECT_TRUE(test::PosesNear(constraint.rig1_from_rig2,
                                gt,
                                kSigmas * std::sqrt(3.0) * options.lidar_rotation_noise,
                                kSigmas * std::sqrt(3.0) * options.lidar_translation_noise));
  }
}

// The model of a fixed-track-length scene with several camera models, as the
// COLMAP I/O tests and benchmarks use it.
TEST(SyntheticDataset, ReconstructionWithFixedTrackLength) {
  SyntheticDatasetOptions options;
  options.num_frames = 12;
  options.num_cameras = 3;
  options.camera_models = {"PINHOLE", "OPENCV_FISHEYE", "OPENCV"};
  options.num_points = 500;
  options.track_length = 4;
  options.pixel_noise = 0.5;
  options.num_random_keypoints = 5;
  const SyntheticDataset dataset = SynthesizeDataset(options);
  const Reconstruction model = SyntheticReconstruction(dataset);
  EXPECT_NO_THROW(model.Validate("synthetic"));
  ASSERT_EQ(model.NumCameras(), 3u);
  EXPECT_EQ(model.GetCamera(1).ModelName(), "PINHOLE");
  EXPECT_EQ(model.GetCamera(2).ModelName(), "OPENCV_FISHEYE");
  EXPECT_EQ(model.GetCamera(3).ModelName(), "OPENCV");
  ASSERT_EQ(model.NumImages(), 12u);
  EXPECT_TRUE(model.Rigs().empty());
  // Every point is observed by exactly track_length distinct images.
  ASSERT_EQ(model.NumPoints3D(), 500u);
  EXPECT_EQ(model.ComputeNumObservations(), 500u * 4u);
  double error_sum = 0.0;
  for (const auto& [point3D_id, point] : model.Points3D()) {
    ASSERT_EQ(point.track.size(), 4u);
    std::set<image_t> images;
    for (const TrackElement& element : point.track) images.insert(element.image_id);
    EXPECT_EQ(images.size(), 4u);
    EXPECT_EQ(point.xyz, dataset.points[point3D_id - 1]);
    error_sum += point.error;
  }
  // Mean error of 2-D N(0, 0.5^2 I) noise: 0.5 sqrt(pi / 2) = 0.627 px; over
  // 2000 observations its standard error is 0.5 sqrt(2 - pi / 2) / sqrt(2000)
  // = 0.007 px, so +-0.04 px is beyond 5 sd.
  EXPECT_NEAR(error_sum / 500.0, 0.5 * std::sqrt(M_PI / 2.0), 0.04);
  // Images: the true poses, camera f % 3, and the keypoints as 2D points.
  for (const Image& image : model.Images()) {
    const SyntheticImage& synthetic = dataset.GetImage(image.image_id);
    EXPECT_EQ(image.camera_id, (image.image_id - 1) % 3 + 1);
    EXPECT_EQ(image.name, synthetic.name);
    EXPECT_TRUE(test::PosesNear(image.CamFromWorld(), synthetic.gt_cam_from_world, 1e-12, 1e-12));
    EXPECT_EQ(StableQvec(image.qvec), image.qvec);
    ASSERT_EQ(image.points2D.size(), synthetic.keypoints.size());
    size_t num_random = 0;
    for (size_t k = 0; k < image.points2D.size(); ++k) {
      EXPECT_EQ(image.points2D[k].xy, synthetic.keypoints[k].xy);
      if (synthetic.keypoints[k].point_index < 0) {
        ++num_random;
        EXPECT_FALSE(image.points2D[k].HasPoint3D());
      } else {
        EXPECT_EQ(image.points2D[k].point3D_id,
                  static_cast<point3D_t>(synthetic.keypoints[k].point_index) + 1);
      }
    }
    EXPECT_EQ(num_random, 5u);
  }
}

// One scene, two outputs: the database and the model hold the same cameras,
// images, keypoints and (with a rig) the same frames.
TEST(SyntheticDataset, DatabaseAndReconstructionDescribeTheSameScene) {
  test::TempDir dir;
  SyntheticDatasetOptions options;
  options.num_frames = 4;
  options.with_rig = true;
  options.num_cameras = 3;
  options.trajectory = SyntheticTrajectory::kRoom;
  options.num_points = 1500;
  options.pixel_noise = 0.3;
  const SyntheticDataset dataset = SynthesizeDataset(options);
  const Reconstruction model = SyntheticReconstruction(dataset);
  WriteSyntheticDatabase(dataset, dir.File("db.db"));
  model.Validate("synthetic");
  const Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  ASSERT_EQ(database.NumImages(), model.NumImages());
  for (const Image& image : model.Images()) {
    const DbImage db_image = database.ReadImage(image.image_id);
    EXPECT_EQ(db_image.name, image.name);
    EXPECT_EQ(db_image.camera_id, image.camera_id);
    EXPECT_EQ(database.ReadCamera(image.camera_id).params, model.GetCamera(image.camera_id).params);
    const KeypointsBlob keypoints = database.ReadKeypoints(image.image_id);
    ASSERT_EQ(static_cast<size_t>(keypoints.rows()), image.points2D.size());
    for (size_t k = 0; k < image.points2D.size(); ++k) {
      EXPECT_EQ(keypoints(static_cast<Eigen::Index>(k), 0),
                static_cast<float>(image.points2D[k].xy.x()));
      EXPECT_EQ(keypoints(static_cast<Eigen::Index>(k), 1),
                static_cast<float>(image.points2D[k].xy.y()));
    }
  }
  // The COLMAP 3.12 rig and frames: cam_from_world = sensor_from_rig * rig_from_world.
  ASSERT_EQ(model.Rigs().size(), 1u);
  ASSERT_EQ(model.Rigs()[0].sensors.size(), 2u);
  ASSERT_EQ(model.Frames().size(), 4u);
  for (const ModelFrame& frame : model.Frames()) {
    const SE3 ref_from_world(Quat(frame.qvec(0), frame.qvec(1), frame.qvec(2), frame.qvec(3)),
                             frame.tvec);
    ASSERT_EQ(frame.data.size(), 3u);
    for (const FrameData& data : frame.data) {
      const image_t image_id = static_cast<image_t>(data.data_id);
      SE3 sensor_from_ref;
      for (const RigSensor& sensor : model.Rigs()[0].sensors) {
        if (sensor.sensor.id != data.sensor.id) continue;
        sensor_from_ref =
            SE3(Quat(sensor.qvec(0), sensor.qvec(1), sensor.qvec(2), sensor.qvec(3)), sensor.tvec);
      }
      EXPECT_TRUE(test::PosesNear(
          sensor_from_ref * ref_from_world, model.GetImage(image_id).CamFromWorld(), 1e-12, 1e-12));
    }
  }
}

TEST(SyntheticDataset, InvalidOptionsThrow) {
  test::TempDir dir;
  SyntheticDatasetOptions options;
  options.camera_models = {"PINHOLE", "FOV"};
  EXPECT_FALSE(options.Check());
  EXPECT_THROW(SynthesizeDataset(options), InternalError);
  options = SyntheticDatasetOptions();
  options.camera_models.clear();
  EXPECT_FALSE(options.Check());
  options = SyntheticDatasetOptions();
  options.with_rig = true;
  options.num_cameras = 6;
  EXPECT_FALSE(options.Check());
  options = SyntheticDatasetOptions();
  options.num_frames = 3;
  options.track_length = 4;  // more views than images
  EXPECT_FALSE(options.Check());
  EXPECT_THROW(SynthesizeDataset(options), InternalError);
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
