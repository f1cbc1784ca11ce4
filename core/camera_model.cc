#include "core/camera_model.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <fmt/format.h>

#include "core/errors.h"

namespace lisfm {
namespace {

// The invertibility of a distortion polynomial is checked at this many
// equally spaced samples of [0, r] (the derivatives are polynomials of degree
// <= 4 in r^2, so 8 samples catch every sign change but a pair of close roots).
constexpr int kMonotonicSamples = 8;

// fx, fy, cx, cy, k1..k4 (zeros without distortion): the parameters of
// CameraModel::ModelId() without an allocation.
std::array<double, 8> ParamArray(const CameraModel& camera) {
  std::array<double, 8> params = {camera.fx, camera.fy, camera.cx, camera.cy, 0.0, 0.0, 0.0, 0.0};
  if (camera.distortion != DistortionModel::kNone) {
    THROW_CHECK_EQ(camera.distortion_coeffs.size(), 4u);
    std::copy(camera.distortion_coeffs.begin(), camera.distortion_coeffs.end(), params.begin() + 4);
  }
  return params;
}

// d/dr of the radial part of radtan, r (1 + k1 r^2 + k2 r^4).
double RadtanRadialSlope(const std::vector<double>& k, double r) {
  const double r2 = r * r;
  return 1.0 + 3.0 * k[0] * r2 + 5.0 * k[1] * r2 * r2;
}

// d/dtheta of the equidistant theta_d(theta) = theta (1 + k1 theta^2 + ... + k4 theta^8).
double EquidistantSlope(const std::vector<double>& k, double theta) {
  const double t2 = theta * theta;
  const double t4 = t2 * t2, t6 = t4 * t2, t8 = t4 * t4;
  return 1.0 + 3.0 * k[0] * t2 + 5.0 * k[1] * t4 + 7.0 * k[2] * t6 + 9.0 * k[3] * t8;
}

// True when slope(s) > 0 at kMonotonicSamples equally spaced s in (0, end].
template <typename Slope>
bool IncreasingUpTo(double end, const Slope& slope) {
  for (int i = 1; i <= kMonotonicSamples; ++i) {
    if (!(slope(end * i / kMonotonicSamples) > 0.0)) return false;
  }
  return true;
}

bool AllFinite(const std::vector<double>& values) {
  for (const double v : values) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

}  // namespace

std::string DistortionModelName(DistortionModel model) {
  switch (model) {
    case DistortionModel::kNone:
      return "none";
    case DistortionModel::kRadtan:
      return "radtan";
    case DistortionModel::kEquidistant:
      return "equidistant";
  }
  return "unknown";
}

DistortionModel ParseDistortionModel(const std::string& name) {
  if (name == "none") return DistortionModel::kNone;
  if (name == "radtan") return DistortionModel::kRadtan;
  if (name == "equidistant") return DistortionModel::kEquidistant;
  throw InputError("unknown distortion model '" + name +
                   "' (expected radtan, equidistant or none)");
}

int NumDistortionCoeffs(DistortionModel model) {
  return model == DistortionModel::kNone ? 0 : 4;
}

bool CameraModel::Project(const Vec3& x_in_cam, Vec2* pixel, bool check_bounds) const {
  THROW_CHECK(pixel != nullptr);
  const std::array<double, 8> params = ParamArray(*this);
  const double x = x_in_cam.x(), y = x_in_cam.y(), z = x_in_cam.z();
  switch (distortion) {
    case DistortionModel::kNone:
      if (!(z > 0.0)) return false;
      PinholeCameraModel::ImgFromCam(params.data(), x / z, y / z, &pixel->x(), &pixel->y());
      break;
    case DistortionModel::kRadtan: {
      if (!(z > 0.0)) return false;
      const double u = x / z, v = y / z;
      OpenCVCameraModel::ImgFromCam(params.data(), u, v, &pixel->x(), &pixel->y());
      const double r = std::hypot(u, v);
      if (!IncreasingUpTo(r, [&](double s) { return RadtanRadialSlope(distortion_coeffs, s); })) {
        return false;
      }
      break;
    }
    case DistortionModel::kEquidistant: {
      if (x == 0.0 && y == 0.0 && !(z > 0.0)) return false;  // on the optical axis, behind
      double a, b;
      const double theta = OpenCVFisheyeCameraModel::FisheyeFromRay(x, y, z, &a, &b);
      OpenCVFisheyeCameraModel::ImgFromUndistorted(params.data(), a, b, &pixel->x(), &pixel->y());
      if (!(theta < M_PI)) return false;
      if (!IncreasingUpTo(theta,
                          [&](double t) { return EquidistantSlope(distortion_coeffs, t); })) {
        return false;
      }
      break;
    }
  }
  return !check_bounds || InImage(*pixel);
}

bool CameraModel::Unproject(const Vec2& pixel, Vec3* ray) const {
  THROW_CHECK(ray != nullptr);
  const std::array<double, 8> params = ParamArray(*this);
  switch (distortion) {
    case DistortionModel::kNone: {
      double u, v;
      PinholeCameraModel::UndistortedFromImg(params.data(), pixel.x(), pixel.y(), &u, &v);
      *ray = Vec3(u, v, 1.0).normalized();
      return true;
    }
    case DistortionModel::kRadtan: {
      double u, v;
      const double residual =
          OpenCVCameraModel::UndistortedFromImg(params.data(), pixel.x(), pixel.y(), &u, &v);
      *ray = Vec3(u, v, 1.0).normalized();
      return residual < kMaxUndistortionResidual && IncreasingUpTo(std::hypot(u, v), [&](double s) {
               return RadtanRadialSlope(distortion_coeffs, s);
             });
    }
    case DistortionModel::kEquidistant: {
      double a, b;
      const double residual =
          OpenCVFisheyeCameraModel::UndistortedFromImg(params.data(), pixel.x(), pixel.y(), &a, &b);
      OpenCVFisheyeCameraModel::RayFromFisheye(a, b, &ray->x(), &ray->y(), &ray->z());
      const double theta = std::hypot(a, b);
      return residual < kMaxUndistortionResidual && theta < M_PI &&
             IncreasingUpTo(theta,
                            [&](double t) { return EquidistantSlope(distortion_coeffs, t); });
    }
  }
  return false;
}

Vec3 CameraModel::Unproject(const Vec2& pixel) const {
  Vec3 ray;
  Unproject(pixel, &ray);
  return ray;
}

bool CameraModel::InImage(const Vec2& pixel) const {
  return pixel.x() >= -0.5 && pixel.x() < width - 0.5 && pixel.y() >= -0.5 &&
         pixel.y() < height - 0.5;
}

CameraModelId CameraModel::ModelId() const {
  switch (distortion) {
    case DistortionModel::kNone:
      return CameraModelId::kPinhole;
    case DistortionModel::kRadtan:
      return CameraModelId::kOpenCV;
    case DistortionModel::kEquidistant:
      return CameraModelId::kOpenCVFisheye;
  }
  return CameraModelId::kInvalid;
}

std::vector<double> CameraModel::Params() const {
  std::vector<double> params = {fx, fy, cx, cy};
  params.insert(params.end(), distortion_coeffs.begin(), distortion_coeffs.end());
  return params;
}

void CameraModel::Validate(const std::string& where) const {
  auto fail = [&](const std::string& field, const std::string& message) {
    throw InputError(where + "." + field + ": " + message);
  };
  if (width <= 0 || height <= 0) {
    fail("resolution", fmt::format("expected positive [width height], found [{} {}]", width, height));
  }
  if (!(std::isfinite(fx) && std::isfinite(fy) && fx > 0.0 && fy > 0.0)) {
    fail("intrinsics", fmt::format("expected focal lengths fu, fv > 0, found {} {}", fx, fy));
  }
  if (!(std::isfinite(cx) && std::isfinite(cy))) {
    fail("intrinsics", fmt::format("expected finite pu, pv, found {} {}", cx, cy));
  }
  const int expected = NumDistortionCoeffs(distortion);
  if (static_cast<int>(distortion_coeffs.size()) != expected) {
    fail("distortion_coeffs",
         fmt::format("expected {} coefficients for distortion_model {}, found {}", expected,
                     DistortionModelName(distortion), distortion_coeffs.size()));
  }
  if (!AllFinite(distortion_coeffs)) fail("distortion_coeffs", "expected finite numbers");
}

}  // namespace lisfm
