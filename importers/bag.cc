#include "importers/bag.h"

#include <bzlib.h>
#include <fmt/format.h>
#include <glob.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <roslz4/lz4s.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <tuple>
#include <vector>

#include "core/io/image_codec.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/rig_io.h"
#include "core/logging.h"
#include "core/progress.h"
#include "importers/bag_message.h"

namespace lisfm {

// A message given as its serialized bytes with its type, md5 and definition
// (for types without generated C++ headers, e.g. livox_ros_driver/CustomMsg).
struct RawRosMessage {
  const char* datatype = "";
  const char* md5sum = "";
  const char* definition = "";
  std::vector<uint8_t> bytes;
};

}  // namespace lisfm

namespace ros {
namespace message_traits {
template <>
struct IsMessage<lisfm::RawRosMessage> : TrueType {};
template <>
struct MD5Sum<lisfm::RawRosMessage> {
  static const char* value(const lisfm::RawRosMessage& m) { return m.md5sum; }
};
template <>
struct DataType<lisfm::RawRosMessage> {
  static const char* value(const lisfm::RawRosMessage& m) { return m.datatype; }
};
template <>
struct Definition<lisfm::RawRosMessage> {
  static const char* value(const lisfm::RawRosMessage& m) { return m.definition; }
};
}  // namespace message_traits
namespace serialization {
template <>
struct Serializer<lisfm::RawRosMessage> {
  template <typename Stream>
  static void write(Stream& stream, const lisfm::RawRosMessage& m) {
    if (!m.bytes.empty())
      std::memcpy(stream.advance(m.bytes.size()), m.bytes.data(), m.bytes.size());
  }
  static uint32_t serializedLength(const lisfm::RawRosMessage& m) {
    return static_cast<uint32_t>(m.bytes.size());
  }
};
}  // namespace serialization
}  // namespace ros

