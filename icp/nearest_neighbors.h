// Nearest-neighbour search over 3D point sets, and voxel downsampling.
//
// Points are float32 (Eigen::Vector3f), contiguous: this is what LiDAR sensors
// deliver, halves memory traffic, and is accurate to < 1 um at 100 m. The tree is
// lisfm's own static KD-tree (exact search; median splits, leaves of 24 points
// stored contiguously in leaf order, parallel build; nearest_neighbors.cc). Chosen by
// benchmark (`lisfm_icp_bench DATA --knn`, scripts/bench_icp.sh, docs/BENCHMARKS.md,
// "ICP registration vs PCL and Open3D"): on the ICP's own queries over a downsampled
// BALM scan (10-NN at target points, 2-NN of source points) it is ~1.25x faster than
// nanoflann 1.4.3 (itself 1.3-1.5x faster than FLANN's exact single KD-tree), builds in
// parallel, and takes ~13 % off a whole registration. FLANN's randomised forests are
// approximate, which ICP's residual statistics and the covariances do not tolerate.
// nanoflann and FLANN stay the references in the benchmark.
//
// Threads: a built KdTree is immutable; all queries are const and thread-safe.
// Failures: constructing from a point set with non-finite coordinates throws
// InputError (the caller names the cloud through `what`).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/StdVector>

#include "core/point_cloud.h"

namespace lisfm {

using PointSet = std::vector<Eigen::Vector3f>;

// Throws InputError(what, "point N", "expected finite x y z, found ...") when a
// point is non-finite.
void CheckFinitePoints(const PointSet& points, const std::string& what);

// Positions of `cloud` as float points. Non-finite points are dropped and counted
// in *num_dropped (may be null); organised clouds (NaN placeholders) are common.
PointSet FinitePointsOf(const PointCloud& cloud, size_t* num_dropped = nullptr);

// One point per occupied voxel of edge `voxel_size_m`: the centroid of the
// voxel's points. voxel_size_m <= 0 returns the input. Deterministic (output in
// order of first appearance). Non-finite points are skipped.
PointSet VoxelDownsamplePoints(const PointSet& points, double voxel_size_m);

class KdTree {
 public:
  // Copies the points and builds the tree. Throws InputError for non-finite points
  // (`what` names the cloud in the message). An empty set gives an empty tree.
  explicit KdTree(PointSet points, const std::string& what = "cloud");
  ~KdTree();
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  const PointSet& points() const { return points_; }
  size_t size() const { return points_.size(); }

  // Nearest point: returns false for an empty tree; else fills index and squared
  // distance (m^2).
  bool Nearest(const Eigen::Vector3f& query, uint32_t* index, float* sq_dist) const;
  // Nearest point with squared distance <= max_sq_dist (m^2), else false. Same
  // result as Nearest() followed by the distance test, but the search prunes with
  // the bound from the start (much cheaper for queries far from every point).
  bool NearestWithin(const Eigen::Vector3f& query, float max_sq_dist, uint32_t* index,
                     float* sq_dist) const;

  // Up to k nearest points, closest first. Returns how many were found.
  size_t Knn(const Eigen::Vector3f& query,
             size_t k,
             uint32_t* indices,
             float* sq_dists) const;
  // Up to k nearest points with squared distance <= max_sq_dist (m^2), closest
  // first: the same points as Knn() followed by dropping those beyond the bound,
  // but the search prunes with the bound until k points are found. Every point
  // not returned is farther than the k-th returned one, or than the bound when
  // fewer than k are returned.
  size_t KnnWithin(const Eigen::Vector3f& query,
                   size_t k,
                   float max_sq_dist,
                   uint32_t* indices,
                   float* sq_dists) const;

  // All points within `radius_m`, closest first.
  void Radius(const Eigen::Vector3f& query,
              float radius_m,
              std::vector<uint32_t>* indices,
              std::vector<float>* sq_dists) const;

 private:
  struct Impl;
  PointSet points_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lisfm
