// The keyframe covariances file (docs/FORMATS.md): pose_slam writes the
// marginal covariance of each optimised keyframe pose, the database importer
// turns it into COLMAP pose priors.
//
// One record per line, 22 fields:
//   t_ns c00 c01 c02 c03 c04 c05 c11 c12 ... c55
// t_ns is the keyframe stamp (ns, IMU clock, the lio pose time); the 21
// numbers are the upper-triangular entries, row-major, of the 6x6 covariance
// of world_from_imu on the right perturbation T = T_hat * Exp(xi),
// xi = [omega; v] (rad, m), with the gauge of the optimisation (the first
// keyframe fixed: its covariance is that of the gauge, usually tiny or zero).
// Stamps strictly increase. Blank lines and lines starting with '#' are
// skipped. Failures throw InputError(path, "line N", "expected ..., found
// ...") for a wrong field count, a non-integer stamp, a non-finite entry, a
// stamp that does not increase, or a covariance that is not positive
// semi-definite (smallest eigenvalue below -1e-9 times the largest).
#pragma once

#include <string>
#include <vector>

#include "core/time.h"
#include "core/types.h"

namespace lisfm {

struct KeyframeCovariance {
  TimestampNs t_ns = 0;
  Mat6 covariance = Mat6::Zero();  // right perturbation of world_from_imu, [omega; v]
};

// Reads a keyframe covariances file (1-based line numbers in errors; a missing
// file is an InputError too). An empty file gives {}.
std::vector<KeyframeCovariance> ReadKeyframeCovariances(const std::string& path);

// Writes `records` atomically (temporary name + rename), 17 significant
// digits. Throws InternalError if the stamps do not strictly increase.
void WriteKeyframeCovariances(const std::vector<KeyframeCovariance>& records,
                              const std::string& path);

}  // namespace lisfm
