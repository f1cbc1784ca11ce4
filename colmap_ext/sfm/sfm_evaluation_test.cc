// sfm_evaluation: synthetic models with exactly known errors, the Strecha,
// Bundler and COLMAP reference readers on the real files, and bad input.
#include "colmap_ext/sfm/sfm_evaluation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "colmap_ext/io/model_io.h"
#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// `n` cameras on a ring of radius 5 around the origin, looking at it, with
// some height and roll variation (non-collinear centres).
std::vector<NamedPose> RingCameras(int n) {
  std::vector<NamedPose> poses;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / n;
    const Vec3 centre(5 * std::cos(a), 5 * std::sin(a), 0.7 * std::sin(3 * a));
    const Vec3 z = (-centre).normalized();  // optical axis towards the origin
    const Vec3 x = z.cross(Vec3::UnitZ()).normalized();
    const Vec3 y = z.cross(x);
    Mat3 world_from_cam;
    world_from_cam << x, y, z;
    const Mat3 cam_from_world = so3::ExpMatrix(Vec3(0, 0, 0.1 * i)) * world_from_cam.transpose();
    NamedPose pose;
    pose.name = "img_" + std::to_string(i) + ".jpg";
    pose.cam_from_world = SE3(cam_from_world, -cam_from_world * centre);
    poses.push_back(pose);
  }
  return poses;
}

// The same cameras in a world related by x_est = S * x_ref (Sim(3)).
std::vector<NamedPose> TransformWorld(const std::vector<NamedPose>& poses, const Sim3& est_from_ref) {
  std::vector<NamedPose> out = poses;
  for (NamedPose& p : out) {
    const Vec3 centre = est_from_ref * p.cam_from_world.Inverse().translation();
    const Quat rotation = p.cam_from_world.rotation() * est_from_ref.pose.rotation().conjugate();
    p.cam_from_world = SE3(rotation, -(rotation * centre));
  }
  return out;
}

Sim3 SomeSimilarity() {
  Sim3 s;
  s.scale = 2.5;
  s.pose = SE3(so3::Exp(Vec3(0.3, -1.2, 2.0)), Vec3(10, -4, 7));
  return s;
}

TEST(SfmEvaluation, RigImagesWithSharedBasenamesMatchByFullName) {
  // Two cameras of one rig write the same <ns>.png under their own folders;
  // the estimate registered only cam0's images: cam1's are unregistered,
  // not ambiguous.
  std::vector<NamedPose> reference = RingCameras(6);
  for (size_t i = 0; i < reference.size(); ++i) {
    reference[i].name = "cam" + std::to_string(i % 2) + "/data/" + std::to_string(i / 2) + ".png";
  }
  std::vector<NamedPose> estimate;
  for (const NamedPose& p : reference) {
    if (p.name.rfind("cam0/", 0) == 0) estimate.push_back(p);
  }
  const SfmEvaluation ev = EvaluatePoses(estimate, reference, SfmEvaluationOptions());
  EXPECT_EQ(ev.num_registered, 3u);
  EXPECT_EQ(ev.num_unmatched_estimated, 0u);
  EXPECT_LT(ev.rotation_error_deg.max, 1e-6);
}

TEST(SfmEvaluation, SimilarityTransformedModelHasZeroErrors) {
  const std::vector<NamedPose> reference = RingCameras(10);
  std::vector<NamedPose> estimate = TransformWorld(reference, SomeSimilarity());
  // Estimated names carry a folder: association falls back to the basename.
  for (NamedPose& p : estimate) p.name = "images/" + p.name;
  std::reverse(estimate.begin(), estimate.end());

  const SfmEvaluation ev = EvaluatePoses(estimate, reference, SfmEvaluationOptions());
  EXPECT_EQ(ev.num_registered, 10u);
  EXPECT_EQ(ev.num_unmatched_estimated, 0u);
  EXPECT_EQ(ev.alignment, "sim3");
  // Double precision through a scale-2.5 similarity: errors are rounding
  // noise (~1e-14 relative); 1e-6 deg / 1e-9 units leave a wide margin while
  // any real misalignment would show degrees / units.
  EXPECT_NEAR(ev.reference_from_estimate.scale, 1.0 / 2.5, 1e-12);
  EXPECT_LT(ev.rotation_error_deg.max, 1e-6);
  EXPECT_LT(ev.position_error.max, 1e-9);
  EXPECT_EQ(ev.position_error.count, 10u);
  EXPECT_EQ(ev.num_pairs, 45u);
  EXPECT_LT(ev.relative_rotation_error_deg.max, 1e-6);
  EXPECT_LT(ev.relative_translation_error_deg.max, 1e-6);
  ASSERT_EQ(ev.auc.size(), 3u);
  for (double auc : ev.auc) EXPECT_GT(auc, 1.0 - 1e-6);

  // SE(3) cannot absorb the scale: positions are off, rotations are not.
  SfmEvaluationOptions se3;
  se3.alignment = AlignmentType::kSE3;
  const SfmEvaluation ev_se3 = EvaluatePoses(estimate, reference, se3);
  EXPECT_EQ(ev_se3.alignment, "se3");
  EXPECT_GT(ev_se3.position_error.mean, 1.0);
  EXPECT_LT(ev_se3.rotation_error_deg.max, 1e-6);
}

