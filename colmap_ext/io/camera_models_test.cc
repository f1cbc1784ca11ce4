#include "colmap_ext/io/camera_models.h"

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

}  // namespace
}  // namespace colmap
}  // namespace lisfm
