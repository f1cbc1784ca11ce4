#include "core/io/cloud_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string_view>

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/file_utils.h"

// PCD binary data is in host byte order (PCL memcpy's it) and our PLY files are
// declared little endian; both writers memcpy native values.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "cloud_io assumes a little-endian host");

namespace lisfm {

namespace {

// Headers larger than this are not headers (PCL writes ~200 bytes).
constexpr size_t kMaxHeaderBytes = 1 << 20;

uint64_t FileSize(const std::string& path) {
  CheckFileExists(path, "point cloud file");
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(path, "", "cannot read the file size: " + ec.message());
  if (size == 0) throw InputError(path, "", "empty file, expected a point cloud");
  return size;
}

// Bytes [offset, offset + count) of the file, or fewer at its end.
std::string ReadBytes(const std::string& path, uint64_t offset, uint64_t count) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open for reading");
  in.seekg(static_cast<std::streamoff>(offset));
  std::string bytes(count, '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(count));
  bytes.resize(static_cast<size_t>(std::max<std::streamsize>(in.gcount(), 0)));
  return bytes;
}

// The whole file as read-only bytes: memory-mapped (the page cache's own pages:
// no copy, and no zero-filled buffer to fault in), or read into memory where
// mapping fails. `size` is the size found by FileSize(); a file that shrinks
// while mapped is outside what this reader supports.
class FileBytes {
 public:
  FileBytes(const std::string& path, uint64_t size) : size_(static_cast<size_t>(size)) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd >= 0) {
      void* map = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
      ::close(fd);
      if (map != MAP_FAILED) map_ = map;
    }
    if (map_ == nullptr) {
      fallback_ = ReadBytes(path, 0, size);
      size_ = fallback_.size();
    }
  }
  ~FileBytes() {
    if (map_ != nullptr) ::munmap(map_, size_);
  }
  FileBytes(const FileBytes&) = delete;
  FileBytes& operator=(const FileBytes&) = delete;
  std::string_view view() const {
    return map_ != nullptr ? std::string_view(static_cast<const char*>(map_), size_)
                           : std::string_view(fallback_);
  }

 private:
  void* map_ = nullptr;
  size_t size_;
  std::string fallback_;
};

// A header token quoted for an error message: printable, at most 40 chars.
std::string Quote(const std::string& s) {
  std::string out;
  for (char c : s.substr(0, 40)) out.push_back(std::isprint(static_cast<unsigned char>(c)) ? c : '?');
  return "'" + out + (s.size() > 40 ? "...'" : "'");
}

std::string Where(int line) { return "line " + std::to_string(line); }

bool IsNumberToken(const std::string& token) {
  if (token.empty()) return false;
  char* end = nullptr;
  std::strtod(token.c_str(), &end);
  return end == token.c_str() + token.size();
}

bool IsIntegerToken(const std::string& token) {
  size_t i = (!token.empty() && (token[0] == '-' || token[0] == '+')) ? 1 : 0;
  if (i == token.size()) return false;
  for (; i < token.size(); ++i) {
    if (!std::isdigit(static_cast<unsigned char>(token[i]))) return false;
  }
  return true;
}

uint64_t ParseCount(const std::string& path, int line, const std::string& what, const std::string& token) {
  int64_t value = 0;
  if (!ParseInt64(token, &value) || value < 0 || value > int64_t{0xffffffff}) {
    throw InputError(path, Where(line), what + ": expected an integer in [0, 2^32), found " + Quote(token));
  }
  return static_cast<uint64_t>(value);
}

// Splits `text` into lines (without "\r\n"); calls f(line, line_number,
// offset_after_line) until f returns false. Returns false if the text ran out.
template <typename F>
bool ForEachLine(std::string_view text, size_t start, int first_line_number, F&& f) {
  size_t pos = start;
  int line_number = first_line_number;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    const size_t next = (end == std::string_view::npos) ? text.size() : end + 1;
    if (end == std::string_view::npos) end = text.size();
    std::string line(text.substr(pos, end - pos));
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!f(line, line_number, next)) return true;
    pos = next;
    ++line_number;
  }
  return false;
}

// ---------------------------------------------------------------------------
// PCD header validation (PCD v0.7 spec, pointclouds.org "The PCD file format").

struct PcdHeader {
  std::vector<std::string> names;
  std::vector<int> sizes;
  std::vector<char> types;
  std::vector<int> counts;
  uint64_t width = 0, height = 1, points = 0;
  std::string data;         // ascii | binary | binary_compressed
  int data_line = 0;        // line number of DATA
  uint64_t data_offset = 0;  // first byte after the DATA line
  uint64_t point_bytes = 0;  // sum of SIZE * COUNT
  uint64_t values_per_point = 0;  // sum of COUNT
};

