#include "icp/nearest_neighbors.h"

#include <cmath>
#include <unordered_map>

#include <fmt/format.h>
#include <nanoflann.hpp>

#include "core/errors.h"

namespace lisfm {

namespace {

// nanoflann dataset adaptor over a PointSet.
struct PointSetAdaptor {
  const PointSet* points;
  size_t kdtree_get_point_count() const { return points->size(); }
  float kdtree_get_pt(size_t i, size_t dim) const { return (*points)[i][dim]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

using NanoTree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<float, PointSetAdaptor>,
    PointSetAdaptor,
    3,
    uint32_t>;

// Leaf size 16: measured on the LiDAR pair, 10..20 are within 5 % of each other.
constexpr size_t kLeafSize = 16;

struct VoxelKey {
  int32_t x, y, z;
  bool operator==(const VoxelKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct VoxelKeyHash {
  size_t operator()(const VoxelKey& k) const {
    // Teschner et al. 2003 spatial hash.
    return (static_cast<size_t>(k.x) * 73856093u) ^ (static_cast<size_t>(k.y) * 19349669u) ^
           (static_cast<size_t>(k.z) * 83492791u);
  }
};

}  // namespace

struct KdTree::Impl {
  PointSetAdaptor adaptor;
  NanoTree tree;
  Impl(const PointSet* points)
      : adaptor{points},
        tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize)) {}
};

void CheckFinitePoints(const PointSet& points, const std::string& what) {
  for (size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      throw InputError(what, fmt::format("point {}", i),
                       fmt::format("expected finite x y z, found {} {} {}", points[i].x(),
                                   points[i].y(), points[i].z()));
    }
  }
}

PointSet FinitePointsOf(const PointCloud& cloud, size_t* num_dropped) {
  PointSet out;
  out.reserve(cloud.size());
  for (const auto& p : cloud.points) {
    const Eigen::Vector3f x = p.xyz();
    if (x.allFinite()) out.push_back(x);
  }
  if (num_dropped != nullptr) *num_dropped = cloud.size() - out.size();
  return out;
}

PointSet VoxelDownsamplePoints(const PointSet& points, double voxel_size_m) {
  if (voxel_size_m <= 0) return points;
  const double inv = 1.0 / voxel_size_m;
  std::unordered_map<VoxelKey, uint32_t, VoxelKeyHash> slot_of;
  slot_of.reserve(points.size());
  std::vector<Eigen::Vector4d> sums;  // xyz sum, count
  for (const auto& p : points) {
    if (!p.allFinite()) continue;
    const VoxelKey key{static_cast<int32_t>(std::floor(p.x() * inv)),
                       static_cast<int32_t>(std::floor(p.y() * inv)),
                       static_cast<int32_t>(std::floor(p.z() * inv))};
    auto [it, inserted] = slot_of.try_emplace(key, static_cast<uint32_t>(sums.size()));
    if (inserted) sums.emplace_back(Eigen::Vector4d::Zero());
    sums[it->second] += Eigen::Vector4d(p.x(), p.y(), p.z(), 1.0);
  }
  PointSet out(sums.size());
  for (size_t i = 0; i < sums.size(); ++i) {
    out[i] = (sums[i].head<3>() / sums[i].w()).cast<float>();
  }
  return out;
}

KdTree::KdTree(PointSet points, const std::string& what) : points_(std::move(points)) {
  CheckFinitePoints(points_, what);
  impl_ = std::make_unique<Impl>(&points_);
}

KdTree::~KdTree() = default;

bool KdTree::Nearest(const Eigen::Vector3f& query, uint32_t* index, float* sq_dist) const {
  if (points_.empty()) return false;
  nanoflann::KNNResultSet<float, uint32_t> result(1);
  result.init(index, sq_dist);
  impl_->tree.findNeighbors(result, query.data(), nanoflann::SearchParams());
  return result.size() == 1;
}

size_t KdTree::Knn(const Eigen::Vector3f& query,
                   size_t k,
                   uint32_t* indices,
                   float* sq_dists) const {
  if (points_.empty() || k == 0) return 0;
  nanoflann::KNNResultSet<float, uint32_t> result(k);
  result.init(indices, sq_dists);
  impl_->tree.findNeighbors(result, query.data(), nanoflann::SearchParams());
  return result.size();
}

void KdTree::Radius(const Eigen::Vector3f& query,
                    float radius_m,
                    std::vector<uint32_t>* indices,
                    std::vector<float>* sq_dists) const {
  indices->clear();
  sq_dists->clear();
  if (points_.empty()) return;
  std::vector<std::pair<uint32_t, float>> matches;
  nanoflann::SearchParams params;
  params.sorted = true;
  impl_->tree.radiusSearch(query.data(), radius_m * radius_m, matches, params);
  for (const auto& m : matches) {
    indices->push_back(m.first);
    sq_dists->push_back(m.second);
  }
}

}  // namespace lisfm
