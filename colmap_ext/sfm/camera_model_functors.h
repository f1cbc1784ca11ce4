// The reprojection cost functors of bundle adjustment (bundle_adjustment.h)
// and the helpers around them, on the camera models of core/camera_models.h:
// each functor takes a model struct (e.g. OpenCVCameraModel; dispatch a
// runtime id with VisitCameraModel) and evaluates its templated
// Model::ImgFromCam with ceres::Jet, so the projection, distortion and their
// Jacobians are the same formulas as Camera::Project (COLMAP 3.8's, for the
// normalised image plane (u, v) = (X/Z, Y/Z) -> COLMAP pixel). Parameters are
// in COLMAP's order (camera_models.h).
//
// Frames: poses are target_from_source with unit Hamilton quaternions stored in
// Eigen's coefficient order (x, y, z, w) -- the layout of
// ceres::EigenQuaternionManifold -- plus a translation.
#pragma once

#include <ceres/autodiff_cost_function.h>
#include <ceres/jet.h>
#include <ceres/sized_cost_function.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <utility>
#include <vector>

#include "colmap_ext/io/camera_models.h"
#include "core/camera_models.h"
#include "core/errors.h"
#include "core/geometry.h"

// Forces every call inside the marked function to be inlined into it (GCC,
// Clang; nothing elsewhere).
#if defined(__GNUC__)
#define LISFM_FLATTEN __attribute__((flatten))
#else
#define LISFM_FLATTEN
#endif

namespace lisfm {
namespace colmap {

// Camera frame -> pixel for a runtime model id (templated over the scalar).
// Returns false for points with z <= 0, like Camera::Project.
template <typename T>
bool ProjectT(int model_id, const T* params, const T* x_in_cam, T* pixel) {
  if (!(x_in_cam[2] > T(0.0))) return false;
  const T u = x_in_cam[0] / x_in_cam[2];
  const T v = x_in_cam[1] / x_in_cam[2];
  VisitCameraModel(model_id, [&](auto model) {
    decltype(model)::ImgFromCam(params, u, v, &pixel[0], &pixel[1]);
    return 0;
  });
  return true;
}

// Indices of the focal length(s), principal point and extra parameters of a
// model (for holding subsets of the intrinsics constant).
struct CameraParamGroups {
  std::vector<int> focal;
  std::vector<int> principal_point;
  std::vector<int> extra;
};
inline CameraParamGroups CameraModelParamGroups(int model_id) {
  return VisitCameraModel(model_id, [](auto model) {
    using Model = decltype(model);
    CameraParamGroups groups;
    const int num_focal = Model::kNumFocalParams;
    for (int i = 0; i < num_focal; ++i) groups.focal.push_back(i);
    groups.principal_point = {num_focal, num_focal + 1};
    for (int i = Model::ExtraParamsIndex(); i < Model::kNumParams; ++i) {
      groups.extra.push_back(i);
    }
    return groups;
  });
}

// Reprojection error of one observation, residual = Project(cam_from_world *
// X) - observed (pixels), with cam_from_world = cam_from_rig * rig_from_world.
// Parameter blocks: rig_from_world rotation (4, Eigen xyzw), rig_from_world
// translation (3), point in world (3), camera parameters (kNumParams).
// `cam_from_rig` is held as a constant of the functor (identity without a
// rig). As in COLMAP's ReprojectionError there is no cheirality test here (a
// failed evaluation at the initial point would abort the solve); triangulation
// and filtering keep points in front of the cameras.
template <typename Model>
struct ReprojectionErrorFunctor {
  ReprojectionErrorFunctor(const Eigen::Vector2d& observed,
                           const Eigen::Quaterniond& cam_from_rig_rotation,
                           const Eigen::Vector3d& cam_from_rig_translation)
      : observed_(observed),
        cam_from_rig_rotation_(cam_from_rig_rotation),
        cam_from_rig_translation_(cam_from_rig_translation) {}

  static ceres::CostFunction* Create(
      const Eigen::Vector2d& observed,
      const Eigen::Quaterniond& cam_from_rig_rotation,
      const Eigen::Vector3d& cam_from_rig_translation) {
    return new ceres::AutoDiffCostFunction<ReprojectionErrorFunctor,
                                           2,
                                           4,
                                           3,
                                           3,
                                           Model::kNumParams>(
        new ReprojectionErrorFunctor(
            observed, cam_from_rig_rotation, cam_from_rig_translation));
  }

