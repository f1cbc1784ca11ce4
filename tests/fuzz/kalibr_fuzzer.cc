// Fuzz target kalibr: one Kalibr camchain-imucam file through LoadKalibrRig
// (file name tag cam0-1, so the file must name cam0 and cam1), and the same
// bytes as a HILTI lidar_calibration.yaml through ReadLidarCalibration.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/rig_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path =
      lisfm::fuzz::WriteScratchFile("calib_cam0-1-camchain-imucam.yaml", data, size);
  try {
    lisfm::LoadKalibrRig({path}, "");
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  try {
    lisfm::ReadLidarCalibration(path);
  } catch (const lisfm::InputError&) {
  }
  return 0;
}
