#include "icp/normals.h"

#include <algorithm>

#include <Eigen/Eigenvalues>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

bool NormalOptions::Check() const {
  CHECK_OPTION_MSG(num_neighbors, num_neighbors >= 3 && num_neighbors <= 64, "in [3, 64]");
  CHECK_OPTION_GT(max_radius_m, 0.0);
  return true;
}

bool EstimateNormalAt(const KdTree& tree,
                      size_t index,
                      const NormalOptions& options,
                      const Eigen::Vector3f& viewpoint,
                      Eigen::Vector3f* normal,
                      float* planarity,
                      float* contrast) {
  constexpr size_t kMaxNeighbors = 64;
  const PointSet& pts = tree.points();
  const size_t k = std::min(static_cast<size_t>(options.num_neighbors), kMaxNeighbors);
  const float max_sq = static_cast<float>(options.max_radius_m * options.max_radius_m);
  uint32_t idx[kMaxNeighbors];
  float d2[kMaxNeighbors];
  const size_t n = tree.Knn(pts[index], k, idx, d2);
  // Mean and covariance around the query point (numerically stable for
  // coordinates far from the origin): float offsets, double sums.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  int count = 0;
  for (size_t j = 0; j < n; ++j) {
    if (d2[j] > max_sq) break;
    const Eigen::Vector3d d = (pts[idx[j]] - pts[index]).cast<double>();
    sum += d;
    outer.noalias() += d * d.transpose();
    ++count;
  }
  if (count < 3) return false;
  const Eigen::Vector3d mean = sum / count;
  const Eigen::Matrix3d cov = outer / count - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(cov);
  const Eigen::Vector3d l = eig.eigenvalues();  // ascending
  if (!(l(2) > 0)) return false;
  Eigen::Vector3f nf = eig.eigenvectors().col(0).cast<float>();
  if (nf.dot(viewpoint - pts[index]) < 0) nf = -nf;
  *normal = nf.normalized();
  *planarity = static_cast<float>(std::max(0.0, (l(1) - l(0)) / l(2)));
  if (contrast != nullptr) {
    // l1 at the rounding level of l2 (a straight line): no determined normal.
    *contrast = l(1) > 1e-9 * l(2) ? static_cast<float>(std::max(0.0, (l(1) - l(0)) / l(1))) : 0.f;
  }
  return true;
}

Normals EstimateNormals(const KdTree& tree,
                        const NormalOptions& options,
                        const Eigen::Vector3f& viewpoint) {
  THROW_CHECK_OPTIONS(options);
  const PointSet& pts = tree.points();
  Normals out;
  out.normals.assign(pts.size(), Eigen::Vector3f::Zero());
  out.planarity.assign(pts.size(), 0.f);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, pts.size(), 256),
                    [&](const tbb::blocked_range<size_t>& range) {
    for (size_t i = range.begin(); i != range.end(); ++i) {
      EstimateNormalAt(tree, i, options, viewpoint, &out.normals[i], &out.planarity[i]);
    }
  });
  return out;
}

Normals EstimateOrganizedNormals(const PointSet& vertex_map, int width, int height) {
  THROW_CHECK_EQ(vertex_map.size(), static_cast<size_t>(width) * static_cast<size_t>(height));
  Normals out;
  out.normals.assign(vertex_map.size(), Eigen::Vector3f::Zero());
  out.planarity.assign(vertex_map.size(), 0.f);
  auto valid = [&](int u, int v) {
    const Eigen::Vector3f& p = vertex_map[static_cast<size_t>(v) * width + u];
    return p.allFinite() && p.z() > 0;
  };
  tbb::parallel_for(1, std::max(1, height - 1), [&](int v) {
    for (int u = 1; u + 1 < width; ++u) {
      if (!valid(u, v) || !valid(u - 1, v) || !valid(u + 1, v) || !valid(u, v - 1) ||
          !valid(u, v + 1)) {
        continue;
      }
      const size_t i = static_cast<size_t>(v) * width + u;
      const Eigen::Vector3f du = vertex_map[i + 1] - vertex_map[i - 1];
      const Eigen::Vector3f dv = vertex_map[i + width] - vertex_map[i - width];
      Eigen::Vector3f n = du.cross(dv);
      const float norm = n.norm();
      if (!(norm > 0)) continue;
      n /= norm;
      if (n.dot(-vertex_map[i]) < 0) n = -n;
      out.normals[i] = n;
      out.planarity[i] = 1.f;
    }
  });
  return out;
}

}  // namespace lisfm
