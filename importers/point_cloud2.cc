#include "importers/point_cloud2.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "core/errors.h"

namespace lisfm {
namespace {

// Reads one value of `datatype` at `p` as double, swapping bytes when the
// message's byte order differs from the host's (little-endian x86/ARM hosts).
double ReadValue(const uint8_t* p, uint8_t datatype, bool swap) {
  uint8_t b[8];
  const size_t n = PointFieldTypeSize(datatype);
  if (swap) {
    for (size_t i = 0; i < n; ++i) b[i] = p[n - 1 - i];
  } else {
    std::memcpy(b, p, n);
  }
  switch (static_cast<PointFieldType>(datatype)) {
    case PointFieldType::kInt8: {
      int8_t v;
      std::memcpy(&v, b, 1);
      return v;
    }
    case PointFieldType::kUint8:
      return b[0];
    case PointFieldType::kInt16: {
      int16_t v;
      std::memcpy(&v, b, 2);
      return v;
    }
    case PointFieldType::kUint16: {
      uint16_t v;
      std::memcpy(&v, b, 2);
      return v;
    }
    case PointFieldType::kInt32: {
      int32_t v;
      std::memcpy(&v, b, 4);
      return v;
    }
    case PointFieldType::kUint32: {
      uint32_t v;
      std::memcpy(&v, b, 4);
      return v;
    }
    case PointFieldType::kFloat32: {
      float v;
      std::memcpy(&v, b, 4);
      return v;
    }
    case PointFieldType::kFloat64: {
      double v;
      std::memcpy(&v, b, 8);
      return v;
    }
  }
  return 0;
}

template <typename T>
void Put(uint8_t* p, T v) {
  std::memcpy(p, &v, sizeof(T));
}

const PointFieldDesc* FindField(const RawPointCloud2& msg, const std::string& name) {
  for (const PointFieldDesc& f : msg.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

std::string FieldNames(const RawPointCloud2& msg) {
  std::string s;
  for (const PointFieldDesc& f : msg.fields) s += (s.empty() ? "" : " ") + f.name;
  return s;
}

bool HostIsBigEndian() {
  const uint16_t one = 1;
  uint8_t b;
  std::memcpy(&b, &one, 1);
  return b == 0;
}

}  // namespace

size_t PointFieldTypeSize(uint8_t datatype) {
  switch (datatype) {
    case 1:
    case 2:
      return 1;
    case 3:
    case 4:
      return 2;
    case 5:
    case 6:
    case 7:
      return 4;
    case 8:
      return 8;
    default:
      return 0;
  }
}

PointCloud DecodePointCloud2(const RawPointCloud2& msg,
                             const PointCloud2Mapping& mapping,
                             const std::string& where) {
  auto fail = [&](const std::string& what) {
    return InputError(fmt::format("{}: PointCloud2: {}", where, what));
  };
  for (const PointFieldDesc& f : msg.fields) {
    const size_t size = PointFieldTypeSize(f.datatype);
    if (size == 0) {
      throw fail(fmt::format("field '{}' has unknown datatype {}", f.name, f.datatype));
    }
    if (static_cast<size_t>(f.offset) + size * std::max<uint32_t>(f.count, 1) > msg.point_step) {
      throw fail(fmt::format("field '{}' (offset {}, {} x {} bytes) ends past point_step {}",
                             f.name,
                             f.offset,
                             f.count,
                             size,
                             msg.point_step));
    }
  }
  if (static_cast<uint64_t>(msg.row_step) < static_cast<uint64_t>(msg.width) * msg.point_step) {
    throw fail(fmt::format(
        "row_step {} < width {} * point_step {}", msg.row_step, msg.width, msg.point_step));
  }
  if (msg.data_size < static_cast<uint64_t>(msg.height) * msg.row_step) {
    throw fail(fmt::format("{} data bytes, expected height {} * row_step {}",
                           msg.data_size,
                           msg.height,
                           msg.row_step));
  }
  auto required = [&](const std::string& name, const char* role) {
    const PointFieldDesc* f = FindField(msg, name);
    if (f == nullptr) {
      throw fail(fmt::format("no {} field '{}' (fields: {})", role, name, FieldNames(msg)));
    }
    if (f->count != 1)
      throw fail(fmt::format("field '{}' has count {}, expected 1", name, f->count));
    return f;
  };
  const PointFieldDesc* fx = required("x", "x");
  const PointFieldDesc* fy = required("y", "y");
  const PointFieldDesc* fz = required("z", "z");
  const PointFieldDesc* ft = required(mapping.time.name, "per-point time");
  const PointFieldDesc* fi = FindField(msg, mapping.intensity_field);
  const PointFieldDesc* fr = FindField(msg, mapping.ring_field);
  const bool swap = msg.is_bigendian != HostIsBigEndian();

  // Per-point time relative to header.stamp, in seconds. Absolute seconds are
  // reduced by the whole seconds of the stamp first: that difference is exact
  // (Sterbenz), so only the absolute time's own rounding remains.
  const TimestampNs header_sec = msg.header_stamp_ns >= 0
                                     ? msg.header_stamp_ns / 1000000000
                                     : -((-msg.header_stamp_ns + 999999999) / 1000000000);
  const double header_frac_s =
      static_cast<double>(msg.header_stamp_ns - header_sec * 1000000000) * 1e-9;
  const bool absolute = mapping.time.reference == PointTimeField::Reference::kAbsolute;
  const double unit_s = mapping.time.unit == PointTimeField::Unit::kNanoseconds ? 1e-9 : 1.0;

  PointCloud cloud;
  const size_t n = static_cast<size_t>(msg.height) * msg.width;
  // Without points there is nothing to read (and no rows to walk: height may be 2^32 - 1).
  if (n == 0) throw fail("no finite point");
  cloud.points.resize(n);
  std::vector<double> rel_s(n);
  double min_rel = std::numeric_limits<double>::infinity();
  double min_abs = 0;
  for (uint32_t r = 0; r < msg.height; ++r) {
    const uint8_t* row = msg.data + static_cast<size_t>(r) * msg.row_step;
    for (uint32_t c = 0; c < msg.width; ++c) {
      const uint8_t* p = row + static_cast<size_t>(c) * msg.point_step;
      const size_t i = static_cast<size_t>(r) * msg.width + c;
      LidarPoint& q = cloud.points[i];
      q.x = static_cast<float>(ReadValue(p + fx->offset, fx->datatype, swap));
      q.y = static_cast<float>(ReadValue(p + fy->offset, fy->datatype, swap));
      q.z = static_cast<float>(ReadValue(p + fz->offset, fz->datatype, swap));
      if (fi != nullptr)
        q.intensity = static_cast<float>(ReadValue(p + fi->offset, fi->datatype, swap));
      if (fr != nullptr) {
        const double ring = ReadValue(p + fr->offset, fr->datatype, swap);
        if (!(ring >= 0 && ring <= 65535)) {
          throw fail(fmt::format("point {}: ring {} outside [0, 65535]", i, ring));
        }
        q.ring = static_cast<uint16_t>(ring);
      }
      const double raw = ReadValue(p + ft->offset, ft->datatype, swap) * unit_s;
      rel_s[i] = absolute ? (raw - static_cast<double>(header_sec)) - header_frac_s : raw;
      if (IsFinite(q) && std::isfinite(rel_s[i]) && rel_s[i] < min_rel) {
        min_rel = rel_s[i];
        min_abs = raw;
      }
    }
  }
  if (!std::isfinite(min_rel)) throw fail("no finite point");
  // The stamp is the earliest finite point. Absolute times agreeing with
  // header.stamp within their own resolution take header.stamp exactly.
  // The stamp must be an int64 ns time: |offset| below 2^63 ns (~292 years).
  if (!(std::abs(min_rel) < 9.2e9)) {
    throw fail(fmt::format("earliest point time {} s from header.stamp is out of range", min_rel));
  }
  TimestampNs offset_ns = std::llround(min_rel * 1e9);
  double resolution_s = 0;
  if (absolute) {
    resolution_s = std::nextafter(std::abs(min_abs), std::numeric_limits<double>::infinity()) -
                   std::abs(min_abs);
    if (std::abs(min_rel) <= resolution_s) offset_ns = 0;
  }
  if (__builtin_add_overflow(msg.header_stamp_ns, offset_ns, &cloud.stamp_ns)) {
    throw fail(fmt::format("earliest point time {} s from header.stamp is out of range", min_rel));
  }
  const double offset_s = static_cast<double>(offset_ns) * 1e-9;
  // The earliest point may fall below the stamp by the stamp's rounding to whole
  // ns, or by the absolute times' resolution: such times become 0.
  const double tolerance_s = std::max(resolution_s, 0.5e-9);
  for (size_t i = 0; i < n; ++i) {
    double t = offset_ns == 0 ? rel_s[i] : rel_s[i] - offset_s;
    if (t < 0 && t >= -tolerance_s) t = 0;
    cloud.points[i].t = static_cast<float>(t);
  }
  return cloud;
}

std::vector<PointFieldDesc> EncodePointCloud2(const PointCloud& cloud,
                                              const PointCloud2Mapping& mapping,
                                              std::vector<uint8_t>* data,
                                              uint32_t* point_step) {
  const uint8_t time_type = mapping.time.datatype;
  const size_t time_size = PointFieldTypeSize(time_type);
  if (time_size == 0 || time_type < 5) {
    throw InternalError(fmt::format("EncodePointCloud2: time datatype {} unsupported", time_type));
  }
  std::vector<PointFieldDesc> fields;
  uint32_t offset = 0;
  auto add = [&](const std::string& name, uint8_t type) {
    const uint32_t size = static_cast<uint32_t>(PointFieldTypeSize(type));
    offset = (offset + size - 1) / size * size;
    fields.push_back({name, offset, type, 1});
    offset += size;
  };
  add("x", 7);
  add("y", 7);
  add("z", 7);
  add(mapping.intensity_field, 7);
  add(mapping.time.name, time_type);
  add(mapping.ring_field, 4);
  *point_step = (offset + 7) / 8 * 8;
  const uint32_t step = *point_step;
  const uint32_t to = fields[4].offset;
  const uint32_t ro = fields[5].offset;
  data->assign(cloud.size() * step, 0);
  const TimestampNs sec = cloud.stamp_ns >= 0 ? cloud.stamp_ns / 1000000000 : 0;
  const double frac_s = static_cast<double>(cloud.stamp_ns - sec * 1000000000) * 1e-9;
  const bool absolute = mapping.time.reference == PointTimeField::Reference::kAbsolute;
  const bool ns = mapping.time.unit == PointTimeField::Unit::kNanoseconds;
  for (size_t i = 0; i < cloud.size(); ++i) {
    const LidarPoint& p = cloud.points[i];
    uint8_t* q = data->data() + i * step;
    Put<float>(q + 0, p.x);
    Put<float>(q + 4, p.y);
    Put<float>(q + 8, p.z);
    Put<float>(q + 12, p.intensity);
    double t = absolute ? static_cast<double>(sec) + (frac_s + static_cast<double>(p.t))
                        : static_cast<double>(p.t);
    if (ns) t = std::round(t * 1e9);
    switch (time_type) {
      case 5:
        Put<int32_t>(q + to, static_cast<int32_t>(t));
        break;
      case 6:
        Put<uint32_t>(q + to, static_cast<uint32_t>(std::max(t, 0.0)));
        break;
      case 7:
        Put<float>(q + to, static_cast<float>(t));
        break;
      default:
        Put<double>(q + to, t);
        break;
    }
    Put<uint16_t>(q + ro, p.ring);
  }
  return fields;
}

}  // namespace lisfm
