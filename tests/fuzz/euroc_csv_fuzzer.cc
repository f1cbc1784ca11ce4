// Fuzz target euroc_csv: EuRoC ground-truth CSV through ReadEurocCsv.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/trajectory_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("euroc_csv.csv", data, size);
  try {
    lisfm::ReadEurocCsv(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
