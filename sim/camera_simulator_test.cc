#include "sim/camera_simulator.h"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/io/rig_io.h"
#include "sim/motion.h"
#include "sim/texture.h"
#include "tests/common/sim_walks.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

class CameraSimulatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (test::SharedData("hilti_exp4_small/calibration").empty()) {
      GTEST_SKIP() << "../shared/data/hilti_exp4_small/calibration is missing";
    }
    rig_ = LoadHiltiCalibration(test::SharedData("hilti_exp4_small/calibration"));
    ASSERT_EQ(rig_.cameras.size(), 5u);
    scene_ = Scene::Generate(DefaultSceneOptions("office"));
    walk_ = GenerateWalking(scene_->route(), 30.0, 0, 4, ThreeStopWalk(), nullptr);
    options_.noise_scale = 0;
  }
  SE3 WorldFromCam(int cam, TimestampNs t) const {
    return walk_.Pose(t) * rig_.cameras[cam].cam_from_imu.Inverse();
  }
  // Projects world points with OpenCV's fisheye model (independent of
  // CameraModel::Project).
  std::vector<cv::Point2d> ProjectOpenCv(int cam, const SE3& world_from_cam,
                                         const std::vector<Vec3>& points) const {
    const CameraModel& m = rig_.cameras[cam].model;
    const SE3 cam_from_world = world_from_cam.Inverse();
    cv::Mat rmat, rvec;
    cv::eigen2cv(Mat3(cam_from_world.RotationMatrix()), rmat);
    cv::Rodrigues(rmat, rvec);
    const cv::Vec3d tvec(cam_from_world.translation().x(), cam_from_world.translation().y(),
                         cam_from_world.translation().z());
    const cv::Matx33d k(m.fx, 0, m.cx, 0, m.fy, m.cy, 0, 0, 1);
    const cv::Vec4d d(m.distortion_coeffs[0], m.distortion_coeffs[1], m.distortion_coeffs[2],
                      m.distortion_coeffs[3]);
    std::vector<cv::Point3d> object;
    for (const Vec3& p : points) object.emplace_back(p.x(), p.y(), p.z());
    std::vector<cv::Point2d> pixels;
    cv::fisheye::projectPoints(object, pixels, rvec, tvec, k, d);
    return pixels;
  }

  Rig rig_;
  std::unique_ptr<Scene> scene_;
  SplineTrajectory walk_;
  CameraSimOptions options_;
};

double Bilinear(const cv::Mat& image, const cv::Point2d& p) {
  cv::Mat patch;
  cv::getRectSubPix(image, cv::Size(1, 1), cv::Point2f(p.x, p.y), patch, CV_32F);
  return patch.at<float>(0, 0);
}

double Correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = a.size();
  double ma = 0, mb = 0;
  for (size_t i = 0; i < n; ++i) {
    ma += a[i] / n;
    mb += b[i] / n;
  }
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < n; ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

// Known scene points (hits of random rays from the camera centre, so they are
// visible) projected with cv::fisheye::projectPoints land where the rendered
// image shows their texture: the rendered value correlates with the texture
// albedo at the point (> 0.85; vignetting/shading and the 1-sample pixel
// footprint keep it below 1), and the same test with a 3 px shift fails.
TEST_F(CameraSimulatorTest, TextureAppearsWhereOpenCvProjects) {
  const int cam = 0;
  const TimestampNs t = SecondsToNs(9.0);
  const CameraRenderer renderer(*scene_, rig_.cameras[cam].model, TextureOptions(), options_);
  const SE3 world_from_cam = WorldFromCam(cam, t);
  const cv::Mat image = renderer.Render(world_from_cam, 1);
  const Texture texture{TextureOptions()};
  std::vector<Vec3> points;
  std::vector<double> albedo;
  for (int i = 0; points.size() < 3000 && i < 100000; ++i) {
    Vec3 d = Vec3::Random();
    d.z() = std::abs(d.z()) + 0.6;
    d.normalize();
    const RayHit hit = scene_->Intersect(world_from_cam.translation(),
                                         world_from_cam.rotation() * d);
    if (!hit.hit) continue;
    const Vec3 x = world_from_cam.translation() + hit.distance * (world_from_cam.rotation() * d);
    points.push_back(x);
    albedo.push_back(texture.Albedo(hit.surface_id, x.cast<float>(), TextureAxis(hit.normal)));
  }
  const auto pixels = ProjectOpenCv(cam, world_from_cam, points);
  std::vector<double> a, rendered, shifted;
  for (size_t i = 0; i < pixels.size(); ++i) {
    const cv::Point2d& p = pixels[i];
    if (p.x < 5 || p.y < 5 || p.x > image.cols - 6 || p.y > image.rows - 6) continue;
    a.push_back(albedo[i]);
    rendered.push_back(Bilinear(image, p));
    shifted.push_back(Bilinear(image, p + cv::Point2d(3, 0)));
  }
  ASSERT_GT(a.size(), 1000u);
  const double corr = Correlation(a, rendered);
  EXPECT_GT(corr, 0.85);
  EXPECT_LT(Correlation(a, shifted), corr - 0.2);
}

