// A LiDAR relative-pose constraint between two rig (IMU) frames: what
// pose_slam writes, the database importer passes on and global_mapper adds to
// bundle adjustment. File formats: core/io/lidar_constraints_io.h.
#pragma once

#include <cstdint>

#include "core/geometry.h"
#include "core/types.h"

namespace lisfm {

struct LidarConstraintRecord {
  // True when the constraint names its frames by stamp (lisfm format).
  // False for GTSFM records: they name frames by keyframe index.
  bool has_stamps = true;
  int64_t t_i_ns = -1;   // stamp of frame i (has_stamps)
  int64_t t_j_ns = -1;   // stamp of frame j (has_stamps)
  int64_t index_i = -1;  // keyframe index of frame i (!has_stamps)
  int64_t index_j = -1;  // keyframe index of frame j (!has_stamps)
  SE3 i_from_j;          // T_i_j, IMU (rig) frame, metres
  Mat6 covariance = Mat6::Identity();  // right perturbation, xi = [omega; v], rad^2 / m^2
};

}  // namespace lisfm
