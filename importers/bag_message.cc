#include "importers/bag_message.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <sstream>

#include "core/errors.h"

namespace lisfm {
namespace {

// Serialized size of a builtin type; 0 for string (variable) and non-builtins.
size_t BuiltinSize(const std::string& t) {
  if (t == "bool" || t == "int8" || t == "uint8" || t == "byte" || t == "char") return 1;
  if (t == "int16" || t == "uint16") return 2;
  if (t == "int32" || t == "uint32" || t == "float32") return 4;
  if (t == "int64" || t == "uint64" || t == "float64" || t == "time" || t == "duration") return 8;
  return 0;
}

// Bounds of a definition's fixed sizes: a fixed array length (ROS uses a few
// dozen at most, e.g. float64[36]) and the fixed size of one field (far beyond
// any message a bag chunk holds), so that no size computation overflows.
constexpr uint32_t kMaxFixedArrayLength = 100000000;
constexpr size_t kMaxFixedMessageBytes = size_t{1} << 40;

bool IsBuiltin(const std::string& t) { return BuiltinSize(t) > 0 || t == "string"; }

std::string Trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

template <typename T>
T ReadLe(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));  // ROS1 serialization is little endian, as the host
  return v;
}

template <typename T>
void AppendLe(std::vector<uint8_t>* out, T v) {
  const size_t n = out->size();
  out->resize(n + sizeof(T));
  std::memcpy(out->data() + n, &v, sizeof(T));
}

}  // namespace

RosMessageDefinition::RosMessageDefinition(const std::string& datatype,
                                           const std::string& text,
                                           const std::string& where)
    : datatype_(datatype), where_(where) {
  // Split into (type, lines) blocks.
  std::vector<std::pair<std::string, std::vector<std::pair<int, std::string>>>> blocks;
  blocks.push_back({datatype, {}});
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  bool expect_msg = false;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string s = Trim(line);
    if (s.size() >= 3 && s.find_first_not_of('=') == std::string::npos) {
      expect_msg = true;
      continue;
    }
    if (expect_msg && s.rfind("MSG:", 0) == 0) {
      blocks.push_back({Trim(s.substr(4)), {}});
      expect_msg = false;
      continue;
    }
    blocks.back().second.push_back({line_no, s});
  }
  for (const auto& [type, lines] : blocks) {
    const std::string package = type.substr(0, type.find('/'));
    std::vector<RosMsgField>& fields = types_[type];
    for (const auto& [no, raw] : lines) {
      const std::string s = Trim(raw.substr(0, raw.find('#')));
      if (s.empty()) continue;
      std::istringstream ls(s);
      std::string t, name;
      ls >> t >> name;
      if (name.empty()) {
        throw InputError(where,
                         fmt::format("message definition of {} line {}", datatype, no),
                         "expected 'type name', found '" + s + "'");
      }
      if (name.find('=') != std::string::npos || s.find('=') != std::string::npos) {
        continue;  // a constant: no bytes in the message
      }
      RosMsgField f;
      f.name = name;
      const size_t bracket = t.find('[');
      if (bracket != std::string::npos) {
        f.is_array = true;
        const std::string n = t.substr(bracket + 1, t.size() - bracket - 2);
        if (t.back() != ']' ||
            (!n.empty() && n.find_first_not_of("0123456789") != std::string::npos)) {
          throw InputError(where,
                           fmt::format("message definition of {} line {}", datatype, no),
                           "bad array type '" + t + "'");
        }
        // A fixed length is at most kMaxFixedArrayLength, so that sizes computed
        // from the definition cannot overflow (FixedSize).
        if (n.size() > 9 || (!n.empty() && std::stoul(n) > kMaxFixedArrayLength)) {
          throw InputError(where,
                           fmt::format("message definition of {} line {}", datatype, no),
                           fmt::format("array length in '{}' exceeds {}", t, kMaxFixedArrayLength));
        }
        f.fixed_count = n.empty() ? 0 : static_cast<uint32_t>(std::stoul(n));
        t = t.substr(0, bracket);
      }
      if (!IsBuiltin(t)) {
        if (t == "Header") {
          t = "std_msgs/Header";
        } else if (t.find('/') == std::string::npos) {
          t = package + "/" + t;
        }
      }
      f.type = t;
      fields.push_back(f);
    }
  }
  for (const auto& [type, fields] : types_) {
    for (const RosMsgField& f : fields) {
      if (!IsBuiltin(f.type) && !types_.count(f.type)) {
        throw InputError(where,
                         "message definition of " + datatype,
                         fmt::format("field {}.{} has type {}, which the definition does not hold",
                                     type,
                                     f.name,
                                     f.type));
      }
    }
  }
  // A type that contains itself (directly or through others) has no finite
  // serialization; the size computations below recurse through the types.
  std::map<std::string, int> state;  // 1: on the current path, 2: done
  std::function<void(const std::string&)> visit = [&](const std::string& type) {
    state[type] = 1;
    for (const RosMsgField& f : types_.at(type)) {
      if (IsBuiltin(f.type) || state[f.type] == 2) continue;
      if (state[f.type] == 1) {
        throw InputError(
            where,
            "message definition of " + datatype,
            fmt::format("type {} contains itself (field {}.{})", f.type, type, f.name));
      }
      visit(f.type);
    }
    state[type] = 2;
  };
  for (const auto& entry : types_) {
    if (state[entry.first] == 0) visit(entry.first);
  }
}

