// Fuzz target tum: TUM trajectories (t tx ty tz qx qy qz qw) through ReadTum.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/trajectory_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("tum.txt", data, size);
  try {
    lisfm::ReadTum(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