// `file`: the whole file (ReadPcd reads it once; only its first kMaxHeaderBytes
// are searched for the header).
PcdHeader ParsePcdHeader(const std::string& path, uint64_t file_size, std::string_view file) {
  const std::string_view head = file.substr(0, kMaxHeaderBytes);
  PcdHeader h;
  std::map<std::string, int> seen;  // keyword -> line
  size_t line_start = 0;
  const bool found_data = ForEachLine(head, 0, 1, [&](const std::string& raw, int line, size_t next) {
    const std::string_view original = head.substr(line_start, next - line_start);  // with '\n'
    line_start = next;
    const std::string text = Trim(raw);
    if (text.empty() && original.find_first_not_of('\n') != std::string_view::npos) {
      // PCL's header reader skips empty lines only; a line of white space (e.g. "\r" of a
      // CRLF blank line) makes it read an empty token list (a crash in PCL 1.13).
      throw InputError(path, Where(line), "a header line of white space only (PCL cannot read it)");
    }
    if (text.empty() || text[0] == '#') return true;
    const std::vector<std::string> tokens = SplitString(text, " \t");
    std::string keyword = tokens[0];
    if (keyword == "COLUMNS") keyword = "FIELDS";  // PCD v0.5 spelling
    static const char* kKeywords[] = {
        "VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA"};
    if (std::find(std::begin(kKeywords), std::end(kKeywords), keyword) == std::end(kKeywords)) {
      throw InputError(path, Where(line),
                       "expected a PCD header keyword (VERSION, FIELDS, SIZE, TYPE, COUNT, WIDTH, "
                       "HEIGHT, VIEWPOINT, POINTS, DATA), found " + Quote(text));
    }
    if (!seen.emplace(keyword, line).second) {
      throw InputError(path, Where(line), keyword + " appears twice (first on line " +
                                              std::to_string(seen[keyword]) + ")");
    }
    const std::vector<std::string> values(tokens.begin() + 1, tokens.end());
    auto expect_one = [&]() {
      if (values.size() != 1) {
        throw InputError(path, Where(line), keyword + ": expected one value, found " +
                                                std::to_string(values.size()));
      }
    };
    if (keyword == "FIELDS") {
      if (values.empty()) throw InputError(path, Where(line), "FIELDS: expected at least one field name");
      h.names = values;
    } else if (keyword == "SIZE" || keyword == "COUNT") {
      std::vector<int>& out = keyword == "SIZE" ? h.sizes : h.counts;
      for (const std::string& v : values) {
        int64_t n = 0;
        if (!ParseInt64(v, &n) || n < 1 || n > 1 << 20) {
          throw InputError(path, Where(line), keyword + ": expected a positive integer, found " + Quote(v));
        }
        out.push_back(static_cast<int>(n));
      }
    } else if (keyword == "TYPE") {
      for (const std::string& v : values) {
        if (v != "F" && v != "I" && v != "U") {
          throw InputError(path, Where(line), "TYPE: expected F, I or U, found " + Quote(v));
        }
        h.types.push_back(v[0]);
      }
    } else if (keyword == "WIDTH") {
      expect_one();
      h.width = ParseCount(path, line, "WIDTH", values[0]);
    } else if (keyword == "HEIGHT") {
      expect_one();
      h.height = ParseCount(path, line, "HEIGHT", values[0]);
    } else if (keyword == "POINTS") {
      expect_one();
      h.points = ParseCount(path, line, "POINTS", values[0]);
    } else if (keyword == "VIEWPOINT") {
      if (values.size() != 7 || !std::all_of(values.begin(), values.end(), IsNumberToken)) {
        throw InputError(path, Where(line), "VIEWPOINT: expected 7 numbers (tx ty tz qw qx qy qz)");
      }
    } else if (keyword == "DATA") {
      expect_one();
      if (values[0] != "ascii" && values[0] != "binary" && values[0] != "binary_compressed") {
        throw InputError(path, Where(line),
                         "DATA: expected ascii, binary or binary_compressed, found " + Quote(values[0]));
      }
      h.data = values[0];
      h.data_line = line;
      h.data_offset = next;
      return false;  // the body starts here
    }
    return true;
  });
  if (!found_data) {
    throw InputError(path, "", head.size() < file_size
                                   ? "no DATA line in the first 1 MiB (not a PCD file?)"
                                   : "the header ends without a DATA line (not a PCD file?)");
  }

  // Consistency of the per-field lines.
  auto line_of = [&](const std::string& keyword) { return seen.count(keyword) ? seen[keyword] : h.data_line; };
  for (const char* required : {"FIELDS", "SIZE", "TYPE"}) {
    if (!seen.count(required)) throw InputError(path, "", std::string("the header has no ") + required + " line");
  }
  if (h.counts.empty()) h.counts.assign(h.names.size(), 1);  // COUNT is optional
  const size_t n = h.names.size();
  auto check_length = [&](const std::string& keyword, size_t length) {
    if (length != n) {
      throw InputError(path, Where(line_of(keyword)),
                       keyword + " has " + std::to_string(length) + " entries but FIELDS has " +
                           std::to_string(n));
    }
  };
  check_length("SIZE", h.sizes.size());
  check_length("TYPE", h.types.size());
  check_length("COUNT", h.counts.size());
  for (size_t i = 0; i < n; ++i) {
    const int s = h.sizes[i];
    const bool ok = h.types[i] == 'F' ? (s == 4 || s == 8) : (s == 1 || s == 2 || s == 4 || s == 8);
    if (!ok) {
      throw InputError(path, Where(line_of("SIZE")),
                       "field " + Quote(h.names[i]) + ": SIZE " + std::to_string(s) +
                           " is not valid for TYPE " + h.types[i]);
    }
    h.point_bytes += static_cast<uint64_t>(s) * static_cast<uint64_t>(h.counts[i]);
    h.values_per_point += static_cast<uint64_t>(h.counts[i]);
  }

  // Point count: WIDTH * HEIGHT, which POINTS (if given) must repeat.
  if (!seen.count("WIDTH")) {
    if (!seen.count("POINTS")) throw InputError(path, "", "the header has neither WIDTH nor POINTS");
    h.width = h.points;
  }
  const uint64_t wh = h.width * h.height;
  if (seen.count("POINTS") && h.points != wh) {
    throw InputError(path, Where(seen["POINTS"]),
                     "POINTS = " + std::to_string(h.points) + " but WIDTH * HEIGHT = " +
                         std::to_string(h.width) + " * " + std::to_string(h.height));
  }
  h.points = wh;

  // The body must hold that many points (and the size must not overflow).
  if (h.point_bytes > 0 && h.points > (uint64_t{1} << 40) / h.point_bytes) {
    throw InputError(path, Where(h.data_line), std::to_string(h.points) + " points of " +
                                                   std::to_string(h.point_bytes) + " bytes exceed 1 TiB");
  }
  const uint64_t body_bytes = file_size - std::min(file_size, h.data_offset);
  const uint64_t needed = h.points * h.point_bytes;
  if (h.data == "binary" && body_bytes < needed) {
    throw InputError(path, Where(h.data_line),
                     "binary data is truncated: " + std::to_string(h.points) + " points of " +
                         std::to_string(h.point_bytes) + " bytes need " + std::to_string(needed) +
                         " bytes after the header, found " + std::to_string(body_bytes));
  }
  if (h.data == "binary_compressed" && h.points > 0) {
    const std::string_view sizes = file.substr(std::min<uint64_t>(h.data_offset, file.size()), 8);
    if (sizes.size() < 8) {
      throw InputError(path, Where(h.data_line), "binary_compressed data is truncated (no size words)");
    }
    uint32_t compressed = 0, uncompressed = 0;
    std::memcpy(&compressed, sizes.data(), 4);
    std::memcpy(&uncompressed, sizes.data() + 4, 4);
    if (body_bytes - 8 < compressed) {
      throw InputError(path, Where(h.data_line),
                       "binary_compressed data is truncated: " + std::to_string(compressed) +
                           " compressed bytes announced, " + std::to_string(body_bytes - 8) + " present");
    }
    // LZF expands at most ~88x (a 3-byte back reference covers 264 bytes).
    if (uncompressed != needed || needed > 128 * static_cast<uint64_t>(compressed) + 1024) {
      throw InputError(path, Where(h.data_line),
                       "binary_compressed data announces " + std::to_string(uncompressed) +
                           " bytes from " + std::to_string(compressed) + " compressed bytes, expected " +
                           std::to_string(needed) + " (" + std::to_string(h.points) + " points)");
    }
  }
  return h;
}

