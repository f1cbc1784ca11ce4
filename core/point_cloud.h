// LiDAR points and clouds (DESIGN.md "Time"): a scan's stamp is the time of its
// first point; each point carries `t`, float32 seconds since the scan stamp, in
// [0, scan period). Points are in the frame named by the owner (sensor frame for
// raw scans, body/IMU frame for de-skewed keyframes, world for maps).
#pragma once

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
// measurements. voxel_size <= 0 returns the input. Deterministic order (by
// first appearance). Points with non-finite coordinates are dropped.
PointCloud VoxelDownsample(const PointCloud& cloud, double voxel_size);

// Applies `target_from_source` to every point (attributes are kept).
PointCloud TransformCloud(const PointCloud& cloud, const SE3& target_from_source);

}  // namespace lisfm
