#include "core/camera_model.h"

#include <cmath>

#include <fmt/format.h>

#include "core/errors.h"

namespace lisfm {
namespace {

// Newton iterations stop when the residual (normalized image coordinates or
// radians) is below kSolveTolerance; a result counts as converged below
// kConvergedTolerance (the 1e-10 of the contract).
constexpr double kSolveTolerance = 1e-14;
constexpr double kConvergedTolerance = 1e-10;
constexpr int kMaxIterations = 100;
// The invertibility of a distortion polynomial is checked at this many
// equally spaced samples of [0, r] (the derivatives are polynomials of degree
// <= 4 in r^2, so 8 samples catch every sign change but a pair of close roots).
constexpr int kMonotonicSamples = 8;

// Radtan distortion of normalized coordinates m and its 2x2 Jacobian.
Vec2 RadtanDistort(const std::vector<double>& k,
                  const Vec2& m,
                  Eigen::Matrix2d* jacobian) {
  const double k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3];
  const double x = m.x(), y = m.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + k1 * r2 + k2 * r2 * r2;
  const Vec2 d(x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
               y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y);
  if (jacobian != nullptr) {
    const double dradial_dr2 = k1 + 2.0 * k2 * r2;
    (*jacobian)(0, 0) = radial + 2.0 * x * x * dradial_dr2 + 2.0 * p1 * y + 6.0 * p2 * x;
    (*jacobian)(0, 1) = 2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y;
    (*jacobian)(1, 0) = (*jacobian)(0, 1);
    (*jacobian)(1, 1) = radial + 2.0 * y * y * dradial_dr2 + 6.0 * p1 * y + 2.0 * p2 * x;
  }
  return d;
}

// d/dr of r (1 + k1 r^2 + k2 r^4).
double RadtanRadialSlope(const std::vector<double>& k, double r) {
  const double r2 = r * r;
  return 1.0 + 3.0 * k[0] * r2 + 5.0 * k[1] * r2 * r2;
}

// theta_d(theta) of the equidistant model and its derivative.
double EquidistantThetaD(const std::vector<double>& k, double theta, double* slope) {
  const double t2 = theta * theta;
  const double t4 = t2 * t2, t6 = t4 * t2, t8 = t4 * t4;
  if (slope != nullptr) {
    *slope = 1.0 + 3.0 * k[0] * t2 + 5.0 * k[1] * t4 + 7.0 * k[2] * t6 + 9.0 * k[3] * t8;
  }
  return theta * (1.0 + k[0] * t2 + k[1] * t4 + k[2] * t6 + k[3] * t8);
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
  const double x = x_in_cam.x(), y = x_in_cam.y(), z = x_in_cam.z();
  Vec2 m_distorted = Vec2::Zero();
  switch (distortion) {
    case DistortionModel::kNone:
    case DistortionModel::kRadtan: {
      if (!(z > 0.0)) return false;
      const Vec2 m(x / z, y / z);
      if (distortion == DistortionModel::kNone) {
        m_distorted = m;
      } else {
        THROW_CHECK_EQ(distortion_coeffs.size(), 4u);
        m_distorted = RadtanDistort(distortion_coeffs, m, nullptr);
        const double r = m.norm();
        if (!IncreasingUpTo(r, [&](double s) { return RadtanRadialSlope(distortion_coeffs, s); })) {
          *pixel = Vec2(fx * m_distorted.x() + cx, fy * m_distorted.y() + cy);
          return false;
        }
      }
      break;
    }
    case DistortionModel::kEquidistant: {
      THROW_CHECK_EQ(distortion_coeffs.size(), 4u);
      const double r = std::hypot(x, y);
      if (r == 0.0 && !(z > 0.0)) return false;  // on the optical axis, behind
      const double theta = std::atan2(r, z);
      const double theta_d = EquidistantThetaD(distortion_coeffs, theta, nullptr);
      // theta_d / r -> 1 / z on the optical axis (theta ~ r / z).
      const double scale = r > 1e-300 ? theta_d / r : 1.0 / z;
      m_distorted = Vec2(x * scale, y * scale);
      *pixel = Vec2(fx * m_distorted.x() + cx, fy * m_distorted.y() + cy);
      if (!(theta < M_PI)) return false;
      double slope = 0.0;
      if (!IncreasingUpTo(theta, [&](double t) {
            EquidistantThetaD(distortion_coeffs, t, &slope);
            return slope;
          })) {
        return false;
      }
      break;
    }
  }
  *pixel = Vec2(fx * m_distorted.x() + cx, fy * m_distorted.y() + cy);
  return !check_bounds || InImage(*pixel);
}

bool CameraModel::Unproject(const Vec2& pixel, Vec3* ray) const {
  THROW_CHECK(ray != nullptr);
  const Vec2 m_distorted((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  switch (distortion) {
    case DistortionModel::kNone:
      *ray = Vec3(m_distorted.x(), m_distorted.y(), 1.0).normalized();
      return true;
    case DistortionModel::kRadtan: {
      THROW_CHECK_EQ(distortion_coeffs.size(), 4u);
      // Newton on d(m) = m_distorted, starting at m = m_distorted.
      Vec2 m = m_distorted;
      double residual = 0.0;
      for (int it = 0; it < kMaxIterations; ++it) {
        Eigen::Matrix2d jacobian;
        const Vec2 error = RadtanDistort(distortion_coeffs, m, &jacobian) - m_distorted;
        residual = error.norm();
        if (residual < kSolveTolerance) break;
        if (!(std::abs(jacobian.determinant()) > 1e-12)) break;
        m -= jacobian.inverse() * error;
        if (!m.allFinite()) break;
      }
      *ray = Vec3(m.x(), m.y(), 1.0).normalized();
      return m.allFinite() && residual < kConvergedTolerance &&
             IncreasingUpTo(m.norm(),
                            [&](double s) { return RadtanRadialSlope(distortion_coeffs, s); });
    }
    case DistortionModel::kEquidistant: {
      THROW_CHECK_EQ(distortion_coeffs.size(), 4u);
      const double theta_d = m_distorted.norm();
      if (theta_d < 1e-300) {
        *ray = Vec3(0.0, 0.0, 1.0);
        return true;
      }
      // Newton on theta_d(theta) = theta_d, starting at theta = theta_d.
      double theta = theta_d;
      double residual = 0.0;
      for (int it = 0; it < kMaxIterations; ++it) {
        double slope = 0.0;
        const double error = EquidistantThetaD(distortion_coeffs, theta, &slope) - theta_d;
        residual = std::abs(error);
        if (residual < kSolveTolerance) break;
        if (!(slope > 1e-12)) break;
        theta -= error / slope;
        if (!std::isfinite(theta)) break;
      }
      const Vec2 direction = m_distorted / theta_d;
      *ray = Vec3(std::sin(theta) * direction.x(), std::sin(theta) * direction.y(),
                  std::cos(theta));
      double slope = 0.0;
      return std::isfinite(theta) && residual < kConvergedTolerance && theta >= 0.0 &&
             theta < M_PI && IncreasingUpTo(theta, [&](double t) {
               EquidistantThetaD(distortion_coeffs, t, &slope);
               return slope;
             });
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
