#include "core/point_cloud.h"

#include <algorithm>
#include <limits>
#include <unordered_map>

#include "core/errors.h"

namespace lisfm {

namespace {

struct VoxelKey {
  int64_t x = 0, y = 0, z = 0;
  bool operator==(const VoxelKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

// The spatial hash of Teschner et al. (2003), as KISS-ICP's VoxelHashMap uses it.
struct VoxelKeyHash {
  size_t operator()(const VoxelKey& k) const {
    return static_cast<size_t>(static_cast<uint64_t>(k.x) * 73856093ULL ^
                               static_cast<uint64_t>(k.y) * 19349669ULL ^
                               static_cast<uint64_t>(k.z) * 83492791ULL);
  }
};

// Integer cell of a coordinate; clamped so that the cast is always defined.
int64_t VoxelIndex(double coordinate, double inv_voxel_size) {
  constexpr double kLimit = 4.6e18;  // < 2^62, well inside int64
  const double cell = std::floor(coordinate * inv_voxel_size);
  return static_cast<int64_t>(std::clamp(cell, -kLimit, kLimit));
}

struct Voxel {
  VoxelKey key{0, 0, 0};
  Vec3 centroid = Vec3::Zero();  // sum of the member points, then their mean
  int64_t count = 0;
  size_t best = 0;  // index of the member nearest to the centroid
  double best_squared_distance = std::numeric_limits<double>::infinity();
};

}  // namespace

Eigen::Matrix3Xd PositionsOf(const PointCloud& cloud) {
  Eigen::Matrix3Xd positions(3, static_cast<Eigen::Index>(cloud.size()));
  for (size_t i = 0; i < cloud.size(); ++i) {
    positions.col(static_cast<Eigen::Index>(i)) = cloud.points[i].xyzd();
  }
  return positions;
}

PointCloud VoxelDownsample(const PointCloud& cloud, double voxel_size) {
  if (!(voxel_size > 0)) return cloud;
  const double inv_voxel_size = 1.0 / voxel_size;
  constexpr uint32_t kDropped = std::numeric_limits<uint32_t>::max();
  THROW_CHECK_LT(cloud.size(), static_cast<size_t>(kDropped));

  // Pass 1: assign each finite point to a voxel (dense ids in order of first
  // appearance) and accumulate the voxel sums.
  std::vector<uint32_t> voxel_of_point(cloud.size(), kDropped);
  std::vector<Voxel> voxels;
  // Open-addressing table (linear probing, power-of-two size, load <= 1/2)
  // from voxel key to dense id: much faster than std::unordered_map here,
  // since this runs on every 64k-point scan.
  std::vector<VoxelKey> slot_keys;
  std::vector<uint32_t> slot_ids;
  size_t mask = 0;
  auto rehash = [&](size_t capacity) {
    slot_keys.assign(capacity, VoxelKey{});
    slot_ids.assign(capacity, kDropped);
    mask = capacity - 1;
    for (uint32_t id = 0; id < voxels.size(); ++id) {
      size_t h = VoxelKeyHash()(voxels[id].key) & mask;
      while (slot_ids[h] != kDropped) h = (h + 1) & mask;
      slot_keys[h] = voxels[id].key;
      slot_ids[h] = id;
    }
  };
  rehash(1024);
  for (size_t i = 0; i < cloud.size(); ++i) {
    const LidarPoint& p = cloud.points[i];
    if (!IsFinite(p)) continue;
    const VoxelKey key{VoxelIndex(p.x, inv_voxel_size),
                       VoxelIndex(p.y, inv_voxel_size),
                       VoxelIndex(p.z, inv_voxel_size)};
    size_t h = VoxelKeyHash()(key) & mask;
    while (slot_ids[h] != kDropped && !(slot_keys[h] == key)) h = (h + 1) & mask;
    uint32_t id = slot_ids[h];
    if (id == kDropped) {
      id = static_cast<uint32_t>(voxels.size());
      voxels.emplace_back();
      voxels.back().key = key;
      slot_keys[h] = key;
      slot_ids[h] = id;
      if (2 * voxels.size() > slot_ids.size()) rehash(2 * slot_ids.size());
    }
    Voxel& voxel = voxels[id];
    voxel.centroid += p.xyzd();
    ++voxel.count;
    voxel_of_point[i] = id;
  }

  for (Voxel& voxel : voxels) voxel.centroid /= static_cast<double>(voxel.count);

  // Pass 2: the member nearest to its voxel's centroid (first one on ties).
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (voxel_of_point[i] == kDropped) continue;
    Voxel& voxel = voxels[voxel_of_point[i]];
    const double d2 = (cloud.points[i].xyzd() - voxel.centroid).squaredNorm();
    if (d2 < voxel.best_squared_distance) {
      voxel.best_squared_distance = d2;
      voxel.best = i;
    }
  }

  PointCloud out;
  out.stamp_ns = cloud.stamp_ns;
  out.points.reserve(voxels.size());
  for (const Voxel& voxel : voxels) out.points.push_back(cloud.points[voxel.best]);
  return out;
}

size_t RemoveNonFinite(PointCloud* cloud) {
  THROW_CHECK(cloud != nullptr);
  const size_t before = cloud->points.size();
  cloud->points.erase(std::remove_if(cloud->points.begin(),
                                     cloud->points.end(),
                                     [](const LidarPoint& p) { return !IsFinite(p); }),
                      cloud->points.end());
  return before - cloud->points.size();
}

PointCloud TransformCloud(const PointCloud& cloud, const SE3& target_from_source) {
  const Mat3 rotation = target_from_source.RotationMatrix();
  const Vec3& translation = target_from_source.translation();
  PointCloud out = cloud;
  for (LidarPoint& p : out.points) {
    const Vec3 x = rotation * p.xyzd() + translation;
    p.x = static_cast<float>(x.x());
    p.y = static_cast<float>(x.y());
    p.z = static_cast<float>(x.z());
  }
  return out;
}

}  // namespace lisfm