TEST(SfmEvaluation, PerturbedRotationGivesItsAngle) {
  const std::vector<NamedPose> reference = RingCameras(10);
  std::vector<NamedPose> estimate = TransformWorld(reference, SomeSimilarity());
  // Rotate camera 3 by 4 degrees about an oblique axis, keeping its centre:
  // the centre-based alignment is unchanged, so its rotation error is 4 deg,
  // the others stay 0.
  const double angle_deg = 4.0;
  const Vec3 axis = Vec3(1, 2, -0.5).normalized();
  SE3& cam3 = estimate[3].cam_from_world;
  const Vec3 centre = cam3.Inverse().translation();
  const Quat rotated = so3::Exp(angle_deg * kDegToRad * axis) * cam3.rotation();
  cam3 = SE3(rotated, -(rotated * centre));

  SfmEvaluationOptions options;
  options.auc_thresholds_deg = {1.0, 5.0, 10.0};
  const SfmEvaluation ev = EvaluatePoses(estimate, reference, options);
  for (size_t i = 0; i < ev.images.size(); ++i) {
    EXPECT_NEAR(ev.images[i].rotation_error_deg, i == 3 ? angle_deg : 0.0, 1e-6) << i;
    EXPECT_LT(ev.images[i].position_error, 1e-9) << i;
  }
  EXPECT_NEAR(ev.rotation_error_deg.max, angle_deg, 1e-6);
  EXPECT_NEAR(ev.rotation_error_deg.mean, angle_deg / 10, 1e-6);
  EXPECT_NEAR(ev.rotation_error_deg.median, 0.0, 1e-6);
  // Every pair with camera 3 has a relative rotation error of exactly 4 deg
  // (R2 R1^T vs R2 R1^T E^T); its translation direction changes by <= 4 deg.
  EXPECT_NEAR(ev.relative_rotation_error_deg.max, angle_deg, 1e-6);
  EXPECT_LE(ev.relative_translation_error_deg.max, angle_deg + 1e-6);
  // 36 pairs at 0 and 9 at 4 deg. The recall curve through (0, 36/45) and
  // (4, 37/45) ... (4, 1): AUC@1 = 36/45, AUC@5 = (4 (36.5/45) + 1) / 5 and
  // AUC@10 = (4 (36.5/45) + 6) / 10.
  ASSERT_EQ(ev.auc.size(), 3u);
  EXPECT_NEAR(ev.auc[0], 36.0 / 45.0, 1e-6);
  EXPECT_NEAR(ev.auc[1], (4 * 36.5 / 45 + 1) / 5, 1e-6);
  EXPECT_NEAR(ev.auc[2], (4 * 36.5 / 45 + 6) / 10, 1e-6);
}

TEST(SfmEvaluation, RotationErrorsIgnorePositionNoise) {
  const std::vector<NamedPose> reference = RingCameras(10);
  std::vector<NamedPose> estimate = TransformWorld(reference, SomeSimilarity());
  // Move every centre by up to 0.2 (estimate units) keeping the rotations:
  // the centre alignment absorbs part of it, the rotation errors must stay 0
  // because they are aligned by rotations alone.
  std::uniform_real_distribution<double> noise(-0.2, 0.2);
  for (NamedPose& p : estimate) {
    const Vec3 centre = p.cam_from_world.Inverse().translation() +
                        Vec3(noise(test::Rng()), noise(test::Rng()), noise(test::Rng()));
    p.cam_from_world = SE3(p.cam_from_world.rotation(), -(p.cam_from_world.rotation() * centre));
  }
  const SfmEvaluation ev = EvaluatePoses(estimate, reference, SfmEvaluationOptions());
  EXPECT_LT(ev.rotation_error_deg.max, 1e-6);
  // 0.2 / 2.5 = 0.08 reference units per axis at most.
  EXPECT_GT(ev.position_error.mean, 1e-3);
  EXPECT_LT(ev.position_error.max, 0.08 * std::sqrt(3.0) * 2);
  EXPECT_LT(ev.relative_rotation_error_deg.max, 1e-6);
}