// PCL reads any token of an ascii body (non-numbers become 0 or garbage) and
// tolerates missing lines, so the body is checked here: POINTS lines of
// sum(COUNT) numeric tokens, integers for I/U fields.
void ValidatePcdAsciiBody(const std::string& path, const PcdHeader& h, std::string_view file) {
  const std::string_view body = file.substr(std::min<uint64_t>(h.data_offset, file.size()));
  std::vector<bool> integer_value;
  for (size_t i = 0; i < h.names.size(); ++i) {
    for (int c = 0; c < h.counts[i]; ++c) integer_value.push_back(h.types[i] != 'F');
  }
  uint64_t points = 0;
  ForEachLine(body, 0, h.data_line + 1, [&](const std::string& line, int line_number, size_t) {
    const std::vector<std::string> tokens = SplitString(line, " \t\r");
    if (tokens.empty()) return true;
    if (points == h.points) {
      throw InputError(path, Where(line_number),
                       "more data lines than the " + std::to_string(h.points) + " points in the header");
    }
    if (tokens.size() != h.values_per_point) {
      throw InputError(path, Where(line_number),
                       "expected " + std::to_string(h.values_per_point) + " values, found " +
                           std::to_string(tokens.size()));
    }
    for (size_t k = 0; k < tokens.size(); ++k) {
      const bool ok = integer_value[k] ? IsIntegerToken(tokens[k]) : IsNumberToken(tokens[k]);
      if (!ok) {
        throw InputError(path, Where(line_number),
                         std::string("value ") + std::to_string(k + 1) + ": expected " +
                             (integer_value[k] ? "an integer" : "a number") + ", found " + Quote(tokens[k]));
      }
    }
    ++points;
    return true;
  });
  if (points != h.points) {
    throw InputError(path, "", "DATA ascii: expected " + std::to_string(h.points) + " points, found " +
                                   std::to_string(points) + " data lines");
  }
}

// ---------------------------------------------------------------------------
// PLY header validation (Paul Bourke's PLY spec).

int PlyTypeSize(const std::string& type) {
  if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
  if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
  if (type == "int" || type == "uint" || type == "int32" || type == "uint32" || type == "float" ||
      type == "float32") {
    return 4;
  }
  if (type == "double" || type == "float64") return 8;
  return 0;
}

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<std::string> properties;
  std::vector<int> sizes;       // scalar size, or the list's count size
  std::vector<std::string> types;  // scalar type, or the list's item type
  std::vector<bool> is_list;
  std::vector<bool> is_integer;
};

struct PlyHeader {
  std::string format;
  std::vector<PlyElement> elements;
  int end_line = 0;
  uint64_t data_offset = 0;
};

