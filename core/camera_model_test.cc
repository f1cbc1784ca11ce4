#include "core/camera_model.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// HILTI 2022 cam0 (calib_3_cam0-1-camchain-imucam.yaml): a real fisheye lens.
CameraModel HiltiCam0() {
  CameraModel camera;
  camera.width = 720;
  camera.height = 540;
  camera.fx = 351.31400364193297;
  camera.fy = 351.4911744656785;
  camera.cx = 367.8522793375995;
  camera.cy = 253.8402144980996;
  camera.distortion = DistortionModel::kEquidistant;
  camera.distortion_coeffs = {-0.03696737352869157, -0.008917880497032812, 0.008912969593422046,
                              -0.0037685977496087313};
  return camera;
}

// A typical radtan camera (EuRoC cam0-like values).
CameraModel RadtanCamera() {
  CameraModel camera;
  camera.width = 752;
  camera.height = 480;
  camera.fx = 458.654;
  camera.fy = 457.296;
  camera.cx = 367.215;
  camera.cy = 248.375;
  camera.distortion = DistortionModel::kRadtan;
  camera.distortion_coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  return camera;
}

CameraModel PinholeCamera() {
  CameraModel camera = RadtanCamera();
  camera.distortion = DistortionModel::kNone;
  camera.distortion_coeffs.clear();
  return camera;
}

// Random points in front of the camera with incidence angle <= max_angle.
std::vector<Vec3> RandomPoints(int count, double max_angle_rad) {
  std::uniform_real_distribution<double> angle(0.0, max_angle_rad);
  std::uniform_real_distribution<double> azimuth(-M_PI, M_PI);
  std::uniform_real_distribution<double> depth(0.2, 30.0);
  std::vector<Vec3> points;
  for (int i = 0; i < count; ++i) {
    const double theta = angle(test::Rng()), phi = azimuth(test::Rng());
    points.push_back(depth(test::Rng()) *
                     Vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                          std::cos(theta)));
  }
  return points;
}

cv::Matx33d CvK(const CameraModel& camera) {
  return cv::Matx33d(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
}

TEST(CameraModel, RadtanMatchesOpenCvProjectPoints) {
  const CameraModel camera = RadtanCamera();
  // 40 deg keeps r = tan(theta) < 0.84 inside the monotonic region of these
  // coefficients (1 + 3 k1 r^2 + 5 k2 r^4 > 0 up to r ~ 1.3).
  const std::vector<Vec3> points = RandomPoints(500, 40.0 * M_PI / 180.0);
  std::vector<cv::Point3d> cv_points;
  for (const Vec3& p : points) cv_points.emplace_back(p.x(), p.y(), p.z());
  std::vector<cv::Point2d> cv_pixels;
  cv::projectPoints(cv_points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), CvK(camera),
                    camera.distortion_coeffs, cv_pixels);
  for (size_t i = 0; i < points.size(); ++i) {
    Vec2 pixel;
    ASSERT_TRUE(camera.Project(points[i], &pixel, /*check_bounds=*/false)) << points[i].transpose();
    // Both evaluate the same double-precision polynomial: agreement to
    // rounding, far below 1e-9 px.
    EXPECT_NEAR(pixel.x(), cv_pixels[i].x, 1e-9);
    EXPECT_NEAR(pixel.y(), cv_pixels[i].y, 1e-9);
  }
}

TEST(CameraModel, EquidistantMatchesOpenCvFisheyeProjectPoints) {
  const CameraModel camera = HiltiCam0();
  // Up to 80 deg incidence: the HILTI lens covers ~80 deg at the image corners.
  const std::vector<Vec3> points = RandomPoints(500, 80.0 * M_PI / 180.0);
  std::vector<cv::Point3d> cv_points;
  for (const Vec3& p : points) cv_points.emplace_back(p.x(), p.y(), p.z());
  std::vector<cv::Point2d> cv_pixels;
  cv::fisheye::projectPoints(cv_points, cv_pixels, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0),
                             CvK(camera), camera.distortion_coeffs);
  for (size_t i = 0; i < points.size(); ++i) {
    Vec2 pixel;
    ASSERT_TRUE(camera.Project(points[i], &pixel, /*check_bounds=*/false)) << points[i].transpose();
    // OpenCV computes theta from atan(r / z) with r, z as given; rounding only.
    EXPECT_NEAR(pixel.x(), cv_pixels[i].x, 1e-9);
    EXPECT_NEAR(pixel.y(), cv_pixels[i].y, 1e-9);
  }
}

