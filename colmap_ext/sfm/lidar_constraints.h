// LiDAR relative-pose constraints for `lisfm global_mapper` (issue 7): the
// constraints file that pose_slam writes and the importer passes on, and how
// its records attach to the rig frames of a MapperState.
//
// File formats (auto-detected per file from the field count of the first
// record; every record of a file must use the same format):
//  (a) lisfm (DESIGN.md "Formats"), 30 fields per line:
//        t_i_ns t_j_ns tx ty tz qx qy qz qw c00 c01 c02 c03 c04 c05 c11 ... c55
//      T_i_j = i_from_j (IMU frame, m), Hamilton quaternion in TUM order, then
//      the 21 upper-triangular entries of the 6x6 covariance, row-major, on
//      the right perturbation T = T_hat * Exp(xi), xi = [omega; v] (rad, m).
//  (b) GTSFM HILTI (borglab/gtsfm gtsfm/common/constraint.py, as read by
//      gtsfm/loader/hilti_loader.py), 50 or 75 fields per line:
//        i j r00 r01 r02 tx r10 r11 r12 ty r20 r21 r22 tz c00 ... c55 [25 counts]
//      i, j are LiDAR keyframe (rig pose) indices; the 3x4 [R|t] is aTb =
//      pose_i^-1 * pose_j = i_from_j (GTSAM BetweenFactor<Pose3>(i, j, aTb));
//      the full 6x6 covariance is in GTSAM's Pose3 tangent order, rotation
//      first, on the right (Pose3::Retract) -- the same convention as (a).
//      The 5x5 per-camera-pair match counts are ignored. GTSFM writes with
//      numpy.savetxt, so i and j may appear as "1.0e+00"; they must be
//      non-negative integers.
// Blank lines and lines starting with '#' are skipped. Failures throw
// InputError(path, "line N", "expected ..., found ...") for a wrong field
// count, a non-numeric or non-finite field, a quaternion whose norm differs
// from 1 by more than 1e-6 (smaller errors are normalised), a rotation matrix
// that is not orthonormal within 1e-6 or has det < 0, a covariance that is
// not symmetric (GTSFM, relative 1e-9) or not positive definite, or i == j.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "colmap_ext/mapper_state.h"
#include "core/geometry.h"
#include "core/types.h"

namespace lisfm {
namespace colmap {

// Default stamp tolerance of AttachLidarConstraints (1 ms, issue 7).
constexpr int64_t kDefaultLidarConstraintToleranceNs = 1000000;

struct LidarConstraintRecord {
  // True for format (a): the constraint names its frames by stamp (ns).
  // False for GTSFM records: they name frames by keyframe index.
  bool has_stamps = true;
  int64_t t_i_ns = -1;   // stamp of frame i (has_stamps)
  int64_t t_j_ns = -1;   // stamp of frame j (has_stamps)
  int64_t index_i = -1;  // keyframe index of frame i (!has_stamps)
  int64_t index_j = -1;  // keyframe index of frame j (!has_stamps)
  SE3 i_from_j;          // T_i_j, IMU (rig) frame, metres
  Mat6 covariance = Mat6::Identity();  // right perturbation, xi = [omega; v], rad^2 / m^2
};

// Reads a constraints file in either format above (1-based line numbers in
// errors; a missing file is an InputError too). An empty file gives {}.
std::vector<LidarConstraintRecord> ReadLidarConstraints(const std::string& path);

// Writes `records` atomically (temporary name + rename): records with stamps
// in format (a), records without stamps in format (b) with zero match counts
// (so both round-trip through ReadLidarConstraints). Numbers are written with
// 17 significant digits. Mixing both kinds in one call throws InternalError.
void WriteLidarConstraints(const std::vector<LidarConstraintRecord>& records,
                           const std::string& path);

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