namespace lisfm {
namespace {

constexpr char kPointCloud2Type[] = "sensor_msgs/PointCloud2";

ros::Time ToRosTime(TimestampNs t_ns, const std::string& what) {
  if (t_ns <= 0)
    throw InputError(fmt::format("{}: stamp {} ns is not a valid ROS time", what, t_ns));
  ros::Time t;
  t.fromNSec(static_cast<uint64_t>(t_ns));
  return t;
}

std::string ReadFilePrefix(const std::string& path, size_t n) {
  std::ifstream in(path, std::ios::binary);
  std::string s(n, '\0');
  in.read(&s[0], static_cast<std::streamsize>(n));
  s.resize(static_cast<size_t>(std::max<std::streamsize>(in.gcount(), 0)));
  return s;
}

// Parses a record header (fields: u32 length, "name=value") into `fields` and returns ""
// or what is wrong. ros::Header::parse, which rosbag_storage uses, reads each field's
// length and bytes without checking them against the header's end, so every field must
// lie inside the header, including the 4 bytes of its length.
std::string ParseHeaderFields(const char* header,
                              size_t size,
                              std::map<std::string, std::string>* fields) {
  fields->clear();
  for (size_t i = 0; i < size;) {
    if (size - i < 4) {
      return fmt::format("header ends {} bytes into a field length", size - i);
    }
    uint32_t field_len = 0;
    std::memcpy(&field_len, header + i, 4);
    if (field_len > size - i - 4) {
      return fmt::format("header field of {} bytes past the header", field_len);
    }
    const std::string field(header + i + 4, field_len);
    const size_t eq = field.find('=');
    if (eq != std::string::npos) (*fields)[field.substr(0, eq)] = field.substr(eq + 1);
    i += 4 + field_len;
  }
  return "";
}

// Walks the records inside a chunk's (uncompressed) data and returns "" when each
// record, its header fields and its data lie inside the chunk, else what is wrong;
// `starts` gets each record's offset in the chunk. `chunk_pos` names the chunk.
std::string ChunkRecordsError(const std::string& chunk,
                              uint64_t chunk_pos,
                              std::set<uint64_t>* starts) {
  starts->clear();
  std::map<std::string, std::string> fields;
  for (uint64_t at = 0; at < chunk.size();) {
    uint32_t inner_header = 0, inner_data = 0;
    if (chunk.size() - at < 4) {
      return fmt::format("chunk at byte {}: record at chunk offset {} cut off", chunk_pos, at);
    }
    std::memcpy(&inner_header, chunk.data() + at, 4);
    if (inner_header > chunk.size() - at - 4 || chunk.size() - at - 4 - inner_header < 4) {
      return fmt::format(
          "chunk at byte {}: record at chunk offset {} has a header of {} "
          "bytes past the chunk",
          chunk_pos,
          at,
          inner_header);
    }
    const std::string field_error = ParseHeaderFields(chunk.data() + at + 4, inner_header, &fields);
    if (!field_error.empty()) {
      return fmt::format(
          "chunk at byte {}: record at chunk offset {}: {}", chunk_pos, at, field_error);
    }
    std::memcpy(&inner_data, chunk.data() + at + 4 + inner_header, 4);
    if (inner_data > chunk.size() - at - 8 - inner_header) {
      return fmt::format(
          "chunk at byte {}: record at chunk offset {} has data of {} bytes "
          "past the chunk",
          chunk_pos,
          at,
          inner_data);
    }
    starts->insert(at);
    at += 8 + uint64_t{inner_header} + inner_data;
  }
  return "";
}

// Decompresses a chunk's data (`compression` none, lz4 or bz2) into `out`, which must
// come to exactly `size` bytes, as rosbag_storage expects; returns "" or what is wrong.
std::string DecompressChunk(std::string data,
                            const std::string& compression,
                            uint32_t size,
                            uint64_t chunk_pos,
                            std::string* out) {
  if (compression == "none") {
    *out = std::move(data);
    return "";
  }
  out->assign(size, '\0');
  unsigned int produced = size;
  bool ok = false;
  if (compression == "lz4") {
    ok = roslz4_buffToBuffDecompress(
             data.data(), static_cast<unsigned int>(data.size()), out->data(), &produced) ==
         ROSLZ4_OK;
  } else if (compression == "bz2") {
    ok = BZ2_bzBuffToBuffDecompress(
             out->data(), &produced, data.data(), static_cast<unsigned int>(data.size()), 0, 0) ==
         BZ_OK;
  } else {
    return fmt::format(
        "chunk at byte {}: compression '{}' is not none, lz4 or bz2", chunk_pos, compression);
  }
  if (!ok || produced != size) {
    return fmt::format(
        "chunk at byte {}: its {} data does not decompress to the {} bytes "
        "announced",
        chunk_pos,
        compression,
        size);
  }
  return "";
}

// Walks the records of a ROS1 bag (format 2.0: "#ROSBAG V2.0\n", then records: u32
// header length, header, u32 data length, data) and returns "" when every record lies
// inside the file, else what is wrong. rosbag_storage allocates a record's announced
// lengths before reading them (up to 4 GiB each) and a chunk's uncompressed `size`
// before decompressing it, reads header fields and the records inside a chunk without
// bounds checks, and reads a message record at every offset an index names: so each
// top-level record, each record inside every chunk (decompressed here for lz4 / bz2),
// every header field and every index offset is checked here first.
// `first_record` is the byte after the version line.
std::string BagRecordError(const std::string& path, uint64_t first_record) {
  constexpr uint64_t kMaxHeaderBytes = uint64_t{1} << 20;  // headers hold a few fields
  constexpr uint64_t kMaxChunkBytes = uint64_t{1} << 30;   // uncompressed chunk (1 GiB)
  std::ifstream in(path, std::ios::binary);
  in.seekg(0, std::ios::end);
  const uint64_t file_size = static_cast<uint64_t>(std::max<std::streamoff>(in.tellg(), 0));
  uint64_t pos = first_record;
  std::set<uint64_t> record_starts;
  std::set<uint64_t> chunk_inner_starts;  // record offsets inside the last chunk
  std::vector<std::tuple<uint64_t, uint64_t, const char*>> pointers;  // record, offset, field
  const auto read_u32 = [&](uint64_t at, uint32_t* v) {
    in.seekg(static_cast<std::streamoff>(at));
    return static_cast<bool>(in.read(reinterpret_cast<char*>(v), 4));
  };
  const auto read_bytes = [&](uint64_t at, uint64_t n) {
    std::string bytes(n, '\0');
    in.seekg(static_cast<std::streamoff>(at));
    in.read(bytes.data(), static_cast<std::streamsize>(n));
    return bytes;
  };
  std::map<std::string, std::string> fields;
  while (pos < file_size) {
    uint32_t header_len = 0, data_len = 0;
    if (file_size - pos < 4 || !read_u32(pos, &header_len)) {
      return fmt::format("record at byte {}: the file ends in its header length", pos);
    }
    if (header_len > kMaxHeaderBytes || header_len > file_size - pos - 4) {
      return fmt::format("record at byte {}: header of {} bytes, {} bytes left in the file",
                         pos,
                         header_len,
                         file_size - pos - 4);
    }
    const std::string header = read_bytes(pos + 4, header_len);
    const std::string field_error = ParseHeaderFields(header.data(), header.size(), &fields);
    if (!field_error.empty()) return fmt::format("record at byte {}: {}", pos, field_error);
    const uint64_t data_at = pos + 4 + header_len;
    if (file_size - data_at < 4 || !read_u32(data_at, &data_len)) {
      return fmt::format("record at byte {}: the file ends in its data length", pos);
    }
    if (data_len > file_size - data_at - 4) {
      return fmt::format("record at byte {}: data of {} bytes, {} bytes left in the file",
                         pos,
                         data_len,
                         file_size - data_at - 4);
    }
    const auto u64_field = [&](const char* key, uint64_t* v) {
      if (fields[key].size() != 8) return false;
      std::memcpy(v, fields[key].data(), 8);
      return true;
    };
    record_starts.insert(pos);
    uint64_t at = 0;
    const std::string op = fields["op"];
    if (op == std::string(1, '\x03') && u64_field("index_pos", &at)) {
      pointers.emplace_back(pos, at, "index_pos");
    } else if (op == std::string(1, '\x06') && u64_field("chunk_pos", &at)) {
      pointers.emplace_back(pos, at, "chunk_pos");
    }
    if (op == std::string(1, '\x05')) {  // a chunk
      uint32_t size = 0;
      if (fields["size"].size() == 4) std::memcpy(&size, fields["size"].data(), 4);
      const std::string& compression = fields["compression"];
      if (size > kMaxChunkBytes || (compression == "none" && size != data_len)) {
        return fmt::format(
            "chunk at byte {}: {} uncompressed bytes announced for {} bytes of "
            "'{}' data",
            pos,
            size,
            data_len,
            compression);
      }
      std::string chunk;
      std::string error =
          DecompressChunk(read_bytes(data_at + 4, data_len), compression, size, pos, &chunk);
      if (error.empty()) error = ChunkRecordsError(chunk, pos, &chunk_inner_starts);
      if (!error.empty()) return error;
    } else if (op == std::string(1, '\x04')) {
      // Index data (version 1) of the preceding chunk: (u32 sec, u32 nsec, u32 offset) per
      // message; rosbag_storage reads a message record at each offset of the chunk.
      const std::string entries = read_bytes(data_at + 4, data_len);
      for (size_t e = 0; e + 12 <= entries.size(); e += 12) {
        uint32_t offset = 0;
        std::memcpy(&offset, entries.data() + e + 8, 4);
        if (chunk_inner_starts.count(offset) == 0) {
          return fmt::format(
              "index at byte {}: message offset {} is not a record start in its "
              "chunk",
              pos,
              offset);
        }
      }
    }
    pos = data_at + 4 + data_len;
  }
  // rosbag_storage seeks to these offsets and reads a record there: each must be the
  // start of a record (index_pos 0 marks an unindexed bag, which rosbag_storage refuses).
  for (const auto& [record, target, name] : pointers) {
    if (target != 0 && record_starts.count(target) == 0) {
      return fmt::format(
          "record at byte {}: {} {} is not the start of a record", record, name, target);
    }
  }
  return "";
}

// rosbag_storage accepts any first line "#ROS<name> V<major>.<minor>" up to the first
// newline and then reads records of that format version. Returns "" for a file that
// is not such a bag (rosbag_storage then refuses it itself) or a format 2.0 bag whose
// records all lie inside the file, else what is wrong. Other versions (1.x) are
// refused: their record layout is not checked here.
std::string BagVersionAndRecordError(const std::string& path) {
  constexpr size_t kMaxVersionLine = 4096;
  const std::string head = ReadFilePrefix(path, kMaxVersionLine);
  if (head.compare(0, 4, "#ROS") != 0) return "";
  const size_t newline = head.find('\n');
  if (newline == std::string::npos) {
    return fmt::format("no end of the version line within its first {} bytes", head.size());
  }
  const std::string line = head.substr(0, newline);
  char name[100];
  int major = 0, minor = 0;
  if (std::sscanf(line.c_str(), "#ROS%99s V%d.%d", name, &major, &minor) != 3) return "";
  if (major != 2 || minor != 0) {
    return fmt::format(
        "bag format version {}.{}; only 2.0 is read (`rosbag fix` converts)", major, minor);
  }
  return BagRecordError(path, newline + 1);
}

TimestampNs ToNs(const ros::Time& t) { return static_cast<TimestampNs>(t.toNSec()); }

uint8_t ParseTimeType(const std::string& s, const std::string& path) {
  if (s == "float32") return 7;
  if (s == "float64") return 8;
  if (s == "uint32") return 6;
  if (s == "int32") return 5;
  throw InputError(path,
                   "lidar_fields.time_type",
                   "expected float32, float64, uint32 or int32, found '" + s + "'");
}

std::vector<std::string> StringList(const YAML::Node& node,
                                    const std::string& path,
                                    const std::string& key) {
  std::vector<std::string> out;
  if (!node) return out;
  if (!node.IsSequence()) throw InputError(path, key, "expected a list of topics");
  for (const YAML::Node& n : node) out.push_back(n.as<std::string>());
  return out;
}

// One topic's bookkeeping while reading.
struct TopicState {
  enum class Kind { kImu, kLidar, kCamera } kind;
  size_t index = 0;  // rig lidar / camera index
  std::string folder;
  std::vector<TimestampNs> stamps;  // header stamps of every message read
  std::vector<TimestampNs> kept;    // stamps written to the folder
  TimestampNs last_kept = 0;
  std::string type;
  std::string msg_def;                        // the connection's message definition
  std::unique_ptr<RosMessageDefinition> def;  // CustomMsg topics
};

std::string Where(const std::string& bag, const std::string& topic, size_t index) {
  return fmt::format("{}: topic {} message {}", bag, topic, index);
}

void WriteIndex(const std::string& path,
                const std::vector<TimestampNs>& stamps,
                const std::string& ext) {
  std::ostringstream csv;
  csv << "#timestamp [ns],filename\n";
  for (TimestampNs t : stamps) csv << t << "," << t << ext << "\n";
  WriteFileAtomically(path, csv.str());
}

BagTopicSummary Summarize(const std::string& topic, const TopicState& s) {
  BagTopicSummary r;
  r.topic = topic;
  r.type = s.type;
  r.num_messages = s.stamps.size();
  r.num_kept = s.kept.size();
  if (s.stamps.empty()) return r;
  r.first_ns = s.stamps.front();
  r.last_ns = s.stamps.back();
  if (s.stamps.size() < 2) return r;
  std::vector<TimestampNs> dt(s.stamps.size() - 1);
  for (size_t i = 1; i < s.stamps.size(); ++i) dt[i - 1] = s.stamps[i] - s.stamps[i - 1];
  r.max_gap_s = NsToSeconds(*std::max_element(dt.begin(), dt.end()));
  r.rate_hz = static_cast<double>(dt.size()) / NsToSeconds(r.last_ns - r.first_ns);
  std::vector<TimestampNs> sorted = dt;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median = static_cast<double>(sorted[sorted.size() / 2]);
  for (TimestampNs d : dt) r.num_gaps += static_cast<double>(d) > 1.5 * median ? 1 : 0;
  return r;
}

}  // namespace

bool BagImportOptions::Check() const {
  return camera_rate_hz >= 0 && std::isfinite(camera_rate_hz);
}

BagPreset ReadBagPreset(const std::string& path) {
  CheckFileExists(path, "bag preset");
  YAML::Node doc;
  try {
    doc = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw InputError(path, fmt::format("line {}", e.mark.line + 1), e.msg);
  }
  BagPreset p;
  p.name = path;
  try {
    if (!doc["imu_topic"]) throw InputError(path, "imu_topic", "missing");
    p.imu_topic = doc["imu_topic"].as<std::string>();
    p.lidar_topics = StringList(doc["lidar_topics"], path, "lidar_topics");
    p.camera_topics = StringList(doc["camera_topics"], path, "camera_topics");
    p.lidar_types = StringList(doc["lidar_types"], path, "lidar_types");
    if (!doc["lidar_types"]) p.lidar_types.assign(p.lidar_topics.size(), kPointCloud2Type);
    if (p.lidar_types.size() != p.lidar_topics.size()) {
      throw InputError(
          path,
          "lidar_types",
          fmt::format("{} types for {} lidar_topics", p.lidar_types.size(), p.lidar_topics.size()));
    }
    for (const std::string& t : p.lidar_types) {
      if (t != kPointCloud2Type && t != kLivoxCustomMsgType) {
        throw InputError(
            path,
            "lidar_types",
            fmt::format("'{}' is not {} or {}", t, kPointCloud2Type, kLivoxCustomMsgType));
      }
    }
    const YAML::Node f = doc["lidar_fields"];
    if (f && !f.IsMap()) {
      throw InputError(path,
                       "lidar_fields",
                       "expected a mapping (time, time_type, ...), found " +
                           std::string(f.IsNull() ? "nothing" : "a list or a scalar"));
    }
    if (f) {
      if (f["time"]) p.lidar_fields.time.name = f["time"].as<std::string>();
      if (f["time_type"]) {
        p.lidar_fields.time.datatype = ParseTimeType(f["time_type"].as<std::string>(), path);
      }
      if (f["time_unit"]) {
        const std::string u = f["time_unit"].as<std::string>();
        if (u != "s" && u != "ns") {
          throw InputError(path, "lidar_fields.time_unit", "expected s or ns, found '" + u + "'");
        }
        p.lidar_fields.time.unit =
            u == "s" ? PointTimeField::Unit::kSeconds : PointTimeField::Unit::kNanoseconds;
      }
      if (f["time_reference"]) {
        const std::string r = f["time_reference"].as<std::string>();
        if (r != "stamp" && r != "absolute") {
          throw InputError(
              path, "lidar_fields.time_reference", "expected stamp or absolute, found '" + r + "'");
        }
        p.lidar_fields.time.reference =
            r == "stamp" ? PointTimeField::Reference::kStamp : PointTimeField::Reference::kAbsolute;
      }
      if (f["intensity"]) p.lidar_fields.intensity_field = f["intensity"].as<std::string>();
      if (f["ring"]) p.lidar_fields.ring_field = f["ring"].as<std::string>();
    }
  } catch (const YAML::Exception& e) {
    throw InputError(path, fmt::format("line {}", e.mark.line + 1), e.msg);
  }
  return p;
}

std::vector<std::string> ExpandBagPaths(const std::string& input) {
  std::vector<std::string> out;
  std::stringstream list(input);
  std::string item;
  while (std::getline(list, item, ',')) {
    if (item.empty()) continue;
    std::vector<std::string> found;
    if (DirExists(item)) {
      for (const auto& e : std::filesystem::directory_iterator(item)) {
        if (e.is_regular_file() && e.path().extension() == ".bag")
          found.push_back(e.path().string());
      }
      if (found.empty()) throw InputError(fmt::format("{}: folder holds no .bag file", item));
    } else if (item.find_first_of("*?[") != std::string::npos) {
      glob_t g;
      if (glob(item.c_str(), 0, nullptr, &g) == 0) {
        for (size_t i = 0; i < g.gl_pathc; ++i) found.push_back(g.gl_pathv[i]);
      }
      globfree(&g);
      if (found.empty()) throw InputError(fmt::format("{}: no file matches the pattern", item));
    } else {
      CheckFileExists(item, "bag");
      found.push_back(item);
    }
    std::sort(found.begin(), found.end());
    out.insert(out.end(), found.begin(), found.end());
  }
  if (out.empty()) throw InputError(fmt::format("'{}': no bag given", input));
  for (size_t i = 1; i < out.size(); ++i) {
    if (std::find(out.begin(), out.begin() + i, out[i]) != out.begin() + i) {
      throw InputError(fmt::format("{}: given twice in '{}'", out[i], input));
    }
  }
  return out;
}

BagImportSummary ImportBag(const std::string& bag_path,
                           const Rig& rig,
                           const std::string& rig_yaml,
                           const BagPreset& preset,
                           const BagImportOptions& options,
                           const std::string& output_dir) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<std::string> paths = ExpandBagPaths(bag_path);
  if (preset.lidar_topics.size() > rig.lidars.size()) {
    throw InputError(fmt::format("{} lists {} LiDAR topics but the rig has {} LiDARs",
                                 preset.name,
                                 preset.lidar_topics.size(),
                                 rig.lidars.size()));
  }
  BagImportSummary summary;
  std::vector<std::unique_ptr<rosbag::Bag>> bags;
  for (const std::string& path : paths) {
    bags.push_back(std::make_unique<rosbag::Bag>());
    try {
      const std::string error = BagVersionAndRecordError(path);
      if (!error.empty()) throw std::runtime_error(error);
      bags.back()->open(path, rosbag::bagmode::Read);
    } catch (const std::exception& e) {
      // A bag starts with "#ROSBAG V2.0\n"; one that does but fails to open has
      // lost its index (an interrupted recording) or is damaged.
      const std::string head = ReadFilePrefix(path, 4);
      if (head == "#ROS") {
        throw InputError(fmt::format(
            "{}: ROS1 bag cannot be opened (truncated, unindexed or corrupted; `rosbag reindex` "
            "repairs an unindexed bag): {}",
            path,
            e.what()));
      }
      throw InputError(fmt::format("{}: not a readable ROS1 bag: {}", path, e.what()));
    }
    summary.bag_bytes += bags.back()->getSize();
  }

