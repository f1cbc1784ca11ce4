// ROS1 messages without their generated C++ types: a message is decoded from
// the definition a bag stores with each connection ("message_definition",
// gendeps format: the message's .msg text, then for every message type it uses
// a line of '=' characters, "MSG: pkg/Type" and that type's .msg text).
// Used for livox_ros_driver/CustomMsg, whose package Debian does not ship.
//
// ROS1 serialization (little endian, no padding): integers and floats by their
// size, bool 1 byte, time / duration = uint32 secs + uint32 nsecs, string =
// uint32 length + bytes, T[] = uint32 count + elements, T[N] = N elements,
// a nested message = its fields in order. Constants ("int8 X=1") take no bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/point_cloud.h"

namespace lisfm {

struct RosMsgField {
  std::string
      type;  // a builtin (int8..float64, bool, byte, char, string, time, duration) or pkg/Type
  std::string name;
  bool is_array = false;
  uint32_t fixed_count = 0;  // T[N]: N; T[] (variable, uint32 count first): 0
};

// The message types of one connection's definition.
class RosMessageDefinition {
 public:
  // `datatype` is the connection's type ("pkg/Type"), `text` its
  // message_definition. Throws InputError naming `where` for a line that is not
  // a field, a constant, a comment or blank, and for a field whose message type
  // has no definition in `text`.
  RosMessageDefinition(const std::string& datatype,
                       const std::string& text,
                       const std::string& where);

  const std::string& datatype() const { return datatype_; }
  bool Has(const std::string& type) const { return types_.count(type) > 0; }
  const std::vector<RosMsgField>& Fields(const std::string& type) const;  // type must exist
  // Serialized size of one value of `field` / of message `type` when it is the
  // same for every message (no string, no variable array inside), else nullopt.
  std::optional<size_t> FixedSize(const RosMsgField& field) const;
  std::optional<size_t> FixedSize(const std::string& type) const;
  // Byte offset of field `name` in message `type` when every field before it
  // has a fixed size; nullopt when absent or after a variable-size field.
  std::optional<size_t> FieldOffset(const std::string& type, const std::string& name) const;
  const RosMsgField* FindField(const std::string& type, const std::string& name) const;

 private:
  std::string datatype_;
  std::string where_;
  std::map<std::string, std::vector<RosMsgField>> types_;
};

// Where the top-level field `field` of a serialized message lies: its bytes
// (for T[]: after the count) and, for arrays, the element count.
struct RosFieldSpan {
  const RosMsgField* field = nullptr;
  const uint8_t* data = nullptr;
  size_t size = 0;     // bytes of the value (all elements for arrays)
  uint32_t count = 1;  // elements (1 for a non-array)
};

// Walks the top-level fields of one serialized message of def.datatype().
// Throws InputError(where, ...) when the bytes end early or remain at the end.
std::map<std::string, RosFieldSpan> SplitRosMessage(const RosMessageDefinition& def,
                                                    const uint8_t* data,
                                                    size_t size,
                                                    const std::string& where);

// livox_ros_driver/CustomMsg (Livox ROS driver 1.x, package livox_ros_driver):
//   Header header; uint64 timebase (ns, time of the first point); uint32 point_num;
//   uint8 lidar_id; uint8[3] rsvd; CustomPoint[] points
//   CustomPoint: uint32 offset_time (ns since timebase); float32 x, y, z (m);
//   uint8 reflectivity; uint8 tag; uint8 line
extern const char kLivoxCustomMsgType[];
extern const char kLivoxCustomMsgMd5[];
extern const char kLivoxCustomMsgDefinition[];  // as a bag stores it (with its dependencies)

// Decodes a CustomMsg with the definition stored in the bag (fields found by
// name, so a definition with other or reordered fields still decodes when it
// has these). Point time = timebase + offset_time (ns, integer); the cloud's
// stamp is the earliest point's time and t = float32 seconds since it;
// intensity = reflectivity, ring = line. Points at exactly (0, 0, 0) (Livox: no
// return) are dropped. Throws InputError(where, ...) when a field is missing or
// has another type, the bytes do not match the definition, or no point is left.
PointCloud DecodeLivoxCustomMsg(const RosMessageDefinition& def,
                                const uint8_t* data,
                                size_t size,
                                const std::string& where);

// Serializes `cloud` as a CustomMsg: header {seq, stamp = cloud.stamp_ns,
// frame_id}, timebase = cloud.stamp_ns, offset_time = round(t * 1e9) ns,
// reflectivity = intensity rounded and clamped to [0, 255], tag 0, line = ring
// (clamped to 255). Points keep their order. Export -> import therefore keeps
// x, y, z and ring exactly, t to 1 ns and intensity to whole numbers.
std::vector<uint8_t> EncodeLivoxCustomMsg(const PointCloud& cloud,
                                          uint32_t seq,
                                          const std::string& frame_id,
                                          uint8_t lidar_id);

}  // namespace lisfm
