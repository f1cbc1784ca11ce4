// Turns a sequence folder's LiDAR scans and IMU samples into the input stream
// of the odometry (lio/lio_odometry.h): one frame per scan of the primary
// LiDAR, joined by the scans of the other selected LiDARs that started after
// the previous primary scan and not after this one (so each secondary scan is
// used once, in the frame whose update is closest to it). Used by `lisfm lio`
// and the LIO tests, so both run exactly the same loop.
#pragma once

#include <vector>

#include "core/point_cloud.h"
#include "importers/sequence.h"
#include "lio/lio_odometry.h"

namespace lisfm {

struct LidarFrame {
  std::vector<PointCloud> clouds;  // sensor frames; stamp_ns from the file name
  std::vector<int> sensor_ids;     // rig LiDAR index of each cloud
  TimestampNs end_ns = 0;          // latest point time on the IMU clock

  // Views for LioOdometry::ProcessFrame (valid while this frame lives).
  std::vector<LidarScanInput> Inputs() const;
};

class LidarFrameReader {
 public:
  // `lidars`: rig LiDAR indices, the first is the primary one. Throws
  // InputError for an index the rig does not have.
  LidarFrameReader(const Sequence& sequence, std::vector<int> lidars);

  size_t num_frames() const;
  // Reads the next frame's clouds (PCD files); false after the last frame.
  bool Next(LidarFrame* frame);
  // Hands `odometry` every IMU sample up to and including the first one after
  // `t_ns` (so the IMU covers t_ns when the data does).
  void FeedImuUntil(TimestampNs t_ns, LioOdometry* odometry);

 private:
  const Sequence& sequence_;
  std::vector<int> lidars_;
  size_t next_frame_ = 0;
  std::vector<size_t> next_scan_;
  TimestampNs previous_primary_ns_ = INT64_MIN;
  size_t next_imu_ = 0;
};

}  // namespace lisfm
