// Templated COLMAP camera projection for Ceres autodiff, and the reprojection
// cost functor of bundle adjustment (bundle_adjustment.h).
//
// Each `CameraModelT<kModel>` has the model's parameter count and
// `ImgFromCam(params, u, v, &x, &y)`: normalised image plane (u, v) = (X/Z,
// Y/Z)
// -> COLMAP pixel, with COLMAP 3.8's distortion formulas -- the same ones as
// camera_models.cc (Camera::ImgFromCam), written for any scalar T (double or
// ceres::Jet). Parameters are in COLMAP's order (camera_models.h). Branches on
// small radii use the same thresholds as camera_models.cc, so a double
// evaluation agrees with Camera::Project to rounding.
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
#include <limits>
#include <utility>
#include <vector>

#include "colmap_ext/io/camera_models.h"
#include "core/errors.h"
#include "core/geometry.h"

namespace lisfm {
namespace colmap {
namespace internal {

// Threshold below which the fisheye models leave the point undistorted
// (camera_models.cc uses machine epsilon as COLMAP 3.8 does).
constexpr double kFisheyeEps = std::numeric_limits<double>::epsilon();

// Equidistant (Kannala-Brandt) mapping: theta = atan(r), theta_d = theta *
// (1 + k1 theta^2 + ...), distorted point = (u, v) * theta_d / r.
template <typename T, int kNumK>
void FisheyeDistort(const T* k, const T& u, const T& v, T* du, T* dv) {
  const T r2 = u * u + v * v;
  // Compare r^2 with eps^2: sqrt of a Jet at 0 has an infinite derivative.
  if (!(r2 > T(kFisheyeEps * kFisheyeEps))) {
    *du = u;
    *dv = v;
    return;
  }
  const T r = ceres::sqrt(r2);
  const T theta = ceres::atan(r);
  const T theta2 = theta * theta;
  T poly = T(1.0);
  T power = T(1.0);
  for (int i = 0; i < kNumK; ++i) {
    power *= theta2;
    poly += k[i] * power;
  }
  const T scale = theta * poly / r;
  *du = u * scale;
  *dv = v * scale;
}

// fx, fy, cx, cy from the parameter vector; `kSingleFocal` models share f.
template <bool kSingleFocal, typename T>
void ApplyIntrinsics(const T* params, const T& du, const T& dv, T* x, T* y) {
  if (kSingleFocal) {
    *x = params[0] * du + params[1];
    *y = params[0] * dv + params[2];
  } else {
    *x = params[0] * du + params[2];
    *y = params[1] * dv + params[3];
  }
}

}  // namespace internal

template <CameraModelId kModel>
struct CameraModelT;

template <>
struct CameraModelT<CameraModelId::kSimplePinhole> {
  static constexpr int kNumParams = 3;  // f, cx, cy
  static constexpr bool kSingleFocal = true;
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    internal::ApplyIntrinsics<true>(params, u, v, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kPinhole> {
  static constexpr int kNumParams = 4;  // fx, fy, cx, cy
  static constexpr bool kSingleFocal = false;
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    internal::ApplyIntrinsics<false>(params, u, v, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kSimpleRadial> {
  static constexpr int kNumParams = 4;  // f, cx, cy, k
  static constexpr bool kSingleFocal = true;
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    const T radial = params[3] * (u * u + v * v);
    internal::ApplyIntrinsics<true>(
        params, u + u * radial, v + v * radial, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kRadial> {
  static constexpr int kNumParams = 5;  // f, cx, cy, k1, k2
  static constexpr bool kSingleFocal = true;
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    const T r2 = u * u + v * v;
    const T radial = params[3] * r2 + params[4] * r2 * r2;
    internal::ApplyIntrinsics<true>(
        params, u + u * radial, v + v * radial, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kOpenCV> {
  static constexpr int kNumParams = 8;  // fx, fy, cx, cy, k1, k2, p1, p2
  static constexpr bool kSingleFocal = false;
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    const T& k1 = params[4];
    const T& k2 = params[5];
    const T& p1 = params[6];
    const T& p2 = params[7];
    const T u2 = u * u, v2 = v * v, uv = u * v, r2 = u2 + v2;
    const T radial = k1 * r2 + k2 * r2 * r2;
    const T du = u + u * radial + T(2.0) * p1 * uv + p2 * (r2 + T(2.0) * u2);
    const T dv = v + v * radial + T(2.0) * p2 * uv + p1 * (r2 + T(2.0) * v2);
    internal::ApplyIntrinsics<false>(params, du, dv, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kOpenCVFisheye> {
  static constexpr int kNumParams = 8;  // fx, fy, cx, cy, k1, k2, k3, k4
  static constexpr bool kSingleFocal = false;
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    T du, dv;
    internal::FisheyeDistort<T, 4>(params + 4, u, v, &du, &dv);
    internal::ApplyIntrinsics<false>(params, du, dv, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kFullOpenCV> {
  static constexpr int kNumParams =
      12;  // fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6
  static constexpr bool kSingleFocal = false;
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    const T& k1 = params[4];
    const T& k2 = params[5];
    const T& p1 = params[6];
    const T& p2 = params[7];
    const T& k3 = params[8];
    const T& k4 = params[9];
    const T& k5 = params[10];
    const T& k6 = params[11];
    const T u2 = u * u, v2 = v * v, uv = u * v, r2 = u2 + v2;
    const T r4 = r2 * r2, r6 = r4 * r2;
    const T radial = (T(1.0) + k1 * r2 + k2 * r4 + k3 * r6) /
                     (T(1.0) + k4 * r2 + k5 * r4 + k6 * r6);
    const T du = u * radial + T(2.0) * p1 * uv + p2 * (r2 + T(2.0) * u2);
    const T dv = v * radial + T(2.0) * p2 * uv + p1 * (r2 + T(2.0) * v2);
    internal::ApplyIntrinsics<false>(params, du, dv, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kFOV> {
  static constexpr int kNumParams = 5;  // fx, fy, cx, cy, omega
  static constexpr bool kSingleFocal = false;
  // Devernay & Faugeras (2001) with COLMAP's series for small omega / radius.
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    const T& omega = params[4];
    const double kSmall = 1e-4;
    const T radius2 = u * u + v * v;
    const T omega2 = omega * omega;
    T factor;
    if (omega2 < T(kSmall)) {
      factor = (omega2 * radius2) / T(3.0) - omega2 / T(12.0) + T(1.0);
    } else if (radius2 < T(kSmall)) {
      const T tan_half_omega = ceres::tan(omega / T(2.0));
      factor = (T(-2.0) * tan_half_omega *
                (T(4.0) * radius2 * tan_half_omega * tan_half_omega - T(3.0))) /
               (T(3.0) * omega);
    } else {
      const T radius = ceres::sqrt(radius2);
      factor = ceres::atan(radius * T(2.0) * ceres::tan(omega / T(2.0))) /
               (radius * omega);
    }
    internal::ApplyIntrinsics<false>(params, u * factor, v * factor, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kSimpleRadialFisheye> {
  static constexpr int kNumParams = 4;  // f, cx, cy, k
  static constexpr bool kSingleFocal = true;
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    T du, dv;
    internal::FisheyeDistort<T, 1>(params + 3, u, v, &du, &dv);
    internal::ApplyIntrinsics<true>(params, du, dv, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kRadialFisheye> {
  static constexpr int kNumParams = 5;  // f, cx, cy, k1, k2
  static constexpr bool kSingleFocal = true;
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    T du, dv;
    internal::FisheyeDistort<T, 2>(params + 3, u, v, &du, &dv);
    internal::ApplyIntrinsics<true>(params, du, dv, x, y);
  }
};

template <>
struct CameraModelT<CameraModelId::kThinPrismFisheye> {
  // fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1
  static constexpr int kNumParams = 12;
  static constexpr bool kSingleFocal = false;
  // Equidistant angle mapping, then radial + tangential + thin prism terms.
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    T uu = u, vv = v;
    const T r2_in = u * u + v * v;
    if (r2_in > T(internal::kFisheyeEps * internal::kFisheyeEps)) {
      const T r = ceres::sqrt(r2_in);
      const T scale = ceres::atan(r) / r;
      uu = u * scale;
      vv = v * scale;
    }
    const T& k1 = params[4];
    const T& k2 = params[5];
    const T& p1 = params[6];
    const T& p2 = params[7];
    const T& k3 = params[8];
    const T& k4 = params[9];
    const T& sx1 = params[10];
    const T& sy1 = params[11];
    const T x2 = uu * uu, y2 = vv * vv, xy = uu * vv, r2 = x2 + y2;
    const T r4 = r2 * r2, r6 = r4 * r2, r8 = r6 * r2;
    const T radial = k1 * r2 + k2 * r4 + k3 * r6 + k4 * r8;
    const T du = uu + uu * radial + T(2.0) * p1 * xy + p2 * (r2 + T(2.0) * x2) +
                 sx1 * r2;
    const T dv = vv + vv * radial + T(2.0) * p2 * xy + p1 * (r2 + T(2.0) * y2) +
                 sy1 * r2;
    internal::ApplyIntrinsics<false>(params, du, dv, x, y);
  }
};

// Calls `visitor(CameraModelT<kModel>{})` for the runtime `model_id` and
// returns its result (every call must return the same type). Throws
// InternalError for an unknown id (cameras are validated when read).
template <typename Visitor>
auto VisitCameraModel(int model_id, Visitor&& visitor) {
  switch (static_cast<CameraModelId>(model_id)) {
    case CameraModelId::kSimplePinhole:
      return visitor(CameraModelT<CameraModelId::kSimplePinhole>{});
    case CameraModelId::kPinhole:
      return visitor(CameraModelT<CameraModelId::kPinhole>{});
    case CameraModelId::kSimpleRadial:
      return visitor(CameraModelT<CameraModelId::kSimpleRadial>{});
    case CameraModelId::kRadial:
      return visitor(CameraModelT<CameraModelId::kRadial>{});
    case CameraModelId::kOpenCV:
      return visitor(CameraModelT<CameraModelId::kOpenCV>{});
    case CameraModelId::kOpenCVFisheye:
      return visitor(CameraModelT<CameraModelId::kOpenCVFisheye>{});
    case CameraModelId::kFullOpenCV:
      return visitor(CameraModelT<CameraModelId::kFullOpenCV>{});
    case CameraModelId::kFOV:
      return visitor(CameraModelT<CameraModelId::kFOV>{});
    case CameraModelId::kSimpleRadialFisheye:
      return visitor(CameraModelT<CameraModelId::kSimpleRadialFisheye>{});
    case CameraModelId::kRadialFisheye:
      return visitor(CameraModelT<CameraModelId::kRadialFisheye>{});
    case CameraModelId::kThinPrismFisheye:
      return visitor(CameraModelT<CameraModelId::kThinPrismFisheye>{});
    case CameraModelId::kInvalid:
      break;
  }
  THROW_CHECK_MSG(false, "unknown camera model id " << model_id);
  // Not reached; keeps the return type deduced from the cases above.
  return visitor(CameraModelT<CameraModelId::kPinhole>{});
}

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
    const int first_extra = Model::kSingleFocal ? 3 : 4;
    groups.focal =
        Model::kSingleFocal ? std::vector<int>{0} : std::vector<int>{0, 1};
    groups.principal_point =
        Model::kSingleFocal ? std::vector<int>{1, 2} : std::vector<int>{2, 3};
    for (int i = first_extra; i < Model::kNumParams; ++i)
      groups.extra.push_back(i);
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

// The residual of ReprojectionErrorFunctor (same parameter blocks: rig_from_world
// rotation (x, y, z, w), translation, point, camera parameters; cam_from_rig
// fixed) with analytic Jacobians for the pose and the point; only the small
// distortion part (2 + kNumParams inputs) goes through Ceres' Jets. About 3x
// cheaper than the all-Jet<14> functor, which dominated bundle adjustment.
// Rotation Jacobian: for unit q = (v, w), R(q) X = X + 2 w (v x X) + 2 v x (v x X),
// so d/dw = 2 v x X and d/dv = -2 w [X]x + 2 ((v.X) I + v X^T - 2 X v^T); along
// the unit sphere (the quaternion manifold's tangent space) this equals the
// derivative of q.toRotationMatrix() * X.
// Pixel of the normalised image point (u, v) = (x/z, y/z) of camera-frame point
// x_in_cam, with d pixel / d x_in_cam (2x3) and d pixel / d params (2 x
// kNumParams, row-major) when those are non-null. Only the distortion part goes
// through Jets (2 + kNumParams inputs). No check of z > 0 (callers decide).
template <typename Model>
inline void ProjectWithJacobians(const double* params,
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
