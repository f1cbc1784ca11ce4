#include "core/camera_models.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// Parameters for every model (640 x 480 image) with distortion large enough
// that a wrong term shows up in pixels; FOV also with omega^2 < 1e-4 (its
// small-omega series).
std::vector<std::pair<int, std::vector<double>>> AllModels() {
  return {
      {0, {500, 320, 240}},
      {1, {510, 490, 321, 239}},
      {2, {500, 320, 240, -0.1}},
      {3, {500, 320, 240, -0.1, 0.02}},
      {4, {510, 490, 320, 240, -0.2, 0.05, 0.001, -0.002}},
      {5, {300, 305, 320, 240, 0.05, -0.01, 0.003, -0.001}},
      {6, {510, 490, 320, 240, -0.2, 0.05, 0.001, -0.002, 0.01, 0.02, 0.003, 0.001}},
      {7, {500, 505, 320, 240, 0.9}},
      {7, {500, 505, 320, 240, 0.005}},
      {8, {300, 320, 240, 0.05}},
      {9, {300, 320, 240, 0.05, -0.01}},
      {10, {300, 305, 320, 240, 0.05, -0.01, 0.001, -0.002, 0.003, -0.001, 0.0005, -0.0004}},
  };
}

// Points in front of the camera within about +-30 degrees, the optical axis,
// a point next to it (below the fisheye models' epsilon radius) and one with
// r^2 < 1e-4 (the FOV model's small-radius series).
std::vector<Vec3> TestPoints() {
  std::uniform_real_distribution<double> uv(-0.6, 0.6), depth(1.0, 5.0);
  std::vector<Vec3> points;
  for (int i = 0; i < 20; ++i) {
    const double z = depth(test::Rng());
    points.emplace_back(uv(test::Rng()) * z, uv(test::Rng()) * z, z);
  }
  points.emplace_back(0.0, 0.0, 2.0);
  points.emplace_back(1e-17, -2e-17, 2.0);
  points.emplace_back(3e-3, 2e-3, 1.0);
  return points;
}

// Pixel of camera-frame point X: Model::ImgFromCam of (X/Z, Y/Z).
template <typename Model, typename T>
Eigen::Matrix<T, 2, 1> Pixel(const T* params, const T* x_in_cam) {
  Eigen::Matrix<T, 2, 1> pixel;
  Model::ImgFromCam(
      params, x_in_cam[0] / x_in_cam[2], x_in_cam[1] / x_in_cam[2], &pixel[0], &pixel[1]);
  return pixel;
}

// The templates evaluated with ceres::Jet (forward-mode derivatives w.r.t. the
// point and every parameter) agree with central differences of the same
// templates evaluated with doubles, for every model, and the Jet's value is the
// double result.
TEST(CameraModels, JetJacobiansMatchCentralDifferencesForEveryModel) {
  for (const auto& [model_id, params] : AllModels()) {
    VisitCameraModel(model_id, [&, &params = params](auto model) {
      using Model = decltype(model);
      constexpr int N = Model::kNumParams;
      ASSERT_EQ(static_cast<int>(params.size()), N);
      using J = ceres::Jet<double, 3 + N>;
      for (const Vec3& x : TestPoints()) {
        J x_jet[3], params_jet[N];
        for (int i = 0; i < 3; ++i) x_jet[i] = J(x[i], i);
        for (int i = 0; i < N; ++i) params_jet[i] = J(params[i], 3 + i);
        const Eigen::Matrix<J, 2, 1> pixel_jet = Pixel<Model>(params_jet, x_jet);
        const Vec2 pixel = Pixel<Model>(params.data(), x.data());
        // Jets divide as a * (1 / b): a few ulps of pixels ~1e3.
        EXPECT_NEAR(pixel_jet[0].a, pixel.x(), 1e-10) << Model::kName;
        EXPECT_NEAR(pixel_jet[1].a, pixel.y(), 1e-10) << Model::kName;
        MatX jet_jacobian(2, 3 + N);
        for (int r = 0; r < 2; ++r) jet_jacobian.row(r) = pixel_jet[r].v.transpose();

        VecX x0(3 + N);
        x0 << x, Eigen::Map<const VecX>(params.data(), N);
        const MatX numeric = test::NumericJacobian(
            [](const VecX& v) -> VecX { return Pixel<Model>(v.data() + 3, v.data()); }, x0);
        // Central differences with step 1e-6 on pixels ~1e3: rounding
        // ~1e-13 / 1e-6 = 1e-7 px per unit, truncation ~1e-12 |f'''|; a
        // missing or wrong term of any model is >= 1e-3 here.
        for (int r = 0; r < 2; ++r) {
          for (int c = 0; c < 3 + N; ++c) {
            EXPECT_NEAR(
                jet_jacobian(r, c), numeric(r, c), 1e-6 * std::max(1.0, std::abs(numeric(r, c))))
                << Model::kName << " params " << params.back() << " point " << x.transpose()
                << " row " << r << " column " << c;
          }
        }
      }
    });
  }
}

