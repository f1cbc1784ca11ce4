// LiDAR points and clouds (DESIGN.md "Time"): a scan's stamp is the time of its
// first point; each point carries `t`, float32 seconds since the scan stamp, in
// [0, scan period). Points are in the frame named by the owner (sensor frame for
// raw scans, body/IMU frame for de-skewed keyframes, world for maps).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/geometry.h"
#include "core/time.h"
#include "core/types.h"

namespace lisfm {

struct LidarPoint {
  float x = 0, y = 0, z = 0;
  float intensity = 0;
  float t = 0;            // seconds since the scan stamp
  uint16_t ring = 0;      // laser ring index (0 for solid-state sensors)
  uint8_t sensor_id = 0;  // which LiDAR produced the point (lidar0, lidar1, ...)

  Eigen::Vector3f xyz() const { return {x, y, z}; }
  Vec3 xyzd() const { return {x, y, z}; }
};

struct PointCloud {
  TimestampNs stamp_ns = 0;  // time of the first point
  std::vector<LidarPoint> points;

  size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
};

// Positions only, as a 3xN matrix (for alignment, kNN and the like).
Eigen::Matrix3Xd PositionsOf(const PointCloud& cloud);

// Keeps one point per voxel of edge `voxel_size` (m): the point nearest to the
// centroid of the voxel's points, so attributes (t, ring, intensity) stay real
// measurements. voxel_size <= 0 (or NaN) returns the input unchanged.
// Deterministic: voxels are emitted in order of their first point, and ties in
// distance go to the earlier point. Points with non-finite coordinates are
// dropped. Voxels are the cells [i, i+1) * voxel_size of a grid anchored at the
// origin (coordinates beyond ~4.6e18 voxels are clamped to the outermost cell).
// O(N): one hashing pass, then one linear pass over the points; no PCL.
PointCloud VoxelDownsample(const PointCloud& cloud, double voxel_size);

// True when x, y and z are finite (organised clouds mark missing returns NaN).
inline bool IsFinite(const LidarPoint& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

// Removes, in place and keeping the order, every point whose x, y or z is NaN
// or infinite (readers keep them so organised clouds keep their layout; call
// this before kNN, ICP and the like). Returns the number of points removed.
size_t RemoveNonFinite(PointCloud* cloud);

// Applies `target_from_source` to every point (attributes and stamp are kept).
// The product is formed in double and rounded to float once per coordinate.
PointCloud TransformCloud(const PointCloud& cloud, const SE3& target_from_source);

}  // namespace lisfm
