#include "colmap_ext/sfm/camera_model_functors.h"

#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <random>
#include <vector>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

// Realistic parameters for every COLMAP model (640 x 480 image), including
// distortion large enough that a wrong term shows up in pixels.
std::vector<Camera> AllModelCameras() {
  const std::vector<std::pair<CameraModelId, std::vector<double>>> specs = {
      {CameraModelId::kSimplePinhole, {500, 320, 240}},
      {CameraModelId::kPinhole, {510, 490, 321, 239}},
      {CameraModelId::kSimpleRadial, {500, 320, 240, -0.1}},
      {CameraModelId::kRadial, {500, 320, 240, -0.1, 0.02}},
      {CameraModelId::kOpenCV, {510, 490, 320, 240, -0.2, 0.05, 0.001, -0.002}},
      {CameraModelId::kOpenCVFisheye,
       {300, 305, 320, 240, 0.05, -0.01, 0.003, -0.001}},
      {CameraModelId::kFullOpenCV,
       {510,
        490,
        320,
        240,
        -0.2,
        0.05,
        0.001,
        -0.002,
        0.01,
        0.02,
        0.003,
        0.001}},
      {CameraModelId::kFOV, {500, 505, 320, 240, 0.9}},
      // omega^2 < 1e-4: the small-omega series branch of the FOV model.
      {CameraModelId::kFOV, {500, 505, 320, 240, 0.005}},
      {CameraModelId::kSimpleRadialFisheye, {300, 320, 240, 0.05}},
      {CameraModelId::kRadialFisheye, {300, 320, 240, 0.05, -0.01}},
      {CameraModelId::kThinPrismFisheye,
       {300,
        305,
        320,
        240,
        0.05,
        -0.01,
        0.001,
        -0.002,
        0.003,
        -0.001,
        0.0005,
        -0.0004}},
  };
  std::vector<Camera> cameras;
  for (size_t i = 0; i < specs.size(); ++i) {
    Camera camera;
    camera.camera_id = static_cast<camera_t>(i + 1);
    camera.model_id = static_cast<int>(specs[i].first);
    camera.width = 640;
    camera.height = 480;
    camera.params = specs[i].second;
    EXPECT_TRUE(camera.VerifyParams()) << camera.ModelName();
    cameras.push_back(camera);
  }
  return cameras;
}

// Points in front of the camera within about +-60 degrees, plus the optical
// axis and points next to it (the small-radius branches of the models).
std::vector<Vec3> TestPoints() {
  std::uniform_real_distribution<double> uv(-0.6, 0.6), depth(1.0, 10.0);
  std::vector<Vec3> points;
  for (int i = 0; i < 50; ++i) {
    const double z = depth(test::Rng());
    points.emplace_back(uv(test::Rng()) * z, uv(test::Rng()) * z, z);
  }
  points.emplace_back(0.0, 0.0, 2.0);
  points.emplace_back(1e-9, -2e-9, 2.0);
  points.emplace_back(
      3e-3, 2e-3, 1.0);  // radius^2 < 1e-4 (FOV small-radius branch)
  return points;
}

TEST(CameraModelFunctors, ProjectMatchesCameraProjectForEveryModel) {
  const std::vector<Camera> cameras = AllModelCameras();
  ASSERT_EQ(cameras.size(), 12u);
  for (const Camera& camera : cameras) {
    for (const Vec3& x : TestPoints()) {
      Vec2 expected;
      ASSERT_TRUE(camera.Project(x, &expected));
      Vec2 actual;
      ASSERT_TRUE(ProjectT(
          camera.model_id, camera.params.data(), x.data(), actual.data()));
      // Same formulas evaluated in double: only rounding differs (pixel values
      // ~1e3, relative rounding ~1e-16 per operation).
      EXPECT_NEAR(actual.x(), expected.x(), 1e-9)
          << camera.ModelName() << " " << x.transpose();
      EXPECT_NEAR(actual.y(), expected.y(), 1e-9)
          << camera.ModelName() << " " << x.transpose();
    }
    Vec2 pixel;
    const Vec3 behind(0.1, 0.2, -1.0);
    EXPECT_FALSE(ProjectT(
        camera.model_id, camera.params.data(), behind.data(), pixel.data()));
  }
}

