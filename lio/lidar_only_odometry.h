// The LiDAR-only baseline of `lisfm lio --method lidar_only`: frame-to-map
// point-to-plane ICP (icp/icp.h RegisterPointToPlane) against the same iVox map
// as the LIO, with a constant-velocity motion model for the prediction and the
// de-skew (as KISS-ICP does). No IMU is used, so the world frame is the IMU
// frame of the first scan (not gravity-aligned); compare with SE(3) alignment.
// It exists to show what the IMU buys (bench_lio.sh runs both side by side).
#pragma once

#include <memory>

#include "core/point_cloud.h"
#include "lio/lio_odometry.h"
#include "lio/voxel_map.h"

namespace lisfm {

class LidarOnlyOdometry {
 public:
  LidarOnlyOdometry(const LioOptions& options, const SE3& imu_from_lidar, double time_offset_s);
  ~LidarOnlyOdometry();

  // One scan of the (single) LiDAR; returns the IMU pose at the scan end.
  LioFrameResult ProcessScan(const PointCloud& scan);
  const VoxelMap& map() const { return *map_; }

 private:
  LioOptions options_;
  SE3 imu_from_lidar_;
  int64_t time_offset_ns_;
  std::unique_ptr<VoxelMap> map_;
  bool have_previous_ = false;
  TimestampNs previous_t_ns_ = 0;
  SE3 previous_pose_;
  Vec6 velocity_ = Vec6::Zero();  // body twist [omega; v] per second (right-multiplied)
};

}  // namespace lisfm
