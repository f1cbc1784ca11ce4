// Synthetic scenes for the icp tests (header-only, tests only): points sampled
// on axis-aligned planes with optional Gaussian noise, and a pinhole renderer of
// a box room for the projective association.
#pragma once

#include <cmath>
#include <random>

#include "core/geometry.h"
#include "icp/icp.h"

namespace lisfm {
namespace test {

// Uniform random points on the rectangle {axis = offset} x [lo, hi] of the two
// other axes, with isotropic Gaussian noise (m).
inline void SamplePlane(int axis, double offset, const Eigen::Vector3d& lo,
                        const Eigen::Vector3d& hi, int count, double noise, std::mt19937& rng,
                        PointSet* out) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int i = 0; i < count; ++i) {
    Eigen::Vector3d p;
    for (int k = 0; k < 3; ++k) p(k) = lo(k) + (hi(k) - lo(k)) * u(rng);
    p(axis) = offset;
    if (noise > 0) p += noise * Eigen::Vector3d(g(rng), g(rng), g(rng));
    out->push_back(p.cast<float>());
  }
}

// The six inner faces of the box [-h, h] (half sizes h), `per_face` points each,
// plus two inner blocks, so that all six DoF are constrained.
inline PointSet SampleBoxRoom(const Eigen::Vector3d& h, int per_face, double noise,
                              std::mt19937& rng) {
  PointSet pts;
  for (int axis = 0; axis < 3; ++axis) {
    for (const double s : {-1.0, 1.0}) SamplePlane(axis, s * h(axis), -h, h, per_face, noise, rng, &pts);
  }
  const Eigen::Vector3d lo(0.3 * h.x(), -h.y(), 0.2 * h.z()), hi(0.6 * h.x(), 0.1 * h.y(), 0.5 * h.z());
  for (int axis = 0; axis < 3; ++axis) {
    for (const double s : {lo(axis), hi(axis)}) SamplePlane(axis, s, lo, hi, per_face / 8, noise, rng, &pts);
  }
  return pts;
}

// A corridor along x: walls y = +-1 and floor/ceiling z = +-1.2, length 2*half_length.
inline PointSet SampleCorridor(double half_length, int per_face, double noise, std::mt19937& rng) {
  PointSet pts;
  const Eigen::Vector3d lo(-half_length, -1.0, -1.2), hi(half_length, 1.0, 1.2);
  SamplePlane(1, -1.0, lo, hi, per_face, noise, rng, &pts);
  SamplePlane(1, 1.0, lo, hi, per_face, noise, rng, &pts);
  SamplePlane(2, -1.2, lo, hi, per_face, noise, rng, &pts);
  SamplePlane(2, 1.2, lo, hi, per_face, noise, rng, &pts);
  return pts;
}

// Renders the inside of the box [-h, h] from a camera at world_from_camera:
// returns the vertex map (camera frame, row-major).
inline PointSet RenderBoxRoom(const Eigen::Vector3d& h, const SE3& world_from_camera,
                              const PinholeIntrinsics& K) {
  PointSet map(static_cast<size_t>(K.width) * K.height);
  const Mat3 R = world_from_camera.RotationMatrix();
  const Vec3 o = world_from_camera.translation();
  for (int v = 0; v < K.height; ++v) {
    for (int u = 0; u < K.width; ++u) {
      const Vec3 d((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);
      const Vec3 dw = R * d;
      double t_hit = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) {
        if (std::abs(dw(k)) < 1e-12) continue;
        const double t = ((dw(k) > 0 ? h(k) : -h(k)) - o(k)) / dw(k);
        if (t > 0) t_hit = std::min(t_hit, t);
      }
      map[static_cast<size_t>(v) * K.width + u] = (t_hit * d).cast<float>();
    }
  }
  return map;
}

inline PointSet Transformed(const PointSet& pts, const SE3& T) {
  PointSet out;
  out.reserve(pts.size());
  for (const auto& p : pts) out.push_back((T * p.cast<double>()).cast<float>());
  return out;
}

}  // namespace test
}  // namespace lisfm