  // Topics of the preset and their types in the bag.
  std::map<std::string, TopicState> topics;
  std::vector<std::string> order;
  auto add_topic = [&](const std::string& topic,
                       TopicState::Kind kind,
                       size_t index,
                       const std::string& folder) {
    TopicState s;
    s.kind = kind;
    s.index = index;
    s.folder = folder;
    topics.emplace(topic, std::move(s));
    order.push_back(topic);
  };
  add_topic(preset.imu_topic, TopicState::Kind::kImu, 0, "imu0");
  for (size_t k = 0; k < preset.lidar_topics.size(); ++k) {
    add_topic(preset.lidar_topics[k], TopicState::Kind::kLidar, k, rig.lidars[k].name);
  }
  for (size_t k = 0; k < preset.camera_topics.size() && k < rig.cameras.size(); ++k) {
    add_topic(preset.camera_topics[k], TopicState::Kind::kCamera, k, rig.cameras[k].name);
  }
  std::vector<std::string> query_topics;
  try {
    rosbag::View all;
    for (const auto& b : bags) all.addQuery(*b);
    for (const rosbag::ConnectionInfo* c : all.getConnections()) {
      auto it = topics.find(c->topic);
      if (it != topics.end() && it->second.type.empty()) {
        it->second.type = c->datatype;
        it->second.msg_def = c->msg_def;
      }
    }
  } catch (const std::exception& e) {
    throw InputError(fmt::format("{}: cannot read the bag index: {}", bag_path, e.what()));
  }
  for (const std::string& topic : order) {
    TopicState& s = topics.at(topic);
    const char* expected = s.kind == TopicState::Kind::kImu     ? "sensor_msgs/Imu"
                           : s.kind == TopicState::Kind::kLidar ? "sensor_msgs/PointCloud2"
                                                                : "sensor_msgs/Image";
    if (s.type.empty()) {
      if (s.kind == TopicState::Kind::kCamera) {
        LogWarning("{}: no topic {} (camera {}); the folder has no {}/",
                   bag_path,
                   topic,
                   s.folder,
                   s.folder);
        continue;
      }
      throw InputError(fmt::format("{}: topic {} ({} of preset {}) is not in the bag",
                                   bag_path,
                                   topic,
                                   expected,
                                   preset.name));
    }
    if (s.kind == TopicState::Kind::kLidar && s.type == kLivoxCustomMsgType) {
      s.def = std::make_unique<RosMessageDefinition>(
          s.type, s.msg_def, fmt::format("{}: topic {}", bag_path, topic));
    } else if (s.type != expected) {
      throw InputError(fmt::format("{}: topic {} has type {}, expected {}{}",
                                   bag_path,
                                   topic,
                                   s.type,
                                   expected,
                                   s.kind == TopicState::Kind::kLidar
                                       ? std::string(" or ") + kLivoxCustomMsgType
                                       : std::string()));
    }
    query_topics.push_back(topic);
    if (s.kind != TopicState::Kind::kImu) CreateDirs(JoinPaths(output_dir, s.folder + "/data"));
  }

