// Drives LioOdometry from a recorded IMU stream: the loop that interleaves a
// reader's IMU samples with its LiDAR frames, shared by `lisfm lio` and the
// tests so both run exactly the same sequence of calls.
#pragma once

#include <cstddef>
#include <vector>

#include "core/sensor_data.h"
#include "core/time.h"
#include "lio/lio_odometry.h"

namespace lisfm {

class ImuFeeder {
 public:
  // `samples` (sorted by time) must outlive the feeder.
  explicit ImuFeeder(const std::vector<ImuSample>& samples) : samples_(samples) {}

  // Hands `odometry` every not yet fed sample up to and including the first
  // one after `t_ns` plus the odometry's TimeOffsetLookaheadNs() (0 unless it
  // estimates the LiDAR time offsets), so the IMU covers a frame ending at t_ns
  // (with the rig's offsets) whenever the recording does.
  void FeedUntil(TimestampNs t_ns, LioOdometry* odometry) {
    t_ns += odometry->TimeOffsetLookaheadNs();
    while (next_ < samples_.size() &&
           (odometry->LatestImuTime() < t_ns || samples_[next_].t_ns <= t_ns)) {
      odometry->AddImu(samples_[next_++]);
    }
  }

 private:
  const std::vector<ImuSample>& samples_;
  size_t next_ = 0;
};

}  // namespace lisfm