// The analytic cost that bundle adjustment uses equals the autodiff functor:
// residuals and all four Jacobian blocks, for every model (1e-9 relative).
TEST(CameraModelFunctors, AnalyticReprojectionCostMatchesAutodiff) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (const Camera& camera : AllModelCameras()) {
    VisitCameraModel(camera.model_id, [&](auto model) {
      using Model = decltype(model);
      constexpr int N = Model::kNumParams;
      for (int trial = 0; trial < 5; ++trial) {
        Eigen::Quaterniond q(uni(rng), uni(rng), uni(rng), 1.5);
        q.normalize();
        const Eigen::Vector3d t(0.2 * uni(rng), 0.2 * uni(rng), 0.1 * uni(rng));
        const Eigen::Quaterniond cam_from_rig_q =
            Eigen::Quaterniond(1.0, 0.05 * uni(rng), 0.05 * uni(rng), 0.05 * uni(rng)).normalized();
        const Eigen::Vector3d cam_from_rig_t(0.05, -0.02, 0.01);
        // A point in front of the camera, within the field of view.
        const Eigen::Vector3d x_in_cam(0.3 * uni(rng), 0.3 * uni(rng), 2.0 + uni(rng));
        const Eigen::Vector3d x = q.conjugate() * (cam_from_rig_q.conjugate() *
                                                       (x_in_cam - cam_from_rig_t) -
                                                   t);
        const Eigen::Vector2d observed(300.0, 250.0);
        std::unique_ptr<ceres::CostFunction> autodiff(
            ReprojectionErrorFunctor<Model>::Create(observed, cam_from_rig_q, cam_from_rig_t));
        AnalyticReprojectionCost<Model> analytic(observed, cam_from_rig_q, cam_from_rig_t);
        std::vector<double> params = camera.params;
        const double* parameters[4] = {q.coeffs().data(), t.data(), x.data(), params.data()};
        double r_a[2], r_b[2];
        std::array<std::vector<double>, 4> ja = {std::vector<double>(8), std::vector<double>(6),
                                                 std::vector<double>(6),
                                                 std::vector<double>(2 * N)};
        std::array<std::vector<double>, 4> jb = ja;
        double* jac_a[4] = {ja[0].data(), ja[1].data(), ja[2].data(), ja[3].data()};
        double* jac_b[4] = {jb[0].data(), jb[1].data(), jb[2].data(), jb[3].data()};
        EXPECT_TRUE(autodiff->Evaluate(parameters, r_a, jac_a));
        EXPECT_TRUE(analytic.Evaluate(parameters, r_b, jac_b));
        for (int i = 0; i < 2; ++i) EXPECT_NEAR(r_a[i], r_b[i], 1e-9 * (1.0 + std::abs(r_a[i])));
        for (int block = 0; block < 4; ++block) {
          for (size_t i = 0; i < ja[block].size(); ++i) {
            EXPECT_NEAR(ja[block][i], jb[block][i], 1e-9 * (1.0 + std::abs(ja[block][i])))
                << camera.ModelName() << " block " << block << " entry " << i;
          }
        }
        // Residual only (no Jacobians) gives the same value.
        double r_c[2];
        EXPECT_TRUE(analytic.Evaluate(parameters, r_c, nullptr));
        EXPECT_NEAR(r_c[0], r_b[0], 1e-12 * (1.0 + std::abs(r_b[0])));
      }
      return 0;
    });
  }
}

TEST(CameraModelFunctors, ParamGroups) {
  const CameraParamGroups opencv =
      CameraModelParamGroups(static_cast<int>(CameraModelId::kOpenCV));
  EXPECT_EQ(opencv.focal, (std::vector<int>{0, 1}));
  EXPECT_EQ(opencv.principal_point, (std::vector<int>{2, 3}));
  EXPECT_EQ(opencv.extra, (std::vector<int>{4, 5, 6, 7}));
  const CameraParamGroups simple =
      CameraModelParamGroups(static_cast<int>(CameraModelId::kSimpleRadial));
  EXPECT_EQ(simple.focal, (std::vector<int>{0}));
  EXPECT_EQ(simple.principal_point, (std::vector<int>{1, 2}));
  EXPECT_EQ(simple.extra, (std::vector<int>{3}));
  for (int model_id = 0; model_id < kNumCameraModels; ++model_id) {
    const CameraParamGroups groups = CameraModelParamGroups(model_id);
    EXPECT_EQ(
        static_cast<int>(groups.focal.size() + groups.principal_point.size() +
                         groups.extra.size()),
        CameraModelNumParams(model_id));
  }
  EXPECT_THROW(CameraModelParamGroups(42), InternalError);
}