  std::vector<ImuSample> imu;
  constexpr int kPngCompression = 1;
  const TimestampNs camera_min_dt_ns =
      options.camera_rate_hz > 0 ? static_cast<TimestampNs>(0.9e9 / options.camera_rate_hz) : 0;
  std::map<std::string, size_t> counters;
  std::vector<uint8_t> raw_bytes;                      // serialized CustomMsg being decoded
  std::string last_read = "before the first message";  // for errors of the chunk reader
  try {
    // Split bags: one view over all files, in receive-time order.
    rosbag::View view;
    for (const auto& b : bags) view.addQuery(*b, rosbag::TopicQuery(query_topics));
    // Progress over the bag's bytes (kB): the message bytes read so far; the
    // record headers and the index make up the rest at the end.
    const int64_t total_kb = static_cast<int64_t>(summary.bag_bytes / 1024);
    ProgressReporter progress("bag_importer " + bag_path + " (kB)", total_kb);
    uint64_t bytes_read = 0;
    int64_t kb_reported = 0;
    auto add_bytes = [&](uint64_t n) {
      bytes_read += n;
      const int64_t kb = std::min<int64_t>(static_cast<int64_t>(bytes_read / 1024), total_kb);
      if (kb > kb_reported) progress.Add(kb - kb_reported);
      kb_reported = std::max(kb, kb_reported);
    };
    for (const rosbag::MessageInstance& m : view) {
      const std::string& topic = m.getTopic();
      TopicState& s = topics.at(topic);
      const size_t index = counters[topic]++;
      last_read = fmt::format("after topic {} message {}", topic, index);
      add_bytes(m.size());
      auto where = [&] { return Where(bag_path, topic, index); };
      auto check_stamp = [&](TimestampNs t_ns) {
        if (t_ns <= 0) throw InputError(fmt::format("{}: header.stamp is 0", where()));
        if (!s.stamps.empty() && t_ns <= s.stamps.back()) {
          throw InputError(fmt::format(
              "{}: stamp {} ns not after the previous {} ns", where(), t_ns, s.stamps.back()));
        }
        s.stamps.push_back(t_ns);
      };
      if (s.kind == TopicState::Kind::kImu) {
        sensor_msgs::Imu::ConstPtr msg;
        try {
          msg = m.instantiate<sensor_msgs::Imu>();
        } catch (const std::exception& e) {
          throw InputError(fmt::format("{}: cannot deserialize: {}", where(), e.what()));
        }
        if (!msg) throw InputError(fmt::format("{}: not a sensor_msgs/Imu", where()));
        ImuSample sample;
        sample.t_ns = ToNs(msg->header.stamp);
        check_stamp(sample.t_ns);
        sample.gyro =
            Vec3(msg->angular_velocity.x, msg->angular_velocity.y, msg->angular_velocity.z);
        sample.accel = Vec3(
            msg->linear_acceleration.x, msg->linear_acceleration.y, msg->linear_acceleration.z);
        if (!sample.gyro.allFinite() || !sample.accel.allFinite()) {
          throw InputError(fmt::format("{}: non-finite angular velocity or acceleration", where()));
        }
        imu.push_back(sample);
        s.kept.push_back(sample.t_ns);
      } else if (s.kind == TopicState::Kind::kLidar && s.def) {
        raw_bytes.resize(m.size());
        ros::serialization::OStream stream(raw_bytes.data(),
                                           static_cast<uint32_t>(raw_bytes.size()));
        m.write(stream);
        PointCloud cloud =
            DecodeLivoxCustomMsg(*s.def, raw_bytes.data(), raw_bytes.size(), where());
        RemoveNonFinite(&cloud);
        if (cloud.points.empty()) throw InputError(fmt::format("{}: no finite point", where()));
        check_stamp(cloud.stamp_ns);
        WritePcd(
            JoinPaths(output_dir, s.folder + "/data/" + std::to_string(cloud.stamp_ns) + ".pcd"),
            cloud,
            true);
        s.kept.push_back(cloud.stamp_ns);
      } else if (s.kind == TopicState::Kind::kLidar) {
        sensor_msgs::PointCloud2::ConstPtr msg;
        try {
          msg = m.instantiate<sensor_msgs::PointCloud2>();
        } catch (const std::exception& e) {
          throw InputError(fmt::format("{}: cannot deserialize: {}", where(), e.what()));
        }
        if (!msg) throw InputError(fmt::format("{}: not a sensor_msgs/PointCloud2", where()));
        RawPointCloud2 raw;
        raw.header_stamp_ns = ToNs(msg->header.stamp);
        raw.height = msg->height;
        raw.width = msg->width;
        for (const sensor_msgs::PointField& f : msg->fields) {
          raw.fields.push_back({f.name, f.offset, f.datatype, f.count});
        }
        raw.is_bigendian = msg->is_bigendian;
        raw.point_step = msg->point_step;
        raw.row_step = msg->row_step;
        raw.data = msg->data.data();
        raw.data_size = msg->data.size();
        raw.is_dense = msg->is_dense;
        PointCloud cloud = DecodePointCloud2(raw, preset.lidar_fields, where());
        RemoveNonFinite(&cloud);
        check_stamp(cloud.stamp_ns);
        WritePcd(
            JoinPaths(output_dir, s.folder + "/data/" + std::to_string(cloud.stamp_ns) + ".pcd"),
            cloud,
            true);
        s.kept.push_back(cloud.stamp_ns);
      } else {
        sensor_msgs::Image::ConstPtr msg;
        try {
          msg = m.instantiate<sensor_msgs::Image>();
        } catch (const std::exception& e) {
          throw InputError(fmt::format("{}: cannot deserialize: {}", where(), e.what()));
        }
        if (!msg) throw InputError(fmt::format("{}: not a sensor_msgs/Image", where()));
        // Camera clock -> IMU clock (Kalibr: t_imu = t_cam + timeshift_cam_imu).
        const TimestampNs t_ns =
            ToNs(msg->header.stamp) + SecondsToNs(rig.cameras[s.index].timeshift_cam_imu_s);
        check_stamp(t_ns);
        const std::string& enc = msg->encoding;
        int channels = 0;
        if (enc == "mono8" || enc == "8UC1") channels = 1;
        if (enc == "bgr8" || enc == "rgb8" || enc == "8UC3") channels = 3;
        if (channels == 0) {
          throw InputError(fmt::format(
              "{}: image encoding '{}' not supported (mono8, bgr8, rgb8)", where(), enc));
        }
        if (msg->step < msg->width * channels ||
            msg->data.size() < static_cast<size_t>(msg->step) * msg->height) {
          throw InputError(fmt::format("{}: image {}x{} step {} with {} data bytes",
                                       where(),
                                       msg->width,
                                       msg->height,
                                       msg->step,
                                       msg->data.size()));
        }
        if (camera_min_dt_ns > 0 && !s.kept.empty() && t_ns - s.last_kept < camera_min_dt_ns) {
          continue;
        }
        const cv::Mat view_mat(static_cast<int>(msg->height),
                               static_cast<int>(msg->width),
                               channels == 1 ? CV_8UC1 : CV_8UC3,
                               const_cast<uint8_t*>(msg->data.data()),
                               msg->step);
        cv::Mat image = view_mat;
        if (enc == "rgb8") cv::cvtColor(view_mat, image, cv::COLOR_RGB2BGR);
        const std::string path =
            JoinPaths(output_dir, s.folder + "/data/" + std::to_string(t_ns) + ".png");
        if (!WritePngFile(path, image, kPngCompression)) {
          throw InputError(path, "image", "cannot write the PNG image");
        }
        s.kept.push_back(t_ns);
        s.last_kept = t_ns;
      }
    }
    if (kb_reported < total_kb) progress.Add(total_kb - kb_reported);
    progress.Finish();
  } catch (const rosbag::BagException& e) {
    throw InputError(fmt::format("{}: bag read failed {} (corrupted chunk or truncated bag): {}",
                                 bag_path,
                                 last_read,
                                 e.what()));
  }
  for (const auto& b : bags) b->close();

