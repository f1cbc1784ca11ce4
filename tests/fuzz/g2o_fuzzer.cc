// Fuzz target g2o: g2o pose graphs (2D and 3D) through ReadG2o and CheckG2oConnected.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/g2o_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("g2o.g2o", data, size);
  try {
    lisfm::CheckG2oConnected(lisfm::ReadG2o(path), path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