PlyHeader ParsePlyHeader(const std::string& path, uint64_t file_size) {
  const std::string head = ReadBytes(path, 0, std::min<uint64_t>(file_size, kMaxHeaderBytes));
  PlyHeader h;
  const bool ended = ForEachLine(head, 0, 1, [&](const std::string& raw, int line, size_t next) {
    const std::string text = Trim(raw);
    if (line == 1) {
      if (text != "ply") throw InputError(path, Where(1), "expected the PLY magic 'ply', found " + Quote(text));
      return true;
    }
    const std::vector<std::string> tokens = SplitString(text, " \t");
    if (tokens.empty()) throw InputError(path, Where(line), "empty header line");
    const std::string& keyword = tokens[0];
    if (keyword == "comment" || keyword == "obj_info") return true;
    if (keyword == "end_header") {
      h.end_line = line;
      h.data_offset = next;
      return false;
    }
    if (keyword == "format") {
      if (tokens.size() != 3 || tokens[2] != "1.0" ||
          (tokens[1] != "ascii" && tokens[1] != "binary_little_endian" && tokens[1] != "binary_big_endian")) {
        throw InputError(path, Where(line),
                         "expected 'format ascii|binary_little_endian|binary_big_endian 1.0', found " +
                             Quote(text));
      }
      h.format = tokens[1];
    } else if (keyword == "element") {
      if (tokens.size() != 3) throw InputError(path, Where(line), "expected 'element <name> <count>', found " + Quote(text));
      PlyElement e;
      e.name = tokens[1];
      e.count = ParseCount(path, line, "element " + e.name, tokens[2]);
      h.elements.push_back(e);
    } else if (keyword == "property") {
      if (h.elements.empty()) throw InputError(path, Where(line), "property before any element");
      PlyElement& e = h.elements.back();
      const bool list = tokens.size() == 5 && tokens[1] == "list";
      const std::string& type = list ? tokens[2] : (tokens.size() > 1 ? tokens[1] : "");
      const int size = PlyTypeSize(type);
      if ((!list && tokens.size() != 3) || size == 0 || (list && PlyTypeSize(tokens[3]) == 0)) {
        throw InputError(path, Where(line),
                         "expected 'property <type> <name>' or 'property list <type> <type> <name>' "
                         "with PLY types, found " + Quote(text));
      }
      e.properties.push_back(tokens.back());
      e.sizes.push_back(list ? PlyTypeSize(tokens[2]) : size);
      e.types.push_back(list ? tokens[3] : type);
      e.is_list.push_back(list);
      e.is_integer.push_back(type.find("float") == std::string::npos && type != "double");
    } else {
      throw InputError(path, Where(line), "expected a PLY header keyword, found " + Quote(text));
    }
    return true;
  });
  if (!ended) throw InputError(path, "", "the header ends without 'end_header' (not a PLY file?)");
  if (h.format.empty()) throw InputError(path, "", "the header has no 'format' line");
  const auto vertex = std::find_if(h.elements.begin(), h.elements.end(),
                                   [](const PlyElement& e) { return e.name == "vertex"; });
  if (vertex == h.elements.end()) throw InputError(path, "", "the header has no 'element vertex'");
  for (const char* axis : {"x", "y", "z"}) {
    if (std::find(vertex->properties.begin(), vertex->properties.end(), axis) == vertex->properties.end()) {
      throw InputError(path, "", std::string("element vertex has no property ") + axis);
    }
  }
  if (h.format != "ascii") {
    // Lower bound on the body size (lists count only their length word).
    uint64_t needed = 0;
    for (const PlyElement& e : h.elements) {
      uint64_t bytes = 0;
      for (int s : e.sizes) bytes += static_cast<uint64_t>(s);
      needed += e.count * bytes;
    }
    const uint64_t body_bytes = file_size - std::min(file_size, h.data_offset);
    if (body_bytes < needed) {
      throw InputError(path, Where(h.end_line),
                       "binary data is truncated: the header's elements need at least " +
                           std::to_string(needed) + " bytes, found " + std::to_string(body_bytes));
    }
  }
  return h;
}

// PCL's ascii PLY parser accepts non-numeric tokens; check the vertex lines
// when they come first (the usual layout) and hold only scalar properties.
void ValidatePlyAsciiVertices(const std::string& path, const PlyHeader& h, uint64_t file_size) {
  const PlyElement& vertex = h.elements.front();
  if (vertex.name != "vertex" ||
      std::find(vertex.is_list.begin(), vertex.is_list.end(), true) != vertex.is_list.end()) {
    return;  // PCL's own checks apply
  }
  const std::string body = ReadBytes(path, h.data_offset, file_size - std::min(file_size, h.data_offset));
  uint64_t points = 0;
  ForEachLine(body, 0, h.end_line + 1, [&](const std::string& line, int line_number, size_t) {
    if (points == vertex.count) return false;
    const std::vector<std::string> tokens = SplitString(line, " \t\r");
    if (tokens.size() != vertex.properties.size()) {
      throw InputError(path, Where(line_number),
                       "vertex " + std::to_string(points) + ": expected " +
                           std::to_string(vertex.properties.size()) + " values, found " +
                           std::to_string(tokens.size()));
    }
    for (size_t k = 0; k < tokens.size(); ++k) {
      const bool ok = vertex.is_integer[k] ? IsIntegerToken(tokens[k]) : IsNumberToken(tokens[k]);
      if (!ok) {
        throw InputError(path, Where(line_number),
                         "property " + vertex.properties[k] + ": expected " +
                             (vertex.is_integer[k] ? "an integer" : "a number") + ", found " + Quote(tokens[k]));
      }
    }
    ++points;
    return true;
  });
  if (points != vertex.count) {
    throw InputError(path, "", "expected " + std::to_string(vertex.count) + " vertex lines, found " +
                                   std::to_string(points));
  }
}

template <typename T>
double Load(const uint8_t* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  return static_cast<double>(value);
}

// Empty clouds never reach PCL (it dereferences an empty mapping); the field
// names still must include x y z.
void CheckXyzNames(const std::string& path, const std::vector<std::string>& names) {
  for (const char* axis : {"x", "y", "z"}) {
    if (std::find(names.begin(), names.end(), axis) == names.end()) {
      throw InputError(path, "", std::string("no field '") + axis + "'");
    }
  }
}

// ---------------------------------------------------------------------------
// Direct decoding of binary and binary_compressed PCD bodies (the PCD v0.7
// layouts PCL writes): no PCLPointCloud2 in between, one pass over the bytes.
// ascii bodies still go through PCL's reader (after ValidatePcdAsciiBody).

// Where the values of one field lie: value of point i at base + i * stride.
struct PcdFieldRef {
  bool present = false;
  uint64_t offset = 0;  // in the record (binary) or of the field's block (compressed)
  char type = 'F';
  int size = 4;
};

