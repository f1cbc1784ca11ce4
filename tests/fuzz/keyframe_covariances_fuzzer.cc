// Fuzz target keyframe_covariances: pose_slam keyframe covariance files through
// ReadKeyframeCovariances.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/keyframe_covariances_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("keyframe_covariances.txt", data, size);
  try {
    lisfm::ReadKeyframeCovariances(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
