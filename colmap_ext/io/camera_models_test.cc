#include "colmap_ext/io/camera_models.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

// Realistic parameters per model (pixels; small distortion as in real lenses).
std::vector<double> SampleParams(int model_id) {
  switch (static_cast<CameraModelId>(model_id)) {
    case CameraModelId::kSimplePinhole: return {500, 320, 240};
    case CameraModelId::kPinhole: return {500, 510, 320, 240};
    case CameraModelId::kSimpleRadial: return {500, 320, 240, -0.05};
    case CameraModelId::kRadial: return {500, 320, 240, -0.05, 0.01};
    case CameraModelId::kOpenCV: return {500, 510, 320, 240, -0.1, 0.02, 0.001, -0.002};
    case CameraModelId::kOpenCVFisheye: return {300, 305, 320, 240, 0.05, -0.01, 0.002, -0.0005};
    case CameraModelId::kFullOpenCV:
      return {500, 510, 320, 240, -0.1, 0.02, 0.001, -0.002, 0.001, 0.01, 0.002, 0.0001};
    case CameraModelId::kFOV: return {500, 510, 320, 240, 0.9};
    case CameraModelId::kSimpleRadialFisheye: return {300, 320, 240, 0.05};
    case CameraModelId::kRadialFisheye: return {300, 320, 240, 0.05, -0.01};
    case CameraModelId::kThinPrismFisheye:
      return {300, 305, 320, 240, 0.05, -0.01, 0.001, -0.001, 0.002, -0.0005, 0.001, -0.001};
    default: return {};
  }
}

TEST(CameraModels, NamesIdsAndParameterCountsAreCOLMAPs) {
  const char* names[] = {"SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV",
                         "OPENCV_FISHEYE", "FULL_OPENCV", "FOV", "SIMPLE_RADIAL_FISHEYE",
                         "RADIAL_FISHEYE", "THIN_PRISM_FISHEYE"};
  const int counts[] = {3, 4, 4, 5, 8, 8, 12, 5, 4, 5, 12};
  for (int id = 0; id < kNumCameraModels; ++id) {
    EXPECT_EQ(CameraModelName(id), names[id]);
    EXPECT_EQ(CameraModelIdFromName(names[id]), id);
    EXPECT_EQ(CameraModelNumParams(id), counts[id]);
  }
  EXPECT_EQ(CameraModelIdFromName("SIMPLE_DIVISION"), -1);
  EXPECT_FALSE(ExistsCameraModel(11));
  EXPECT_EQ(CameraModelNumParams(-1), -1);
}

TEST(CameraModels, ProjectUnprojectRoundTripForAllModels) {
  for (int id = 0; id < kNumCameraModels; ++id) {
    Camera camera;
    camera.camera_id = 1;
    camera.model_id = id;
    camera.width = 640;
    camera.height = 480;
    camera.params = SampleParams(id);
    ASSERT_TRUE(camera.VerifyParams()) << CameraModelName(id);
    for (double x = -0.6; x <= 0.6; x += 0.15) {
      for (double y = -0.45; y <= 0.45; y += 0.15) {
        const Vec3 point(x, y, 1.0);
        Vec2 pixel;
        ASSERT_TRUE(camera.Project(2.5 * point, &pixel));
        const Vec3 ray = camera.Unproject(pixel);
        // Newton converges to ~1e-12 in the normalised plane; 1e-9 leaves
        // margin for the conditioning of the distortion Jacobian.
        EXPECT_NEAR((ray - point.normalized()).norm(), 0.0, 1e-9)
            << CameraModelName(id) << " at " << x << ", " << y;
        const Vec2 normalized = camera.CamFromImg(pixel);
        EXPECT_NEAR((camera.ImgFromCam(normalized) - pixel).norm(), 0.0, 1e-6);
      }
    }
    Vec2 pixel;
    EXPECT_FALSE(camera.Project(Vec3(0, 0, -1), &pixel));
  }
}

TEST(CameraModels, PinholeProjectionIsExact) {
  Camera camera;
  camera.model_id = static_cast<int>(CameraModelId::kPinhole);
  camera.params = {500, 510, 320.5, 240.5};
  Vec2 pixel;
  ASSERT_TRUE(camera.Project(Vec3(0.2, -0.1, 2.0), &pixel));
  EXPECT_DOUBLE_EQ(pixel.x(), 500 * 0.1 + 320.5);
  EXPECT_DOUBLE_EQ(pixel.y(), 510 * -0.05 + 240.5);
  EXPECT_DOUBLE_EQ(camera.MeanFocalLength(), 505);
}

