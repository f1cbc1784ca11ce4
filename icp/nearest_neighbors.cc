#include "icp/nearest_neighbors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <unordered_map>

#include <fmt/format.h>
#include <tbb/parallel_invoke.h>

#include "core/errors.h"

namespace lisfm {

namespace {

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

// lisfm's own static 3-D KD-tree, the engine behind KdTree (chosen by benchmark
// over nanoflann 1.4.3 and FLANN; `lisfm_icp_bench --knn`, nearest_neighbors.h).
// - Build: median split (nth_element) along the widest side of the node's cell,
//   leaves of at most kLeafSize points. The points are permuted in place as
//   (x, y, z, index) records, so at the end they lie in leaf order, each leaf one
//   contiguous run, and are stored as three float arrays (structure of arrays) for
//   the leaf scan. Nodes are numbered in pre-order from the subtree sizes, which
//   follow from the point counts alone, so the halves of the top levels are built
//   as parallel TBB tasks and the tree does not depend on the thread count.
// - Each inner node keeps the largest coordinate of its left half and the smallest
//   of its right half along the split axis (the gap between the halves prunes
//   too), and the search carries the incremental squared distance to the cell
//   (Arya & Mount 1993): a subtree is visited only when its cell is strictly closer
//   than the current k-th distance. A leaf computes all its squared distances
//   first (a loop the compiler vectorises), then inserts those below the bound.
// Exact: the same neighbours as a brute-force scan with the float distance
// (dx^2 + dy^2) + dz^2, up to the order among exactly equal distances.
class StaticKdTree {
 public:
  static constexpr uint32_t kLeafSize = 24;

  explicit StaticKdTree(const PointSet& points) {
    const size_t n = points.size();
    if (n == 0) return;
    std::vector<Record> records(n);
    Eigen::Vector3f lo = points[0], hi = points[0];
    for (size_t i = 0; i < n; ++i) {
      records[i] = Record{{points[i].x(), points[i].y(), points[i].z()}, static_cast<uint32_t>(i)};
      lo = lo.cwiseMin(points[i]);
      hi = hi.cwiseMax(points[i]);
    }
    nodes_.resize(NumNodes(n));
    Build(records.data(), 0, static_cast<uint32_t>(n), 0, lo, hi);
    x_.resize(n);
    y_.resize(n);
    z_.resize(n);
    original_.resize(n);
    for (size_t i = 0; i < n; ++i) {
      x_[i] = records[i].p[0];
      y_[i] = records[i].p[1];
      z_[i] = records[i].p[2];
      original_[i] = records[i].index;
    }
  }

  bool empty() const { return nodes_.empty(); }

  // k-NN with squared distance strictly below *bound (the caller's pruning bound);
  // dist/index sorted ascending, `count` filled so far.
  struct Result {
    size_t k;
    float* dist;
    uint32_t* index;
    size_t count = 0;
    float worst;  // the k-th distance once full, else the bound
    void Add(float d, uint32_t i) {
      size_t j = count < k ? count++ : k - 1;
      while (j > 0 && dist[j - 1] > d) {
        dist[j] = dist[j - 1];
        index[j] = index[j - 1];
        --j;
      }
      dist[j] = d;
      index[j] = i;
      if (count == k) worst = dist[k - 1];
    }
  };

  void Knn(const float* q, Result* result) const {
    float off[3] = {0.f, 0.f, 0.f};
    Search(0, q, 0.f, off, result);
    for (size_t j = 0; j < result->count; ++j) result->index[j] = original_[result->index[j]];
  }

  // All points with squared distance <= r2, unsorted (positions mapped to the
  // caller's indices).
  void Radius(const float* q, float r2, std::vector<std::pair<float, uint32_t>>* out) const {
    float off[3] = {0.f, 0.f, 0.f};
    RadiusSearch(0, q, 0.f, off, r2, out);
  }

 private:
  struct Record {
    float p[3];
    uint32_t index;
  };
  struct Node {
    // Inner: split axis (0..2), left_max / right_min along it, right child id
    // (left child = this + 1). Leaf: axis 3, points [begin, end).
    uint32_t axis;
    uint32_t right_or_begin;
    uint32_t end;
    float left_max, right_min;
  };

