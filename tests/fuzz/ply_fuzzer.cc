// Fuzz target ply: PLY point clouds (ascii, binary little/big endian) through ReadPly.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/cloud_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("ply.ply", data, size);
  try {
    lisfm::ReadPly(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