TEST(SfmEvaluation, MissingImagesCountAsInfiniteErrors) {
  const std::vector<NamedPose> reference = RingCameras(10);
  std::vector<NamedPose> estimate = TransformWorld(reference, SomeSimilarity());
  estimate.erase(estimate.begin() + 5);
  NamedPose extra = estimate[0];
  extra.name = "not_in_reference.jpg";
  estimate.push_back(extra);
  const SfmEvaluation ev = EvaluatePoses(estimate, reference, SfmEvaluationOptions());
  EXPECT_EQ(ev.num_registered, 9u);
  EXPECT_EQ(ev.num_unmatched_estimated, 1u);
  EXPECT_FALSE(ev.images[5].registered);
  EXPECT_TRUE(std::isnan(ev.images[5].rotation_error_deg));
  EXPECT_EQ(ev.rotation_error_deg.count, 9u);
  // 36 of 45 pairs have both images (error ~0), 9 are infinite.
  for (double auc : ev.auc) EXPECT_NEAR(auc, 36.0 / 45.0, 1e-6);
}

TEST(SfmEvaluation, FewImagesFallBackToRotationOnly) {
  const std::vector<NamedPose> reference = RingCameras(10);
  const std::vector<NamedPose> all = TransformWorld(reference, SomeSimilarity());
  const std::vector<NamedPose> estimate = {all[2], all[7]};
  const SfmEvaluation ev = EvaluatePoses(estimate, reference, SfmEvaluationOptions());
  EXPECT_EQ(ev.alignment, "rotation_only");
  EXPECT_EQ(ev.num_registered, 2u);
  EXPECT_LT(ev.rotation_error_deg.max, 1e-6);
  EXPECT_EQ(ev.position_error.count, 0u);
  EXPECT_TRUE(std::isnan(ev.images[2].position_error));
}

TEST(SfmEvaluation, NoCommonImageIsAnInputError) {
  std::vector<NamedPose> estimate = RingCameras(4);
  for (NamedPose& p : estimate) p.name = "other_" + p.name;
  EXPECT_THROW(EvaluatePoses(estimate, RingCameras(4), SfmEvaluationOptions()), InputError);
}

TEST(SfmEvaluation, PoseAucMatchesHandComputation) {
  // Errors 0.5 and 2 (of 4 pairs, two infinite): recall 1/4 at 0.5, 2/4 at 2.
  const std::vector<double> errors = {2.0, std::numeric_limits<double>::infinity(), 0.5,
                                      std::numeric_limits<double>::infinity()};
  const std::vector<double> auc = PoseAuc(errors, {1.0, 3.0});
  // Recall curve (0, 0), (0.5, 1/4), (2, 2/4), linear between points and flat
  // after the last error below the threshold (SuperGlue's pose_auc).
  // @1: 0.5 * 0.5 * 0.25 + 0.5 * 0.25 = 0.1875.
  EXPECT_NEAR(auc[0], 0.1875, 1e-12);
  // @3: 0.0625 + (0.25 + 0.5) / 2 * 1.5 + 1 * 0.5 = 1.125, / 3.
  EXPECT_NEAR(auc[1], 1.125 / 3.0, 1e-12);
}

TEST(SfmEvaluation, DetectsFormatsAndRejectsBadFiles) {
  test::TempDir dir;
  EXPECT_THROW(DetectReferenceFormat(dir.path()), InputError);
  EXPECT_THROW(DetectReferenceFormat(dir.File("missing")), InputError);
  test::WriteText(dir.File("a.camera"), "1 0 0\n0 1 0\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n");
  EXPECT_EQ(DetectReferenceFormat(dir.path()), ReferenceFormat::kStrecha);
  // A truncated .camera file.
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadStrechaCameras(dir.path()); }, {"a.camera", "number 19"}));
  // A Bundler point seen by camera 3 of 1.
  test::WriteText(dir.File("b.out"),
                  "# Bundle file v0.3\n1 1\n500 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n"
                  "0 0 -5\n255 0 0\n1 3 0 1.5 2.5\n");
  EXPECT_EQ(DetectReferenceFormat(dir.File("b.out")), ReferenceFormat::kBundler);
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadBundlerFile(dir.File("b.out")); }, {"line 10"}));
  test::WriteText(dir.File("c.out"), "not a bundle file\n");
  EXPECT_THROW(ReadBundlerFile(dir.File("c.out")), InputError);
  // No list.txt and no images/ beside it: the cameras cannot be named.
  test::WriteText(dir.File("d.out"),
                  "# Bundle file v0.3\n1 0\n500 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 0\n");
  EXPECT_THROW(ReadBundlerPoses(dir.File("d.out"), ""), InputError);
  test::WriteText(dir.File("list.txt"), "x.jpg 0 500\n");
  const std::vector<NamedPose> poses = ReadBundlerPoses(dir.File("d.out"), "");
  ASSERT_EQ(poses.size(), 1u);
  EXPECT_EQ(poses[0].name, "x.jpg");
}

