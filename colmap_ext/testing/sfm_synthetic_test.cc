#include "colmap_ext/testing/sfm_synthetic.h"

#include <unistd.h>

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "colmap_ext/io/database.h"
#include "colmap_ext/sfm/lidar_constraints.h"
#include "colmap_ext/sfm/mapper_state.h"
#include "core/errors.h"
#include "core/file_utils.h"
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

// Checks every two-view geometry of the database against the scene: true
// matches see the same GT point and the keypoints lie within `max_px` of the
// GT projections; outlier pairs hold no true match. Returns the number of
// wrong matches found outside the outlier pairs.
size_t CheckPairs(const Database& database, const SyntheticSfmScene& scene, double max_px,
                  size_t* num_true_matches) {
  size_t num_wrong = 0;
  *num_true_matches = 0;
  const auto geometries = database.ReadAllTwoViewGeometries();
  EXPECT_EQ(geometries.size(), scene.num_pairs);
  size_t num_matches = 0;
  for (const auto& [pair_id, geometry] : geometries) {
    image_t id1 = 0, id2 = 0;
    PairIdToImagePair(pair_id, &id1, &id2);
    EXPECT_EQ(geometry.config, static_cast<int>(TwoViewConfig::kCalibrated));
    EXPECT_EQ(database.ReadMatches(id1, id2).rows(), geometry.inlier_matches.rows());
    const KeypointsBlob keypoints1 = database.ReadKeypoints(id1);
    const KeypointsBlob keypoints2 = database.ReadKeypoints(id2);
    const std::vector<int>& points1 = scene.keypoint_point_ids.at(id1);
    const std::vector<int>& points2 = scene.keypoint_point_ids.at(id2);
    EXPECT_EQ(static_cast<size_t>(keypoints1.rows()), points1.size());
    const SE3& cam1 = scene.gt_cam_from_world.at(id1);
    const SE3& cam2 = scene.gt_cam_from_world.at(id2);
    const Camera& camera1 = scene.cameras.at(scene.image_camera_ids.at(id1));
    const Camera& camera2 = scene.cameras.at(scene.image_camera_ids.at(id2));
    const bool outlier_pair = scene.outlier_pairs.count(pair_id) > 0;
    const SE3 gt_cam2_from_cam1 = cam2 * cam1.Inverse();
    const Quat stored_rotation(geometry.qvec(0), geometry.qvec(1), geometry.qvec(2),
                               geometry.qvec(3));
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
      const int p1 = points1.at(k1);
      const int p2 = points2.at(k2);
      if (p1 < 0 || p1 != p2) {
        ++num_wrong;
        EXPECT_TRUE(scene.num_outlier_matches > 0) << "unexpected wrong match";
        continue;
      }
      EXPECT_FALSE(outlier_pair) << "true match in an outlier pair";
      ++*num_true_matches;
      const Vec3& x = scene.points[static_cast<size_t>(p1)];
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
  EXPECT_EQ(num_matches, scene.num_matches);
  return num_wrong;
}

TEST(SfmSynthetic, RingWithoutRigReadsBack) {
  test::TempDir dir;
  SyntheticSfmOptions options;
  options.num_frames = 8;
  options.num_points = 400;
  options.pixel_noise = 0.5;
  options.prior_position_noise = 0.02;
  options.prior_rotation_noise = 0.005;
  const std::string path = dir.File("db.db");
  const SyntheticSfmScene scene = WriteSyntheticSfmDatabase(options, path);
  EXPECT_FALSE(FileExists(path + ".tmp-" + std::to_string(::getpid())));

  Database database(path, Database::OpenMode::kReadOnly);
  EXPECT_EQ(database.NumCameras(), 1u);
  EXPECT_EQ(database.NumImages(), 8u);
  EXPECT_TRUE(database.ReadCamera(1).has_prior_focal_length);
  EXPECT_EQ(database.ReadCamera(1).ModelName(), "PINHOLE");
  // 8 ring cameras all see the whole cube: every pair is written.
  EXPECT_EQ(scene.num_pairs, 28u);
  ASSERT_EQ(scene.frames.size(), 8u);

  size_t num_true = 0;
  EXPECT_EQ(CheckPairs(database, scene, kSigmas * options.pixel_noise, &num_true), 0u);
  EXPECT_EQ(num_true, scene.num_matches);

  double max_position_error = 0.0;
  for (const DbImage& image : database.ReadAllImages()) {
    EXPECT_EQ(image.name, "image_000" + std::to_string(image.image_id) + ".png");
    const SE3& gt = scene.gt_cam_from_world.at(image.image_id);
    // Without a rig the frame pose is the camera pose.
    EXPECT_TRUE(test::PosesNear(scene.frames[image.image_id - 1].gt_rig_from_world, gt, 0, 0));
    ASSERT_TRUE(image.has_prior_position);
    ASSERT_TRUE(image.has_prior_rotation);
    const Vec3 error = image.prior_position - Centre(gt);
    EXPECT_LE(error.cwiseAbs().maxCoeff(), kSigmas * options.prior_position_noise);
    max_position_error = std::max(max_position_error, error.cwiseAbs().maxCoeff());
    const Quat prior(image.prior_qvec(0), image.prior_qvec(1), image.prior_qvec(2),
                     image.prior_qvec(3));
    EXPECT_LE(so3::AngularDistance(prior, gt.rotation()), kSigmas * options.prior_rotation_noise);
    EXPECT_GT(so3::AngularDistance(prior, gt.rotation()), 0.0);
    EXPECT_NEAR(image.prior_position_covariance(0, 0), 0.02 * 0.02, 1e-15);
    EXPECT_EQ(image.prior_position_covariance(0, 1), 0.0);
  }
  // The priors are perturbed (24 draws of sigma 2 cm all below 2 mm: p < 1e-20).
  EXPECT_GT(max_position_error, 0.002);
  // Random keypoints exist and are not matched to points.
  size_t num_random = 0;
  for (const int p : scene.keypoint_point_ids.at(1)) num_random += p < 0 ? 1 : 0;
  EXPECT_EQ(num_random, static_cast<size_t>(options.num_random_keypoints));
}

TEST(SfmSynthetic, FisheyeRigInRoomWithConstraints) {
  test::TempDir dir;
  SyntheticSfmOptions options;
  options.num_frames = 10;
  options.num_rig_cameras = 5;
  options.camera_model = "OPENCV_FISHEYE";
  options.trajectory = SyntheticTrajectory::kRoom;
  options.num_points = 3000;
  options.max_frame_gap = 3;
  options.num_lidar_neighbors = 2;
  options.lidar_translation_noise = 0.005;
  options.lidar_rotation_noise = 0.00175;
  options.rig_path = dir.File("rig.yaml");
  options.lidar_constraints_path = dir.File("constraints.txt");
  const std::string path = dir.File("db.db");
  const SyntheticSfmScene scene = WriteSyntheticSfmDatabase(options, path);

  Database database(path, Database::OpenMode::kReadOnly);
  EXPECT_EQ(database.NumCameras(), 5u);
  EXPECT_EQ(database.NumImages(), 50u);
  for (const Camera& camera : database.ReadAllCameras()) {
    EXPECT_EQ(camera.ModelName(), "OPENCV_FISHEYE");
  }
  // No pixel noise: keypoints are the exact projections (float32 storage).
  size_t num_true = 0;
  EXPECT_EQ(CheckPairs(database, scene, kFloatPx, &num_true), 0u);
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
  for (const auto& [image_id, point_ids] : scene.keypoint_point_ids) {
    EXPECT_GT(point_ids.size(), 50u + options.num_random_keypoints) << image_id;
  }

  // Names, rig and poses are consistent.
  const Rig rig = ReadRigYaml(options.rig_path);
  ASSERT_EQ(rig.cameras.size(), 5u);
  for (const SyntheticSfmFrame& frame : scene.frames) {
    ASSERT_EQ(frame.image_ids.size(), 5u);
    for (int k = 0; k < 5; ++k) {
      const image_t image_id = frame.image_ids[k];
      EXPECT_EQ(database.ReadImage(image_id).name,
                "cam" + std::to_string(k) + "/data/" + std::to_string(frame.stamp_ns) + ".png");
      EXPECT_FALSE(database.ReadImage(image_id).has_prior_position);
      EXPECT_TRUE(test::PosesNear(rig.cameras[k].cam_from_imu * frame.gt_rig_from_world,
                                  scene.gt_cam_from_world.at(image_id), 1e-12, 1e-12));
    }
  }
  // The stereo pair: 0.11 m baseline.
  EXPECT_NEAR((Centre(rig.cameras[0].cam_from_imu) - Centre(rig.cameras[1].cam_from_imu)).norm(),
              0.11, 1e-12);

  // Constraints: written and read back; within their noise of the GT
  // relative poses, with a plausible normalised error.
  const auto records = ReadLidarConstraints(options.lidar_constraints_path);
  ASSERT_EQ(records.size(), 9u + 8u);  // (k, k+1) and (k, k+2)
  ASSERT_EQ(scene.constraints.size(), records.size());
  double nees_sum = 0.0;
  for (size_t c = 0; c < records.size(); ++c) {
    const auto& record = records[c];
    ASSERT_TRUE(record.has_stamps);
    EXPECT_EQ(record.t_i_ns, scene.constraints[c].t_i_ns);
    const SE3 gt = scene.gt_rig_from_world.at(record.t_i_ns) *
                   scene.gt_rig_from_world.at(record.t_j_ns).Inverse();
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

TEST(SfmSynthetic, OpenCvOutliers) {
  test::TempDir dir;
  SyntheticSfmOptions options;
  options.num_frames = 12;
  options.num_points = 300;
  options.camera_model = "OPENCV";
  options.outlier_match_ratio = 0.2;
  options.outlier_pair_ratio = 0.2;
  options.num_random_keypoints = 100;  // room for the wrong matches
  const SyntheticSfmScene scene = WriteSyntheticSfmDatabase(options, dir.File("db.db"));
  Database database(dir.File("db.db"), Database::OpenMode::kReadOnly);
  EXPECT_EQ(database.ReadCamera(1).ModelName(), "OPENCV");
  size_t num_true = 0;
  const size_t num_wrong = CheckPairs(database, scene, kFloatPx, &num_true);
  EXPECT_EQ(num_wrong, scene.num_outlier_matches);
  ASSERT_EQ(scene.num_pairs, 66u);
  // Outlier pairs ~ Binomial(66, 0.2): mean 13.2, sd 3.2.
  EXPECT_GE(scene.outlier_pairs.size(), 3u);
  EXPECT_LE(scene.outlier_pairs.size(), 26u);
  // In the other pairs, round(0.2 n) wrong matches per n true ones (fewer
  // only when a random pairing happens to be right, which is rare).
  size_t wrong_in_good_pairs = 0;
  for (const auto& [pair_id, geometry] : database.ReadAllTwoViewGeometries()) {
    if (scene.outlier_pairs.count(pair_id)) continue;
    image_t id1 = 0, id2 = 0;
    PairIdToImagePair(pair_id, &id1, &id2);
    for (Eigen::Index m = 0; m < geometry.inlier_matches.rows(); ++m) {
      const int p1 = scene.keypoint_point_ids.at(id1).at(geometry.inlier_matches(m, 0));
      const int p2 = scene.keypoint_point_ids.at(id2).at(geometry.inlier_matches(m, 1));
      wrong_in_good_pairs += (p1 < 0 || p1 != p2) ? 1 : 0;
    }
  }
  const double ratio = static_cast<double>(wrong_in_good_pairs) / num_true;
  EXPECT_NEAR(ratio, 0.2, 0.01);
}

TEST(SfmSynthetic, DeterministicPerSeed) {
  test::TempDir dir;
  SyntheticSfmOptions options;
  options.num_frames = 5;
  options.num_points = 200;
  options.pixel_noise = 1.0;
  options.outlier_match_ratio = 0.1;
  const SyntheticSfmScene a = WriteSyntheticSfmDatabase(options, dir.File("a.db"));
  const SyntheticSfmScene b = WriteSyntheticSfmDatabase(options, dir.File("b.db"));
  options.seed = 7;
  const SyntheticSfmScene c = WriteSyntheticSfmDatabase(options, dir.File("c.db"));
  Database da(dir.File("a.db"), Database::OpenMode::kReadOnly);
  Database db(dir.File("b.db"), Database::OpenMode::kReadOnly);
  Database dc(dir.File("c.db"), Database::OpenMode::kReadOnly);
  EXPECT_EQ(a.num_matches, b.num_matches);
  EXPECT_EQ(da.ReadKeypoints(3), db.ReadKeypoints(3));
  EXPECT_EQ(da.ReadMatches(1, 4), db.ReadMatches(1, 4));
  EXPECT_FALSE(da.ReadKeypoints(3).rows() == dc.ReadKeypoints(3).rows() &&
               da.ReadKeypoints(3) == dc.ReadKeypoints(3));
  // Rewriting replaces the file.
  WriteSyntheticSfmDatabase(options, dir.File("a.db"));
  Database again(dir.File("a.db"), Database::OpenMode::kReadOnly);
  EXPECT_EQ(again.ReadKeypoints(3), dc.ReadKeypoints(3));
}

TEST(SfmSynthetic, NoRigConstraintsAttachByIndex) {
  test::TempDir dir;
  SyntheticSfmOptions options;
  options.num_frames = 6;
  options.num_points = 200;
  options.num_lidar_neighbors = 1;
  options.lidar_constraints_path = dir.File("c.txt");
  const SyntheticSfmScene scene = WriteSyntheticSfmDatabase(options, dir.File("db.db"));
  const auto records = ReadLidarConstraints(options.lidar_constraints_path);
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
    const SE3 gt = scene.gt_cam_from_world.at(constraint.frame_id1) *
                   scene.gt_cam_from_world.at(constraint.frame_id2).Inverse();
    EXPECT_TRUE(test::PosesNear(constraint.rig1_from_rig2, gt,
                                kSigmas * std::sqrt(3.0) * options.lidar_rotation_noise,
                                kSigmas * std::sqrt(3.0) * options.lidar_translation_noise));
  }
}

TEST(SfmSynthetic, InvalidOptionsThrow) {
  test::TempDir dir;
  SyntheticSfmOptions options;
  options.camera_model = "FOV";
  EXPECT_FALSE(options.Check());
  EXPECT_THROW(WriteSyntheticSfmDatabase(options, dir.File("db.db")), InternalError);
  options = SyntheticSfmOptions();
  options.rig_path = dir.File("rig.yaml");  // a rig file without a rig
  EXPECT_FALSE(options.Check());
  options = SyntheticSfmOptions();
  options.num_rig_cameras = 6;
  EXPECT_FALSE(options.Check());
  EXPECT_FALSE(FileExists(dir.File("db.db")));
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
