// Fuzz target colmap_cameras_txt: a COLMAP cameras.txt through ReadCamerasText into an empty
// reconstruction, then Reconstruction::Validate.
#include <cstddef>
#include <cstdint>
#include <string>

#include "colmap_ext/io/model_io.h"
#include "colmap_ext/io/reconstruction.h"
#include "core/errors.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("cameras.txt", data, size);
  lisfm::colmap::Reconstruction reconstruction;
  try {
    lisfm::colmap::ReadCamerasText(path, &reconstruction);
    reconstruction.Validate(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
