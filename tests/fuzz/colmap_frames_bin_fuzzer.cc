// Fuzz target colmap_frames_bin: a COLMAP frames.bin through ReadFramesBinary into an empty
// reconstruction, then Reconstruction::Validate.
#include <cstddef>
#include <cstdint>
#include <string>

#include "colmap_ext/io/model_io.h"
#include "colmap_ext/io/reconstruction.h"
#include "core/errors.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("frames.bin", data, size);
  lisfm::colmap::Reconstruction reconstruction;
  try {
    lisfm::colmap::ReadFramesBinary(path, &reconstruction);
    reconstruction.Validate(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