void ExpectRoundTrip(const CameraModel& camera, double max_angle_rad) {
  for (const Vec3& point : RandomPoints(500, max_angle_rad)) {
    Vec2 pixel;
    ASSERT_TRUE(camera.Project(point, &pixel, /*check_bounds=*/false));
    Vec3 ray;
    ASSERT_TRUE(camera.Unproject(pixel, &ray)) << pixel.transpose();
    EXPECT_NEAR(ray.norm(), 1.0, 1e-12);
    // Undistortion converges to 1e-10 in normalized units; the direction error
    // is of the same order (the distortion Jacobian is near identity).
    EXPECT_LT((ray - point.normalized()).norm(), 1e-9)
        << DistortionModelName(camera.distortion) << " point " << point.transpose();
    EXPECT_TRUE(camera.Unproject(pixel).isApprox(ray, 1e-15));
  }
}

TEST(CameraModel, UnprojectInvertsProjectForEveryModel) {
  ExpectRoundTrip(PinholeCamera(), 60.0 * M_PI / 180.0);
  ExpectRoundTrip(RadtanCamera(), 40.0 * M_PI / 180.0);
  ExpectRoundTrip(HiltiCam0(), 85.0 * M_PI / 180.0);
}

TEST(CameraModel, ProjectInvertsUnprojectOnTheWholeImage) {
  for (const CameraModel& camera : {PinholeCamera(), RadtanCamera(), HiltiCam0()}) {
    std::uniform_real_distribution<double> u(-0.5, camera.width - 0.5);
    std::uniform_real_distribution<double> v(-0.5, camera.height - 0.5);
    for (int i = 0; i < 500; ++i) {
      const Vec2 pixel(u(test::Rng()), v(test::Rng()));
      Vec3 ray;
      ASSERT_TRUE(camera.Unproject(pixel, &ray)) << pixel.transpose();
      Vec2 back;
      ASSERT_TRUE(camera.Project(ray, &back));
      // 1e-10 in normalized coordinates times f ~ 460 px -> < 1e-7 px.
      EXPECT_LT((back - pixel).norm(), 1e-7) << DistortionModelName(camera.distortion);
    }
  }
}

TEST(CameraModel, PointsBehindTheCameraDoNotProject) {
  Vec2 pixel;
  for (const CameraModel& camera : {PinholeCamera(), RadtanCamera()}) {
    EXPECT_FALSE(camera.Project(Vec3(0.1, 0.2, -1.0), &pixel, false));
    EXPECT_FALSE(camera.Project(Vec3(0.1, 0.2, 0.0), &pixel, false));
    EXPECT_FALSE(camera.Project(Vec3(0.0, 0.0, -1.0), &pixel, false));
  }
  const CameraModel fisheye = HiltiCam0();
  EXPECT_FALSE(fisheye.Project(Vec3(0.0, 0.0, -1.0), &pixel, false));  // theta = pi
  EXPECT_FALSE(fisheye.Project(Vec3(0.01, 0.0, -1.0), &pixel, false));
  // Beyond the HILTI lens's invertible range: theta_d'(theta) < 0 before 120 deg.
  EXPECT_FALSE(fisheye.Project(Vec3(std::sin(2.1), 0.0, std::cos(2.1)), &pixel, false));
}