// The first field called `name` (PCL's rule), with the same checks and messages
// as FindField on PCL's blob.
PcdFieldRef FindPcdField(const std::string& path, const PcdHeader& h, const std::string& name,
                         bool required, bool compressed) {
  PcdFieldRef ref;
  uint64_t offset = 0;
  for (size_t i = 0; i < h.names.size(); ++i) {
    const uint64_t bytes = static_cast<uint64_t>(h.sizes[i]) * static_cast<uint64_t>(h.counts[i]);
    if (h.names[i] == name) {
      if (h.counts[i] != 1) {
        throw InputError(path, "field " + name, "expected COUNT 1, found " + std::to_string(h.counts[i]));
      }
      ref.present = true;
      ref.offset = offset;
      ref.type = h.types[i];
      ref.size = h.sizes[i];
      return ref;
    }
    offset += compressed ? bytes * h.points : bytes;
  }
  if (required) {
    std::string names;
    for (const std::string& n : h.names) names += (names.empty() ? "" : " ") + n;
    throw InputError(path, "", "no field '" + name + "' (the file has: " + names + ")");
  }
  return ref;
}

double LoadPcdValue(const uint8_t* p, char type, int size) {
  if (type == 'F') return size == 4 ? Load<float>(p) : Load<double>(p);
  if (type == 'I') {
    switch (size) {
      case 1: return Load<int8_t>(p);
      case 2: return Load<int16_t>(p);
      case 4: return Load<int32_t>(p);
      default: return Load<int64_t>(p);
    }
  }
  switch (size) {
    case 1: return Load<uint8_t>(p);
    case 2: return Load<uint16_t>(p);
    case 4: return Load<uint32_t>(p);
    default: return Load<uint64_t>(p);
  }
}

// LZF decompression (the format of liblzf, which PCL's binary_compressed uses):
// a control byte c < 32 copies the next c + 1 literal bytes; otherwise it is a
// back reference of length (c >> 5) + 2 (with 7 meaning "add the next byte")
// starting ((c & 31) << 8) + next byte + 1 bytes back. Returns false on a
// malformed stream or an output size other than `out->size()`.
bool LzfDecompress(const uint8_t* in, size_t in_size, std::vector<uint8_t>* out) {
  uint8_t* const begin = out->data();
  uint8_t* const end = begin + out->size();
  uint8_t* op = begin;
  const uint8_t* ip = in;
  const uint8_t* const in_end = in + in_size;
  while (ip < in_end) {
    const unsigned ctrl = *ip++;
    if (ctrl < 32) {
      const size_t len = ctrl + 1;
      if (static_cast<size_t>(in_end - ip) < len || static_cast<size_t>(end - op) < len) return false;
      std::memcpy(op, ip, len);
      op += len;
      ip += len;
    } else {
      size_t len = ctrl >> 5;
      if (len == 7) {
        if (ip >= in_end) return false;
        len += *ip++;
      }
      len += 2;
      if (ip >= in_end) return false;
      const size_t back = ((ctrl & 0x1fu) << 8) + *ip++ + 1;
      if (static_cast<size_t>(op - begin) < back || static_cast<size_t>(end - op) < len) return false;
      const uint8_t* ref = op - back;
      for (size_t k = 0; k < len; ++k) *op++ = *ref++;  // may overlap: byte by byte
    }
  }
  return op == end;
}

// The body of a binary or binary_compressed PCD `file` (header `h` already
// validated: sizes, truncation, announced sizes): the records of a binary body, or
// the field blocks of a binary_compressed one (LZF-decoded here), with its x y z
// fields located.
class PcdBody {
 public:
  PcdBody(const std::string& path, const PcdHeader& h, std::string_view file)
      : compressed_(h.data == "binary_compressed"), point_bytes_(h.point_bytes) {
    data_ = reinterpret_cast<const uint8_t*>(file.data()) + h.data_offset;
    if (compressed_) {
      const uint64_t needed = h.points * h.point_bytes;
      uint32_t compressed_bytes = 0;
      std::memcpy(&compressed_bytes, data_, 4);
      unpacked_.resize(needed);
      if (!LzfDecompress(data_ + 8, compressed_bytes, &unpacked_)) {
        throw InputError(path, Where(h.data_line),
                         "binary_compressed data is corrupt (the LZF stream does not decode to " +
                             std::to_string(needed) + " bytes)");
      }
      data_ = unpacked_.data();
    }
    x_ = Field(path, h, "x", true);
    y_ = Field(path, h, "y", true);
    z_ = Field(path, h, "z", true);
    xyz_float_ = x_.type == 'F' && x_.size == 4 && y_.type == 'F' && y_.size == 4 &&
                 z_.type == 'F' && z_.size == 4;
  }
  PcdFieldRef Field(const std::string& path, const PcdHeader& h, const std::string& name,
                    bool required) const {
    return FindPcdField(path, h, name, required, compressed_);
  }
  // Value of field f of point i: binary records are interleaved (stride =
  // point_bytes); compressed bodies hold one block per field (stride = size).
  const uint8_t* At(const PcdFieldRef& f, uint64_t i) const {
    return data_ + f.offset + i * (compressed_ ? static_cast<uint64_t>(f.size) : point_bytes_);
  }
  double Value(const PcdFieldRef& f, uint64_t i) const { return LoadPcdValue(At(f, i), f.type, f.size); }
  void Position(uint64_t i, float* x, float* y, float* z) const {
    if (xyz_float_) {
      std::memcpy(x, At(x_, i), 4);
      std::memcpy(y, At(y_, i), 4);
      std::memcpy(z, At(z_, i), 4);
    } else {
      *x = static_cast<float>(Value(x_, i));
      *y = static_cast<float>(Value(y_, i));
      *z = static_cast<float>(Value(z_, i));
    }
  }

 private:
  bool compressed_;
  uint64_t point_bytes_;
  const uint8_t* data_ = nullptr;
  std::vector<uint8_t> unpacked_;
  PcdFieldRef x_, y_, z_;
  bool xyz_float_ = false;
};

