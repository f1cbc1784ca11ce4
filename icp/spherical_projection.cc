#include "icp/spherical_projection.h"

#include <cmath>
#include <limits>

#include "core/errors.h"

namespace lisfm {

SphericalProjection::SphericalProjection(int width,
                                         int height,
                                         double elevation_top_rad,
                                         double elevation_step_rad)
    : width_(width),
      height_(height),
      azimuth_step_(2.0 * M_PI / width),
      elevation_top_(elevation_top_rad),
      elevation_step_(elevation_step_rad) {
  THROW_CHECK(width >= 1 && height >= 1 && elevation_step_rad > 0);
  elevation_top_f_ = static_cast<float>(elevation_top_);
  inv_elevation_step_f_ = static_cast<float>(1.0 / elevation_step_);
  inv_azimuth_step_f_ = static_cast<float>(1.0 / azimuth_step_);
  const double above = elevation_top_ + 0.5 * elevation_step_ + 1e-3;
  const double below = elevation_top_ - (height - 0.5) * elevation_step_ - 1e-3;
  const float inf = std::numeric_limits<float>::infinity();
  tan_above_ = above < 0.5 * M_PI - 1e-6 ? static_cast<float>(std::tan(above)) : inf;
  tan_below_ = below > -0.5 * M_PI + 1e-6 ? static_cast<float>(std::tan(below)) : -inf;
  cos_azimuth_.resize(width);
  sin_azimuth_.resize(width);
  for (int u = 0; u < width; ++u) {
    const double a = M_PI - (u + 0.5) * azimuth_step_;
    cos_azimuth_[u] = static_cast<float>(std::cos(a));
    sin_azimuth_[u] = static_cast<float>(std::sin(a));
  }
  cos_elevation_.resize(height);
  sin_elevation_.resize(height);
  for (int v = 0; v < height; ++v) {
    const double e = elevation_top_ - v * elevation_step_;
    cos_elevation_[v] = static_cast<float>(std::cos(e));
    sin_elevation_[v] = static_cast<float>(std::sin(e));
  }
}

}  // namespace lisfm