TEST(SfmEvaluation, LundDoorReferenceAgainstItselfIsExact) {
  LISFM_REQUIRE_SHARED_DATA("sfm_lund_door/colmap_ground_truth/images.txt");
  const std::string path = test::SharedData("sfm_lund_door/colmap_ground_truth");
  EXPECT_EQ(DetectReferenceFormat(path), ReferenceFormat::kColmap);
  const std::vector<NamedPose> reference = ReadReferencePoses(path, ReferenceFormat::kAuto);
  ASSERT_EQ(reference.size(), 12u);
  // A Sim(3)-moved copy of the real cameras scores (numerically) zero.
  const SfmEvaluation ev =
      EvaluatePoses(TransformWorld(reference, SomeSimilarity()), reference, SfmEvaluationOptions());
  EXPECT_EQ(ev.num_registered, 12u);
  EXPECT_LT(ev.rotation_error_deg.max, 1e-6);
  EXPECT_LT(ev.position_error.max, 1e-8);
  for (double auc : ev.auc) EXPECT_GT(auc, 1.0 - 1e-6);
}

TEST(SfmEvaluation, StrechaCamerasSeeTheSceneTheyWereTakenOf) {
  LISFM_REQUIRE_SHARED_DATA("sfm_strecha/fountain-P11/gt_dense_cameras/0000.jpg.camera");
  const std::string path = test::SharedData("sfm_strecha/fountain-P11");
  EXPECT_EQ(DetectReferenceFormat(path), ReferenceFormat::kStrecha);
  const std::vector<NamedPose> cameras = ReadReferencePoses(path, ReferenceFormat::kAuto);
  ASSERT_EQ(cameras.size(), 11u);
  EXPECT_EQ(cameras.front().name, "0000.jpg");
  EXPECT_EQ(cameras.back().name, "0010.jpg");
  // Values from 0000.jpg.camera (K row 1, C, size).
  EXPECT_EQ(cameras[0].camera.ModelName(), "PINHOLE");
  EXPECT_DOUBLE_EQ(cameras[0].camera.params[0], 2759.48);
  EXPECT_DOUBLE_EQ(cameras[0].camera.params[2], 1520.69);
  EXPECT_EQ(cameras[0].camera.width, 3072u);
  EXPECT_TRUE(cameras[0].cam_from_world.Inverse().translation().isApprox(
      Vec3(-7.28137, -7.57667, 0.204446), 1e-9));
  // The point nearest to all optical axes (least squares) is the fountain
  // every camera looks at: with the right convention (R = world_from_cam) it
  // lies in front of every camera and projects into every image. With R
  // transposed or the axis flipped it would not.
  Mat3 a = Mat3::Zero();
  Vec3 b = Vec3::Zero();
  for (const NamedPose& c : cameras) {
    const Vec3 centre = c.cam_from_world.Inverse().translation();
    const Vec3 axis = c.cam_from_world.rotation().conjugate() * Vec3::UnitZ();
    const Mat3 p = Mat3::Identity() - axis * axis.transpose();
    a += p;
    b += p * centre;
  }
  const Vec3 target = a.ldlt().solve(b);
  for (const NamedPose& c : cameras) {
    const Vec3 x = c.cam_from_world * target;
    ASSERT_GT(x.z(), 1.0) << c.name;  // metres in front of the camera
    const double u = c.camera.params[0] * x.x() / x.z() + c.camera.params[2];
    const double v = c.camera.params[1] * x.y() / x.z() + c.camera.params[3];
    EXPECT_GT(u, 0.0) << c.name;
    EXPECT_LT(u, static_cast<double>(c.camera.width)) << c.name;
    EXPECT_GT(v, 0.0) << c.name;
    EXPECT_LT(v, static_cast<double>(c.camera.height)) << c.name;
  }
}