const std::vector<RosMsgField>& RosMessageDefinition::Fields(const std::string& type) const {
  return types_.at(type);
}

std::optional<size_t> RosMessageDefinition::FixedSize(const RosMsgField& field) const {
  if (field.is_array && field.fixed_count == 0) return std::nullopt;
  const std::optional<size_t> one = FixedSize(field.type);
  if (!one) return std::nullopt;
  const size_t count = field.is_array ? field.fixed_count : 1;
  if (count > 0 && *one > kMaxFixedMessageBytes / count) {
    throw InputError(where_,
                     "message definition of " + datatype_,
                     fmt::format("field {} of type {} holds more than {} bytes",
                                 field.name,
                                 field.type,
                                 kMaxFixedMessageBytes));
  }
  return *one * count;
}

std::optional<size_t> RosMessageDefinition::FixedSize(const std::string& type) const {
  if (const size_t b = BuiltinSize(type)) return b;
  if (type == "string") return std::nullopt;
  size_t total = 0;
  for (const RosMsgField& f : types_.at(type)) {
    const std::optional<size_t> s = FixedSize(f);
    if (!s) return std::nullopt;
    total += *s;
    if (total > kMaxFixedMessageBytes) {
      throw InputError(
          where_,
          "message definition of " + datatype_,
          fmt::format("type {} holds more than {} bytes", type, kMaxFixedMessageBytes));
    }
  }
  return total;
}

std::optional<size_t> RosMessageDefinition::FieldOffset(const std::string& type,
                                                        const std::string& name) const {
  size_t offset = 0;
  for (const RosMsgField& f : types_.at(type)) {
    if (f.name == name) return offset;
    const std::optional<size_t> s = FixedSize(f);
    if (!s) return std::nullopt;
    offset += *s;
  }
  return std::nullopt;
}

