#include "colmap_ext/io/model_io.h"

#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {
namespace colmap {
namespace {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
              "COLMAP files are little-endian; big-endian hosts need byte swaps");

// ---- binary helpers ----

std::string ReadWholeFile(const std::string& path) {
  CheckFileExists(path);
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError(path, "", "cannot open for reading");
  const std::streamoff size = in.tellg();
  std::string data(static_cast<size_t>(size), '\0');
  in.seekg(0);
  if (size > 0 && !in.read(&data[0], size)) throw InputError(path, "", "read failed");
  return data;
}

// Bounds-checked little-endian reader; errors name the file and record.
class BinaryReader {
 public:
  BinaryReader(const std::string& path) : path_(path), data_(ReadWholeFile(path)) {}

  template <typename T>
  T Read(const char* what) {
    T value;
    Need(sizeof(T), what);
    std::memcpy(&value, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  void ReadDoubles(double* out, size_t n, const char* what) {
    Need(n * sizeof(double), what);
    std::memcpy(out, data_.data() + pos_, n * sizeof(double));
    pos_ += n * sizeof(double);
  }
  std::string ReadNulString(const char* what) {
    const void* end = std::memchr(data_.data() + pos_, '\0', data_.size() - pos_);
    if (end == nullptr) {
      throw InputError(path_, Where(), std::string("truncated: expected a NUL-terminated ") +
                                           what + ", found end of file");
    }
    const size_t len = static_cast<const char*>(end) - (data_.data() + pos_);
    std::string s(data_.data() + pos_, len);
    pos_ += len + 1;
    return s;
  }
  // The record count of the file header (named in truncation errors).
  uint64_t ReadHeaderCount(const char* what) {
    header_count_ = Read<uint64_t>(what);
    return header_count_;
  }
  // A count inside a record, checked against the bytes left so that a
  // corrupt count cannot allocate huge amounts of memory.
  uint64_t ReadCount(size_t min_bytes_each, const char* what) {
    const uint64_t n = Read<uint64_t>(what);
    if (min_bytes_each > 0 && n > (data_.size() - pos_) / min_bytes_each) {
      throw InputError(path_, Where(),
                       std::string("wrong ") + what + ": " + std::to_string(n) +
                           " entries need at least " + std::to_string(min_bytes_each) +
                           " bytes each, but only " + std::to_string(data_.size() - pos_) +
                           " bytes remain");
    }
    return n;
  }
  void SetRecord(uint64_t record) { record_ = static_cast<int64_t>(record); }
  void ExpectEnd() {
    if (pos_ != data_.size()) {
      throw InputError(path_, "",
                       "expected end of file after the last record, found " +
                           std::to_string(data_.size() - pos_) +
                           " extra bytes (wrong count?)");
    }
  }
  std::string Where() const {
    return record_ < 0 ? std::string("header") : "record " + std::to_string(record_);
  }
  const std::string& path() const { return path_; }

 private:
  void Need(size_t n, const char* what) {
    if (data_.size() - pos_ < n) {
      throw InputError(path_, Where(),
                       std::string("truncated: expected ") + std::to_string(n) +
                           " bytes for " + what + ", found " +
                           std::to_string(data_.size() - pos_) + " (the header announces " +
                           std::to_string(header_count_) + " records)");
    }
  }
  std::string path_;
  std::string data_;
  size_t pos_ = 0;
  int64_t record_ = -1;
  uint64_t header_count_ = 0;
};

template <typename T>
void Put(std::string* out, T value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

// ---- text helpers ----

// "%.17g", which is what std::ostream with precision(17) produces.
void AppendDouble(std::string* out, double value) {
  char buf[40];
  const int n = std::snprintf(buf, sizeof(buf), "%.17g", value);
  out->append(buf, static_cast<size_t>(n));
}
void AppendUint(std::string* out, uint64_t value) {
  char buf[24];
  const int n = std::snprintf(buf, sizeof(buf), "%" PRIu64, value);
  out->append(buf, static_cast<size_t>(n));
}

// Splits a text line into space-separated tokens (as COLMAP writes them).
std::vector<std::string> Tokens(const std::string& line) {
  return SplitString(line, " \t", true);
}

class TextParser {
 public:
  TextParser(const LineReader& reader) : reader_(reader) {}
  double Double(const std::string& token, const char* field) const {
    errno = 0;
    char* end = nullptr;
    const double v = std::strtod(token.c_str(), &end);
    if (token.empty() || *end != '\0' || errno == ERANGE) Fail(field, "a number", token);
    return v;
  }
  uint64_t Uint(const std::string& token, const char* field, uint64_t max) const {
    errno = 0;
    char* end = nullptr;
    if (token.empty() || token[0] == '-' || token[0] == '+') Fail(field, "an unsigned integer", token);
    const unsigned long long v = std::strtoull(token.c_str(), &end, 10);
    if (*end != '\0' || errno == ERANGE || v > max) Fail(field, "an unsigned integer", token);
    return v;
  }
  [[noreturn]] void Fail(const std::string& field,
                         const std::string& expected,
                         const std::string& found) const {
    throw InputError(reader_.path(), reader_.Where(),
                     "expected " + expected + " for " + field + ", found '" + found + "'");
  }

 private:
  const LineReader& reader_;
};

// Next data line (trimmed), skipping empty and comment lines.
bool NextDataLine(LineReader* reader, std::string* line) {
  while (reader->Next(line)) {
    *line = Trim(*line);
    if (!line->empty() && (*line)[0] != '#') return true;
  }
  return false;
}

void CheckCamera(const std::string& path, const std::string& where, const Camera& camera) {
  if (!ExistsCameraModel(camera.model_id)) {
    throw InputError(path, where,
                     "expected a camera model id in 0-10, found " +
                         std::to_string(camera.model_id));
  }
  if (!camera.VerifyParams()) {
    throw InputError(path, where,
                     "expected " + std::to_string(CameraModelNumParams(camera.model_id)) +
                         " finite parameters for " + camera.ModelName() + ", found " +
                         std::to_string(camera.params.size()));
  }
}

}  // namespace

// ---------------- binary ----------------

void ReadCamerasBinary(const std::string& path, Reconstruction* reconstruction) {
  BinaryReader in(path);
  const uint64_t n = in.ReadHeaderCount("camera count");
  for (uint64_t i = 0; i < n; ++i) {
    in.SetRecord(i);
    Camera camera;
    camera.camera_id = in.Read<uint32_t>("camera id");
    camera.model_id = in.Read<int32_t>("model id");
    camera.width = in.Read<uint64_t>("width");
    camera.height = in.Read<uint64_t>("height");
    if (!ExistsCameraModel(camera.model_id)) {
      throw InputError(path, in.Where(),
                       "expected a camera model id in 0-10, found " +
                           std::to_string(camera.model_id));
    }
    camera.params.resize(CameraModelNumParams(camera.model_id));
    in.ReadDoubles(camera.params.data(), camera.params.size(), "camera params");
    if (reconstruction->ExistsCamera(camera.camera_id)) {
      throw InputError(path, in.Where(), "duplicate camera id " + std::to_string(camera.camera_id));
    }
    reconstruction->AddCamera(std::move(camera));
  }
  in.ExpectEnd();
}

void ReadImagesBinary(const std::string& path, Reconstruction* reconstruction) {
  BinaryReader in(path);
  const uint64_t n = in.ReadHeaderCount("image count");
  for (uint64_t i = 0; i < n; ++i) {
    in.SetRecord(i);
    Image image;
    image.image_id = in.Read<uint32_t>("image id");
    in.ReadDoubles(image.qvec.data(), 4, "qvec");
    in.ReadDoubles(image.tvec.data(), 3, "tvec");
    image.camera_id = in.Read<uint32_t>("camera id");
    image.name = in.ReadNulString("image name");
    const uint64_t num_points2D = in.ReadCount(24, "number of 2D points");
    image.points2D.resize(num_points2D);
    for (uint64_t j = 0; j < num_points2D; ++j) {
      Point2D& p = image.points2D[j];
      in.ReadDoubles(p.xy.data(), 2, "point2D xy");
      p.point3D_id = in.Read<uint64_t>("point3D id");
    }
    if (reconstruction->ExistsImage(image.image_id)) {
      throw InputError(path, in.Where(), "duplicate image id " + std::to_string(image.image_id));
    }
    reconstruction->AddImage(std::move(image));
  }
  in.ExpectEnd();
}

void ReadPoints3DBinary(const std::string& path, Reconstruction* reconstruction) {
  BinaryReader in(path);
  const uint64_t n = in.ReadHeaderCount("point count");
  for (uint64_t i = 0; i < n; ++i) {
    in.SetRecord(i);
    const point3D_t id = in.Read<uint64_t>("point3D id");
    Point3D point;
    in.ReadDoubles(point.xyz.data(), 3, "xyz");
    for (int c = 0; c < 3; ++c) point.color[c] = in.Read<uint8_t>("color");
    point.error = in.Read<double>("error");
    const uint64_t track_length = in.ReadCount(8, "track length");
    point.track.resize(track_length);
    for (uint64_t j = 0; j < track_length; ++j) {
      point.track[j].image_id = in.Read<uint32_t>("track image id");
      point.track[j].point2D_idx = in.Read<uint32_t>("track point2D idx");
    }
    if (reconstruction->ExistsPoint3D(id)) {
      throw InputError(path, in.Where(), "duplicate point3D id " + std::to_string(id));
    }
    reconstruction->AddPoint3D(id, std::move(point));
  }
  in.ExpectEnd();
}

void ReadRigsBinary(const std::string& path, Reconstruction* reconstruction) {
  BinaryReader in(path);
  const uint64_t n = in.ReadHeaderCount("rig count");
  for (uint64_t i = 0; i < n; ++i) {
    in.SetRecord(i);
    ModelRig rig;
    rig.rig_id = in.Read<uint32_t>("rig id");
    const uint32_t num_sensors = in.Read<uint32_t>("sensor count");
    if (num_sensors > 0) {
      rig.has_ref_sensor = true;
      rig.ref_sensor.type = static_cast<SensorType>(in.Read<int32_t>("ref sensor type"));
      rig.ref_sensor.id = in.Read<uint32_t>("ref sensor id");
    }
    for (uint32_t j = 1; j < num_sensors; ++j) {
      RigSensor sensor;
      sensor.sensor.type = static_cast<SensorType>(in.Read<int32_t>("sensor type"));
      sensor.sensor.id = in.Read<uint32_t>("sensor id");
      sensor.has_pose = in.Read<uint8_t>("has_pose") != 0;
      if (sensor.has_pose) {
        in.ReadDoubles(sensor.qvec.data(), 4, "sensor_from_rig rotation");
        in.ReadDoubles(sensor.tvec.data(), 3, "sensor_from_rig translation");
      }
      rig.sensors.push_back(sensor);
    }
    reconstruction->Rigs().push_back(std::move(rig));
  }
  in.ExpectEnd();
}

void ReadFramesBinary(const std::string& path, Reconstruction* reconstruction) {
  BinaryReader in(path);
  const uint64_t n = in.ReadHeaderCount("frame count");
  for (uint64_t i = 0; i < n; ++i) {
    in.SetRecord(i);
    ModelFrame frame;
    frame.frame_id = in.Read<uint32_t>("frame id");
    frame.rig_id = in.Read<uint32_t>("rig id");
    in.ReadDoubles(frame.qvec.data(), 4, "rig_from_world rotation");
    in.ReadDoubles(frame.tvec.data(), 3, "rig_from_world translation");
    const uint32_t num_data = in.Read<uint32_t>("data id count");
    for (uint32_t j = 0; j < num_data; ++j) {
      FrameData d;
      d.sensor.type = static_cast<SensorType>(in.Read<int32_t>("sensor type"));
      d.sensor.id = in.Read<uint32_t>("sensor id");
      d.data_id = in.Read<uint64_t>("data id");
      frame.data.push_back(d);
    }
    reconstruction->Frames().push_back(std::move(frame));
  }
  in.ExpectEnd();
}

std::string CamerasBinary(const Reconstruction& reconstruction) {
  std::string out;
  Put<uint64_t>(&out, reconstruction.NumCameras());
  for (const Camera& camera : reconstruction.Cameras()) {
    Put<uint32_t>(&out, camera.camera_id);
    Put<int32_t>(&out, camera.model_id);
    Put<uint64_t>(&out, camera.width);
    Put<uint64_t>(&out, camera.height);
    for (double p : camera.params) Put<double>(&out, p);
  }
  return out;
}

std::string ImagesBinary(const Reconstruction& reconstruction) {
  size_t size = 8;
  for (const Image& image : reconstruction.Images()) {
    size += 73 + image.name.size() + 24 * image.points2D.size();
  }
  std::string out;
  out.reserve(size);
  Put<uint64_t>(&out, reconstruction.NumImages());
  for (const Image& image : reconstruction.Images()) {
    Put<uint32_t>(&out, image.image_id);
    const Vec4 q = QvecForWriting(image.qvec);
    for (int k = 0; k < 4; ++k) Put<double>(&out, q(k));
    for (int k = 0; k < 3; ++k) Put<double>(&out, image.tvec(k));
    Put<uint32_t>(&out, image.camera_id);
    out.append(image.name.c_str(), image.name.size() + 1);
    Put<uint64_t>(&out, image.points2D.size());
    for (const Point2D& p : image.points2D) {
      Put<double>(&out, p.xy.x());
      Put<double>(&out, p.xy.y());
      Put<uint64_t>(&out, p.point3D_id);
    }
  }
  return out;
}

std::string Points3DBinary(const Reconstruction& reconstruction) {
  size_t size = 8;
  for (const auto& entry : reconstruction.Points3D()) size += 51 + 8 * entry.second.track.size();
  std::string out;
  out.reserve(size);
  Put<uint64_t>(&out, reconstruction.NumPoints3D());
  for (const auto& entry : reconstruction.Points3D()) {
    const Point3D& p = entry.second;
    Put<uint64_t>(&out, entry.first);
    for (int k = 0; k < 3; ++k) Put<double>(&out, p.xyz(k));
    for (int k = 0; k < 3; ++k) Put<uint8_t>(&out, p.color[k]);
    Put<double>(&out, p.error);
    Put<uint64_t>(&out, p.track.size());
    for (const TrackElement& el : p.track) {
      Put<uint32_t>(&out, el.image_id);
      Put<uint32_t>(&out, el.point2D_idx);
    }
  }
  return out;
}

std::string RigsBinary(const Reconstruction& reconstruction) {
  std::string out;
  Put<uint64_t>(&out, reconstruction.Rigs().size());
  for (const ModelRig& rig : reconstruction.Rigs()) {
    THROW_CHECK(rig.has_ref_sensor || rig.sensors.empty());
    Put<uint32_t>(&out, rig.rig_id);
    Put<uint32_t>(&out, static_cast<uint32_t>(rig.sensors.size() + (rig.has_ref_sensor ? 1 : 0)));
    if (rig.has_ref_sensor) {
      Put<int32_t>(&out, static_cast<int32_t>(rig.ref_sensor.type));
      Put<uint32_t>(&out, rig.ref_sensor.id);
    }
    for (const RigSensor& s : rig.sensors) {
      Put<int32_t>(&out, static_cast<int32_t>(s.sensor.type));
      Put<uint32_t>(&out, s.sensor.id);
      Put<uint8_t>(&out, s.has_pose ? 1 : 0);
      if (s.has_pose) {
        for (int k = 0; k < 4; ++k) Put<double>(&out, s.qvec(k));
        for (int k = 0; k < 3; ++k) Put<double>(&out, s.tvec(k));
      }
    }
  }
  return out;
}

std::string FramesBinary(const Reconstruction& reconstruction) {
  std::string out;
  Put<uint64_t>(&out, reconstruction.Frames().size());
  for (const ModelFrame& frame : reconstruction.Frames()) {
    Put<uint32_t>(&out, frame.frame_id);
    Put<uint32_t>(&out, frame.rig_id);
    for (int k = 0; k < 4; ++k) Put<double>(&out, frame.qvec(k));
    for (int k = 0; k < 3; ++k) Put<double>(&out, frame.tvec(k));
    Put<uint32_t>(&out, static_cast<uint32_t>(frame.data.size()));
    for (const FrameData& d : frame.data) {
      Put<int32_t>(&out, static_cast<int32_t>(d.sensor.type));
      Put<uint32_t>(&out, d.sensor.id);
      Put<uint64_t>(&out, d.data_id);
    }
  }
  return out;
}

// ---------------- text ----------------

std::string CamerasText(const Reconstruction& reconstruction) {
  std::string out =
      "# Camera list with one line of data per camera:\n"
      "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      "# Number of cameras: ";
  AppendUint(&out, reconstruction.NumCameras());
  out += '\n';
  for (const Camera& camera : reconstruction.Cameras()) {
    AppendUint(&out, camera.camera_id);
    out += ' ';
    out += camera.ModelName();
    out += ' ';
    AppendUint(&out, camera.width);
    out += ' ';
    AppendUint(&out, camera.height);
    for (double p : camera.params) {
      out += ' ';
      AppendDouble(&out, p);
    }
    out += '\n';
  }
  return out;
}

std::string ImagesText(const Reconstruction& reconstruction) {
  std::string out =
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      "# Number of images: ";
  AppendUint(&out, reconstruction.NumImages());
  out += ", mean observations per image: ";
  AppendDouble(&out, reconstruction.ComputeMeanObservationsPerRegImage());
  out += '\n';
  for (const Image& image : reconstruction.Images()) {
    AppendUint(&out, image.image_id);
    const Vec4 q = QvecForWriting(image.qvec);
    for (int k = 0; k < 4; ++k) {
      out += ' ';
      AppendDouble(&out, q(k));
    }
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      AppendDouble(&out, image.tvec(k));
    }
    out += ' ';
    AppendUint(&out, image.camera_id);
    out += ' ';
    out += image.name;
    out += '\n';
    bool first = true;
    for (const Point2D& p : image.points2D) {
      if (!first) out += ' ';
      first = false;
      AppendDouble(&out, p.xy.x());
      out += ' ';
      AppendDouble(&out, p.xy.y());
      out += ' ';
      if (p.HasPoint3D()) {
        AppendUint(&out, p.point3D_id);
      } else {
        out += "-1";
      }
    }
    out += '\n';
  }
  return out;
}

std::string Points3DText(const Reconstruction& reconstruction) {
  std::string out =
      "# 3D point list with one line of data per point:\n"
      "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
      "# Number of points: ";
  AppendUint(&out, reconstruction.NumPoints3D());
  out += ", mean track length: ";
  AppendDouble(&out, reconstruction.ComputeMeanTrackLength());
  out += '\n';
  for (const auto& entry : reconstruction.Points3D()) {
    const Point3D& p = entry.second;
    AppendUint(&out, entry.first);
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      AppendDouble(&out, p.xyz(k));
    }
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      AppendUint(&out, p.color[k]);
    }
    out += ' ';
    AppendDouble(&out, p.error);
    // COLMAP writes "error " and then the track joined by spaces, so a point
    // without a track keeps the trailing space.
    out += ' ';
    bool first = true;
    for (const TrackElement& el : p.track) {
      if (!first) out += ' ';
      first = false;
      AppendUint(&out, el.image_id);
      out += ' ';
      AppendUint(&out, el.point2D_idx);
    }
    out += '\n';
  }
  return out;
}

