#include "core/trajectory.h"

#include <algorithm>
#include <cstdlib>
#include <utility>

#include "core/errors.h"

namespace lisfm {

namespace {

bool StampLess(const StampedPose& p, TimestampNs t_ns) { return p.t_ns < t_ns; }

}  // namespace

Trajectory::Trajectory(std::vector<StampedPose> poses)
    : poses_(std::move(poses)) {
  for (size_t i = 1; i < poses_.size(); ++i) {
    THROW_CHECK_MSG(poses_[i].t_ns > poses_[i - 1].t_ns,
                    "trajectory stamps not strictly increasing at index "
                        << i << " (" << poses_[i - 1].t_ns << " then "
                        << poses_[i].t_ns << " ns)");
  }
}

void Trajectory::PushBack(const StampedPose& pose) {
  if (!poses_.empty()) THROW_CHECK_GT(pose.t_ns, poses_.back().t_ns);
  poses_.push_back(pose);
}

TimestampNs Trajectory::start_ns() const {
  THROW_CHECK_MSG(!poses_.empty(), "start_ns() of an empty trajectory");
  return poses_.front().t_ns;
}

TimestampNs Trajectory::end_ns() const {
  THROW_CHECK_MSG(!poses_.empty(), "end_ns() of an empty trajectory");
  return poses_.back().t_ns;
}

std::optional<SE3> Trajectory::Interpolate(TimestampNs t_ns,
                                           int64_t max_gap_ns) const {
  if (poses_.empty() || t_ns < poses_.front().t_ns ||
      t_ns > poses_.back().t_ns) {
    return std::nullopt;
  }
  // First sample with stamp >= t_ns; exists because t_ns <= back().t_ns.
  const auto it =
      std::lower_bound(poses_.begin(), poses_.end(), t_ns, StampLess);
  if (it->t_ns == t_ns) return it->pose;
  const StampedPose& b = *it;
  const StampedPose& a =
      *(it - 1);  // it != begin() because t_ns > front().t_ns
  const int64_t gap = b.t_ns - a.t_ns;
  if (max_gap_ns > 0 && gap > max_gap_ns) return std::nullopt;
  // Differences of int64 stamps keep full precision for large absolute stamps.
  const double s =
      static_cast<double>(t_ns - a.t_ns) / static_cast<double>(gap);
  return lisfm::Interpolate(a.pose, b.pose, s);
}

int Trajectory::Nearest(TimestampNs t_ns, int64_t max_dt_ns) const {
  if (poses_.empty()) return -1;
  const auto it =
      std::lower_bound(poses_.begin(), poses_.end(), t_ns, StampLess);
  int best = -1;
  int64_t best_dt = 0;
  auto consider = [&](std::vector<StampedPose>::const_iterator c) {
    const int64_t dt = std::llabs(c->t_ns - t_ns);
    if (best < 0 || dt < best_dt) {
      best = static_cast<int>(c - poses_.begin());
      best_dt = dt;
    }
  };
  // The earlier neighbour is considered first, so ties go to the earlier
  // sample.
  if (it != poses_.begin()) consider(it - 1);
  if (it != poses_.end()) consider(it);
  if (best >= 0 && best_dt > max_dt_ns) return -1;
  return best;
}

double Trajectory::PathLength() const {
  double length = 0;
  for (size_t i = 1; i < poses_.size(); ++i) {
    length += (poses_[i].pose.translation() - poses_[i - 1].pose.translation())
                  .norm();
  }
  return length;
}

}  // namespace lisfm
