// Per-sensor frame indexes of a sequence folder (DESIGN.md "Formats",
// docs/FORMATS.md "Sequence folder"): `lidarK/data.csv`, `camK/data.csv`.
//
// EuRoC/ASL style: '#' header / comment lines and blank lines are skipped;
// every other row is `t_ns,filename` (int64 nanoseconds, a file name relative
// to the sensor's `data/` folder). Stamps strictly increase.
//
// Failures (InputError naming the file and line): a wrong column count, a
// stamp that is not an integer or does not increase, a row whose file does
// not exist.
#pragma once

#include <string>
#include <vector>

#include "core/time.h"

namespace lisfm {

struct SensorFile {
  TimestampNs t_ns = 0;
  std::string path;  // absolute or relative to the working directory
};

// Reads a `t_ns, filename` index; files are resolved against `data_dir`.
std::vector<SensorFile> ReadSensorIndex(const std::string& path, const std::string& data_dir);

}  // namespace lisfm
