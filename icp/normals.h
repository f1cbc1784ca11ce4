// Surface normals by PCA over neighbourhoods, with a planarity score.
//
// For each point, the covariance of its k nearest neighbours (within
// max_radius_m) has eigenvalues l0 <= l1 <= l2; the normal is the eigenvector of
// l0, oriented towards `viewpoint` (the sensor origin, in the cloud's frame), and
//   planarity = (l1 - l0) / l2   in [0, 1]
// (Demantke et al. 2011): ~1 on a plane, ~0 on a line or an isotropic blob.
// Points with fewer than 3 usable neighbours get a zero normal and planarity 0
// (callers treat them as invalid). Organised (image-shaped) vertex maps get
// normals from central differences of the neighbouring pixels instead.
//
// Threads: EstimateNormals runs in parallel (TBB) over points.
#pragma once

#include <vector>

#include "icp/nearest_neighbors.h"

namespace lisfm {

struct NormalOptions {
  int num_neighbors = 10;     // k of the kNN neighbourhood (3..64)
  double max_radius_m = 1.0;  // neighbours farther than this are ignored (m, > 0)
  bool Check() const;
};

struct Normals {
  std::vector<Eigen::Vector3f> normals;  // unit, or zero when invalid
  std::vector<float> planarity;          // (l1 - l0) / l2, 0 when invalid
  size_t size() const { return normals.size(); }
};

// Normal and planarity of point `index` of `tree` (the per-point work of
// EstimateNormals). Returns false (and leaves the outputs alone) when the point
// has fewer than 3 usable neighbours or a degenerate neighbourhood. When given,
// *contrast = (l1 - l0) / l1 in [0, 1]: how well the normal direction is determined
// (the ratio of the two smallest eigenvalues), independent of the neighbourhood's
// extent l2; 0 when l1 <= 1e-9 l2 (a straight line).
bool EstimateNormalAt(const KdTree& tree,
                      size_t index,
                      const NormalOptions& options,
                      const Eigen::Vector3f& viewpoint,
                      Eigen::Vector3f* normal,
                      float* planarity,
                      float* contrast = nullptr);

// Normals of `tree.points()`. Throws InternalError if options fail Check().
Normals EstimateNormals(const KdTree& tree,
                        const NormalOptions& options,
                        const Eigen::Vector3f& viewpoint = Eigen::Vector3f::Zero());

// Normals of an organised vertex map (row-major, width*height, camera frame,
// invalid pixels non-finite or z <= 0): n = (v(u+1) - v(u-1)) x (v(w+1) - v(w-1)),
// oriented towards the camera. Border and invalid pixels get zero normals.
// Planarity is 1 for valid normals (no neighbourhood statistics here).
Normals EstimateOrganizedNormals(const PointSet& vertex_map, int width, int height);

}  // namespace lisfm
