// Attaches LiDAR relative-pose constraints (core/lidar_constraint.h, read by
// core/io/lidar_constraints_io.h) to the rig frames of a MapperState.
#pragma once

#include <cstdint>
#include <vector>

#include "colmap_ext/sfm/mapper_state.h"
#include "core/lidar_constraint.h"

namespace lisfm {
namespace colmap {

// Default stamp tolerance of AttachLidarConstraints (1 ms).
constexpr int64_t kDefaultLidarConstraintToleranceNs = 1000000;

// Attaches records to the frames of `state` and appends them to
// state->lidar_constraints (frame_id1 = frame of i, frame_id2 = frame of j,
// rig1_from_rig2 = i_from_j). Returns the number attached.
//  - Records with stamps attach to the frames whose stamp_ns is nearest to
//    t_i_ns / t_j_ns, if within `tolerance_ns` (>= 0); frames without a
//    stamp (stamp_ns < 0) never match.
//  - Records without stamps (GTSFM) attach by keyframe index: index k is the
//    k-th frame of `state` in stamp order when every frame has a stamp,
//    otherwise in frame-id order.
// Records that match no frame (or whose i and j fall on the same frame) are
// skipped and counted in one LogWarning. Thread safety: none (mutates state).
size_t AttachLidarConstraints(const std::vector<LidarConstraintRecord>& records,
                              int64_t tolerance_ns,
                              MapperState* state);

}  // namespace colmap
}  // namespace lisfm