  static size_t NumNodes(size_t n) {
    return n <= kLeafSize ? 1 : 1 + NumNodes(n / 2) + NumNodes(n - n / 2);
  }

  void Build(Record* r, uint32_t begin, uint32_t end, uint32_t id, Eigen::Vector3f lo,
             Eigen::Vector3f hi) {
    Node& node = nodes_[id];
    const uint32_t n = end - begin;
    if (n <= kLeafSize) {
      node = Node{3u, begin, end, 0.f, 0.f};
      return;
    }
    int axis = 0;
    const Eigen::Vector3f extent = hi - lo;
    if (extent.y() > extent[axis]) axis = 1;
    if (extent.z() > extent[axis]) axis = 2;
    const uint32_t mid = begin + n / 2;
    // One comparator per axis (a constant index compiles to a plain load).
    const auto select = [&](auto axis_constant) {
      constexpr int a = decltype(axis_constant)::value;
      std::nth_element(r + begin, r + mid, r + end,
                       [](const Record& x, const Record& y) { return x.p[a] < y.p[a]; });
    };
    if (axis == 0) {
      select(std::integral_constant<int, 0>());
    } else if (axis == 1) {
      select(std::integral_constant<int, 1>());
    } else {
      select(std::integral_constant<int, 2>());
    }
    float left_max = r[begin].p[axis];
    for (uint32_t i = begin + 1; i < mid; ++i) left_max = std::max(left_max, r[i].p[axis]);
    const float right_min = r[mid].p[axis];
    const uint32_t right_id = id + 1 + static_cast<uint32_t>(NumNodes(n / 2));
    node = Node{static_cast<uint32_t>(axis), right_id, 0u, left_max, right_min};
    Eigen::Vector3f left_hi = hi, right_lo = lo;
    left_hi[axis] = left_max;
    right_lo[axis] = right_min;
    if (n > 8192) {
      tbb::parallel_invoke([&] { Build(r, begin, mid, id + 1, lo, left_hi); },
                           [&] { Build(r, mid, end, right_id, right_lo, hi); });
    } else {
      Build(r, begin, mid, id + 1, lo, left_hi);
      Build(r, mid, end, right_id, right_lo, hi);
    }
  }

  void Search(uint32_t id, const float* q, float rd, float* off, Result* result) const {
    const Node& node = nodes_[id];
    if (node.axis == 3) {
      float d2[kLeafSize];
      const uint32_t b = node.right_or_begin, m = node.end - b;
      const float* xs = x_.data() + b;
      const float* ys = y_.data() + b;
      const float* zs = z_.data() + b;
      for (uint32_t j = 0; j < m; ++j) {
        const float dx = xs[j] - q[0], dy = ys[j] - q[1], dz = zs[j] - q[2];
        d2[j] = dx * dx + dy * dy + dz * dz;
      }
      for (uint32_t j = 0; j < m; ++j) {
        if (d2[j] < result->worst) result->Add(d2[j], b + j);
      }
      return;
    }
    const uint32_t axis = node.axis;
    const float to_left = q[axis] - node.left_max;    // > 0: q beyond the left cell
    const float to_right = q[axis] - node.right_min;  // < 0: q before the right cell
    uint32_t first, second;
    float cut;
    if (to_left + to_right < 0) {
      first = id + 1;
      second = node.right_or_begin;
      cut = to_right;
    } else {
      first = node.right_or_begin;
      second = id + 1;
      cut = to_left;
    }
    Search(first, q, rd, off, result);
    const float saved = off[axis];
    const float rd_second = rd - saved * saved + cut * cut;
    if (rd_second < result->worst) {
      off[axis] = cut;
      Search(second, q, rd_second, off, result);
      off[axis] = saved;
    }
  }

