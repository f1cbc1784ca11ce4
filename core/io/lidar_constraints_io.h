// The LiDAR constraints file (docs/FORMATS.md): pose_slam writes it, the
// database importer passes it on, global_mapper reads it.
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

#include <string>
#include <vector>

#include "core/lidar_constraint.h"

namespace lisfm {

// Reads a constraints file in either format above (1-based line numbers in
// errors; a missing file is an InputError too). An empty file gives {}.
std::vector<LidarConstraintRecord> ReadLidarConstraints(const std::string& path);

// Writes `records` atomically (temporary name + rename): records with stamps
// in format (a), records without stamps in format (b) with zero match counts
// (so both round-trip through ReadLidarConstraints). Numbers are written with
// 17 significant digits. Mixing both kinds in one call throws InternalError.
void WriteLidarConstraints(const std::vector<LidarConstraintRecord>& records,
                           const std::string& path);

}  // namespace lisfm