const RosMsgField* RosMessageDefinition::FindField(const std::string& type,
                                                   const std::string& name) const {
  for (const RosMsgField& f : types_.at(type)) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

namespace {

// Bytes taken by one value of `type` starting at p (at most n bytes available).
size_t ValueSize(const RosMessageDefinition& def,
                 const std::string& type,
                 const uint8_t* p,
                 size_t n,
                 const std::string& where);

size_t FieldSize(const RosMessageDefinition& def,
                 const RosMsgField& f,
                 const uint8_t* p,
                 size_t n,
                 const std::string& where,
                 uint32_t* count) {
  size_t used = 0;
  uint32_t elements = 1;
  if (f.is_array) {
    elements = f.fixed_count;
    if (f.fixed_count == 0) {
      if (n < 4)
        throw InputError(fmt::format("{}: message ends in the count of {}", where, f.name));
      elements = ReadLe<uint32_t>(p);
      used = 4;
    }
  }
  if (count) *count = elements;
  const std::optional<size_t> one = def.FixedSize(f.type);
  if (one) {
    const uint64_t bytes = static_cast<uint64_t>(*one) * elements;
    if (bytes > n - used) {
      throw InputError(fmt::format("{}: message ends inside field {} ({} elements of {} bytes)",
                                   where,
                                   f.name,
                                   elements,
                                   *one));
    }
    return used + static_cast<size_t>(bytes);
  }
  for (uint32_t i = 0; i < elements; ++i) used += ValueSize(def, f.type, p + used, n - used, where);
  return used;
}

size_t ValueSize(const RosMessageDefinition& def,
                 const std::string& type,
                 const uint8_t* p,
                 size_t n,
                 const std::string& where) {
  if (type == "string") {
    if (n < 4) throw InputError(fmt::format("{}: message ends in a string length", where));
    const uint32_t len = ReadLe<uint32_t>(p);
    if (len > n - 4) throw InputError(fmt::format("{}: message ends inside a string", where));
    return 4 + len;
  }
  if (const size_t b = BuiltinSize(type)) {
    if (b > n) throw InputError(fmt::format("{}: message ends inside a {}", where, type));
    return b;
  }
  size_t used = 0;
  for (const RosMsgField& f : def.Fields(type)) {
    used += FieldSize(def, f, p + used, n - used, where, nullptr);
  }
  return used;
}

}  // namespace

std::map<std::string, RosFieldSpan> SplitRosMessage(const RosMessageDefinition& def,
                                                    const uint8_t* data,
                                                    size_t size,
                                                    const std::string& where) {
  std::map<std::string, RosFieldSpan> out;
  size_t used = 0;
  for (const RosMsgField& f : def.Fields(def.datatype())) {
    RosFieldSpan span;
    span.field = &f;
    const size_t n = FieldSize(def, f, data + used, size - used, where, &span.count);
    const size_t prefix = f.is_array && f.fixed_count == 0 ? 4 : 0;
    span.data = data + used + prefix;
    span.size = n - prefix;
    out[f.name] = span;
    used += n;
  }
  if (used != size) {
    throw InputError(fmt::format("{}: {} bytes after the last field of {} ({} bytes used)",
                                 where,
                                 size - used,
                                 def.datatype(),
                                 used));
  }
  return out;
}

const char kLivoxCustomMsgType[] = "livox_ros_driver/CustomMsg";
const char kLivoxCustomMsgMd5[] = "e4d6829bdfe657cb6c21a746c86b21a6";
const char kLivoxCustomMsgDefinition[] =
    "# Livox publish pointcloud msg format.\n"
    "\n"
    "Header header             # ROS standard message header\n"
    "uint64 timebase           # The time of first point\n"
    "uint32 point_num          # Total number of pointclouds\n"
    "uint8  lidar_id           # Lidar device id number\n"
    "uint8[3]  rsvd            # Reserved use\n"
    "CustomPoint[] points      # Pointcloud data\n"
    "\n"
    "\n"
    "================================================================================\n"
    "MSG: std_msgs/Header\n"
    "# Standard metadata for higher-level stamped data types.\n"
    "# This is generally used to communicate timestamped data \n"
    "# in a particular coordinate frame.\n"
    "# \n"
    "# sequence ID: consecutively increasing ID \n"
    "uint32 seq\n"
    "#Two-integer timestamp that is expressed as:\n"
    "# * stamp.sec: seconds (stamp_secs) since epoch (in Python the variable is called 'secs')\n"
    "# * stamp.nsec: nanoseconds since stamp_secs (in Python the variable is called 'nsecs')\n"
    "# time-handling sugar is provided by the client library\n"
    "time stamp\n"
    "#Frame this data is associated with\n"
    "string frame_id\n"
    "\n"
    "================================================================================\n"
    "MSG: livox_ros_driver/CustomPoint\n"
    "# Livox costom pointcloud format.\n"
    "\n"
    "uint32 offset_time      # offset time relative to the base time\n"
    "float32 x               # X axis, unit:m\n"
    "float32 y               # Y axis, unit:m\n"
    "float32 z               # Z axis, unit:m\n"
    "uint8 reflectivity      # reflectivity, 0~255\n"
    "uint8 tag               # livox tag\n"
    "uint8 line              # laser number in lidar\n"
    "\n";

PointCloud DecodeLivoxCustomMsg(const RosMessageDefinition& def,
                                const uint8_t* data,
                                size_t size,
                                const std::string& where) {
  const std::map<std::string, RosFieldSpan> top = SplitRosMessage(def, data, size, where);
  auto need = [&](const std::string& name, const std::string& type, bool array) {
    auto it = top.find(name);
    if (it == top.end() || it->second.field->type != type || it->second.field->is_array != array) {
      throw InputError(fmt::format(
          "{}: {} has no field {} {}{}", where, def.datatype(), type, name, array ? "[]" : ""));
    }
    return it->second;
  };
  const RosFieldSpan timebase = need("timebase", "uint64", false);
  const RosFieldSpan points = need("points", "livox_ros_driver/CustomPoint", true);
  const std::string pt = points.field->type;
  const std::optional<size_t> step = def.FixedSize(pt);
  auto offset = [&](const std::string& name, const std::string& type) -> size_t {
    const RosMsgField* f = def.FindField(pt, name);
    const std::optional<size_t> o = def.FieldOffset(pt, name);
    if (!f || f->type != type || f->is_array || !o) {
      throw InputError(fmt::format("{}: {} has no field {} {}", where, pt, type, name));
    }
    return *o;
  };
  if (!step) throw InputError(fmt::format("{}: {} is not of fixed size", where, pt));
  const size_t o_time = offset("offset_time", "uint32");
  const size_t o_x = offset("x", "float32");
  const size_t o_y = offset("y", "float32");
  const size_t o_z = offset("z", "float32");
  const size_t o_refl = offset("reflectivity", "uint8");
  const size_t o_line = offset("line", "uint8");
  const uint64_t base = ReadLe<uint64_t>(timebase.data);

  PointCloud cloud;
  cloud.points.reserve(points.count);
  std::vector<uint32_t> offsets;
  offsets.reserve(points.count);
  uint32_t min_offset = UINT32_MAX;
  for (uint32_t i = 0; i < points.count; ++i) {
    const uint8_t* p = points.data + static_cast<size_t>(i) * *step;
    LidarPoint q;
    q.x = ReadLe<float>(p + o_x);
    q.y = ReadLe<float>(p + o_y);
    q.z = ReadLe<float>(p + o_z);
    if (q.x == 0 && q.y == 0 && q.z == 0) continue;
    q.intensity = static_cast<float>(p[o_refl]);
    q.ring = p[o_line];
    const uint32_t off = ReadLe<uint32_t>(p + o_time);
    min_offset = std::min(min_offset, off);
    offsets.push_back(off);
    cloud.points.push_back(q);
  }
  if (cloud.points.empty()) {
    throw InputError(fmt::format("{}: no point (of {}) away from the origin", where, points.count));
  }
  if (base + min_offset > static_cast<uint64_t>(INT64_MAX) || base == 0) {
    throw InputError(fmt::format("{}: timebase {} ns is not a valid time", where, base));
  }
  cloud.stamp_ns = static_cast<TimestampNs>(base + min_offset);
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    cloud.points[i].t = static_cast<float>(static_cast<double>(offsets[i] - min_offset) * 1e-9);
  }
  return cloud;
}