void ReadCamerasText(const std::string& path, Reconstruction* reconstruction) {
  CheckFileExists(path);
  LineReader reader(path);
  TextParser parse(reader);
  std::string line;
  while (NextDataLine(&reader, &line)) {
    const std::vector<std::string> t = Tokens(line);
    if (t.size() < 4) parse.Fail("a camera line", "CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]", line);
    Camera camera;
    camera.camera_id = static_cast<camera_t>(parse.Uint(t[0], "CAMERA_ID", UINT32_MAX));
    camera.model_id = CameraModelIdFromName(t[1]);
    if (camera.model_id < 0) parse.Fail("MODEL", "a COLMAP camera model name", t[1]);
    camera.width = parse.Uint(t[2], "WIDTH", UINT64_MAX);
    camera.height = parse.Uint(t[3], "HEIGHT", UINT64_MAX);
    for (size_t i = 4; i < t.size(); ++i) camera.params.push_back(parse.Double(t[i], "PARAMS"));
    CheckCamera(path, reader.Where(), camera);
    if (reconstruction->ExistsCamera(camera.camera_id)) {
      throw InputError(path, reader.Where(), "duplicate camera id " + t[0]);
    }
    reconstruction->AddCamera(std::move(camera));
  }
}

void ReadImagesText(const std::string& path, Reconstruction* reconstruction) {
  CheckFileExists(path);
  LineReader reader(path);
  TextParser parse(reader);
  std::string line;
  while (NextDataLine(&reader, &line)) {
    std::vector<std::string> t = Tokens(line);
    if (t.size() < 10) {
      parse.Fail("an image line", "IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", line);
    }
    Image image;
    image.image_id = static_cast<image_t>(parse.Uint(t[0], "IMAGE_ID", UINT32_MAX));
    for (int k = 0; k < 4; ++k) image.qvec(k) = parse.Double(t[1 + k], "QVEC");
    for (int k = 0; k < 3; ++k) image.tvec(k) = parse.Double(t[5 + k], "TVEC");
    image.camera_id = static_cast<camera_t>(parse.Uint(t[8], "CAMERA_ID", UINT32_MAX));
    image.name = t[9];
    for (size_t i = 10; i < t.size(); ++i) image.name += " " + t[i];
    // The 2D point line follows directly and may be empty.
    if (!reader.Next(&line)) {
      throw InputError(path, "line " + std::to_string(reader.line_number() + 1),
                       "expected the POINTS2D line of image " + t[0] + ", found end of file");
    }
    const std::vector<std::string> p = Tokens(line);
    if (p.size() % 3 != 0) {
      parse.Fail("POINTS2D", "triples (X Y POINT3D_ID)",
                 std::to_string(p.size()) + " values");
    }
    image.points2D.resize(p.size() / 3);
    for (size_t i = 0; i < image.points2D.size(); ++i) {
      Point2D& pt = image.points2D[i];
      pt.xy.x() = parse.Double(p[3 * i], "X");
      pt.xy.y() = parse.Double(p[3 * i + 1], "Y");
      pt.point3D_id = p[3 * i + 2] == "-1" ? kInvalidPoint3DId
                                            : parse.Uint(p[3 * i + 2], "POINT3D_ID", UINT64_MAX);
    }
    if (reconstruction->ExistsImage(image.image_id)) {
      throw InputError(path, reader.Where(), "duplicate image id " + t[0]);
    }
    reconstruction->AddImage(std::move(image));
  }
}