  for (const std::string& topic : order) {
    const TopicState& s = topics.at(topic);
    if (s.type.empty()) continue;
    if (s.kind == TopicState::Kind::kImu) {
      if (imu.size() < 2) {
        throw InputError(fmt::format(
            "{}: topic {} has {} messages, need at least 2", bag_path, topic, imu.size()));
      }
      std::ostringstream csv;
      csv << std::setprecision(17);
      csv << "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
             "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
      for (const ImuSample& q : imu) {
        csv << q.t_ns << "," << q.gyro.x() << "," << q.gyro.y() << "," << q.gyro.z() << ","
            << q.accel.x() << "," << q.accel.y() << "," << q.accel.z() << "\n";
      }
      CreateDirs(JoinPaths(output_dir, "imu0"));
      WriteFileAtomically(JoinPaths(output_dir, "imu0/data.csv"), csv.str());
    } else {
      if (s.kind == TopicState::Kind::kLidar && s.kept.empty()) {
        throw InputError(fmt::format("{}: topic {} has no messages", bag_path, topic));
      }
      WriteIndex(JoinPaths(output_dir, s.folder + "/data.csv"),
                 s.kept,
                 s.kind == TopicState::Kind::kLidar ? ".pcd" : ".png");
    }
    summary.topics.push_back(Summarize(topic, s));
  }
  WriteFileAtomically(JoinPaths(output_dir, "rig.yaml"), rig_yaml);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return summary;
}

