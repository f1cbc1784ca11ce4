// Fuzz target colmap_points3d_bin: a COLMAP points3D.bin through ReadPoints3DBinary into an empty
// reconstruction, then Reconstruction::Validate.
#include <cstddef>
#include <cstdint>
#include <string>

#include "colmap_ext/io/model_io.h"
#include "colmap_ext/io/reconstruction.h"
#include "core/errors.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("points3D.bin", data, size);
  lisfm::colmap::Reconstruction reconstruction;
  try {
    lisfm::colmap::ReadPoints3DBinary(path, &reconstruction);
    reconstruction.Validate(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