void ReadPoints3DText(const std::string& path, Reconstruction* reconstruction) {
  CheckFileExists(path);
  LineReader reader(path);
  TextParser parse(reader);
  std::string line;
  while (NextDataLine(&reader, &line)) {
    const std::vector<std::string> t = Tokens(line);
    if (t.size() < 8 || (t.size() - 8) % 2 != 0) {
      parse.Fail("a point line",
                 "POINT3D_ID X Y Z R G B ERROR and (IMAGE_ID POINT2D_IDX) pairs", line);
    }
    const point3D_t id = parse.Uint(t[0], "POINT3D_ID", UINT64_MAX);
    Point3D point;
    for (int k = 0; k < 3; ++k) point.xyz(k) = parse.Double(t[1 + k], "XYZ");
    for (int k = 0; k < 3; ++k) point.color[k] = static_cast<uint8_t>(parse.Uint(t[4 + k], "RGB", 255));
    point.error = parse.Double(t[7], "ERROR");
    point.track.resize((t.size() - 8) / 2);
    for (size_t i = 0; i < point.track.size(); ++i) {
      point.track[i].image_id = static_cast<image_t>(parse.Uint(t[8 + 2 * i], "IMAGE_ID", UINT32_MAX));
      point.track[i].point2D_idx =
          static_cast<point2D_t>(parse.Uint(t[9 + 2 * i], "POINT2D_IDX", UINT32_MAX));
    }
    if (reconstruction->ExistsPoint3D(id)) {
      throw InputError(path, reader.Where(), "duplicate point3D id " + t[0]);
    }
    reconstruction->AddPoint3D(id, std::move(point));
  }
}

