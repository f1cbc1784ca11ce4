// Fuzz target sequence_csv: the CSV files of a sequence folder: the bytes as
// imu0/data.csv (ReadImuCsv) and as a lidarK/camK data.csv index
// (ReadSensorIndex, files resolved in a folder holding "0.pcd" and "1.png").
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/sensor_index_io.h"
#include "importers/sequence.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string data_dir = [] {
    lisfm::fuzz::WriteScratchFile("0.pcd", nullptr, 0);
    lisfm::fuzz::WriteScratchFile("1.png", nullptr, 0);
    return lisfm::fuzz::ScratchDir();
  }();
  const std::string path = lisfm::fuzz::WriteScratchFile("data.csv", data, size);
  try {
    lisfm::ReadImuCsv(path);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  try {
    lisfm::ReadSensorIndex(path, data_dir);
  } catch (const lisfm::InputError&) {
  }
  return 0;
}