  void RadiusSearch(uint32_t id, const float* q, float rd, float* off, float r2,
                    std::vector<std::pair<float, uint32_t>>* out) const {
    const Node& node = nodes_[id];
    if (node.axis == 3) {
      for (uint32_t j = node.right_or_begin; j < node.end; ++j) {
        const float dx = x_[j] - q[0], dy = y_[j] - q[1], dz = z_[j] - q[2];
        const float d = dx * dx + dy * dy + dz * dz;
        if (d <= r2) out->emplace_back(d, original_[j]);
      }
      return;
    }
    const uint32_t axis = node.axis;
    const float to_left = q[axis] - node.left_max;
    const float to_right = q[axis] - node.right_min;
    const bool left_first = to_left + to_right < 0;
    const uint32_t first = left_first ? id + 1 : node.right_or_begin;
    const uint32_t second = left_first ? node.right_or_begin : id + 1;
    const float cut = left_first ? to_right : to_left;
    RadiusSearch(first, q, rd, off, r2, out);
    const float saved = off[axis];
    const float rd_second = rd - saved * saved + cut * cut;
    if (rd_second <= r2) {
      off[axis] = cut;
      RadiusSearch(second, q, rd_second, off, r2, out);
      off[axis] = saved;
    }
  }

  std::vector<Node> nodes_;
  std::vector<float> x_, y_, z_;    // points in leaf order
  std::vector<uint32_t> original_;  // leaf-order position -> caller's index
};

struct KdTree::Impl {
  StaticKdTree tree;
  explicit Impl(const PointSet& points) : tree(points) {}
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
  // The table grows with the number of voxels (doubling and re-inserting the
  // entries; each keeps its rank of first appearance, so the order is
  // unaffected) from a start sized for half the points (below).
  constexpr int64_t kHalfRange = int64_t{1} << 20;
  constexpr uint64_t kEmpty = ~uint64_t{0};
  // One table entry per voxel holds the key, the running sums and the voxel's
  // rank of first appearance, so a point costs one random memory access (the
  // points of a scan file are often not in scan order).
  struct Entry {
    uint64_t key;
    double sum[3];
    uint32_t count;
    uint32_t order;  // rank of first appearance = output position
  };
  // Initial capacity: a power of two >= half the points, enough for a BALM scan
  // at 0.1 m (90k points, 25k voxels) without a growth step, whose re-insertion
  // cost ~15 % of that grid; at 0.25 m (10k voxels) the larger table costs
  // nothing measurable (its accesses are prefetched, below).
  size_t capacity = 1024;
  while (capacity < points.size() / 2) capacity *= 2;
  int shift = 64;
  for (size_t c = capacity; c > 1; c >>= 1) --shift;
  std::vector<Entry> table(capacity);
  for (Entry& e : table) e.key = kEmpty;
  uint32_t num_voxels = 0;
  const auto grow = [&] {
    std::vector<Entry> old(2 * capacity);
    for (Entry& e : old) e.key = kEmpty;
    old.swap(table);
    capacity *= 2;
    --shift;
    for (const Entry& e : old) {
      if (e.key == kEmpty) continue;
      size_t h = static_cast<size_t>((e.key * 0x9E3779B97F4A7C15ULL) >> shift);
      while (table[h].key != kEmpty) h = (h + 1) & (capacity - 1);
      table[h] = e;
    }
  };
  // The keys first (a sequential pass; kEmpty marks non-finite points), so that
  // the table slot of a point kPrefetch ahead can be prefetched: the table does
  // not fit the L2 cache and the accesses are random, so the loop below is bound
  // by memory latency, which the prefetches overlap (hints only: the output is
  // unaffected).
  std::vector<uint64_t> keys(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    if (!p.allFinite()) {
      keys[i] = kEmpty;
      continue;
    }
    const double fx = std::floor(p.x() * inv), fy = std::floor(p.y() * inv),
                 fz = std::floor(p.z() * inv);
    if (!(std::abs(fx) < kHalfRange && std::abs(fy) < kHalfRange && std::abs(fz) < kHalfRange)) {
      return VoxelDownsampleHashMap(points, inv);
    }
    keys[i] = (static_cast<uint64_t>(static_cast<int64_t>(fx) + kHalfRange) << 42) |
              (static_cast<uint64_t>(static_cast<int64_t>(fy) + kHalfRange) << 21) |
              static_cast<uint64_t>(static_cast<int64_t>(fz) + kHalfRange);
  }
  constexpr size_t kPrefetch = 16;
  for (size_t i = 0; i < points.size(); ++i) {
    if (i + kPrefetch < points.size() && keys[i + kPrefetch] != kEmpty) {
      __builtin_prefetch(
          &table[static_cast<size_t>((keys[i + kPrefetch] * 0x9E3779B97F4A7C15ULL) >> shift)], 1);
    }
    const uint64_t key = keys[i];
    if (key == kEmpty) continue;
    const Eigen::Vector3f& p = points[i];
    size_t h = static_cast<size_t>((key * 0x9E3779B97F4A7C15ULL) >> shift);
    while (table[h].key != kEmpty && table[h].key != key) h = (h + 1) & (capacity - 1);
    if (table[h].key == kEmpty) {
      table[h] = Entry{key, {0.0, 0.0, 0.0}, 0u, num_voxels++};
      if (2 * static_cast<size_t>(num_voxels) > capacity) {
        grow();  // h is stale now: find the new voxel again
        h = static_cast<size_t>((key * 0x9E3779B97F4A7C15ULL) >> shift);
        while (table[h].key != key) h = (h + 1) & (capacity - 1);
      }
    }
    Entry& e = table[h];
    e.sum[0] += p.x();
    e.sum[1] += p.y();
    e.sum[2] += p.z();
    ++e.count;
  }
  PointSet out(num_voxels);
  for (const Entry& e : table) {
    if (e.key == kEmpty) continue;
    const double n = e.count;
    out[e.order] = Eigen::Vector3d(e.sum[0] / n, e.sum[1] / n, e.sum[2] / n).cast<float>();
  }
  return out;
}

KdTree::KdTree(PointSet points, const std::string& what) : points_(std::move(points)) {
  CheckFinitePoints(points_, what);
  impl_ = std::make_unique<Impl>(points_);
}

KdTree::~KdTree() = default;

bool KdTree::Nearest(const Eigen::Vector3f& query, uint32_t* index, float* sq_dist) const {
  return NearestWithin(query, std::numeric_limits<float>::infinity(), index, sq_dist);
}

bool KdTree::NearestWithin(const Eigen::Vector3f& query, float max_sq_dist, uint32_t* index,
                           float* sq_dist) const {
  return KnnWithin(query, 1, max_sq_dist, index, sq_dist) == 1;
}

size_t KdTree::Knn(const Eigen::Vector3f& query,
                   size_t k,
                   uint32_t* indices,
                   float* sq_dists) const {
  return KnnWithin(query, k, std::numeric_limits<float>::infinity(), indices, sq_dists);
}

size_t KdTree::KnnWithin(const Eigen::Vector3f& query,
                         size_t k,
                         float max_sq_dist,
                         uint32_t* indices,
                         float* sq_dists) const {
  if (impl_->tree.empty() || k == 0 || !(max_sq_dist >= 0)) return 0;
  // Points exactly at the bound are included: the search keeps points strictly
  // below `worst`, so start it one float above the bound.
  StaticKdTree::Result result{k, sq_dists, indices, 0,
                              std::nextafter(max_sq_dist, std::numeric_limits<float>::infinity())};
  impl_->tree.Knn(query.data(), &result);
  return result.count;
}

void KdTree::Radius(const Eigen::Vector3f& query,
                    float radius_m,
                    std::vector<uint32_t>* indices,
                    std::vector<float>* sq_dists) const {
  indices->clear();
  sq_dists->clear();
  if (impl_->tree.empty()) return;
  std::vector<std::pair<float, uint32_t>> matches;
  impl_->tree.Radius(query.data(), radius_m * radius_m, &matches);
  std::sort(matches.begin(), matches.end());
  for (const auto& m : matches) {
    indices->push_back(m.second);
    sq_dists->push_back(m.first);
  }
}

}  // namespace lisfm
