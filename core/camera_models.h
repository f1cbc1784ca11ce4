// The camera models 0-10 of COLMAP (ids, parameter orders and COLMAP 3.8's
// formulas): the one implementation of projection, distortion and
// undistortion. The rig calibration (core/camera_model.h), the COLMAP camera
// record (colmap_ext/io/camera_models.h) and bundle adjustment
// (colmap_ext/sfm/camera_model_functors.h) all evaluate these templates.
//
// Geometry. A point (x, y, z) in the camera frame (z forward, x right, y down)
// maps to the normalised image plane (u, v) = (x / z, y / z). A model's
// Distortion<T>(extra, a, b) returns the distorted point (a', b') of its
// undistorted coordinates (a, b), and the pixel is
//   (fx a' + cx, fy b' + cy)        (f for fx and fy with one focal length).
// Perspective models distort the normalised plane, (a, b) = (u, v). Fisheye
// models (kIsFisheye) distort the equidistant plane
//   (a, b) = theta (u, v) / r,  r = |(u, v)|,  theta = atan(r),
// whose radius theta is the incidence angle of the ray (rad), so rays beyond
// 90 degrees have fisheye coordinates (FisheyeFromRay, RayFromFisheye) though
// no normalised ones. The maths does not depend on the pixel convention: cx, cy are OpenCV's
// (centre of the top-left pixel at (0, 0)) or COLMAP's (at (0.5, 0.5)) as the
// caller stores them.
//
// Scalars. ImgFromCam, ImgFromUndistorted and Distortion are templates on the
// scalar T: double, or ceres::Jet for Jacobians by automatic differentiation.
// core does not depend on Ceres: the templates call sqrt / atan / tan
// unqualified after `using std::...;`, so argument-dependent lookup finds
// Ceres' Jet overloads. Branches on small radii compare squared radii (sqrt of
// a Jet at 0 has an infinite derivative) against COLMAP 3.8's thresholds:
// r > machine epsilon for the equidistant mapping, and omega^2 < 1e-4 or
// r^2 < 1e-4 for the series of the FOV model.
//
// Undistortion (CamFromImg, UndistortedFromImg; double only) inverts Distortion
// by IterativeUndistortion: Newton's method with a central-difference
// Jacobian, as COLMAP 3.8 does; the identity for models without distortion.
// Everything here is a pure function of its arguments (thread-safe).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/LU>

#include "core/errors.h"

namespace lisfm {

// COLMAP's model ids; the numeric values are part of COLMAP's file formats.
enum class CameraModelId : int {
  kInvalid = -1,
  kSimplePinhole = 0,        // f, cx, cy
  kPinhole = 1,              // fx, fy, cx, cy
  kSimpleRadial = 2,         // f, cx, cy, k
  kRadial = 3,               // f, cx, cy, k1, k2
  kOpenCV = 4,               // fx, fy, cx, cy, k1, k2, p1, p2
  kOpenCVFisheye = 5,        // fx, fy, cx, cy, k1, k2, k3, k4
  kFullOpenCV = 6,           // fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6
  kFOV = 7,                  // fx, fy, cx, cy, omega
  kSimpleRadialFisheye = 8,  // f, cx, cy, k
  kRadialFisheye = 9,        // f, cx, cy, k1, k2
  kThinPrismFisheye = 10,    // fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1
};

constexpr int kNumCameraModels = 11;

// Undistortion counts as converged when |Distortion(a, b) - target| is below
// this (undistorted units: normalised plane, or radians on the fisheye plane).
constexpr double kMaxUndistortionResidual = 1e-10;

// Members shared by every model (CRTP). A model struct defines
//   kModelId, kName, kParamsInfo, kNumParams,
//   kNumFocalParams  1 (f) or 2 (fx, fy); the principal point follows, then
//                    the extra (distortion) parameters,
//   kIsFisheye       Distortion acts on the equidistant plane,
//   Distortion<T>(const T* extra, const T& a, const T& b, T* da, T* db).
template <typename Model>
struct BaseCameraModel {
  // Index of the first extra parameter (after f or fx, fy and cx, cy).
  static constexpr int ExtraParamsIndex() { return Model::kNumFocalParams + 2; }
  static constexpr int NumExtraParams() { return Model::kNumParams - ExtraParamsIndex(); }