BagExportSummary ExportBag(const std::string& seq_root,
                           const BagPreset& preset,
                           const std::string& bag_path,
                           const std::string& compression) {
  rosbag::compression::CompressionType type = rosbag::compression::Uncompressed;
  if (compression == "lz4") {
    type = rosbag::compression::LZ4;
  } else if (compression == "bz2") {
    type = rosbag::compression::BZ2;
  } else if (compression != "none") {
    throw InternalError("ExportBag: compression '" + compression + "' is not none, lz4 or bz2");
  }
  const Sequence seq = ReadSequence(seq_root);
  size_t num_lidars = 0;
  for (size_t k = 0; k < seq.lidar_scans.size(); ++k) {
    if (!seq.lidar_scans[k].empty()) num_lidars = k + 1;
  }
  if (num_lidars > preset.lidar_topics.size()) {
    throw InputError(fmt::format("{}: {} LiDARs but preset {} has {} LiDAR topics",
                                 seq_root,
                                 num_lidars,
                                 preset.name,
                                 preset.lidar_topics.size()));
  }
  BagExportSummary summary;
  const std::string temp = fmt::format("{}.tmp-{}", bag_path, getpid());
  try {
    rosbag::Bag bag;
    bag.open(temp, rosbag::bagmode::Write);
    bag.setCompression(type);
    for (size_t i = 0; i < seq.imu.size(); ++i) {
      const ImuSample& q = seq.imu[i];
      sensor_msgs::Imu m;
      m.header.seq = static_cast<uint32_t>(i);
      m.header.stamp = ToRosTime(q.t_ns, seq_root + "/imu0/data.csv");
      m.header.frame_id = "imu0";
      m.orientation.w = 1.0;
      m.orientation_covariance[0] = -1.0;  // orientation not provided (REP 145)
      m.angular_velocity.x = q.gyro.x();
      m.angular_velocity.y = q.gyro.y();
      m.angular_velocity.z = q.gyro.z();
      m.linear_acceleration.x = q.accel.x();
      m.linear_acceleration.y = q.accel.y();
      m.linear_acceleration.z = q.accel.z();
      bag.write(preset.imu_topic, m.header.stamp, m);
      ++summary.num_imu;
    }
    for (size_t k = 0; k < seq.lidar_scans.size() && k < preset.lidar_topics.size(); ++k) {
      for (size_t i = 0; i < seq.lidar_scans[k].size(); ++i) {
        const SensorFile& f = seq.lidar_scans[k][i];
        PointCloud cloud = ReadPcd(f.path);
        cloud.stamp_ns = f.t_ns;
        float t_max = 0;
        for (const LidarPoint& p : cloud.points) t_max = std::max(t_max, p.t);
        // Received at the last point, as a driver publishes it.
        const ros::Time received = ToRosTime(f.t_ns + SecondsToNs(t_max), f.path);
        if (k < preset.lidar_types.size() && preset.lidar_types[k] == kLivoxCustomMsgType) {
          (void)ToRosTime(f.t_ns, f.path);  // header.stamp and timebase must be valid times
          RawRosMessage raw;
          raw.datatype = kLivoxCustomMsgType;
          raw.md5sum = kLivoxCustomMsgMd5;
          raw.definition = kLivoxCustomMsgDefinition;
          raw.bytes = EncodeLivoxCustomMsg(
              cloud, static_cast<uint32_t>(i), seq.rig.lidars[k].name, static_cast<uint8_t>(k));
          bag.write(preset.lidar_topics[k], received, raw);
          ++summary.num_scans;
          continue;
        }
        sensor_msgs::PointCloud2 m;
        m.header.seq = static_cast<uint32_t>(i);
        m.header.stamp = ToRosTime(f.t_ns, f.path);
        m.header.frame_id = seq.rig.lidars[k].name;
        std::vector<uint8_t> data;
        uint32_t step = 0;
        for (const PointFieldDesc& d :
             EncodePointCloud2(cloud, preset.lidar_fields, &data, &step)) {
          sensor_msgs::PointField pf;
          pf.name = d.name;
          pf.offset = d.offset;
          pf.datatype = d.datatype;
          pf.count = d.count;
          m.fields.push_back(pf);
        }
        m.height = 1;
        m.width = static_cast<uint32_t>(cloud.size());
        m.is_bigendian = false;
        m.point_step = step;
        m.row_step = step * m.width;
        m.is_dense = std::all_of(cloud.points.begin(), cloud.points.end(), [](const LidarPoint& p) {
          return IsFinite(p);
        });
        m.data = std::move(data);
        bag.write(preset.lidar_topics[k], received, m);
        ++summary.num_scans;
      }
    }
    for (size_t k = 0; k < seq.camera_frames.size() && k < preset.camera_topics.size(); ++k) {
      for (size_t i = 0; i < seq.camera_frames[k].size(); ++i) {
        const SensorFile& f = seq.camera_frames[k][i];
        std::string why;
        const cv::Mat image = ReadImageFile(f.path, ImageReadMode::kUnchanged, &why);
        if (image.empty()) throw InputError(f.path, "image", "cannot read: " + why);
        if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3)) {
          throw InputError(f.path, "image", "expected an 8-bit grey or BGR image");
        }
        sensor_msgs::Image m;
        m.header.seq = static_cast<uint32_t>(i);
        // IMU clock -> camera clock, the inverse of the import.
        m.header.stamp =
            ToRosTime(f.t_ns - SecondsToNs(seq.rig.cameras[k].timeshift_cam_imu_s), f.path);
        m.header.frame_id = seq.rig.cameras[k].name;
        m.height = static_cast<uint32_t>(image.rows);
        m.width = static_cast<uint32_t>(image.cols);
        m.encoding = image.channels() == 1 ? "mono8" : "bgr8";
        m.is_bigendian = 0;
        m.step = static_cast<uint32_t>(image.cols * image.channels());
        m.data.resize(static_cast<size_t>(m.step) * m.height);
        for (int r = 0; r < image.rows; ++r) {
          std::memcpy(m.data.data() + static_cast<size_t>(r) * m.step, image.ptr(r), m.step);
        }
        bag.write(preset.camera_topics[k], m.header.stamp, m);
        ++summary.num_images;
      }
    }
    bag.close();
    summary.bag_bytes = static_cast<uint64_t>(std::filesystem::file_size(temp));
    if (std::rename(temp.c_str(), bag_path.c_str()) != 0) {
      throw InputError(bag_path, "rename", "cannot move " + temp + " into place");
    }
  } catch (const rosbag::BagException& e) {
    std::remove(temp.c_str());
    throw InputError(bag_path, "write", e.what());
  } catch (...) {
    std::remove(temp.c_str());
    throw;
  }
  return summary;
}

