// Fuzz target rig_yaml: lisfm rig YAML (Kalibr-style cameras, imu0, lidars)
// through ParseRigYaml.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/io/rig_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    lisfm::ParseRigYaml(text, "rig.yaml");
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