  // Normalised image plane (u, v) -> pixel (x, y). No check of the ray: the
  // caller ensures z > 0.
  template <typename T>
  static void ImgFromCam(const T* params, const T& u, const T& v, T* x, T* y) {
    if constexpr (Model::kIsFisheye) {
      T a, b;
      FisheyeFromNormal(u, v, &a, &b);
      ImgFromUndistorted(params, a, b, x, y);
    } else {
      ImgFromUndistorted(params, u, v, x, y);
    }
  }

  // Pixel (x, y) -> normalised image plane (u, v), the inverse of ImgFromCam.
  // Returns false when the undistortion did not converge to
  // kMaxUndistortionResidual or the ray is not in front of the camera
  // (fisheye: incidence angle >= 90 degrees). u, v are NaN when the iteration
  // diverged or the ray is not in front of the camera.
  static bool CamFromImg(const double* params, double x, double y, double* u, double* v) {
    double a, b;
    const double residual = UndistortedFromImg(params, x, y, &a, &b);
    if (residual == std::numeric_limits<double>::infinity()) {
      a = b = std::numeric_limits<double>::quiet_NaN();
    }
    bool in_front = true;
    if constexpr (Model::kIsFisheye) {
      in_front = NormalFromFisheye(a, b, u, v);
    } else {
      *u = a;
      *v = b;
    }
    return in_front && residual < kMaxUndistortionResidual;
  }

  // Solves Distortion(extra, a, b) = (a0, b0) for (a, b), given (a0, b0) in
  // *a, *b on entry: Newton's method from (a0, b0) with the Jacobian from
  // central differences (step max(1e-9, 1e-7 |a|) per coordinate), at most 100
  // iterations, until the step is below 1e-14 max(1, |(a, b)|). Returns the
  // final |Distortion(a, b) - (a0, b0)|, or +infinity when an iterate was not
  // finite (diverged; a, b then hold the last finite iterate).
  static double IterativeUndistortion(const double* extra, double* a, double* b) {
    using Vec2d = Eigen::Vector2d;
    if constexpr (NumExtraParams() == 0) return 0.0;
    const Vec2d target(*a, *b);
    const auto distorted = [extra](const Vec2d& p) {
      Vec2d d;
      Model::Distortion(extra, p.x(), p.y(), &d.x(), &d.y());
      return d;
    };
    constexpr int kMaxIterations = 100;
    Vec2d p = target;
    for (int it = 0; it < kMaxIterations; ++it) {
      const Vec2d f = distorted(p) - target;
      Eigen::Matrix2d jacobian;
      for (int c = 0; c < 2; ++c) {
        const double step = std::max(1e-9, 1e-7 * std::abs(p(c)));
        Vec2d plus = p, minus = p;
        plus(c) += step;
        minus(c) -= step;
        jacobian.col(c) = (distorted(plus) - distorted(minus)) / (2.0 * step);
      }
      const Vec2d delta = jacobian.partialPivLu().solve(f);
      const Vec2d next = p - delta;
      if (!next.allFinite()) {
        *a = p.x();
        *b = p.y();
        return std::numeric_limits<double>::infinity();
      }
      p = next;
      if (delta.squaredNorm() < 1e-28 * std::max(1.0, p.squaredNorm())) break;
    }
    *a = p.x();
    *b = p.y();
    return (distorted(p) - target).norm();
  }

  // Undistorted coordinates (a, b) (normalised plane, or the equidistant
  // plane of fisheye models) -> pixel: Distortion, then focal length and
  // principal point.
  template <typename T>
  static void ImgFromUndistorted(const T* params, const T& a, const T& b, T* x, T* y) {
    T da, db;
    Model::Distortion(params + ExtraParamsIndex(), a, b, &da, &db);
    if constexpr (Model::kNumFocalParams == 1) {
      *x = params[0] * da + params[1];
      *y = params[0] * db + params[2];
    } else {
      *x = params[0] * da + params[2];
      *y = params[1] * db + params[3];
    }
  }