std::vector<uint8_t> EncodeLivoxCustomMsg(const PointCloud& cloud,
                                          uint32_t seq,
                                          const std::string& frame_id,
                                          uint8_t lidar_id) {
  std::vector<uint8_t> out;
  out.reserve(40 + frame_id.size() + cloud.size() * 19);
  const uint64_t stamp = static_cast<uint64_t>(cloud.stamp_ns);
  AppendLe<uint32_t>(&out, seq);
  AppendLe<uint32_t>(&out, static_cast<uint32_t>(stamp / 1000000000ULL));
  AppendLe<uint32_t>(&out, static_cast<uint32_t>(stamp % 1000000000ULL));
  AppendLe<uint32_t>(&out, static_cast<uint32_t>(frame_id.size()));
  out.insert(out.end(), frame_id.begin(), frame_id.end());
  AppendLe<uint64_t>(&out, stamp);                                // timebase
  AppendLe<uint32_t>(&out, static_cast<uint32_t>(cloud.size()));  // point_num
  AppendLe<uint8_t>(&out, lidar_id);                              // lidar_id
  for (int i = 0; i < 3; ++i) AppendLe<uint8_t>(&out, 0);         // rsvd
  AppendLe<uint32_t>(&out, static_cast<uint32_t>(cloud.size()));  // points[] count
  for (const LidarPoint& p : cloud.points) {
    const double t_ns = std::round(static_cast<double>(p.t) * 1e9);
    AppendLe<uint32_t>(&out, static_cast<uint32_t>(std::clamp(t_ns, 0.0, 4294967295.0)));
    AppendLe<float>(&out, p.x);
    AppendLe<float>(&out, p.y);
    AppendLe<float>(&out, p.z);
    const float refl = std::round(p.intensity);
    AppendLe<uint8_t>(&out, static_cast<uint8_t>(std::clamp(refl, 0.0f, 255.0f)));
    AppendLe<uint8_t>(&out, 0);  // tag
    AppendLe<uint8_t>(&out, static_cast<uint8_t>(std::min<int>(p.ring, 255)));
  }
  return out;
}

}  // namespace lisfm
