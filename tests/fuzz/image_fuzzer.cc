// Fuzz target image: PNG and JPEG files through ReadImageFile (both modes).
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/io/image_codec.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("image.img", data, size);
  // Bad input gives an empty image (and the reason), never an exception.
  std::string why;
  (void)lisfm::ReadImageFile(path, lisfm::ImageReadMode::kUnchanged, &why);
  (void)lisfm::ReadImageFile(path, lisfm::ImageReadMode::kColor, &why);
  return 0;
}