  template <typename T>
  bool operator()(const T* rig_from_world_q,
                  const T* rig_from_world_t,
                  const T* point,
                  const T* params,
                  T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(rig_from_world_q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(rig_from_world_t);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> x(point);
    const Eigen::Matrix<T, 3, 1> x_in_rig = q * x + t;
    const Eigen::Matrix<T, 3, 1> x_in_cam =
        cam_from_rig_rotation_.cast<T>() * x_in_rig +
        cam_from_rig_translation_.cast<T>();
    return Residual(x_in_cam, params, residual);
  }

  template <typename T>
  bool Residual(const Eigen::Matrix<T, 3, 1>& x_in_cam,
                const T* params,
                T* residual) const {
    T px, py;
    Model::ImgFromCam(
        params, x_in_cam[0] / x_in_cam[2], x_in_cam[1] / x_in_cam[2], &px, &py);
    residual[0] = px - T(observed_.x());
    residual[1] = py - T(observed_.y());
    return true;
  }

 private:
  Eigen::Vector2d observed_;
  Eigen::Quaterniond cam_from_rig_rotation_;
  Eigen::Vector3d cam_from_rig_translation_;
};

// Pixel of the normalised image point (u, v) = (x/z, y/z) of camera-frame point
// x_in_cam, with d pixel / d x_in_cam (2x3) and d pixel / d params (2 x
// kNumParams, row-major) when those are non-null. Only Model::ImgFromCam goes
// through Jets (2 + kNumParams inputs); the perspective division is
// differentiated by hand. No check of z > 0 (callers decide).
// Runs once per observation in triangulation and the Schur bundle adjuster,
// inside visitors over all models: LISFM_FLATTEN keeps the Jet arithmetic
// (Ceres' Eigen kernels) inlined here, which GCC otherwise leaves as calls in
// such large visitor functions (2x the instructions).
template <typename Model>
LISFM_FLATTEN inline void ProjectWithJacobians(const double* params,
                                               const Eigen::Vector3d& x_in_cam,
                                               Eigen::Vector2d* pixel,
                                               Eigen::Matrix<double, 2, 3>* d_pixel_d_cam,
                                               double* d_pixel_d_params) {
  constexpr int N = Model::kNumParams;
  const double inv_z = 1.0 / x_in_cam.z();
  const double u = x_in_cam.x() * inv_z;
  const double v = x_in_cam.y() * inv_z;
  if (d_pixel_d_cam == nullptr && d_pixel_d_params == nullptr) {
    Model::ImgFromCam(params, u, v, &pixel->x(), &pixel->y());
    return;
  }
  using J = ceres::Jet<double, 2 + N>;
  J params_jet[N];
  for (int i = 0; i < N; ++i) params_jet[i] = J(params[i], 2 + i);
  J px, py;
  Model::ImgFromCam(params_jet, J(u, 0), J(v, 1), &px, &py);
  *pixel = Eigen::Vector2d(px.a, py.a);
  if (d_pixel_d_cam != nullptr) {
    Eigen::Matrix<double, 2, 2> d_pixel_d_uv;
    d_pixel_d_uv << px.v[0], px.v[1], py.v[0], py.v[1];
    Eigen::Matrix<double, 2, 3> d_uv_d_cam;
    d_uv_d_cam << inv_z, 0.0, -u * inv_z, 0.0, inv_z, -v * inv_z;
    *d_pixel_d_cam = d_pixel_d_uv * d_uv_d_cam;
  }
  if (d_pixel_d_params != nullptr) {
    for (int i = 0; i < N; ++i) {
      d_pixel_d_params[i] = px.v[2 + i];
      d_pixel_d_params[N + i] = py.v[2 + i];
    }
  }
}

// The residual of ReprojectionErrorFunctor (same parameter blocks:
// rig_from_world rotation (x, y, z, w), translation, point, camera parameters;
// cam_from_rig fixed) with analytic Jacobians for the pose and the point; only
// the small distortion part (2 + kNumParams inputs) goes through Ceres' Jets.
// About 3x cheaper than the all-Jet<14> functor, which dominated bundle
// adjustment. Rotation Jacobian: for unit q = (v, w), R(q) X = X + 2 w (v x X)
// + 2 v x (v x X), so d/dw = 2 v x X and d/dv = -2 w [X]x + 2 ((v.X) I + v X^T
// - 2 X v^T); along the unit sphere (the quaternion manifold's tangent space)
// this equals the derivative of q.toRotationMatrix() * X.
template <typename Model>
class AnalyticReprojectionCost
    : public ceres::SizedCostFunction<2, 4, 3, 3, Model::kNumParams> {
 public:
  AnalyticReprojectionCost(const Eigen::Vector2d& observed,
                           const Eigen::Quaterniond& cam_from_rig_rotation,
                           const Eigen::Vector3d& cam_from_rig_translation)
      : observed_(observed),
        cam_from_rig_rotation_(cam_from_rig_rotation.normalized().toRotationMatrix()),
        cam_from_rig_translation_(cam_from_rig_translation) {}

  bool Evaluate(double const* const* parameters,
                double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Eigen::Quaterniond> q(parameters[0]);
    const Eigen::Map<const Eigen::Vector3d> t(parameters[1]);
    const Eigen::Map<const Eigen::Vector3d> x(parameters[2]);
    const double* params = parameters[3];
    const Eigen::Matrix3d R = q.toRotationMatrix();
    const Eigen::Vector3d x_in_cam =
        cam_from_rig_rotation_ * (R * x + t) + cam_from_rig_translation_;
    Eigen::Vector2d pixel;
    if (jacobians == nullptr) {
      ProjectWithJacobians<Model>(params, x_in_cam, &pixel, nullptr, nullptr);
      residuals[0] = pixel.x() - observed_.x();
      residuals[1] = pixel.y() - observed_.y();
      return true;
    }
    Eigen::Matrix<double, 2, 3> d_pixel_d_cam;
    ProjectWithJacobians<Model>(params, x_in_cam, &pixel, &d_pixel_d_cam,
                                jacobians[3]);
    residuals[0] = pixel.x() - observed_.x();
    residuals[1] = pixel.y() - observed_.y();
    // d pixel / d x_in_rig.
    const Eigen::Matrix<double, 2, 3> d_rig = d_pixel_d_cam * cam_from_rig_rotation_;
    if (jacobians[0] != nullptr) {
      const Eigen::Vector3d qv(q.x(), q.y(), q.z());
      const double qw = q.w();
      const Eigen::Vector3d v_cross_x = qv.cross(x);
      Eigen::Matrix<double, 3, 4> d_rx_d_q;
      d_rx_d_q.leftCols<3>() =
          -2.0 * qw * Hat(x) +
          2.0 * (qv.dot(x) * Eigen::Matrix3d::Identity() + qv * x.transpose() -
                 2.0 * x * qv.transpose());
      d_rx_d_q.col(3) = 2.0 * v_cross_x;
      Eigen::Map<Eigen::Matrix<double, 2, 4, Eigen::RowMajor>> j_q(jacobians[0]);
      j_q = d_rig * d_rx_d_q;
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> j_t(jacobians[1]);
      j_t = d_rig;
    }
    if (jacobians[2] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> j_x(jacobians[2]);
      j_x = d_rig * R;
    }
    return true;
  }

 private:
  Eigen::Vector2d observed_;
  Eigen::Matrix3d cam_from_rig_rotation_;
  Eigen::Vector3d cam_from_rig_translation_;
};

// As ReprojectionErrorFunctor, with cam_from_rig as parameters (refined):
// blocks cam_from_rig rotation (4), cam_from_rig translation (3),
// rig_from_world rotation (4), rig_from_world translation (3), point (3),
// camera parameters (kNumParams).
template <typename Model>
struct RigReprojectionErrorFunctor {
  explicit RigReprojectionErrorFunctor(const Eigen::Vector2d& observed)
      : base_(
            observed, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()) {
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& observed) {
    return new ceres::AutoDiffCostFunction<RigReprojectionErrorFunctor,
                                           2,
                                           4,
                                           3,
                                           4,
                                           3,
                                           3,
                                           Model::kNumParams>(
        new RigReprojectionErrorFunctor(observed));
  }

  template <typename T>
  bool operator()(const T* cam_from_rig_q,
                  const T* cam_from_rig_t,
                  const T* rig_from_world_q,
                  const T* rig_from_world_t,
                  const T* point,
                  const T* params,
                  T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_cr(cam_from_rig_q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_cr(cam_from_rig_t);
    const Eigen::Map<const Eigen::Quaternion<T>> q_rw(rig_from_world_q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_rw(rig_from_world_t);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> x(point);
    const Eigen::Matrix<T, 3, 1> x_in_cam = q_cr * (q_rw * x + t_rw) + t_cr;
    return base_.Residual(x_in_cam, params, residual);
  }

 private:
  ReprojectionErrorFunctor<Model> base_;
};

}  // namespace colmap
}  // namespace lisfm
