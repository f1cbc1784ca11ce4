// Turns a sequence folder's LiDAR scans into LiDAR frames (core/sensor_data.h):
// one frame per scan of the primary LiDAR, joined by the scans of the other
// selected LiDARs that started after the previous primary scan and not after
// this one (so each secondary scan is used once, in the frame whose update is
// closest to it). The caller hands the frames and the sequence's IMU samples to
// an estimator (lio/imu_feeder.h).
#pragma once

#include <vector>

#include "core/sensor_data.h"
#include "importers/sequence.h"

namespace lisfm {

class LidarFrameReader {
 public:
  // `lidars`: rig LiDAR indices, the first is the primary one. Throws
  // InputError for an index the rig does not have.
  LidarFrameReader(const Sequence& sequence, std::vector<int> lidars);

  size_t num_frames() const;
  // Reads the next frame's clouds (PCD files; stamp_ns from the file name);
  // false after the last frame. Throws InputError naming the file and record
  // for a point whose time `t` is not finite seconds within the int64
  // nanosecond range.
  bool Next(LidarFrame* frame);

 private:
  const Sequence& sequence_;
  std::vector<int> lidars_;
  size_t next_frame_ = 0;
  std::vector<size_t> next_scan_;
  TimestampNs previous_primary_ns_ = INT64_MIN;
};

}  // namespace lisfm
