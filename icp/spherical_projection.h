// Spherical (range-image) projection of a spinning LiDAR: azimuth x elevation.
//
// Frame: the sensor (LiDAR) frame, x forward, z up the spin axis. A point p has
//   range r = |p| (m), azimuth a = atan2(p_y, p_x) in (-pi, pi], elevation
//   e = atan2(p_z, sqrt(p_x^2 + p_y^2)) (rad).
// Pixels: column u covers azimuths pi - (u + 1) da < a <= pi - u da with
//   da = 2 pi / width (u grows clockwise seen from above: the image shows the scene
//   left to right, forward (a = 0) in the middle); columns wrap around (u = width
//   is u = 0). Row v covers elevations within de / 2 of e_v = elevation_top - v de
//   (row 0 highest). The ray of pixel (u, v) is the unit vector at a_u = pi -
//   (u + 1/2) da and e_v.
// Project computes the angles with FastAtan2 (a polynomial, within 1e-5 rad of
// atan2: a 300th of the finest default step, 0.18 deg), the only per-point cost of
// rendering a map into the image.
// A pixel's "depth" is the range along its unit ray, so that the vertex of a pixel
// at depth r is r * Ray(u, v) (compare the pinhole z along (x/z, y/z, 1)).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

namespace lisfm {

// atan2(y, x) in [-pi, pi] within 1e-5 rad (an odd minimax polynomial of degree 11
// for atan on [0, 1], then octant symmetries); 0 for x = y = 0.
inline float FastAtan2(float y, float x) {
  const float ax = std::abs(x), ay = std::abs(y);
  const float hi = std::max(ax, ay);
  if (!(hi > 0.f)) return 0.f;
  const float a = std::min(ax, ay) / hi;
  const float s = a * a;
  float r =
      a * (0.99997726f +
           s * (-0.33262347f +
                s * (0.19354346f + s * (-0.11643287f + s * (0.05265332f + s * -0.01172120f)))));
  if (ay > ax) r = 1.57079637f - r;
  if (x < 0.f) r = 3.14159274f - r;
  return y < 0.f ? -r : r;
}

class SphericalProjection {
 public:
  SphericalProjection() = default;
  // width >= 1 columns over 360 deg, height >= 1 rows; elevation_step_rad > 0.
  // Throws InternalError otherwise.
  SphericalProjection(int width, int height, double elevation_top_rad, double elevation_step_rad);

  int width() const { return width_; }
  int height() const { return height_; }
  double azimuth_step_rad() const { return azimuth_step_; }
  double elevation_top_rad() const { return elevation_top_; }
  double elevation_step_rad() const { return elevation_step_; }
  size_t num_pixels() const { return static_cast<size_t>(width_) * static_cast<size_t>(height_); }

  // The pixel of p and its range; false for p = 0 and for elevations outside the
  // rows (the image wraps in azimuth, so every azimuth has a column).
  bool Project(const Eigen::Vector3f& p, int* u, int* v, float* range) const {
    const float rxy2 = p.x() * p.x() + p.y() * p.y();
    const float r2 = rxy2 + p.z() * p.z();
    if (!(r2 > 0.f)) return false;
    const float rxy = std::sqrt(rxy2);
    // Far above or below the rows (a cheap test before the angle; conservative by 1e-3 rad).
    if (p.z() > tan_above_ * rxy || p.z() < tan_below_ * rxy) return false;
    const float y = (elevation_top_f_ - FastAtan2(p.z(), rxy)) * inv_elevation_step_f_ + 0.5f;
    if (!(y >= 0.f && y < static_cast<float>(height_))) return false;
    *u = Column(p);
    *v = static_cast<int>(y);
    *range = std::sqrt(r2);
    return true;
  }

  // The column of p (p_x, p_y not both 0).
  int Column(const Eigen::Vector3f& p) const {
    const int col = static_cast<int>((kPiF - FastAtan2(p.y(), p.x())) * inv_azimuth_step_f_);
    return col >= width_ ? col - width_ : (col < 0 ? col + width_ : col);
  }

  // Unit ray of pixel (u, v), 0 <= u < width, 0 <= v < height (tables).
  Eigen::Vector3f Ray(int u, int v) const {
    const float ce = cos_elevation_[v];
    return Eigen::Vector3f(ce * cos_azimuth_[u], ce * sin_azimuth_[u], sin_elevation_[v]);
  }

  // Column u + du wrapped into [0, width).
  int WrapColumn(int u) const {
    if (u >= width_) return u - width_;
    if (u < 0) return u + width_;
    return u;
  }

 private:
  static constexpr float kPiF = 3.14159265358979f;
  int width_ = 0, height_ = 0;
  double azimuth_step_ = 0, elevation_top_ = 0, elevation_step_ = 0;
  // tan of the elevations 1e-3 rad beyond the top and bottom rows' edges (+-inf past +-90 deg).
  float tan_above_ = 0, tan_below_ = 0;
  float elevation_top_f_ = 0, inv_elevation_step_f_ = 0, inv_azimuth_step_f_ = 0;
  std::vector<float> cos_azimuth_, sin_azimuth_, cos_elevation_, sin_elevation_;
};

}  // namespace lisfm
