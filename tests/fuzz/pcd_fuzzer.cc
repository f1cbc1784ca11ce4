// Fuzz target pcd: PCD files (ascii, binary, binary_compressed) through ReadPcd.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/cloud_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("pcd.pcd", data, size);
  try {
    lisfm::ReadPcd(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