PointCloud DecodePcdBody(const std::string& path, const PcdHeader& h, std::string_view file) {
  const PcdBody body(path, h, file);
  const PcdFieldRef intensity = body.Field(path, h, "intensity", false);
  const PcdFieldRef t = body.Field(path, h, "t", false);
  const PcdFieldRef ring = body.Field(path, h, "ring", false);
  const PcdFieldRef sensor_id = body.Field(path, h, "sensor_id", false);
  if (t.present && t.type != 'F') {
    throw InputError(path, "field t",
                     "expected float seconds since the scan stamp, found an integer type (e.g. Ouster "
                     "nanoseconds); convert the file first");
  }
  // An integer field of point i in [0, max], else an InputError naming the record.
  const auto integer = [&](const PcdFieldRef& f, const char* name, double max, uint64_t i) {
    const double v = body.Value(f, i);
    if (!(v >= 0 && v <= max && v == std::floor(v))) {
      throw InputError(path, "record " + std::to_string(i),
                       fmt::format("{} = {}, expected an integer in [0, {}]", name, std::to_string(v), max));
    }
    return v;
  };
  PointCloud cloud;
  cloud.points.resize(h.points);
  for (uint64_t i = 0; i < h.points; ++i) {
    LidarPoint& p = cloud.points[i];
    body.Position(i, &p.x, &p.y, &p.z);
    if (intensity.present) p.intensity = static_cast<float>(body.Value(intensity, i));
    if (t.present) p.t = static_cast<float>(body.Value(t, i));
    if (ring.present) p.ring = static_cast<uint16_t>(integer(ring, "ring", 65535, i));
    if (sensor_id.present) p.sensor_id = static_cast<uint8_t>(integer(sensor_id, "sensor_id", 255, i));
  }
  return cloud;
}

// Only x, y, z of a binary or binary_compressed body, finite points only (the
// same positions as DecodePcdBody followed by the finiteness filter).
std::vector<Eigen::Vector3f> DecodePcdPositions(const std::string& path, const PcdHeader& h,
                                                std::string_view file, size_t* num_non_finite) {
  const PcdBody body(path, h, file);
  std::vector<Eigen::Vector3f> out;
  out.reserve(h.points);
  for (uint64_t i = 0; i < h.points; ++i) {
    Eigen::Vector3f p;
    body.Position(i, &p.x(), &p.y(), &p.z());
    if (p.allFinite()) out.push_back(p);
  }
  if (num_non_finite != nullptr) *num_non_finite = h.points - out.size();
  return out;
}

// ---------------------------------------------------------------------------
// ascii PCD bodies and PLY vertices: converted to binary records (the PCD
// binary layout of a header from BinaryRecordsHeader), then DecodePcdBody.

// The header of `h`'s records as a binary body starting at offset 0.
PcdHeader BinaryRecordsHeader(const PcdHeader& h) {
  PcdHeader b = h;
  b.data = "binary";
  b.data_offset = 0;
  return b;
}

// Stores the (validated) number token as a value of PCD type (type, size) at
// `out`, as PCL's ascii reader converts it: parsed, then cast to the field
// type ("nan" is NaN; integers wrap to the field's width).
void StoreToken(const std::string& token, char type, int size, uint8_t* out) {
  const auto store = [out](auto value) { std::memcpy(out, &value, sizeof(value)); };
  if (type == 'F') {
    const double v = std::strtod(token.c_str(), nullptr);
    if (size == 4) {
      store(static_cast<float>(v));
    } else {
      store(v);
    }
    return;
  }
  const bool negative = !token.empty() && token[0] == '-';
  const uint64_t bits = negative ? static_cast<uint64_t>(std::strtoll(token.c_str(), nullptr, 10))
                                 : std::strtoull(token.c_str(), nullptr, 10);
  switch (size) {
    case 1: store(static_cast<uint8_t>(bits)); break;
    case 2: store(static_cast<uint16_t>(bits)); break;
    case 4: store(static_cast<uint32_t>(bits)); break;
    default: store(bits); break;
  }
}

// The binary records of `count` ascii lines of the fields of `h` from `body`
// (empty lines skipped), starting at line `first_line`; `*next` gets the
// offset after the last line read. InputError naming the line for a wrong
// token count, a token that is not a number (an integer for I/U fields), or
// too few lines.
std::string AsciiRecords(const std::string& path, const PcdHeader& h, std::string_view body,
                         int first_line, uint64_t count, const std::string& what, size_t* next) {
  std::string records(count * h.point_bytes, '\0');
  uint64_t done = 0;
  size_t end = 0;
  if (count > 0) {
    ForEachLine(body, 0, first_line, [&](const std::string& line, int line_number, size_t after) {
      end = after;
      const std::vector<std::string> tokens = SplitString(line, " \t\r");
      if (tokens.empty()) return true;
      if (tokens.size() != h.values_per_point) {
        throw InputError(path, Where(line_number),
                         what + " " + std::to_string(done) + ": expected " +
                             std::to_string(h.values_per_point) + " values, found " +
                             std::to_string(tokens.size()));
      }
      uint8_t* out = reinterpret_cast<uint8_t*>(records.data()) + done * h.point_bytes;
      size_t k = 0;
      for (size_t f = 0; f < h.names.size(); ++f) {
        for (int c = 0; c < h.counts[f]; ++c, ++k) {
          const bool integer = h.types[f] != 'F';
          if (!(integer ? IsIntegerToken(tokens[k]) : IsNumberToken(tokens[k]))) {
            throw InputError(path, Where(line_number),
                             what + " " + std::to_string(done) + ", " + h.names[f] + ": expected " +
                                 (integer ? "an integer" : "a number") + ", found " + Quote(tokens[k]));
          }
          StoreToken(tokens[k], h.types[f], h.sizes[f], out);
          out += h.sizes[f];
        }
      }
      return ++done < count;
    });
  }
  if (done != count) {
    throw InputError(path, "", "expected " + std::to_string(count) + " " + what + " lines, found " +
                                   std::to_string(done));
  }
  if (next != nullptr) *next = end;
  return records;
}