// ---------------- folders ----------------

bool HasModel(const std::string& folder, ModelFormat format) {
  const char* ext = format == ModelFormat::kBinary ? ".bin" : ".txt";
  for (const char* name : {"cameras", "images", "points3D"}) {
    if (!FileExists(JoinPaths(folder, std::string(name) + ext))) return false;
  }
  return true;
}

Reconstruction ReadModelBinary(const std::string& folder) {
  Reconstruction r;
  ReadCamerasBinary(JoinPaths(folder, "cameras.bin"), &r);
  ReadImagesBinary(JoinPaths(folder, "images.bin"), &r);
  ReadPoints3DBinary(JoinPaths(folder, "points3D.bin"), &r);
  if (FileExists(JoinPaths(folder, "rigs.bin"))) ReadRigsBinary(JoinPaths(folder, "rigs.bin"), &r);
  if (FileExists(JoinPaths(folder, "frames.bin"))) {
    ReadFramesBinary(JoinPaths(folder, "frames.bin"), &r);
  }
  r.Validate(folder);
  return r;
}

Reconstruction ReadModelText(const std::string& folder) {
  Reconstruction r;
  ReadCamerasText(JoinPaths(folder, "cameras.txt"), &r);
  ReadImagesText(JoinPaths(folder, "images.txt"), &r);
  ReadPoints3DText(JoinPaths(folder, "points3D.txt"), &r);
  r.Validate(folder);
  return r;
}

