#include "core/point_cloud.h"

#include <algorithm>
#include <limits>
#include <unordered_map>

#include "core/errors.h"

namespace lisfm {

namespace {

struct VoxelKey {
  int64_t x, y, z;
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
  std::unordered_map<VoxelKey, uint32_t, VoxelKeyHash> voxel_ids;
  voxel_ids.reserve(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    const LidarPoint& p = cloud.points[i];
    if (!IsFinite(p)) continue;
    const VoxelKey key{VoxelIndex(p.x, inv_voxel_size),
                       VoxelIndex(p.y, inv_voxel_size),
                       VoxelIndex(p.z, inv_voxel_size)};
    const auto [it, inserted] = voxel_ids.try_emplace(key, static_cast<uint32_t>(voxels.size()));
    if (inserted) voxels.emplace_back();
    Voxel& voxel = voxels[it->second];
    voxel.centroid += p.xyzd();
    ++voxel.count;
    voxel_of_point[i] = it->second;
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
