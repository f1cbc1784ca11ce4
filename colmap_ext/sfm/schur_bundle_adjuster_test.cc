#include "colmap_ext/sfm/schur_bundle_adjuster.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include "colmap_ext/sfm/camera_model_functors.h"
#include "core/camera_models.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

// Parameters of every model (640 x 480 image), distortion in the regime where
// each term shows up in pixels.
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
      {8, {300, 320, 240, 0.05}},
      {9, {300, 320, 240, 0.05, -0.01}},
      {10, {300, 305, 320, 240, 0.05, -0.01, 0.001, -0.002, 0.003, -0.001, 0.0005, -0.0004}},
  };
}

// The Schur solver's hand-written Jacobians of an observation (perspective
// division, rotation tangent q <- Exp(dtheta) q, cam_from_rig, point) against
// automatic differentiation of ReprojectionErrorFunctor, i.e. the templated
// camera model evaluated with Jets end to end: every model, free intrinsics
// all or a subset.
TEST(SchurBundleAdjuster, ObservationJacobiansMatchAutodiff) {
  const SE3 rig_from_world = test::RandomPose(0.5, 1.0);
  const SE3 cam_from_rig = test::RandomPose(0.3, 0.2);
  const SE3 cam_from_world = cam_from_rig * rig_from_world;
  const std::vector<Vec3> points_in_cam = {
      Vec3(0.4, -0.3, 3.0), Vec3(-0.9, 0.5, 2.0), Vec3(0.05, 0.02, 5.0)};
  for (const auto& [model_id, params] : AllModels()) {
    for (const bool all_free : {true, false}) {
      SchurBaProblem problem;
      SchurBaFrame frame;
      frame.rig_from_world_rotation = rig_from_world.rotation();
      frame.rig_from_world_translation = rig_from_world.translation();
      problem.frames.push_back(frame);
      SchurBaCamera camera;
      camera.model_id = model_id;
      camera.params = params;
      for (int i = 0; i < static_cast<int>(params.size()); ++i) {
        if (all_free || i % 2 == 1) camera.free_indices.push_back(i);
      }
      camera.cam_from_rig_rotation = cam_from_rig.rotation().toRotationMatrix();
      camera.cam_from_rig_translation = cam_from_rig.translation();
      problem.cameras.push_back(camera);
      for (size_t p = 0; p < points_in_cam.size(); ++p) {
        problem.points.push_back(cam_from_world.Inverse() * points_in_cam[p]);
        SchurBaObservation o;
        o.point = static_cast<int>(p);
        o.observed = Vec2(300.0, 250.0);
        problem.observations.push_back(o);
      }

      VisitCameraModel(model_id, [&, &params = params](auto model) {
        using Model = decltype(model);
        constexpr int N = Model::kNumParams;
        // Inputs: dtheta (3), dt (3), dx (3), camera parameters (N).
        using J = ceres::Jet<double, 9 + N>;
        const ReprojectionErrorFunctor<Model> functor(
            Vec2(300.0, 250.0), cam_from_rig.rotation(), cam_from_rig.translation());
        for (size_t p = 0; p < points_in_cam.size(); ++p) {
          // Exp(dtheta) = (1, dtheta / 2) to first order.
          const Eigen::Quaternion<J> dq(J(1.0), J(0.0, 0) * 0.5, J(0.0, 1) * 0.5, J(0.0, 2) * 0.5);
          const Eigen::Quaternion<J> q = dq * rig_from_world.rotation().cast<J>();
          J t[3], x[3], param_jets[N], residual[2];
          for (int i = 0; i < 3; ++i) {
            t[i] = J(rig_from_world.translation()[i], 3 + i);
            x[i] = J(problem.points[p][i], 6 + i);
          }
          for (int i = 0; i < N; ++i) param_jets[i] = J(params[i], 9 + i);
          ASSERT_TRUE(functor(q.coeffs().data(), t, x, param_jets, residual));

          const SchurBaObservationLinearisation lin =
              LineariseSchurBaObservation(problem, static_cast<int>(p));
          for (int r = 0; r < 2; ++r) {
            // Same maths, evaluated in a different order: rounding only.
            EXPECT_NEAR(lin.residual[r], residual[r].a, 1e-9) << Model::kName;
            const auto expect_near = [&](double actual, int column, const char* what) {
              const double expected = residual[r].v[column];
              EXPECT_NEAR(actual, expected, 1e-9 * std::max(1.0, std::abs(expected)))
                  << Model::kName << " point " << p << " row " << r << " " << what << " column "
                  << column;
            };
            for (int c = 0; c < 6; ++c) expect_near(lin.d_frame(r, c), c, "frame");
            for (int c = 0; c < 3; ++c) expect_near(lin.d_point(r, c), 6 + c, "point");
            ASSERT_EQ(lin.d_free_params.cols(), static_cast<int>(camera.free_indices.size()));
            for (size_t k = 0; k < camera.free_indices.size(); ++k) {
              expect_near(lin.d_free_params(r, k), 9 + camera.free_indices[k], "params");
            }
          }
        }
      });
    }
  }
}

TEST(SchurBundleAdjuster, LineariseRejectsABadIndex) {
  SchurBaProblem problem;
  EXPECT_THROW(LineariseSchurBaObservation(problem, 0), InternalError);
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