// COLMAP's bogus-parameter test: focal length / max(width, height) and
// |distortion parameter| bounds (mapper defaults 0.1, 10, 1).
TEST(CameraModels, BogusParamsFollowCOLMAPsBounds) {
  Camera c;
  c.camera_id = 3;
  c.model_id = static_cast<int>(CameraModelId::kPinhole);
  c.width = 720;
  c.height = 540;
  c.params = {350.0, 352.0, 360.0, 270.0};
  std::string why;
  EXPECT_FALSE(c.HasBogusParams(0.1, 10.0, 1.0, &why));
  EXPECT_EQ(why, "");
  c.params[1] = 7300.0;  // 10.14x the 720 px side
  EXPECT_TRUE(c.HasBogusParams(0.1, 10.0, 1.0, &why));
  EXPECT_NE(why.find("fy = 7300.0 px is 10.14x max(width, height)"), std::string::npos) << why;
  c.params[1] = 71.0;  // 0.0986x
  EXPECT_TRUE(c.HasBogusParams(0.1, 10.0, 1.0));
  c.params[1] = 73.0;  // 0.101x
  EXPECT_FALSE(c.HasBogusParams(0.1, 10.0, 1.0));
  c.model_id = static_cast<int>(CameraModelId::kSimpleRadial);
  c.params = {350.0, 360.0, 270.0, -0.2};
  EXPECT_FALSE(c.HasBogusParams(0.1, 10.0, 1.0));
  c.params[3] = -1.2;
  EXPECT_TRUE(c.HasBogusParams(0.1, 10.0, 1.0, &why));
  EXPECT_NE(why.find("extra parameter 0 = -1.2"), std::string::npos) << why;
  EXPECT_FALSE(c.HasBogusParams(0.1, 10.0, 1.5));
}

TEST(CameraModels, FromRigCalibrationShiftsPrincipalPointByHalfAPixel) {
  CameraModel model;
  model.width = 720;
  model.height = 540;
  model.fx = 350;
  model.fy = 351;
  model.cx = 360;
  model.cy = 270;
  model.distortion = DistortionModel::kEquidistant;
  model.distortion_coeffs = {0.1, -0.02, 0.003, -0.0004};
  const Camera camera = CameraFromCameraModel(model, 7);
  EXPECT_EQ(camera.camera_id, 7u);
  EXPECT_EQ(camera.ModelName(), "OPENCV_FISHEYE");
  EXPECT_TRUE(camera.has_prior_focal_length);
  ASSERT_EQ(camera.params.size(), 8u);
  EXPECT_EQ(camera.params[2], 360.5);
  EXPECT_EQ(camera.params[3], 270.5);
  EXPECT_EQ(camera.params[7], -0.0004);
  model.distortion = DistortionModel::kRadtan;
  EXPECT_EQ(CameraFromCameraModel(model, 1).ModelName(), "OPENCV");
  model.distortion = DistortionModel::kNone;
  model.distortion_coeffs.clear();
  EXPECT_EQ(CameraFromCameraModel(model, 1).ModelName(), "PINHOLE");
  model.distortion = DistortionModel::kRadtan;
  EXPECT_THROW(CameraFromCameraModel(model, 1), InputError);
}

// The rig calibration's cameras (core/camera_model.h) and the COLMAP cameras
// made from them evaluate the same model maths: identical pixels up to the
// 0.5 px shift of the principal point, and identical rays back.
TEST(CameraModels, RigCameraAndColmapCameraGiveTheSamePixels) {
  CameraModel fisheye;  // HILTI 2022 cam0
  fisheye.width = 720;
  fisheye.height = 540;
  fisheye.fx = 351.31400364193297;
  fisheye.fy = 351.4911744656785;
  fisheye.cx = 367.8522793375995;
  fisheye.cy = 253.8402144980996;
  fisheye.distortion = DistortionModel::kEquidistant;
  fisheye.distortion_coeffs = {
      -0.03696737352869157, -0.008917880497032812, 0.008912969593422046, -0.0037685977496087313};
  CameraModel radtan;  // EuRoC cam0
  radtan.width = 752;
  radtan.height = 480;
  radtan.fx = 458.654;
  radtan.fy = 457.296;
  radtan.cx = 367.215;
  radtan.cy = 248.375;
  radtan.distortion = DistortionModel::kRadtan;
  radtan.distortion_coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  CameraModel pinhole = radtan;
  pinhole.distortion = DistortionModel::kNone;
  pinhole.distortion_coeffs.clear();

  std::uniform_real_distribution<double> uv(-0.8, 0.8), depth(0.5, 20.0);
  for (const CameraModel& model : {pinhole, radtan, fisheye}) {
    const Camera camera = CameraFromCameraModel(model, 1);
    EXPECT_EQ(camera.model_id, static_cast<int>(model.ModelId()));
    int num_compared = 0;
    for (int i = 0; i < 300; ++i) {
      const double z = depth(test::Rng());
      const Vec3 x_in_cam(uv(test::Rng()) * z, uv(test::Rng()) * z, z);
      Vec2 rig_pixel;
      if (!model.Project(x_in_cam, &rig_pixel, /*check_bounds=*/true)) continue;
      Vec2 colmap_pixel;
      ASSERT_TRUE(camera.Project(x_in_cam, &colmap_pixel));
      // Same formulas; only the rounding of cx + 0.5 and, for the fisheye,
      // of atan2(r, z) vs atan(r / z) differ: ~1e-13 px at pixels ~1e3.
      EXPECT_NEAR(colmap_pixel.x(), rig_pixel.x() + 0.5, 1e-10)
          << DistortionModelName(model.distortion) << " " << x_in_cam.transpose();
      EXPECT_NEAR(colmap_pixel.y(), rig_pixel.y() + 0.5, 1e-10)
          << DistortionModelName(model.distortion) << " " << x_in_cam.transpose();
      // Newton stops at 1e-10 in normalised units: rays agree far below that.
      EXPECT_LT((camera.Unproject(colmap_pixel) - model.Unproject(rig_pixel)).norm(), 1e-12)
          << DistortionModelName(model.distortion) << " " << rig_pixel.transpose();
      ++num_compared;
    }
    EXPECT_GT(num_compared, 100) << DistortionModelName(model.distortion);
  }
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