// cam0 and cam1 (the front stereo pair): a scene point seen in cam0 appears in
// cam1 where OpenCV projects it with the rig extrinsics, with the same grey
// value (noise-free, view-independent shading; median difference < 8 DN
// allows vignetting differences and sampling at texture edges).
TEST_F(CameraSimulatorTest, FrontCamerasAreAConsistentStereoPair) {
  const TimestampNs t = SecondsToNs(9.0);
  const CameraRenderer r0(*scene_, rig_.cameras[0].model, TextureOptions(), options_);
  const CameraRenderer r1(*scene_, rig_.cameras[1].model, TextureOptions(), options_);
  const SE3 w0 = WorldFromCam(0, t), w1 = WorldFromCam(1, t);
  const cv::Mat im0 = r0.Render(w0, 1), im1 = r1.Render(w1, 2);
  std::vector<Vec3> points;
  std::vector<cv::Point2d> pix0;
  for (int y = 60; y < 480; y += 23) {
    for (int x = 60; x < 660; x += 23) {
      const Vec3 d = rig_.cameras[0].model.Unproject(Vec2(x, y));
      const RayHit hit = scene_->Intersect(w0.translation(), w0.rotation() * d);
      if (!hit.hit) continue;
      points.push_back(w0.translation() + hit.distance * (w0.rotation() * d));
      pix0.emplace_back(x, y);
    }
  }
  const auto pix1 = ProjectOpenCv(1, w1, points);
  std::vector<double> diff, diff_wrong;
  for (size_t i = 0; i < points.size(); ++i) {
    const cv::Point2d& p = pix1[i];
    if (p.x < 5 || p.y < 5 || p.x > im1.cols - 6 || p.y > im1.rows - 6) continue;
    // Occlusion check from cam1's centre.
    const Vec3 ray = points[i] - w1.translation();
    const RayHit hit = scene_->Intersect(w1.translation(), ray.normalized());
    if (!hit.hit || std::abs(hit.distance - ray.norm()) > 0.01) continue;
    const double v0 = im0.at<uint8_t>(static_cast<int>(pix0[i].y), static_cast<int>(pix0[i].x));
    diff.push_back(std::abs(v0 - Bilinear(im1, p)));
    diff_wrong.push_back(std::abs(v0 - Bilinear(im1, p + cv::Point2d(0, 4))));
  }
  ASSERT_GT(diff.size(), 200u);
  std::nth_element(diff.begin(), diff.begin() + diff.size() / 2, diff.end());
  std::nth_element(diff_wrong.begin(), diff_wrong.begin() + diff_wrong.size() / 2,
                   diff_wrong.end());
  EXPECT_LT(diff[diff.size() / 2], 8.0);
  EXPECT_GT(diff_wrong[diff_wrong.size() / 2], 2 * diff[diff.size() / 2]);
}

// The texture is dense and distinctive enough for SIFT: >= 2000 keypoints on a
// 720x540 render (with the default noise), for every camera of the rig.
TEST_F(CameraSimulatorTest, SiftFindsAtLeast2000Features) {
  CameraSimOptions noisy;
  const auto sift = cv::SIFT::create();
  for (int cam = 0; cam < 5; ++cam) {
    const CameraRenderer renderer(*scene_, rig_.cameras[cam].model, TextureOptions(), noisy);
    const cv::Mat image = renderer.Render(WorldFromCam(cam, SecondsToNs(12.0)), 3);
    ASSERT_EQ(image.cols, 720);
    ASSERT_EQ(image.rows, 540);
    std::vector<cv::KeyPoint> keypoints;
    sift->detect(image, keypoints);
    EXPECT_GE(keypoints.size(), 2000u) << "cam" << cam;
  }
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
