// Fuzz target livox_msg: a ROS1 message definition and a serialized message,
// as a bag stores them for livox_ros_driver/CustomMsg, through
// RosMessageDefinition, SplitRosMessage and DecodeLivoxCustomMsg. The input is
// the definition text, one NUL byte, then the message bytes (no NUL: the whole
// input is the definition and the message is empty).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "core/errors.h"
#include "importers/bag_message.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const void* nul = std::memchr(data, 0, size);
  const size_t text_size = nul != nullptr ? static_cast<const uint8_t*>(nul) - data : size;
  const std::string text(reinterpret_cast<const char*>(data), text_size);
  const uint8_t* message = data + std::min(size, text_size + 1);
  const size_t message_size = size - std::min(size, text_size + 1);
  const std::string where = "fuzz.bag: topic /livox/lidar message 0";
  try {
    const lisfm::RosMessageDefinition def(lisfm::kLivoxCustomMsgType, text, where);
    if (def.Has(def.datatype())) {
      lisfm::SplitRosMessage(def, message, message_size, where);
    }
    lisfm::DecodeLivoxCustomMsg(def, message, message_size, where);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