  // Pixel -> undistorted coordinates (inverse of ImgFromUndistorted). Returns
  // the residual of IterativeUndistortion (0 without distortion).
  static double UndistortedFromImg(const double* params, double x, double y, double* a, double* b) {
    if constexpr (Model::kNumFocalParams == 1) {
      *a = (x - params[1]) / params[0];
      *b = (y - params[2]) / params[0];
    } else {
      *a = (x - params[2]) / params[0];
      *b = (y - params[3]) / params[1];
    }
    return IterativeUndistortion(params + ExtraParamsIndex(), a, b);
  }

  // Normalised plane -> equidistant plane: (u, v) atan(r) / r, the identity
  // for r <= machine epsilon (COLMAP 3.8's branch).
  template <typename T>
  static void FisheyeFromNormal(const T& u, const T& v, T* a, T* b) {
    using std::atan;
    using std::sqrt;
    constexpr double kEps = std::numeric_limits<double>::epsilon();
    const T r2 = u * u + v * v;
    if (r2 > T(kEps * kEps)) {
      const T r = sqrt(r2);
      const T scale = atan(r) / r;
      *a = u * scale;
      *b = v * scale;
    } else {
      *a = u;
      *b = v;
    }
  }

  // Equidistant plane -> normalised plane: (a, b) tan(theta) / theta with
  // theta = |(a, b)|, the identity for theta <= machine epsilon. Returns false
  // (u, v NaN) for theta >= pi / 2, a ray not in front of the camera.
  static bool NormalFromFisheye(double a, double b, double* u, double* v) {
    const double theta = std::sqrt(a * a + b * b);
    if (!(theta < 0.5 * M_PI)) {
      *u = *v = std::numeric_limits<double>::quiet_NaN();
      return false;
    }
    const double scale =
        theta > std::numeric_limits<double>::epsilon() ? std::tan(theta) / theta : 1.0;
    *u = a * scale;
    *v = b * scale;
    return true;
  }

  // Ray (x, y, z) in the camera frame (any length, any direction but the
  // negative optical axis) -> equidistant plane: (a, b) = theta (x, y) /
  // |(x, y)|, (x / z, y / z) on the optical axis (|(x, y)| <= 1e-300). Returns
  // the incidence angle theta = atan2(|(x, y)|, z) in [0, pi] (rad).
  static double FisheyeFromRay(double x, double y, double z, double* a, double* b) {
    const double r = std::hypot(x, y);
    const double theta = std::atan2(r, z);
    if (r > 1e-300) {
      const double scale = theta / r;
      *a = x * scale;
      *b = y * scale;
    } else {
      *a = x / z;
      *b = y / z;
    }
    return theta;
  }

  // Equidistant plane -> unit ray (sin(theta) (a, b) / theta, cos(theta)),
  // theta = |(a, b)| (rad); (0, 0, 1) at theta = 0.
  static void RayFromFisheye(double a, double b, double* x, double* y, double* z) {
    const double theta = std::sqrt(a * a + b * b);
    if (theta == 0.0) {
      *x = 0.0;
      *y = 0.0;
      *z = 1.0;
      return;
    }
    const double scale = std::sin(theta) / theta;
    *x = a * scale;
    *y = b * scale;
    *z = std::cos(theta);
  }
};

namespace camera_models_internal {

// 1 + k[0] t2 + k[1] t2^2 + ... + k[kNumK-1] t2^kNumK.
template <int kNumK, typename T>
T EvenPolynomial(const T* k, const T& t2) {
  T poly = T(1.0);
  T power = T(1.0);
  for (int i = 0; i < kNumK; ++i) {
    power *= t2;
    poly += k[i] * power;
  }
  return poly;
}

// Radial-only fisheye distortion on the equidistant plane:
// (a, b) (1 + k1 theta^2 + ... + kn theta^2n), theta^2 = a^2 + b^2.
template <int kNumK, typename T>
void EquidistantRadialDistortion(const T* k, const T& a, const T& b, T* da, T* db) {
  const T poly = EvenPolynomial<kNumK>(k, a * a + b * b);
  *da = a * poly;
  *db = b * poly;
}

}  // namespace camera_models_internal

// f, cx, cy. No distortion.
struct SimplePinholeCameraModel : BaseCameraModel<SimplePinholeCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kSimplePinhole;
  static constexpr const char* kName = "SIMPLE_PINHOLE";
  static constexpr const char* kParamsInfo = "f, cx, cy";
  static constexpr int kNumParams = 3;
  static constexpr int kNumFocalParams = 1;
  static constexpr bool kIsFisheye = false;
  template <typename T>
  static void Distortion(const T* /*extra*/, const T& a, const T& b, T* da, T* db) {
    *da = a;
    *db = b;
  }
};

