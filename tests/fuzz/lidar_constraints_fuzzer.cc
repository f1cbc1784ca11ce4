// Fuzz target lidar_constraints: LiDAR constraint files, lisfm (30 fields) and GTSFM HILTI (50/75
// fields), through ReadLidarConstraints.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/lidar_constraints_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("lidar_constraints.txt", data, size);
  try {
    lisfm::ReadLidarConstraints(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