// Autodiff Jacobians of the reprojection cost (with and without refined
// cam_from_rig) against central differences of the same cost, every block.
TEST(CameraModelFunctors, ReprojectionJacobiansMatchNumeric) {
  const SE3 rig_from_world = test::RandomPose(0.5, 1.0);
  const SE3 cam_from_rig = test::RandomPose(0.3, 0.2);
  const SE3 cam_from_world = cam_from_rig * rig_from_world;
  for (const Camera& camera : AllModelCameras()) {
    // A point in front of the camera, off-axis.
    const Vec3 x_world = cam_from_world.Inverse() * Vec3(0.4, -0.3, 3.0);
    Vec2 observed;
    ASSERT_TRUE(camera.Project(Vec3(0.4, -0.3, 3.0), &observed));
    observed += Vec2(0.7, -0.4);  // non-zero residual
    for (bool refine_rig : {false, true}) {
      std::unique_ptr<ceres::CostFunction> cost(VisitCameraModel(
          camera.model_id, [&](auto model) -> ceres::CostFunction* {
            using Model = decltype(model);
            if (refine_rig)
              return RigReprojectionErrorFunctor<Model>::Create(observed);
            return ReprojectionErrorFunctor<Model>::Create(
                observed, cam_from_rig.rotation(), cam_from_rig.translation());
          }));
      std::vector<std::vector<double>> blocks;
      auto quat = [](const SE3& p) {
        return std::vector<double>(p.rotation().coeffs().data(),
                                   p.rotation().coeffs().data() + 4);
      };
      auto trans = [](const SE3& p) {
        return std::vector<double>(p.translation().data(),
                                   p.translation().data() + 3);
      };
      if (refine_rig) {
        blocks.push_back(quat(cam_from_rig));
        blocks.push_back(trans(cam_from_rig));
      }
      blocks.push_back(quat(rig_from_world));
      blocks.push_back(trans(rig_from_world));
      blocks.emplace_back(x_world.data(), x_world.data() + 3);
      blocks.push_back(camera.params);
      ASSERT_EQ(cost->parameter_block_sizes().size(), blocks.size());

      std::vector<const double*> ptrs;
      for (const auto& b : blocks) ptrs.push_back(b.data());
      std::vector<std::vector<double>> jac(blocks.size());
      std::vector<double*> jac_ptrs;
      for (size_t b = 0; b < blocks.size(); ++b) {
        jac[b].resize(2 * blocks[b].size());
        jac_ptrs.push_back(jac[b].data());
      }
      Vec2 residual;
      ASSERT_TRUE(
          cost->Evaluate(ptrs.data(), residual.data(), jac_ptrs.data()));
      // At the truth plus the injected offset the residual is that offset.
      EXPECT_NEAR(residual.x(), -0.7, 1e-9) << camera.ModelName();
      EXPECT_NEAR(residual.y(), 0.4, 1e-9) << camera.ModelName();

      for (size_t b = 0; b < blocks.size(); ++b) {
        const int n = static_cast<int>(blocks[b].size());
        auto f = [&](const VecX& x) -> VecX {
          std::vector<std::vector<double>> perturbed = blocks;
          for (int i = 0; i < n; ++i) perturbed[b][i] = x[i];
          std::vector<const double*> p;
          for (const auto& pb : perturbed) p.push_back(pb.data());
          VecX r(2);
          EXPECT_TRUE(cost->Evaluate(p.data(), r.data(), nullptr));
          return r;
        };
        const VecX x0 = Eigen::Map<const VecX>(blocks[b].data(), n);
        const MatX numeric = test::NumericJacobian(f, x0);
        const Eigen::Map<
            const Eigen::
                Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>
            analytic(jac[b].data(), 2, n);
        // Central differences (step 1e-6) on pixel values ~1e3: truncation
        // ~1e-12 * f''' and rounding ~1e-16 * 1e3 / 1e-6 = 1e-7 px per unit;
        // 1e-5 relative to the largest entry leaves margin for both.
        const double scale = std::max(1.0, analytic.cwiseAbs().maxCoeff());
        EXPECT_LT((analytic - numeric).cwiseAbs().maxCoeff(), 1e-5 * scale)
            << camera.ModelName() << " block " << b << " refine_rig "
            << refine_rig << "\nanalytic\n"
            << analytic << "\nnumeric\n"
            << numeric;
      }
    }
  }
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