TEST(SfmEvaluation, BundlerReprojectsItsOwnPoints) {
  LISFM_REQUIRE_SHARED_DATA("sfm_balbianello/Balbianello.out");
  const std::string path = test::SharedData("sfm_balbianello/Balbianello.out");
  const BundlerModel model = ReadBundlerFile(path);
  ASSERT_EQ(model.cameras.size(), 5u);
  ASSERT_EQ(model.points.size(), 544u);
  // The same projection through COLMAP's RADIAL model with the Bundler pose
  // converted to COLMAP's camera frame: pixel = (w/2 + x, h/2 - y).
  const double w = 640, h = 427;
  std::vector<double> errors;
  for (const BundlerPoint& point : model.points) {
    for (const BundlerObservation& obs : point.observations) {
      const BundlerCamera& cam = model.cameras[static_cast<size_t>(obs.camera_index)];
      Vec2 xy;
      ASSERT_TRUE(BundlerProject(cam, point.xyz, &xy));
      errors.push_back((xy - obs.xy).norm());
      Camera colmap_camera;
      colmap_camera.model_id = static_cast<int>(CameraModelId::kRadial);
      colmap_camera.width = 640;
      colmap_camera.height = 427;
      colmap_camera.params = {cam.focal_px, w / 2, h / 2, cam.k1, cam.k2};
      const Vec3 x_cam = BundlerCamFromWorld(cam) * point.xyz;
      ASSERT_GT(x_cam.z(), 0.0);
      const Vec2 pixel = colmap_camera.ImgFromCam(x_cam.head<2>() / x_cam.z());
      EXPECT_NEAR(pixel.x(), w / 2 + xy.x(), 1e-9);
      EXPECT_NEAR(pixel.y(), h / 2 - xy.y(), 1e-9);
    }
  }
  ASSERT_GT(errors.size(), 1000u);
  std::sort(errors.begin(), errors.end());
  // Bundler's bundle adjustment leaves sub-pixel residuals on SIFT keypoints
  // (measured on this file: 1417 observations, median 0.13 px, 90th
  // percentile 0.41 px, max 6.9 px); a wrong sign of y, of the viewing
  // direction or of k1 gives errors of tens to hundreds of pixels.
  EXPECT_LT(errors[errors.size() / 2], 1.0);
  EXPECT_LT(errors.back(), 10.0);
}

TEST(SfmEvaluation, BundlerCameraOrderMatchesTheImages) {
  LISFM_REQUIRE_SHARED_DATA("sfm_balbianello/images/BalbianelloMedium-1.jpg");
  const std::string path = test::SharedData("sfm_balbianello/Balbianello.out");
  const BundlerModel model = ReadBundlerFile(path);
  const std::vector<std::string> names = BundlerImageNames(path, "", model.cameras.size());
  ASSERT_EQ(names.size(), 5u);
  EXPECT_EQ(names[0], "BalbianelloMedium-1.jpg");
  EXPECT_EQ(names[4], "BalbianelloMedium-5.jpg");
  // Colour check: each camera's observations sampled in image k should match
  // the points' stored RGB best for k = the camera's own image.
  std::vector<cv::Mat> images;
  for (const std::string& name : names) {
    images.push_back(cv::imread(test::SharedData("sfm_balbianello/images/" + name)));
    ASSERT_FALSE(images.back().empty()) << name;
  }
  for (size_t c = 0; c < model.cameras.size(); ++c) {
    std::vector<double> diff(images.size(), 0.0);
    std::vector<int> count(images.size(), 0);
    for (const BundlerPoint& point : model.points) {
      for (const BundlerObservation& obs : point.observations) {
        if (obs.camera_index != static_cast<int>(c)) continue;
        for (size_t k = 0; k < images.size(); ++k) {
          const cv::Mat& img = images[k];
          const int col = static_cast<int>(std::lround(img.cols / 2.0 + obs.xy.x() - 0.5));
          const int row = static_cast<int>(std::lround(img.rows / 2.0 - obs.xy.y() - 0.5));
          if (col < 0 || row < 0 || col >= img.cols || row >= img.rows) continue;
          const cv::Vec3b bgr = img.at<cv::Vec3b>(row, col);
          diff[k] += std::abs(bgr[2] - point.color[0]) + std::abs(bgr[1] - point.color[1]) +
                     std::abs(bgr[0] - point.color[2]);
          ++count[k];
        }
      }
    }
    for (size_t k = 0; k < images.size(); ++k) diff[k] /= std::max(count[k], 1);
    const size_t best = static_cast<size_t>(std::min_element(diff.begin(), diff.end()) - diff.begin());
    EXPECT_EQ(best, c) << "camera " << c << " matches image " << names[best] << " best";
  }
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