// CamFromImg inverts ImgFromCam (iterative undistortion) for every model.
TEST(CameraModels, CamFromImgInvertsImgFromCamForEveryModel) {
  for (const auto& [model_id, params] : AllModels()) {
    VisitCameraModel(model_id, [&, &params = params](auto model) {
      using Model = decltype(model);
      for (const Vec3& x : TestPoints()) {
        const Vec2 normalized = x.head<2>() / x.z();
        const Vec2 pixel = Pixel<Model>(params.data(), x.data());
        Vec2 back;
        EXPECT_TRUE(Model::CamFromImg(params.data(), pixel.x(), pixel.y(), &back.x(), &back.y()))
            << Model::kName;
        // Newton converges to a residual < 1e-10 (kMaxUndistortionResidual);
        // in practice to rounding.
        EXPECT_LT((back - normalized).norm(), 1e-10) << Model::kName << " " << x.transpose();
      }
    });
  }
}

TEST(CameraModels, FisheyeRaysBeyondNinetyDegrees) {
  const std::vector<double> params = {300, 305, 320, 240, 0.05, -0.01, 0.003, -0.001};
  using Model = OpenCVFisheyeCameraModel;
  const double theta = 100.0 * M_PI / 180.0;
  const Vec3 ray(std::sin(theta) * 0.6, std::sin(theta) * 0.8, std::cos(theta));
  double a, b;
  EXPECT_DOUBLE_EQ(Model::FisheyeFromRay(ray.x(), ray.y(), ray.z(), &a, &b), theta);
  EXPECT_NEAR(std::hypot(a, b), theta, 1e-15);
  Vec2 pixel;
  Model::ImgFromUndistorted(params.data(), a, b, &pixel.x(), &pixel.y());
  // theta_d = theta (1 + k1 theta^2 + ...), along the azimuth (0.6, 0.8).
  const double t2 = theta * theta;
  const double theta_d =
      theta * (1 + 0.05 * t2 - 0.01 * t2 * t2 + 0.003 * std::pow(t2, 3) - 0.001 * std::pow(t2, 4));
  EXPECT_NEAR(pixel.x(), 300 * 0.6 * theta_d + 320, 1e-9);
  EXPECT_NEAR(pixel.y(), 305 * 0.8 * theta_d + 240, 1e-9);
  // Back to the ray through the equidistant plane ...
  double a2, b2;
  EXPECT_LT(Model::UndistortedFromImg(params.data(), pixel.x(), pixel.y(), &a2, &b2),
            kMaxUndistortionResidual);
  Vec3 back;
  Model::RayFromFisheye(a2, b2, &back.x(), &back.y(), &back.z());
  EXPECT_LT((back - ray).norm(), 1e-10);
  // ... but not to the normalised image plane (the ray is behind z = 0).
  double u, v;
  EXPECT_FALSE(Model::CamFromImg(params.data(), pixel.x(), pixel.y(), &u, &v));
  EXPECT_TRUE(std::isnan(u) && std::isnan(v));
}

TEST(CameraModels, PinholeModelsAreExact) {
  const double params[] = {500, 510, 320.5, 240.5};
  double x, y;
  PinholeCameraModel::ImgFromCam(params, 0.1, -0.05, &x, &y);
  EXPECT_EQ(x, 500 * 0.1 + 320.5);
  EXPECT_EQ(y, 510 * -0.05 + 240.5);
  double u, v;
  EXPECT_TRUE(PinholeCameraModel::CamFromImg(params, x, y, &u, &v));
  EXPECT_EQ(u, (x - 320.5) / 500);
  EXPECT_EQ(v, (y - 240.5) / 510);
}

TEST(CameraModels, IdsNamesAndParameterGroups) {
  for (int id = 0; id < kNumCameraModels; ++id) {
    VisitCameraModel(id, [&](auto model) {
      using Model = decltype(model);
      EXPECT_EQ(static_cast<int>(Model::kModelId), id);
      // The parameter list names one entry per parameter: f or fx, fy; cx, cy.
      const std::string info = Model::kParamsInfo;
      EXPECT_EQ(static_cast<int>(std::count(info.begin(), info.end(), ',')) + 1, Model::kNumParams)
          << Model::kName;
      EXPECT_EQ(info.rfind(Model::kNumFocalParams == 1 ? "f, cx, cy" : "fx, fy, cx, cy", 0), 0u)
          << Model::kName;
      EXPECT_EQ(Model::ExtraParamsIndex(), Model::kNumFocalParams + 2);
    });
  }
  EXPECT_THROW(VisitCameraModel(11, [](auto) { return 0; }), InternalError);
  EXPECT_THROW(VisitCameraModel(-1, [](auto) { return 0; }), InternalError);
}

}  // namespace
}  // namespace lisfm