std::string AsciiPcdRecords(const std::string& path, const PcdHeader& h, std::string_view file) {
  const std::string_view body = file.substr(std::min<uint64_t>(h.data_offset, file.size()));
  return AsciiRecords(path, h, body, h.data_line + 1, h.points, "point", nullptr);
}

// PLY scalar type -> PCD (type, size).
char PlyPcdType(const std::string& type) {
  if (type.find("float") != std::string::npos || type == "double") return 'F';
  if (type[0] == 'u') return 'U';
  return 'I';
}

uint64_t LoadUnsigned(const uint8_t* p, int size, bool big_endian) {
  uint8_t bytes[8] = {};
  for (int i = 0; i < size; ++i) bytes[i] = p[big_endian ? size - 1 - i : i];
  uint64_t v = 0;
  std::memcpy(&v, bytes, 8);
  return v;
}

// The vertices of a PLY file: the vertex element's scalar properties as PCD
// fields, the other elements skipped (ascii: one line per item; binary: list
// lengths read to find the item sizes).
PointCloud DecodePly(const std::string& path, const PlyHeader& ply, std::string_view file) {
  const auto vertex = std::find_if(ply.elements.begin(), ply.elements.end(),
                                   [](const PlyElement& e) { return e.name == "vertex"; });
  if (std::find(vertex->is_list.begin(), vertex->is_list.end(), true) != vertex->is_list.end()) {
    throw InputError(path, "element vertex", "list properties of vertices are not supported");
  }
  PcdHeader h;
  h.names = vertex->properties;
  for (size_t k = 0; k < vertex->properties.size(); ++k) {
    h.types.push_back(PlyPcdType(vertex->types[k]));
    h.sizes.push_back(vertex->sizes[k]);
    h.counts.push_back(1);
    h.point_bytes += static_cast<uint64_t>(vertex->sizes[k]);
  }
  h.values_per_point = h.names.size();
  h.width = h.points = vertex->count;
  h.data = "binary";
  const std::string_view body = file.substr(std::min<uint64_t>(ply.data_offset, file.size()));
  if (ply.format == "ascii") {
    size_t pos = 0;
    int line = ply.end_line + 1;
    for (auto e = ply.elements.begin(); e != vertex; ++e) {  // one line per item
      uint64_t items = 0;
      ForEachLine(body, pos, line, [&](const std::string& text, int line_number, size_t after) {
        pos = after;
        line = line_number + 1;
        if (text.find_first_not_of(" \t\r") == std::string::npos) return true;
        return ++items < e->count;
      });
      if (items < e->count) {
        throw InputError(path, "element " + e->name,
                         "expected " + std::to_string(e->count) + " lines, found " + std::to_string(items));
      }
    }
    const std::string records = AsciiRecords(path, h, body.substr(pos), line, vertex->count, "vertex", nullptr);
    return DecodePcdBody(path, h, records);
  }
  const bool big_endian = ply.format == "binary_big_endian";
  const auto* data = reinterpret_cast<const uint8_t*>(body.data());
  uint64_t pos = 0;
  const auto need = [&](uint64_t bytes, const std::string& element) {
    if (bytes > body.size() || pos > body.size() - bytes) {
      throw InputError(path, "element " + element, "binary data is truncated");
    }
  };
  for (auto e = ply.elements.begin(); e != vertex; ++e) {
    for (uint64_t i = 0; i < e->count; ++i) {
      for (size_t k = 0; k < e->properties.size(); ++k) {
        need(static_cast<uint64_t>(e->sizes[k]), e->name);
        if (!e->is_list[k]) {
          pos += static_cast<uint64_t>(e->sizes[k]);
          continue;
        }
        const uint64_t length = LoadUnsigned(data + pos, e->sizes[k], big_endian);
        pos += static_cast<uint64_t>(e->sizes[k]);
        const uint64_t item = static_cast<uint64_t>(PlyTypeSize(e->types[k]));
        if (length > body.size() / item) throw InputError(path, "element " + e->name, "binary data is truncated");
        need(length * item, e->name);
        pos += length * item;
      }
    }
  }
  if (h.point_bytes > 0 && vertex->count > body.size() / h.point_bytes) {
    throw InputError(path, "element vertex", "binary data is truncated");
  }
  need(vertex->count * h.point_bytes, "vertex");
  if (!big_endian) return DecodePcdBody(path, h, body.substr(pos, vertex->count * h.point_bytes));
  std::string records(body.substr(pos, vertex->count * h.point_bytes));
  for (uint64_t i = 0; i < vertex->count; ++i) {
    char* record = records.data() + i * h.point_bytes;
    for (int size : h.sizes) {
      std::reverse(record, record + size);
      record += size;
    }
  }
  return DecodePcdBody(path, h, records);
}

// A PCD file mapped once, its header parsed and (ascii) its body validated.
class PcdFile {
 public:
  explicit PcdFile(const std::string& path)
      : path_(path), size_(FileSize(path)), bytes_(path, size_) {
    header_ = ParsePcdHeader(path_, size_, bytes_.view());
    if (header_.data == "ascii") ValidatePcdAsciiBody(path_, header_, bytes_.view());
  }
  const PcdHeader& header() const { return header_; }
  std::string_view bytes() const { return bytes_.view(); }
  // Binary bodies are decoded in place; ascii bodies are first converted to
  // binary records.
  bool DecodesDirectly() const { return header_.data != "ascii"; }
  PointCloud Cloud() const {
    if (header_.points == 0) {
      CheckXyzNames(path_, header_.names);
      return PointCloud();
    }
    if (DecodesDirectly()) return DecodePcdBody(path_, header_, bytes_.view());
    const std::string records = AsciiPcdRecords(path_, header_, bytes_.view());
    return DecodePcdBody(path_, BinaryRecordsHeader(header_), records);
  }

