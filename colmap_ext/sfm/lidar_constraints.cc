#include "colmap_ext/sfm/lidar_constraints.h"

#include <algorithm>
#include <iterator>
#include <utility>

#include "core/errors.h"
#include "core/logging.h"

namespace lisfm {
namespace colmap {

size_t AttachLidarConstraints(const std::vector<LidarConstraintRecord>& records,
                              int64_t tolerance_ns,
                              MapperState* state) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_GE(tolerance_ns, 0);
  // (stamp, frame id) of stamped frames, sorted by stamp.
  std::vector<std::pair<int64_t, frame_t>> by_stamp;
  bool all_stamped = true;
  for (const auto& [frame_id, frame] : state->frames) {
    if (frame.stamp_ns >= 0) {
      by_stamp.emplace_back(frame.stamp_ns, frame_id);
    } else {
      all_stamped = false;
    }
  }
  std::sort(by_stamp.begin(), by_stamp.end());
  // Keyframe index -> frame id for GTSFM records.
  std::vector<frame_t> by_index;
  if (all_stamped) {
    for (const auto& entry : by_stamp) by_index.push_back(entry.second);
  } else {
    for (const auto& entry : state->frames) by_index.push_back(entry.first);
  }

  auto find_by_stamp = [&](int64_t t_ns, frame_t* frame_id) {
    auto it = std::lower_bound(by_stamp.begin(), by_stamp.end(),
                               std::make_pair(t_ns, frame_t{0}));
    int64_t best = -1;
    for (auto candidate : {it, it == by_stamp.begin() ? it : std::prev(it)}) {
      if (candidate == by_stamp.end()) continue;
      // |difference| without overflow for stamps of either sign.
      const int64_t diff = candidate->first > t_ns ? candidate->first - t_ns
                                                   : t_ns - candidate->first;
      if (diff <= tolerance_ns && (best < 0 || diff < best)) {
        best = diff;
        *frame_id = candidate->second;
      }
    }
    return best >= 0;
  };
  auto find_by_index = [&](int64_t index, frame_t* frame_id) {
    if (index < 0 || index >= static_cast<int64_t>(by_index.size())) return false;
    *frame_id = by_index[static_cast<size_t>(index)];
    return true;
  };

  size_t num_attached = 0;
  size_t num_skipped = 0;
  for (const LidarConstraintRecord& record : records) {
    frame_t frame_i = 0;
    frame_t frame_j = 0;
    const bool found = record.has_stamps ? find_by_stamp(record.t_i_ns, &frame_i) &&
                                               find_by_stamp(record.t_j_ns, &frame_j)
                                         : find_by_index(record.index_i, &frame_i) &&
                                               find_by_index(record.index_j, &frame_j);
    if (!found || frame_i == frame_j) {
      ++num_skipped;
      continue;
    }
    LidarConstraint constraint;
    constraint.frame_id1 = frame_i;
    constraint.frame_id2 = frame_j;
    constraint.rig1_from_rig2 = record.i_from_j;
    constraint.covariance = record.covariance;
    state->lidar_constraints.push_back(constraint);
    ++num_attached;
  }
  if (num_skipped > 0) {
    LogWarning("LiDAR constraints: {} of {} match no pair of frames (stamp tolerance {} ns) "
               "and are skipped",
               num_skipped, records.size(), tolerance_ns);
  }
  return num_attached;
}

}  // namespace colmap
}  // namespace lisfm