TEST(CameraModel, EquidistantWithoutDistortionSeesBeyondNinetyDegrees) {
  CameraModel camera = HiltiCam0();
  camera.distortion_coeffs = {0, 0, 0, 0};
  const double theta = 100.0 * M_PI / 180.0;  // z < 0, still a valid fisheye ray
  const Vec3 point(std::sin(theta), 0.0, std::cos(theta));
  Vec2 pixel;
  ASSERT_TRUE(camera.Project(point, &pixel, /*check_bounds=*/false));
  EXPECT_NEAR(pixel.x(), camera.cx + camera.fx * theta, 1e-9);  // r_d = theta exactly
  EXPECT_NEAR(pixel.y(), camera.cy, 1e-9);
  EXPECT_FALSE(camera.Project(point, &pixel, /*check_bounds=*/true));  // off the image
  const Vec3 ray = camera.Unproject(pixel);
  EXPECT_LT((ray - point).norm(), 1e-10);
}

TEST(CameraModel, BoundsCheckAndInImage) {
  const CameraModel camera = PinholeCamera();
  Vec2 pixel;
  // x/z = 1 -> u = cx + fx ~ 826 > 752: outside.
  EXPECT_FALSE(camera.Project(Vec3(1.0, 0.0, 1.0), &pixel, true));
  EXPECT_TRUE(camera.Project(Vec3(1.0, 0.0, 1.0), &pixel, false));
  EXPECT_NEAR(pixel.x(), camera.cx + camera.fx, 1e-12);
  EXPECT_TRUE(camera.Project(Vec3(0.0, 0.0, 1.0), &pixel, true));
  EXPECT_TRUE(camera.InImage(Vec2(-0.5, -0.5)));
  EXPECT_TRUE(camera.InImage(Vec2(751.49, 479.49)));
  EXPECT_FALSE(camera.InImage(Vec2(751.5, 10.0)));
  EXPECT_FALSE(camera.InImage(Vec2(10.0, 479.5)));
  EXPECT_FALSE(camera.InImage(Vec2(-0.51, 10.0)));
}

TEST(CameraModel, RadtanRejectsPointsThatWouldFoldBackIntoTheImage) {
  CameraModel camera = RadtanCamera();
  camera.distortion_coeffs = {-0.5, 0.0, 0.0, 0.0};  // r (1 - 0.5 r^2) peaks at r = 0.816
  Vec2 pixel;
  EXPECT_TRUE(camera.Project(Vec3(0.7, 0.0, 1.0), &pixel, false));
  // r = 1.6 distorts to 1.6 (1 - 1.28) = -0.45: back on the image, but invalid.
  EXPECT_FALSE(camera.Project(Vec3(1.6, 0.0, 1.0), &pixel, false));
  Vec3 ray;
  // Beyond the maximum distorted radius 0.544 there is no inverse.
  EXPECT_FALSE(camera.Unproject(Vec2(camera.cx + camera.fx * 0.6, camera.cy), &ray));
}

TEST(CameraModel, ValidateNamesTheField) {
  CameraModel camera = HiltiCam0();
  EXPECT_NO_THROW(camera.Validate("rig.yaml:cam0"));
  camera.distortion_coeffs.pop_back();
  EXPECT_TRUE(test::ThrowsInputError([&] { camera.Validate("rig.yaml:cam2"); },
                                     {"rig.yaml:cam2.distortion_coeffs: expected 4"}));
  camera = HiltiCam0();
  camera.fx = 0.0;
  EXPECT_THROW(camera.Validate("x"), InputError);
  camera = HiltiCam0();
  camera.width = 0;
  EXPECT_THROW(camera.Validate("x"), InputError);
  camera = PinholeCamera();
  camera.distortion_coeffs = {0.1};
  EXPECT_THROW(camera.Validate("x"), InputError);
  camera = RadtanCamera();
  camera.distortion_coeffs[0] = std::nan("");
  EXPECT_THROW(camera.Validate("x"), InputError);
}

TEST(CameraModel, DistortionModelNames) {
  for (const DistortionModel model :
       {DistortionModel::kNone, DistortionModel::kRadtan, DistortionModel::kEquidistant}) {
    EXPECT_EQ(ParseDistortionModel(DistortionModelName(model)), model);
  }
  EXPECT_THROW(ParseDistortionModel("fisheye"), InputError);
  EXPECT_EQ(NumDistortionCoeffs(DistortionModel::kNone), 0);
  EXPECT_EQ(NumDistortionCoeffs(DistortionModel::kRadtan), 4);
}

}  // namespace
}  // namespace lisfm