std::string FolderRigYaml(const Rig& rig, const std::string& rig_file_text) {
  Rig folder_rig = rig;
  bool shifted = false;
  for (RigCamera& c : folder_rig.cameras) {
    shifted = shifted || c.timeshift_cam_imu_s != 0;
    c.timeshift_cam_imu_s = 0;
  }
  if (!shifted) return rig_file_text;
  return RigToYaml(folder_rig,
                   "# lisfm bag_importer: timeshift_cam_imu applied to the camera stamps "
                   "(t_imu = t_cam + shift), so 0 here.");
}

std::string FormatBagSummary(const BagImportSummary& summary) {
  std::string s = fmt::format("{:<36} {:<24} {:>8} {:>8} {:>9} {:>9} {:>6} {:>9}\n",
                              "topic",
                              "type",
                              "messages",
                              "kept",
                              "rate Hz",
                              "span s",
                              "gaps",
                              "max gap s");
  for (const BagTopicSummary& t : summary.topics) {
    s += fmt::format("{:<36} {:<24} {:>8} {:>8} {:>9.2f} {:>9.2f} {:>6} {:>9.3f}\n",
                     t.topic,
                     t.type,
                     t.num_messages,
                     t.num_kept,
                     t.rate_hz,
                     NsToSeconds(t.last_ns - t.first_ns),
                     t.num_gaps,
                     t.max_gap_s);
  }
  return s;
}

}  // namespace lisfm