Reconstruction ReadModel(const std::string& folder, ModelFormat* format) {
  CheckDirExists(folder, "model folder");
  if (HasModel(folder, ModelFormat::kBinary)) {
    if (format != nullptr) *format = ModelFormat::kBinary;
    return ReadModelBinary(folder);
  }
  if (HasModel(folder, ModelFormat::kText)) {
    if (format != nullptr) *format = ModelFormat::kText;
    return ReadModelText(folder);
  }
  throw InputError(folder, "",
                   "expected a COLMAP model (cameras, images, points3D as .bin or .txt), "
                   "found none");
}

namespace {
void WriteBinaryFile(const std::string& path, const std::string& contents) {
  AtomicOutputFile out(path, true);
  out.stream().write(contents.data(), static_cast<std::streamsize>(contents.size()));
  out.Commit();
}
}  // namespace

void WriteModelBinary(const Reconstruction& reconstruction, const std::string& folder) {
  CreateDirs(folder);
  WriteBinaryFile(JoinPaths(folder, "cameras.bin"), CamerasBinary(reconstruction));
  WriteBinaryFile(JoinPaths(folder, "images.bin"), ImagesBinary(reconstruction));
  WriteBinaryFile(JoinPaths(folder, "points3D.bin"), Points3DBinary(reconstruction));
  if (!reconstruction.Rigs().empty() || !reconstruction.Frames().empty()) {
    WriteBinaryFile(JoinPaths(folder, "rigs.bin"), RigsBinary(reconstruction));
    WriteBinaryFile(JoinPaths(folder, "frames.bin"), FramesBinary(reconstruction));
  }
}