// fx, fy, cx, cy. No distortion.
struct PinholeCameraModel : BaseCameraModel<PinholeCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kPinhole;
  static constexpr const char* kName = "PINHOLE";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy";
  static constexpr int kNumParams = 4;
  static constexpr int kNumFocalParams = 2;
  static constexpr bool kIsFisheye = false;
  template <typename T>
  static void Distortion(const T* /*extra*/, const T& a, const T& b, T* da, T* db) {
    *da = a;
    *db = b;
  }
};

// f, cx, cy, k: (u, v) (1 + k r^2).
struct SimpleRadialCameraModel : BaseCameraModel<SimpleRadialCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kSimpleRadial;
  static constexpr const char* kName = "SIMPLE_RADIAL";
  static constexpr const char* kParamsInfo = "f, cx, cy, k";
  static constexpr int kNumParams = 4;
  static constexpr int kNumFocalParams = 1;
  static constexpr bool kIsFisheye = false;
  template <typename T>
  static void Distortion(const T* extra, const T& u, const T& v, T* du, T* dv) {
    const T radial = extra[0] * (u * u + v * v);
    *du = u + u * radial;
    *dv = v + v * radial;
  }
};

// f, cx, cy, k1, k2: (u, v) (1 + k1 r^2 + k2 r^4).
struct RadialCameraModel : BaseCameraModel<RadialCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kRadial;
  static constexpr const char* kName = "RADIAL";
  static constexpr const char* kParamsInfo = "f, cx, cy, k1, k2";
  static constexpr int kNumParams = 5;
  static constexpr int kNumFocalParams = 1;
  static constexpr bool kIsFisheye = false;
  template <typename T>
  static void Distortion(const T* extra, const T& u, const T& v, T* du, T* dv) {
    const T r2 = u * u + v * v;
    const T radial = extra[0] * r2 + extra[1] * r2 * r2;
    *du = u + u * radial;
    *dv = v + v * radial;
  }
};

// fx, fy, cx, cy, k1, k2, p1, p2: OpenCV's radial + tangential model
// (cv::projectPoints with [k1 k2 p1 p2], Kalibr "radtan"):
//   u' = u (1 + k1 r^2 + k2 r^4) + 2 p1 u v + p2 (r^2 + 2 u^2)
//   v' = v (1 + k1 r^2 + k2 r^4) + 2 p2 u v + p1 (r^2 + 2 v^2)
struct OpenCVCameraModel : BaseCameraModel<OpenCVCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kOpenCV;
  static constexpr const char* kName = "OPENCV";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy, k1, k2, p1, p2";
  static constexpr int kNumParams = 8;
  static constexpr int kNumFocalParams = 2;
  static constexpr bool kIsFisheye = false;
  template <typename T>
  static void Distortion(const T* extra, const T& u, const T& v, T* du, T* dv) {
    const T& k1 = extra[0];
    const T& k2 = extra[1];
    const T& p1 = extra[2];
    const T& p2 = extra[3];
    const T u2 = u * u, v2 = v * v, uv = u * v, r2 = u2 + v2;
    const T radial = k1 * r2 + k2 * r2 * r2;
    *du = u + u * radial + T(2.0) * p1 * uv + p2 * (r2 + T(2.0) * u2);
    *dv = v + v * radial + T(2.0) * p2 * uv + p1 * (r2 + T(2.0) * v2);
  }
};

// fx, fy, cx, cy, k1, k2, k3, k4: OpenCV's fisheye (Kannala-Brandt) model
// (cv::fisheye::projectPoints, Kalibr "equidistant"): on the equidistant plane
//   (a', b') = (a, b) (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8).
struct OpenCVFisheyeCameraModel : BaseCameraModel<OpenCVFisheyeCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kOpenCVFisheye;
  static constexpr const char* kName = "OPENCV_FISHEYE";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy, k1, k2, k3, k4";
  static constexpr int kNumParams = 8;
  static constexpr int kNumFocalParams = 2;
  static constexpr bool kIsFisheye = true;
  template <typename T>
  static void Distortion(const T* extra, const T& a, const T& b, T* da, T* db) {
    camera_models_internal::EquidistantRadialDistortion<4>(extra, a, b, da, db);
  }
};

// fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6: OpenCV's rational model,
//   u' = u (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
//        + 2 p1 u v + p2 (r^2 + 2 u^2), v' likewise.
struct FullOpenCVCameraModel : BaseCameraModel<FullOpenCVCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kFullOpenCV;
  static constexpr const char* kName = "FULL_OPENCV";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6";
  static constexpr int kNumParams = 12;
  static constexpr int kNumFocalParams = 2;
  static constexpr bool kIsFisheye = false;
  template <typename T>
  static void Distortion(const T* extra, const T& u, const T& v, T* du, T* dv) {
    const T& k1 = extra[0];
    const T& k2 = extra[1];
    const T& p1 = extra[2];
    const T& p2 = extra[3];
    const T& k3 = extra[4];
    const T& k4 = extra[5];
    const T& k5 = extra[6];
    const T& k6 = extra[7];
    const T u2 = u * u, v2 = v * v, uv = u * v, r2 = u2 + v2;
    const T r4 = r2 * r2, r6 = r4 * r2;
    const T radial =
        (T(1.0) + k1 * r2 + k2 * r4 + k3 * r6) / (T(1.0) + k4 * r2 + k5 * r4 + k6 * r6);
    *du = u * radial + T(2.0) * p1 * uv + p2 * (r2 + T(2.0) * u2);
    *dv = v * radial + T(2.0) * p2 * uv + p1 * (r2 + T(2.0) * v2);
  }
};

// fx, fy, cx, cy, omega: the field-of-view model of Devernay & Faugeras
// (2001), (u, v) atan(2 r tan(omega / 2)) / (r omega), with COLMAP 3.8's
// series for omega^2 < 1e-4 (1 + omega^2 r^2 / 3 - omega^2 / 12) and for
// r^2 < 1e-4 (2 tan(omega / 2) (3 - 4 r^2 tan^2(omega / 2)) / (3 omega)).
struct FOVCameraModel : BaseCameraModel<FOVCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kFOV;
  static constexpr const char* kName = "FOV";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy, omega";
  static constexpr int kNumParams = 5;
  static constexpr int kNumFocalParams = 2;
  static constexpr bool kIsFisheye = false;
  template <typename T>
  static void Distortion(const T* extra, const T& u, const T& v, T* du, T* dv) {
    using std::atan;
    using std::sqrt;
    using std::tan;
    constexpr double kSmall = 1e-4;
    const T& omega = extra[0];
    const T radius2 = u * u + v * v;
    const T omega2 = omega * omega;
    T factor;
    if (omega2 < T(kSmall)) {
      factor = (omega2 * radius2) / T(3.0) - omega2 / T(12.0) + T(1.0);
    } else if (radius2 < T(kSmall)) {
      const T tan_half_omega = tan(omega / T(2.0));
      factor = (T(-2.0) * tan_half_omega *
                (T(4.0) * radius2 * tan_half_omega * tan_half_omega - T(3.0))) /
               (T(3.0) * omega);
    } else {
      const T radius = sqrt(radius2);
      factor = atan(radius * T(2.0) * tan(omega / T(2.0))) / (radius * omega);
    }
    *du = u * factor;
    *dv = v * factor;
  }
};

// f, cx, cy, k: on the equidistant plane (a, b) (1 + k theta^2).
struct SimpleRadialFisheyeCameraModel : BaseCameraModel<SimpleRadialFisheyeCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kSimpleRadialFisheye;
  static constexpr const char* kName = "SIMPLE_RADIAL_FISHEYE";
  static constexpr const char* kParamsInfo = "f, cx, cy, k";
  static constexpr int kNumParams = 4;
  static constexpr int kNumFocalParams = 1;
  static constexpr bool kIsFisheye = true;
  template <typename T>
  static void Distortion(const T* extra, const T& a, const T& b, T* da, T* db) {
    camera_models_internal::EquidistantRadialDistortion<1>(extra, a, b, da, db);
  }
};

