// Trajectory and control-point files (DESIGN.md "Formats", "Time").
//
// TUM (.txt/.tum): one pose per line `t x y z qx qy qz qw`, t in seconds
//   (decimal; parsed digit by digit to exact ns), position in metres, Hamilton
//   quaternion in TUM order. Whitespace separated; blank lines and lines
//   starting with `#` are skipped.
// ASL/EuRoC groundtruth (.csv): header
//   `#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x
//   [],q_RS_y [],q_RS_z []` then `t_ns,x,y,z,qw,qx,qy,qz[,more]`; extra columns
//   (velocities, biases) are ignored on read. Lines starting with `#` and blank
//   lines are skipped.
// HILTI 2022 control points (.txt): `t x y z [qx qy qz qw]` (4 or 8 columns;
//   the orientation, always `0 0 0 1` in the real files, is ignored) or
//   `t id x y z` (5 columns, id any token). The files carry a misleading header
//   `# timestamp_s id x y z` over 8-column rows: headers are comments and the
//   layout is decided per line by its column count.
//
// Poses are whatever the file holds, usually world_from_imu.
//
// Failures (all InputError naming the file, and `line N` where there is one):
// missing file; a wrong column count or a token that is not a number (naming
// the column and what was expected); timestamps not strictly increasing;
// a quaternion whose norm is more than 1e-3 from 1 (a norm within that is
// normalised); a file without any pose. Writers write atomically (temporary
// name + rename) and throw InputError when the file cannot be written.
#pragma once

#include <string>
#include <vector>

#include "core/evaluation.h"
#include "core/trajectory.h"

namespace lisfm {

Trajectory ReadTum(const std::string& path);
// Time with 9 decimals (exact ns), values with the shortest text that reads
// back to the same double (at most 17 significant digits), so a write/read
// round trip is exact.
void WriteTum(const std::string& path, const Trajectory& trajectory);

Trajectory ReadEurocCsv(const std::string& path);
// Writes the 8 standard columns with the EuRoC header; values as in WriteTum.
void WriteEurocCsv(const std::string& path, const Trajectory& trajectory);

// Dispatches on the extension: .csv -> EuRoC, .txt/.tum -> TUM; any other
// extension is sniffed (a comma in the first data line means EuRoC).
Trajectory ReadTrajectory(const std::string& path);

// HILTI 2022 control points, strictly increasing in time.
std::vector<ControlPoint> ReadControlPoints(const std::string& path);

}  // namespace lisfm
