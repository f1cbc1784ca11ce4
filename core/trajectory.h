// Time-stamped pose sequences (e.g. world_from_imu), strictly increasing in time.
#pragma once

#include <optional>
#include <vector>

#include "core/geometry.h"
#include "core/time.h"

namespace lisfm {

struct StampedPose {
  TimestampNs t_ns = 0;
  SE3 pose;  // the owner states the frames, usually world_from_imu
};

class Trajectory {
 public:
  Trajectory() = default;
  // Throws InternalError if stamps are not strictly increasing (readers check
  // input files themselves and throw InputError with the line first).
  explicit Trajectory(std::vector<StampedPose> poses);

  void PushBack(const StampedPose& pose);  // must be later than back()
  const std::vector<StampedPose>& poses() const { return poses_; }
  size_t size() const { return poses_.size(); }
  bool empty() const { return poses_.empty(); }
  const StampedPose& operator[](size_t i) const { return poses_[i]; }
  TimestampNs start_ns() const;
  TimestampNs end_ns() const;

  // Pose at t_ns by slerp/linear interpolation between the neighbouring
  // samples; nullopt outside [start, end] or when the bracketing samples are
  // more than `max_gap_ns` apart (0 = no limit).
  std::optional<SE3> Interpolate(TimestampNs t_ns, int64_t max_gap_ns = 0) const;

  // Index of the sample nearest to t_ns if within max_dt_ns, else -1.
  int Nearest(TimestampNs t_ns, int64_t max_dt_ns) const;

  // Sum of distances between consecutive positions (m).
  double PathLength() const;

 private:
  std::vector<StampedPose> poses_;
};

}  // namespace lisfm