void WriteModelText(const Reconstruction& reconstruction, const std::string& folder) {
  CreateDirs(folder);
  WriteBinaryFile(JoinPaths(folder, "cameras.txt"), CamerasText(reconstruction));
  WriteBinaryFile(JoinPaths(folder, "images.txt"), ImagesText(reconstruction));
  WriteBinaryFile(JoinPaths(folder, "points3D.txt"), Points3DText(reconstruction));
}

void WriteModel(const Reconstruction& reconstruction,
                const std::string& folder,
                ModelFormat format) {
  if (format == ModelFormat::kBinary) {
    WriteModelBinary(reconstruction, folder);
  } else {
    WriteModelText(reconstruction, folder);
  }
}

void WritePly(const Reconstruction& reconstruction, const std::string& path) {
  std::string out =
      "ply\nformat binary_little_endian 1.0\nelement vertex " +
      std::to_string(reconstruction.NumPoints3D()) +
      "\nproperty float x\nproperty float y\nproperty float z\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  out.reserve(out.size() + 15 * reconstruction.NumPoints3D());
  for (const auto& entry : reconstruction.Points3D()) {
    for (int k = 0; k < 3; ++k) Put<float>(&out, static_cast<float>(entry.second.xyz(k)));
    for (int k = 0; k < 3; ++k) Put<uint8_t>(&out, entry.second.color[k]);
  }
  WriteBinaryFile(path, out);
}

}  // namespace colmap
}  // namespace lisfm
