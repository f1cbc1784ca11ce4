#include "icp/nearest_neighbors.h"

#include <cmath>
#include <limits>
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

namespace {

// Reference implementation (std::unordered_map); used when a voxel index does
// not fit the 21-bit packing of the fast path below.
PointSet VoxelDownsampleHashMap(const PointSet& points, double inv) {
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

}  // namespace

PointSet VoxelDownsamplePoints(const PointSet& points, double voxel_size_m) {
  if (voxel_size_m <= 0) return points;
  const double inv = 1.0 / voxel_size_m;
  // Fast path: voxel indices packed into 63 bits (21 bits per axis, offset by
  // 2^20) in an open-addressing table (linear probing, load <= 0.5). Same
  // first-appearance order and summation order as the hash map, hence
  // bit-identical output; ~3x faster than std::unordered_map on 100k points.
  // The table grows with the number of voxels (doubling, rehashing the keys;
  // the voxel order lives in `sums`, so it is unaffected): a downsampled scan
  // has a fraction of its points' voxels, and a table sized for the points
  // would not stay in cache.
  constexpr int64_t kHalfRange = int64_t{1} << 20;
  constexpr uint64_t kEmpty = ~uint64_t{0};
  size_t capacity = 1024;
  while (capacity < points.size() / 4) capacity *= 2;
  int shift = 64;
  for (size_t c = capacity; c > 1; c >>= 1) --shift;
  std::vector<uint64_t> keys(capacity, kEmpty);
  std::vector<uint32_t> slots(capacity);
  std::vector<Eigen::Vector4d> sums;  // xyz sum, count
  sums.reserve(points.size() / 4 + 16);
  const auto grow = [&] {
    std::vector<uint64_t> old_keys(2 * capacity, kEmpty);
    std::vector<uint32_t> old_slots(2 * capacity);
    old_keys.swap(keys);
    old_slots.swap(slots);
    capacity *= 2;
    --shift;
    for (size_t j = 0; j < old_keys.size(); ++j) {
      if (old_keys[j] == kEmpty) continue;
      size_t h = static_cast<size_t>((old_keys[j] * 0x9E3779B97F4A7C15ULL) >> shift);
      while (keys[h] != kEmpty) h = (h + 1) & (capacity - 1);
      keys[h] = old_keys[j];
      slots[h] = old_slots[j];
    }
  };
  for (const auto& p : points) {
    if (!p.allFinite()) continue;
    const double fx = std::floor(p.x() * inv), fy = std::floor(p.y() * inv),
                 fz = std::floor(p.z() * inv);
    if (!(std::abs(fx) < kHalfRange && std::abs(fy) < kHalfRange && std::abs(fz) < kHalfRange)) {
      return VoxelDownsampleHashMap(points, inv);
    }
    const uint64_t key = (static_cast<uint64_t>(static_cast<int64_t>(fx) + kHalfRange) << 42) |
                         (static_cast<uint64_t>(static_cast<int64_t>(fy) + kHalfRange) << 21) |
                         static_cast<uint64_t>(static_cast<int64_t>(fz) + kHalfRange);
    size_t h = static_cast<size_t>((key * 0x9E3779B97F4A7C15ULL) >> shift);
    while (keys[h] != kEmpty && keys[h] != key) h = (h + 1) & (capacity - 1);
    if (keys[h] == kEmpty) {
      keys[h] = key;
      slots[h] = static_cast<uint32_t>(sums.size());
      sums.emplace_back(Eigen::Vector4d::Zero());
      if (2 * sums.size() > capacity) {
        grow();  // h is stale now; the new voxel is the last one
        sums.back() += Eigen::Vector4d(p.x(), p.y(), p.z(), 1.0);
        continue;
      }
    }
    sums[slots[h]] += Eigen::Vector4d(p.x(), p.y(), p.z(), 1.0);
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

bool KdTree::NearestWithin(const Eigen::Vector3f& query, float max_sq_dist, uint32_t* index,
                           float* sq_dist) const {
  if (points_.empty() || !(max_sq_dist >= 0)) return false;
  nanoflann::KNNResultSet<float, uint32_t> result(1);
  result.init(index, sq_dist);
  // Seed the worst distance with the bound (next float up, so that a point exactly
  // at the bound is still found): nanoflann adds only points strictly closer than
  // worstDist() and prunes every cell farther than it.
  *sq_dist = std::nextafter(max_sq_dist, std::numeric_limits<float>::infinity());
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

size_t KdTree::KnnWithin(const Eigen::Vector3f& query,
                         size_t k,
                         float max_sq_dist,
                         uint32_t* indices,
                         float* sq_dists) const {
  if (points_.empty() || k == 0 || !(max_sq_dist >= 0)) return 0;
  nanoflann::KNNResultSet<float, uint32_t> result(k);
  result.init(indices, sq_dists);
  // As in NearestWithin: the k-th slot is nanoflann's pruning bound (worstDist)
  // until k points closer than it are found.
  sq_dists[k - 1] = std::nextafter(max_sq_dist, std::numeric_limits<float>::infinity());
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
