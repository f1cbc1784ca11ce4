#include "colmap_ext/io/camera_models.h"

#include <cmath>

#include "core/errors.h"

namespace lisfm {
namespace colmap {
namespace {

struct ModelInfo {
  const char* name;
  int num_params;
  const char* params_info;
  bool single_focal;  // f instead of fx, fy
};

const ModelInfo kModels[kNumCameraModels] = {
    {"SIMPLE_PINHOLE", 3, "f, cx, cy", true},
    {"PINHOLE", 4, "fx, fy, cx, cy", false},
    {"SIMPLE_RADIAL", 4, "f, cx, cy, k", true},
    {"RADIAL", 5, "f, cx, cy, k1, k2", true},
    {"OPENCV", 8, "fx, fy, cx, cy, k1, k2, p1, p2", false},
    {"OPENCV_FISHEYE", 8, "fx, fy, cx, cy, k1, k2, k3, k4", false},
    {"FULL_OPENCV", 12, "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6", false},
    {"FOV", 5, "fx, fy, cx, cy, omega", false},
    {"SIMPLE_RADIAL_FISHEYE", 4, "f, cx, cy, k", true},
    {"RADIAL_FISHEYE", 5, "f, cx, cy, k1, k2", true},
    {"THIN_PRISM_FISHEYE", 12, "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1", false},
};

constexpr double kEps = std::numeric_limits<double>::epsilon();

// Equidistant (Kannala-Brandt) radial mapping used by the fisheye models:
// returns the distorted normalised point for the polynomial theta_d(theta).
Vec2 FisheyeDistort(const Vec2& uv, const double* k, int num_k) {
  const double r = uv.norm();
  if (r <= kEps) return uv;
  const double theta = std::atan(r);
  const double theta2 = theta * theta;
  double poly = 1.0, power = 1.0;
  for (int i = 0; i < num_k; ++i) {
    power *= theta2;
    poly += k[i] * power;
  }
  const double theta_d = theta * poly;
  return uv * (theta_d / r);
}

// COLMAP 3.8 distortion models in the normalised image plane. `extra` points
// to the parameters after the focal lengths and principal point.
Vec2 Distort(CameraModelId model, const double* extra, const Vec2& uv) {
  const double u = uv.x(), v = uv.y();
  switch (model) {
    case CameraModelId::kSimplePinhole:
    case CameraModelId::kPinhole:
      return uv;
    case CameraModelId::kSimpleRadial:
    case CameraModelId::kRadial: {
      const double r2 = u * u + v * v;
      double radial = extra[0] * r2;
      if (model == CameraModelId::kRadial) radial += extra[1] * r2 * r2;
      return uv + uv * radial;
    }
    case CameraModelId::kOpenCV: {
      const double k1 = extra[0], k2 = extra[1], p1 = extra[2], p2 = extra[3];
      const double u2 = u * u, v2 = v * v, uv2 = u * v, r2 = u2 + v2;
      const double radial = k1 * r2 + k2 * r2 * r2;
      return {u + u * radial + 2.0 * p1 * uv2 + p2 * (r2 + 2.0 * u2),
              v + v * radial + 2.0 * p2 * uv2 + p1 * (r2 + 2.0 * v2)};
    }
    case CameraModelId::kOpenCVFisheye:
      return FisheyeDistort(uv, extra, 4);
    case CameraModelId::kFullOpenCV: {
      const double k1 = extra[0], k2 = extra[1], p1 = extra[2], p2 = extra[3];
      const double k3 = extra[4], k4 = extra[5], k5 = extra[6], k6 = extra[7];
      const double u2 = u * u, v2 = v * v, uv2 = u * v, r2 = u2 + v2;
      const double r4 = r2 * r2, r6 = r4 * r2;
      const double radial =
          (1.0 + k1 * r2 + k2 * r4 + k3 * r6) / (1.0 + k4 * r2 + k5 * r4 + k6 * r6);
      return {u * radial + 2.0 * p1 * uv2 + p2 * (r2 + 2.0 * u2),
              v * radial + 2.0 * p2 * uv2 + p1 * (r2 + 2.0 * v2)};
    }
    case CameraModelId::kFOV: {
      // Devernay & Faugeras (2001) field-of-view model, with COLMAP's series
      // expansions for small omega and small radius.
      const double omega = extra[0];
      const double kSmall = 1e-4;
      const double radius2 = u * u + v * v;
      const double omega2 = omega * omega;
      double factor;
      if (omega2 < kSmall) {
        factor = (omega2 * radius2) / 3.0 - omega2 / 12.0 + 1.0;
      } else if (radius2 < kSmall) {
        const double tan_half_omega = std::tan(omega / 2.0);
        factor = (-2.0 * tan_half_omega *
                  (4.0 * radius2 * tan_half_omega * tan_half_omega - 3.0)) /
                 (3.0 * omega);
      } else {
        const double radius = std::sqrt(radius2);
        factor = std::atan(radius * 2.0 * std::tan(omega / 2.0)) / (radius * omega);
      }
      return uv * factor;
    }
    case CameraModelId::kSimpleRadialFisheye:
      return FisheyeDistort(uv, extra, 1);
    case CameraModelId::kRadialFisheye:
      return FisheyeDistort(uv, extra, 2);
    case CameraModelId::kThinPrismFisheye: {
      // Equidistant angle mapping, then radial + tangential + thin prism.
      const double r = uv.norm();
      Vec2 uu = uv;
      if (r > kEps) uu = uv * (std::atan(r) / r);
      const double k1 = extra[0], k2 = extra[1], p1 = extra[2], p2 = extra[3];
      const double k3 = extra[4], k4 = extra[5], sx1 = extra[6], sy1 = extra[7];
      const double x = uu.x(), y = uu.y();
      const double x2 = x * x, y2 = y * y, xy = x * y, r2 = x2 + y2;
      const double r4 = r2 * r2, r6 = r4 * r2, r8 = r6 * r2;
      const double radial = k1 * r2 + k2 * r4 + k3 * r6 + k4 * r8;
      return {x + x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2) + sx1 * r2,
              y + y * radial + 2.0 * p2 * xy + p1 * (r2 + 2.0 * y2) + sy1 * r2};
    }
    case CameraModelId::kInvalid:
      break;
  }
  THROW_CHECK_MSG(false, "unknown camera model id " << static_cast<int>(model));
}

// Newton iteration for Distort(uv) = target with a central-difference
// Jacobian (COLMAP 3.8 inverts its models the same way).
Vec2 Undistort(CameraModelId model, const double* extra, const Vec2& target) {
  if (model == CameraModelId::kSimplePinhole || model == CameraModelId::kPinhole) {
    return target;
  }
  Vec2 uv = target;
  const int kMaxIterations = 100;
  for (int it = 0; it < kMaxIterations; ++it) {
    const Vec2 f = Distort(model, extra, uv) - target;
    Eigen::Matrix2d jacobian;
    for (int c = 0; c < 2; ++c) {
      const double step = std::max(1e-9, 1e-7 * std::abs(uv(c)));
      Vec2 plus = uv, minus = uv;
      plus(c) += step;
      minus(c) -= step;
      jacobian.col(c) =
          (Distort(model, extra, plus) - Distort(model, extra, minus)) / (2.0 * step);
    }
    const Vec2 delta = jacobian.partialPivLu().solve(f);
    uv -= delta;
    if (!uv.allFinite()) return Vec2::Constant(std::numeric_limits<double>::quiet_NaN());
    if (delta.squaredNorm() < 1e-28 * std::max(1.0, uv.squaredNorm())) break;
  }
  return uv;
}

}  // namespace

bool ExistsCameraModel(int model_id) { return model_id >= 0 && model_id < kNumCameraModels; }

std::string CameraModelName(int model_id) {
  return ExistsCameraModel(model_id) ? kModels[model_id].name : "";
}

int CameraModelIdFromName(const std::string& name) {
  for (int i = 0; i < kNumCameraModels; ++i) {
    if (name == kModels[i].name) return i;
  }
  return static_cast<int>(CameraModelId::kInvalid);
}

int CameraModelNumParams(int model_id) {
  return ExistsCameraModel(model_id) ? kModels[model_id].num_params : -1;
}

std::string CameraModelParamsInfo(int model_id) {
  return ExistsCameraModel(model_id) ? kModels[model_id].params_info : "";
}

bool Camera::VerifyParams() const {
  if (!ExistsCameraModel(model_id)) return false;
  if (static_cast<int>(params.size()) != CameraModelNumParams(model_id)) return false;
  for (double p : params) {
    if (!std::isfinite(p)) return false;
  }
  return true;
}

double Camera::MeanFocalLength() const {
  THROW_CHECK(VerifyParams());
  return kModels[model_id].single_focal ? params[0] : 0.5 * (params[0] + params[1]);
}

double Camera::PrincipalPointX() const {
  THROW_CHECK(VerifyParams());
  return kModels[model_id].single_focal ? params[1] : params[2];
}

double Camera::PrincipalPointY() const {
  THROW_CHECK(VerifyParams());
  return kModels[model_id].single_focal ? params[2] : params[3];
}

Vec2 Camera::ImgFromCam(const Vec2& normalized) const {
  THROW_CHECK_MSG(VerifyParams(), "camera " << camera_id << " has invalid parameters");
  const bool single = kModels[model_id].single_focal;
  const double fx = params[0], fy = single ? params[0] : params[1];
  const double cx = single ? params[1] : params[2], cy = single ? params[2] : params[3];
  const double* extra = params.data() + (single ? 3 : 4);
  const Vec2 d = Distort(static_cast<CameraModelId>(model_id), extra, normalized);
  return {fx * d.x() + cx, fy * d.y() + cy};
}

Vec2 Camera::CamFromImg(const Vec2& pixel) const {
  THROW_CHECK_MSG(VerifyParams(), "camera " << camera_id << " has invalid parameters");
  const bool single = kModels[model_id].single_focal;
  const double fx = params[0], fy = single ? params[0] : params[1];
  const double cx = single ? params[1] : params[2], cy = single ? params[2] : params[3];
  const double* extra = params.data() + (single ? 3 : 4);
  const Vec2 d((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  return Undistort(static_cast<CameraModelId>(model_id), extra, d);
}

bool Camera::Project(const Vec3& x_in_cam, Vec2* pixel) const {
  if (!(x_in_cam.z() > 0.0)) return false;
  *pixel = ImgFromCam(x_in_cam.head<2>() / x_in_cam.z());
  return pixel->allFinite();
}

Vec3 Camera::Unproject(const Vec2& pixel) const {
  return CamFromImg(pixel).homogeneous().normalized();
}

Camera CameraFromCameraModel(const CameraModel& model, camera_t camera_id) {
  Camera camera;
  camera.camera_id = camera_id;
  camera.width = static_cast<uint64_t>(model.width);
  camera.height = static_cast<uint64_t>(model.height);
  camera.has_prior_focal_length = true;
  camera.params = {model.fx, model.fy, model.cx + 0.5, model.cy + 0.5};
  switch (model.distortion) {
    case DistortionModel::kNone:
      camera.model_id = static_cast<int>(CameraModelId::kPinhole);
      break;
    case DistortionModel::kRadtan:
      camera.model_id = static_cast<int>(CameraModelId::kOpenCV);
      break;
    case DistortionModel::kEquidistant:
      camera.model_id = static_cast<int>(CameraModelId::kOpenCVFisheye);
      break;
  }
  if (model.distortion != DistortionModel::kNone) {
    if (model.distortion_coeffs.size() != 4) {
      throw InputError("camera " + std::to_string(camera_id), "",
                       "expected 4 distortion coefficients, found " +
                           std::to_string(model.distortion_coeffs.size()));
    }
    camera.params.insert(camera.params.end(), model.distortion_coeffs.begin(),
                         model.distortion_coeffs.end());
  }
  return camera;
}

}  // namespace colmap
}  // namespace lisfm
