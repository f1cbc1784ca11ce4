#include "core/io/cloud_io_pcl.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <string>

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {
namespace {

void SilencePcl() {
  static std::once_flag once;
  std::call_once(once, [] { pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS); });
}

// PCLPointCloud2 -> PointCloud, by field name.

int DatatypeSize(uint8_t type) {
  switch (type) {
    case pcl::PCLPointField::INT8:
    case pcl::PCLPointField::UINT8: return 1;
    case pcl::PCLPointField::INT16:
    case pcl::PCLPointField::UINT16: return 2;
    case pcl::PCLPointField::INT32:
    case pcl::PCLPointField::UINT32:
    case pcl::PCLPointField::FLOAT32: return 4;
    case pcl::PCLPointField::INT64:
    case pcl::PCLPointField::UINT64:
    case pcl::PCLPointField::FLOAT64: return 8;
    default: return 0;
  }
}

template <typename T>
double Load(const uint8_t* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  return static_cast<double>(value);
}

double LoadValue(const uint8_t* p, uint8_t type) {
  switch (type) {
    case pcl::PCLPointField::INT8: return Load<int8_t>(p);
    case pcl::PCLPointField::UINT8: return Load<uint8_t>(p);
    case pcl::PCLPointField::INT16: return Load<int16_t>(p);
    case pcl::PCLPointField::UINT16: return Load<uint16_t>(p);
    case pcl::PCLPointField::INT32: return Load<int32_t>(p);
    case pcl::PCLPointField::UINT32: return Load<uint32_t>(p);
    case pcl::PCLPointField::INT64: return Load<int64_t>(p);
    case pcl::PCLPointField::UINT64: return Load<uint64_t>(p);
    case pcl::PCLPointField::FLOAT32: return Load<float>(p);
    default: return Load<double>(p);  // FLOAT64; other types are rejected in FindField
  }
}

struct FieldRef {
  bool present = false;
  uint32_t offset = 0;
  uint8_t type = 0;
};

FieldRef FindField(const std::string& path, const pcl::PCLPointCloud2& blob, const std::string& name, bool required) {
  FieldRef ref;
  for (const pcl::PCLPointField& f : blob.fields) {
    if (f.name != name) continue;
    const int size = DatatypeSize(f.datatype);
    if (size == 0) {
      throw InputError(path, "field " + name, "unsupported data type " + std::to_string(f.datatype));
    }
    if (f.count != 1) {
      throw InputError(path, "field " + name, "expected COUNT 1, found " + std::to_string(f.count));
    }
    if (f.offset + static_cast<uint32_t>(size) > blob.point_step) {
      throw InputError(path, "field " + name, "lies outside the point record");
    }
    ref.present = true;
    ref.offset = f.offset;
    ref.type = f.datatype;
    return ref;
  }
  if (required) {
    std::string names;
    for (const pcl::PCLPointField& f : blob.fields) names += (names.empty() ? "" : " ") + f.name;
    throw InputError(path, "", "no field '" + name + "' (the file has: " + names + ")");
  }
  return ref;
}

PointCloud CloudFromBlob(const std::string& path, const pcl::PCLPointCloud2& blob) {
  if (blob.is_bigendian) throw InputError(path, "", "big-endian point data is not supported");
  const uint64_t width = blob.width, height = blob.height;
  if (height > 0 && (blob.row_step < width * blob.point_step ||
                     blob.data.size() < (height - 1) * blob.row_step + width * blob.point_step)) {
    throw InputError(path, "", "PCL returned fewer data bytes than WIDTH * HEIGHT points need");
  }
  const FieldRef x = FindField(path, blob, "x", true);
  const FieldRef y = FindField(path, blob, "y", true);
  const FieldRef z = FindField(path, blob, "z", true);
  const FieldRef intensity = FindField(path, blob, "intensity", false);
  const FieldRef t = FindField(path, blob, "t", false);
  const FieldRef ring = FindField(path, blob, "ring", false);
  const FieldRef sensor_id = FindField(path, blob, "sensor_id", false);
  if (t.present && t.type != pcl::PCLPointField::FLOAT32 && t.type != pcl::PCLPointField::FLOAT64) {
    throw InputError(path, "field t",
                     "expected float seconds since the scan stamp, found an integer type (e.g. Ouster "
                     "nanoseconds); convert the file first");
  }

  PointCloud cloud;
  cloud.points.resize(width * height);
  for (uint64_t row = 0; row < height; ++row) {
    for (uint64_t col = 0; col < width; ++col) {
      const uint64_t index = row * width + col;
      const uint8_t* record = blob.data.data() + row * blob.row_step + col * blob.point_step;
      LidarPoint& p = cloud.points[index];
      p.x = static_cast<float>(LoadValue(record + x.offset, x.type));
      p.y = static_cast<float>(LoadValue(record + y.offset, y.type));
      p.z = static_cast<float>(LoadValue(record + z.offset, z.type));
      if (intensity.present) p.intensity = static_cast<float>(LoadValue(record + intensity.offset, intensity.type));
      if (t.present) p.t = static_cast<float>(LoadValue(record + t.offset, t.type));
      if (ring.present) {
        const double v = LoadValue(record + ring.offset, ring.type);
        if (!(v >= 0 && v <= 65535 && v == std::floor(v))) {
          throw InputError(path, "record " + std::to_string(index),
                           "ring = " + std::to_string(v) + ", expected an integer in [0, 65535]");
        }
        p.ring = static_cast<uint16_t>(v);
      }
      if (sensor_id.present) {
        const double v = LoadValue(record + sensor_id.offset, sensor_id.type);
        if (!(v >= 0 && v <= 255 && v == std::floor(v))) {
          throw InputError(path, "record " + std::to_string(index),
                           "sensor_id = " + std::to_string(v) + ", expected an integer in [0, 255]");
        }
        p.sensor_id = static_cast<uint8_t>(v);
      }
    }
  }
  return cloud;
}


// Reads `path` with PCL's Reader (pcl::PCDReader / pcl::PLYReader); PCL's
// exceptions and a non-zero status become InputErrors (`status_message`).
template <typename Reader>
pcl::PCLPointCloud2 ReadBlobWithPcl(const std::string& path, const std::string& status_message) {
  pcl::PCLPointCloud2 blob;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  int status = -1;
  try {
    Reader reader;
    status = reader.read(path, blob, origin, orientation, version, 0);
  } catch (const std::exception& e) {
    throw InputError(path, "", std::string("PCL could not read the file: ") + e.what());
  } catch (...) {
    throw InputError(path, "", "PCL could not read the file");
  }
  if (status != 0) throw InputError(path, "", status_message);
  return blob;
}

}  // namespace

PointCloud ReadPcdWithPclReader(const std::string& path) {
  CheckFileExists(path, "point cloud file");
  SilencePcl();
  return CloudFromBlob(
      path, ReadBlobWithPcl<pcl::PCDReader>(path, "PCL could not read the file (corrupt data?)"));
}

PointCloud ReadPlyWithPclReader(const std::string& path) {
  CheckFileExists(path, "point cloud file");
  SilencePcl();
  return CloudFromBlob(path, ReadBlobWithPcl<pcl::PLYReader>(
                                 path, "PCL could not parse the PLY data (truncated or malformed)"));
}

}  // namespace lisfm