 private:
  std::string path_;
  uint64_t size_;  // (FileSize checks existence and emptiness before the mapping)
  FileBytes bytes_;
  PcdHeader header_;
};

// ---------------------------------------------------------------------------
// Writers.

bool AnySensorId(const PointCloud& cloud) {
  return std::any_of(cloud.points.begin(), cloud.points.end(),
                     [](const LidarPoint& p) { return p.sensor_id != 0; });
}

template <typename T>
void Append(std::string* out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out->append(bytes, sizeof(T));
}

// x y z intensity t ring [sensor_id], packed (22 or 23 bytes per point).
std::string PackPoints(const PointCloud& cloud, bool with_sensor_id) {
  std::string out;
  out.reserve(cloud.size() * (with_sensor_id ? 23 : 22));
  for (const LidarPoint& p : cloud.points) {
    Append(&out, p.x);
    Append(&out, p.y);
    Append(&out, p.z);
    Append(&out, p.intensity);
    Append(&out, p.t);
    Append(&out, p.ring);
    if (with_sensor_id) Append(&out, p.sensor_id);
  }
  return out;
}

// 9 significant digits restore every float32 exactly; NaN is written "nan".
std::string FloatText(float v) {
  if (std::isnan(v)) return "nan";
  return fmt::format("{:.9g}", v);
}

std::string Lowercase(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

PointCloud ReadPcd(const std::string& path) { return PcdFile(path).Cloud(); }

PointCloud ReadPly(const std::string& path) {
  const uint64_t file_size = FileSize(path);
  const PlyHeader header = ParsePlyHeader(path, file_size);
  if (header.format == "ascii") ValidatePlyAsciiVertices(path, header, file_size);
  const auto vertex = std::find_if(header.elements.begin(), header.elements.end(),
                                   [](const PlyElement& e) { return e.name == "vertex"; });
  if (vertex->count == 0) return PointCloud();
  const FileBytes bytes(path, file_size);
  return DecodePly(path, header, bytes.view());
}

void WritePcd(const std::string& path, const PointCloud& cloud, bool binary) {
  const bool with_sensor_id = AnySensorId(cloud);
  const std::string n = std::to_string(cloud.size());
  std::string text =
      "# .PCD v0.7 - Point Cloud Data file format (lisfm; t = seconds since the scan stamp)\n"
      "VERSION 0.7\n";
  text += with_sensor_id ? "FIELDS x y z intensity t ring sensor_id\nSIZE 4 4 4 4 4 2 1\n"
                           "TYPE F F F F F U U\nCOUNT 1 1 1 1 1 1 1\n"
                         : "FIELDS x y z intensity t ring\nSIZE 4 4 4 4 4 2\n"
                           "TYPE F F F F F U\nCOUNT 1 1 1 1 1 1\n";
  text += "WIDTH " + n + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\n";
  if (binary) {
    text += "DATA binary\n";
    text += PackPoints(cloud, with_sensor_id);
  } else {
    text += "DATA ascii\n";
    for (const LidarPoint& p : cloud.points) {
      text += FloatText(p.x) + ' ' + FloatText(p.y) + ' ' + FloatText(p.z) + ' ' + FloatText(p.intensity) +
              ' ' + FloatText(p.t) + ' ' + std::to_string(p.ring);
      if (with_sensor_id) text += ' ' + std::to_string(p.sensor_id);
      text += '\n';
    }
  }
  WriteFileAtomically(path, text);
}

void WritePly(const std::string& path, const PointCloud& cloud) {
  const bool with_sensor_id = AnySensorId(cloud);
  std::string text =
      "ply\nformat binary_little_endian 1.0\n"
      "comment lisfm point cloud; t = seconds since the scan stamp\n"
      "element vertex " + std::to_string(cloud.size()) + "\n"
      "property float x\nproperty float y\nproperty float z\nproperty float intensity\n"
      "property float t\nproperty ushort ring\n";
  if (with_sensor_id) text += "property uchar sensor_id\n";
  text += "end_header\n";
  text += PackPoints(cloud, with_sensor_id);
  WriteFileAtomically(path, text);
}

std::vector<Eigen::Vector3f> ReadPointPositions(const std::string& path, size_t* num_non_finite) {
  const std::string extension = Lowercase(std::filesystem::path(path).extension().string());
  PointCloud cloud;
  if (extension == ".pcd") {
    const PcdFile file(path);
    if (file.header().points > 0 && file.DecodesDirectly()) {
      return DecodePcdPositions(path, file.header(), file.bytes(), num_non_finite);
    }
    cloud = file.Cloud();
  } else {
    cloud = ReadPointCloud(path);
  }
  std::vector<Eigen::Vector3f> out;
  out.reserve(cloud.size());
  for (const LidarPoint& p : cloud.points) {
    if (IsFinite(p)) out.push_back(p.xyz());
  }
  if (num_non_finite != nullptr) *num_non_finite = cloud.size() - out.size();
  return out;
}

PointCloud ReadPointCloud(const std::string& path) {
  const std::string extension = Lowercase(std::filesystem::path(path).extension().string());
  if (extension == ".pcd") return ReadPcd(path);
  if (extension == ".ply") return ReadPly(path);
  throw InputError(path, "", "unknown point cloud extension " + Quote(extension) + ", expected .pcd or .ply");
}

void WritePointCloud(const std::string& path, const PointCloud& cloud) {
  const std::string extension = Lowercase(std::filesystem::path(path).extension().string());
  if (extension == ".pcd") return WritePcd(path, cloud);
  if (extension == ".ply") return WritePly(path, cloud);
  throw InputError(path, "", "unknown point cloud extension " + Quote(extension) + ", expected .pcd or .ply");
}

}  // namespace lisfm
