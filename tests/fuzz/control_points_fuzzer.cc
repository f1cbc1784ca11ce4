// Fuzz target control_points: HILTI-style control-point files through ReadControlPoints.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/trajectory_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("control_points.txt", data, size);
  try {
    lisfm::ReadControlPoints(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