// f, cx, cy, k1, k2: on the equidistant plane (a, b) (1 + k1 theta^2 + k2
// theta^4).
struct RadialFisheyeCameraModel : BaseCameraModel<RadialFisheyeCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kRadialFisheye;
  static constexpr const char* kName = "RADIAL_FISHEYE";
  static constexpr const char* kParamsInfo = "f, cx, cy, k1, k2";
  static constexpr int kNumParams = 5;
  static constexpr int kNumFocalParams = 1;
  static constexpr bool kIsFisheye = true;
  template <typename T>
  static void Distortion(const T* extra, const T& a, const T& b, T* da, T* db) {
    camera_models_internal::EquidistantRadialDistortion<2>(extra, a, b, da, db);
  }
};

// fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1: Weng et al. (1992) on the
// equidistant plane, radial + tangential + thin prism with t2 = a^2 + b^2:
//   a' = a (1 + k1 t2 + k2 t2^2 + k3 t2^3 + k4 t2^4) + 2 p1 a b + p2 (t2 + 2
//   a^2)
//        + sx1 t2, b' likewise with p1 <-> p2 and sy1.
struct ThinPrismFisheyeCameraModel : BaseCameraModel<ThinPrismFisheyeCameraModel> {
  static constexpr CameraModelId kModelId = CameraModelId::kThinPrismFisheye;
  static constexpr const char* kName = "THIN_PRISM_FISHEYE";
  static constexpr const char* kParamsInfo = "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1";
  static constexpr int kNumParams = 12;
  static constexpr int kNumFocalParams = 2;
  static constexpr bool kIsFisheye = true;
  template <typename T>
  static void Distortion(const T* extra, const T& a, const T& b, T* da, T* db) {
    const T& k1 = extra[0];
    const T& k2 = extra[1];
    const T& p1 = extra[2];
    const T& p2 = extra[3];
    const T& k3 = extra[4];
    const T& k4 = extra[5];
    const T& sx1 = extra[6];
    const T& sy1 = extra[7];
    const T a2 = a * a, b2 = b * b, ab = a * b, t2 = a2 + b2;
    const T t4 = t2 * t2, t6 = t4 * t2, t8 = t6 * t2;
    const T radial = k1 * t2 + k2 * t4 + k3 * t6 + k4 * t8;
    *da = a + a * radial + T(2.0) * p1 * ab + p2 * (t2 + T(2.0) * a2) + sx1 * t2;
    *db = b + b * radial + T(2.0) * p2 * ab + p1 * (t2 + T(2.0) * b2) + sy1 * t2;
  }
};

// Calls visitor(Model{}) with the model struct of the runtime `model_id` and
// returns its result (every call must return the same type). Throws
// InternalError for an unknown id (callers validate ids read from files).
template <typename Visitor>
auto VisitCameraModel(int model_id, Visitor&& visitor) {
  switch (static_cast<CameraModelId>(model_id)) {
    case CameraModelId::kSimplePinhole:
      return visitor(SimplePinholeCameraModel{});
    case CameraModelId::kPinhole:
      return visitor(PinholeCameraModel{});
    case CameraModelId::kSimpleRadial:
      return visitor(SimpleRadialCameraModel{});
    case CameraModelId::kRadial:
      return visitor(RadialCameraModel{});
    case CameraModelId::kOpenCV:
      return visitor(OpenCVCameraModel{});
    case CameraModelId::kOpenCVFisheye:
      return visitor(OpenCVFisheyeCameraModel{});
    case CameraModelId::kFullOpenCV:
      return visitor(FullOpenCVCameraModel{});
    case CameraModelId::kFOV:
      return visitor(FOVCameraModel{});
    case CameraModelId::kSimpleRadialFisheye:
      return visitor(SimpleRadialFisheyeCameraModel{});
    case CameraModelId::kRadialFisheye:
      return visitor(RadialFisheyeCameraModel{});
    case CameraModelId::kThinPrismFisheye:
      return visitor(ThinPrismFisheyeCameraModel{});
    case CameraModelId::kInvalid:
      break;
  }
  THROW_CHECK_MSG(false, "unknown camera model id " << model_id);
  // Not reached; gives the return type of the cases above.
  return visitor(PinholeCameraModel{});
}

}  // namespace lisfm
