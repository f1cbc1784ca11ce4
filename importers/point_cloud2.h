// sensor_msgs/PointCloud2 bodies without ROS: a plain description of the
// message (fields, steps, endianness, bytes) and a decoder into PointCloud for
// any field layout, plus the encoder the bag exporter uses.
//
// Decoding: point (row r, column c) starts at byte r * row_step + c * point_step;
// each field is read at its offset with its PointField datatype (INT8=1 .. FLOAT64=8)
// and converted; both byte orders (is_bigendian). x, y, z are required; intensity
// and ring are optional (missing -> 0). Non-finite points are kept (organised
// clouds keep their layout; is_dense is informational), the caller drops them.
//
// Per-point time (DESIGN.md "Time"): the output stamp is the time of the earliest
// finite point and each point's `t` is float32 seconds since that stamp. How the
// message's time field is read is configurable (PointTimeField):
//   Hesai      `timestamp` float64, absolute seconds (reference kAbsolute);
//   Velodyne   `time` float32, seconds since header.stamp (kStamp, unit s);
//   Ouster     `t` uint32, nanoseconds since header.stamp (kStamp, unit ns).
// When the earliest point is at header.stamp (relative layouts) the per-point
// times are copied exactly. Absolute float64 seconds resolve ~2.4e-7 s at
// 1.7e9 s, so Hesai-style times carry that rounding. A time below the new
// stamp by no more than the stamp's rounding to whole ns (or that resolution)
// becomes 0.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/point_cloud.h"
#include "core/time.h"

namespace lisfm {

// sensor_msgs/PointField datatypes.
enum class PointFieldType : uint8_t {
  kInt8 = 1,
  kUint8 = 2,
  kInt16 = 3,
  kUint16 = 4,
  kInt32 = 5,
  kUint32 = 6,
  kFloat32 = 7,
  kFloat64 = 8,
};
size_t PointFieldTypeSize(uint8_t datatype);  // 0 for an unknown datatype

struct PointFieldDesc {
  std::string name;
  uint32_t offset = 0;   // bytes from the start of the point
  uint8_t datatype = 0;  // PointFieldType
  uint32_t count = 1;
};

// A PointCloud2 message body; `data` points to height * row_step bytes.
struct RawPointCloud2 {
  TimestampNs header_stamp_ns = 0;
  uint32_t height = 1;
  uint32_t width = 0;
  std::vector<PointFieldDesc> fields;
  bool is_bigendian = false;
  uint32_t point_step = 0;
  uint32_t row_step = 0;
  const uint8_t* data = nullptr;
  size_t data_size = 0;
  bool is_dense = true;
};

struct PointTimeField {
  enum class Reference { kStamp, kAbsolute };
  enum class Unit { kSeconds, kNanoseconds };
  std::string name = "t";                   // field holding the per-point time
  Reference reference = Reference::kStamp;  // relative to header.stamp or absolute (epoch)
  Unit unit = Unit::kSeconds;
  uint8_t datatype = 7;  // written by the encoder (the decoder takes the message's)
};

struct PointCloud2Mapping {
  PointTimeField time;
  std::string intensity_field = "intensity";
  std::string ring_field = "ring";
};

// Throws InputError(`where`, ...) when the layout is inconsistent (a field past
// point_step, row_step < width * point_step, too few bytes), x/y/z or the time
// field is missing or has COUNT != 1, or no point is finite.
PointCloud DecodePointCloud2(const RawPointCloud2& msg,
                             const PointCloud2Mapping& mapping,
                             const std::string& where);

// Little-endian, unorganised (height 1), dense: fields x y z intensity (float32),
// the time field (its datatype and reference), ring (uint16), each aligned to
// its size, point_step a multiple of 8 (Hesai: 32 bytes). header.stamp = the
// scan stamp. Returns the fields and fills `data`; the point step is the last
// output.
std::vector<PointFieldDesc> EncodePointCloud2(const PointCloud& cloud,
                                              const PointCloud2Mapping& mapping,
                                              std::vector<uint8_t>* data,
                                              uint32_t* point_step);

}  // namespace lisfm
