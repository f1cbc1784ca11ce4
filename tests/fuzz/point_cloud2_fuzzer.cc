// Fuzz target point_cloud2: sensor_msgs/PointCloud2 bodies through
// DecodePointCloud2. The input is a little-endian description of the message
// followed by its point bytes:
//   u32 height, u32 width, u32 point_step, u32 row_step, u8 is_bigendian,
//   u8 time reference (bit 0: absolute), u8 time unit (bit 0: ns),
//   u8 field count n (at most 16), n x {u8 name index, u32 offset, u8 datatype, u32 count},
//   the rest: data (data_size = the bytes left).
// Names are indices into kNames, so every layout (xyz, intensity, ring and the
// time fields of Hesai, Velodyne and Ouster) is reachable.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "core/errors.h"
#include "importers/point_cloud2.h"

namespace {

const char* const kNames[] = {"x", "y", "z", "intensity", "ring", "t", "timestamp", "time"};

struct Bytes {
  const uint8_t* data;
  size_t size;
  bool Take(void* out, size_t n) {
    if (size < n) return false;
    std::memcpy(out, data, n);
    data += n;
    size -= n;
    return true;
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Bytes in{data, size};
  lisfm::RawPointCloud2 msg;
  msg.header_stamp_ns = 1700000000000000000;
  uint8_t big = 0, reference = 0, unit = 0, num_fields = 0;
  if (!in.Take(&msg.height, 4) || !in.Take(&msg.width, 4) || !in.Take(&msg.point_step, 4) ||
      !in.Take(&msg.row_step, 4) || !in.Take(&big, 1) || !in.Take(&reference, 1) ||
      !in.Take(&unit, 1) || !in.Take(&num_fields, 1)) {
    return 0;
  }
  msg.is_bigendian = (big & 1) != 0;
  lisfm::PointCloud2Mapping mapping;
  mapping.time.reference = (reference & 1) != 0 ? lisfm::PointTimeField::Reference::kAbsolute
                                                : lisfm::PointTimeField::Reference::kStamp;
  mapping.time.unit = (unit & 1) != 0 ? lisfm::PointTimeField::Unit::kNanoseconds
                                      : lisfm::PointTimeField::Unit::kSeconds;
  mapping.time.name = kNames[5 + (reference >> 1) % 3];
  for (int i = 0; i < (num_fields & 15); ++i) {
    uint8_t name = 0;
    lisfm::PointFieldDesc field;
    if (!in.Take(&name, 1) || !in.Take(&field.offset, 4) || !in.Take(&field.datatype, 1) ||
        !in.Take(&field.count, 4)) {
      return 0;
    }
    field.name = kNames[name % (sizeof(kNames) / sizeof(kNames[0]))];
    msg.fields.push_back(field);
  }
  msg.data = in.data;
  msg.data_size = in.size;
  try {
    lisfm::DecodePointCloud2(msg, mapping, "fuzz.bag: topic /points message 0");
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}
