#include "core/io/cloud_io.h"
#include "core/io/cloud_io_pcl.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// A cloud whose attributes exercise float32 exactly: random values over many
// magnitudes, a denormal, -0, the float extremes, the full ring range.
PointCloud RandomCloud(size_t n, bool with_sensor_id) {
  std::uniform_real_distribution<float> u(-100.f, 100.f);
  std::uniform_real_distribution<float> t(0.f, 0.1f);
  std::uniform_int_distribution<int> ring(0, 65535);
  std::uniform_int_distribution<int> sensor(0, 255);
  PointCloud cloud;
  cloud.stamp_ns = 1646307131123456789LL;
  for (size_t i = 0; i < n; ++i) {
    LidarPoint p;
    const float scale = std::pow(10.f, static_cast<float>(static_cast<int>(i % 9) - 4));
    p.x = u(test::Rng()) * scale;
    p.y = u(test::Rng());
    p.z = u(test::Rng()) / 3.f;
    p.intensity = std::abs(u(test::Rng())) * 2.55f;
    p.t = t(test::Rng());
    p.ring = static_cast<uint16_t>(ring(test::Rng()));
    p.sensor_id = with_sensor_id ? static_cast<uint8_t>(sensor(test::Rng())) : 0;
    cloud.points.push_back(p);
  }
  if (n >= 4) {
    cloud.points[0].x = std::numeric_limits<float>::denorm_min();
    cloud.points[0].y = -0.f;
    cloud.points[1].x = std::numeric_limits<float>::max();
    cloud.points[1].y = std::numeric_limits<float>::lowest();
    cloud.points[1].z = std::numeric_limits<float>::min();
    cloud.points[2].ring = 65535;
    cloud.points[3].ring = 0;
  }
  return cloud;
}

bool SameFloat(float a, float b) {
  if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b);
  return std::memcmp(&a, &b, sizeof(float)) == 0;  // distinguishes -0 from 0
}

void ExpectSameCloud(const PointCloud& expected, const PointCloud& actual) {
  ASSERT_EQ(expected.size(), actual.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    const LidarPoint& a = expected.points[i];
    const LidarPoint& b = actual.points[i];
    EXPECT_TRUE(SameFloat(a.x, b.x)) << "point " << i << ": " << a.x << " vs " << b.x;
    EXPECT_TRUE(SameFloat(a.y, b.y)) << "point " << i << ": " << a.y << " vs " << b.y;
    EXPECT_TRUE(SameFloat(a.z, b.z)) << "point " << i << ": " << a.z << " vs " << b.z;
    EXPECT_TRUE(SameFloat(a.intensity, b.intensity)) << "point " << i;
    EXPECT_TRUE(SameFloat(a.t, b.t)) << "point " << i;
    EXPECT_EQ(a.ring, b.ring) << "point " << i;
    EXPECT_EQ(a.sensor_id, b.sensor_id) << "point " << i;
  }
}

// The header lines of a PCD file up to DATA, read independently of cloud_io.
std::map<std::string, std::string> PcdHeaderFields(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::map<std::string, std::string> fields;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const size_t space = line.find(' ');
    fields[line.substr(0, space)] = space == std::string::npos ? "" : line.substr(space + 1);
    if (line.rfind("DATA", 0) == 0) {
      fields["@data_offset"] = std::to_string(static_cast<long long>(in.tellg()));
      break;
    }
  }
  return fields;
}

size_t PointsInHeader(const std::string& path) {
  const auto h = PcdHeaderFields(path);
  return std::stoul(h.at("WIDTH")) * std::stoul(h.at("HEIGHT"));
}

std::string Bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
}

// ---------------------------------------------------------------------------
// Round trips.

TEST(CloudIo, PcdBinaryRoundTripIsExact) {
  test::TempDir dir;
  for (bool with_sensor_id : {false, true}) {
    const PointCloud cloud = RandomCloud(1000, with_sensor_id);
    const std::string path = dir.File("scan.pcd");
    WritePcd(path, cloud);
    const auto header = PcdHeaderFields(path);
    EXPECT_EQ(header.at("DATA"), "binary");
    EXPECT_EQ(header.at("FIELDS"), with_sensor_id ? "x y z intensity t ring sensor_id" : "x y z intensity t ring");
    const PointCloud back = ReadPcd(path);
    EXPECT_EQ(back.stamp_ns, 0);  // the stamp lives in the file name
    ExpectSameCloud(cloud, back);
  }
}

TEST(CloudIo, PcdAsciiRoundTripIsExact) {
  test::TempDir dir;
  for (bool with_sensor_id : {false, true}) {
    PointCloud cloud = RandomCloud(1000, with_sensor_id);
    cloud.points[5].x = std::numeric_limits<float>::quiet_NaN();  // organised-cloud gaps survive
    const std::string path = dir.File("scan.pcd");
    WritePcd(path, cloud, /*binary=*/false);
    EXPECT_EQ(PcdHeaderFields(path).at("DATA"), "ascii");
    ExpectSameCloud(cloud, ReadPcd(path));
  }
}

TEST(CloudIo, PlyRoundTripIsExact) {
  test::TempDir dir;
  for (bool with_sensor_id : {false, true}) {
    const PointCloud cloud = RandomCloud(1000, with_sensor_id);
    const std::string path = dir.File("scan.ply");
    WritePly(path, cloud);
    EXPECT_EQ(Bytes(path).rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
    ExpectSameCloud(cloud, ReadPly(path));
  }
}

TEST(CloudIo, EmptyCloudRoundTrips) {
  test::TempDir dir;
  for (const std::string name : {"empty.pcd", "empty.ply"}) {
    WritePointCloud(dir.File(name), PointCloud());
    EXPECT_TRUE(ReadPointCloud(dir.File(name)).empty()) << name;
  }
  WritePcd(dir.File("empty_ascii.pcd"), PointCloud(), false);
  EXPECT_TRUE(ReadPcd(dir.File("empty_ascii.pcd")).empty());
}

TEST(CloudIo, DispatchOnExtensionIsCaseInsensitiveAndAtomic) {
  test::TempDir dir;
  const PointCloud cloud = RandomCloud(50, true);
  for (const std::string name : {"a.pcd", "b.PLY", "c.Pcd"}) {
    WritePointCloud(dir.File(name), cloud);
    ExpectSameCloud(cloud, ReadPointCloud(dir.File(name)));
  }
  // Only the three outputs exist: no temporary files are left behind.
  size_t files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, 3u);
  EXPECT_TRUE(test::ThrowsInputError([&] { WritePointCloud(dir.File("d.xyz"), cloud); },
                                     {dir.File("d.xyz"), "extension"}));
  EXPECT_TRUE(test::ThrowsInputError([&] { WritePcd(dir.File("no/such/dir/e.pcd"), cloud); },
                                     {dir.File("no/such/dir/e.pcd"), "cannot open"}));
}

// ---------------------------------------------------------------------------
// Other writers' files.

TEST(CloudIo, ReadsForeignFieldSets) {
  test::TempDir dir;
  // rgb only, double coordinates, uint8 ring, an extra COUNT 3 field, a comment.
  const std::string pcd = dir.File("foreign.pcd");
  test::WriteText(pcd,
                  "# made by hand\nVERSION 0.7\nFIELDS rgb x y z ring extra\nSIZE 4 8 8 8 1 4\n"
                  "TYPE F F F F U F\nCOUNT 1 1 1 1 1 3\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
                  "POINTS 2\nDATA ascii\n"
                  "4.2108e+06 1.5 -2.25 0.125 7 1 2 3\n"
                  "0 nan nan nan 0 0 0 0\n");
  const PointCloud a = ReadPcd(pcd);
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(a.points[0].xyz(), Eigen::Vector3f(1.5f, -2.25f, 0.125f));
  EXPECT_EQ(a.points[0].ring, 7);
  EXPECT_EQ(a.points[0].intensity, 0.f);  // missing -> 0
  EXPECT_EQ(a.points[0].t, 0.f);
  EXPECT_FALSE(IsFinite(a.points[1]));  // kept on read

  // An organised ascii cloud (HEIGHT 2) keeps every point in row-major order.
  const std::string organised = dir.File("organised.pcd");
  test::WriteText(organised,
                  "VERSION .5\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 2\n"
                  "POINTS 4\nDATA ascii\n1 0 0\nnan nan nan\n3 0 0\n4 0 0\n");
  PointCloud b = ReadPcd(organised);
  ASSERT_EQ(b.size(), 4u);
  EXPECT_EQ(b.points[3].x, 4.f);
  EXPECT_EQ(RemoveNonFinite(&b), 1u);

  // An ascii PLY mesh: uchar intensity, a face element (ignored).
  const std::string ply = dir.File("mesh.ply");
  test::WriteText(ply,
                  "ply\nformat ascii 1.0\ncomment hand made\nelement vertex 3\nproperty float x\n"
                  "property float y\nproperty float z\nproperty uchar intensity\nelement face 1\n"
                  "property list uchar int vertex_indices\nend_header\n"
                  "0 0 0 10\n1 0 0 20\n0 1 0 255\n3 0 1 2\n");
  const PointCloud c = ReadPly(ply);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(c.points[2].intensity, 255.f);
  EXPECT_EQ(c.points[1].x, 1.f);
}

TEST(CloudIo, ReadsFilesWrittenByPcl) {
  // tests/data/clouds/README.md: point i = (0.25 i, -0.5 i, 0.125 i + 1), intensity i.
  for (const std::string name : {"pcl_xyzi_binary.ply", "pcl_xyzi_ascii.ply", "pcl_xyzi_compressed.pcd"}) {
    const PointCloud cloud = ReadPointCloud(test::SourceDir() + "/tests/data/clouds/" + name);
    ASSERT_EQ(cloud.size(), 20u) << name;
    for (size_t i = 0; i < cloud.size(); ++i) {
      const float f = static_cast<float>(i);  // all values are exact in float32
      EXPECT_EQ(cloud.points[i].xyz(), Eigen::Vector3f(0.25f * f, -0.5f * f, 0.125f * f + 1)) << name;
      EXPECT_EQ(cloud.points[i].intensity, f) << name;
      EXPECT_EQ(cloud.points[i].t, 0.f) << name;
    }
  }
}

// ---------------------------------------------------------------------------
// Real files: counts are checked against the headers, parsed here independently.

TEST(CloudIoRealData, PclBunniesAscii) {
  LISFM_REQUIRE_SHARED_DATA("pointclouds_pcl/bun0.pcd");
  for (const std::string name : {"pointclouds_pcl/bun0.pcd", "pointclouds_pcl/bun4.pcd"}) {
    const std::string path = test::SharedData(name);
    const PointCloud cloud = ReadPointCloud(path);
    EXPECT_EQ(cloud.size(), PointsInHeader(path)) << name;
    // The first point equals the first data line of the file.
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line) && line.rfind("DATA", 0) != 0) {
    }
    float x = 0, y = 0, z = 0;
    in >> x >> y >> z;
    EXPECT_EQ(cloud.points[0].xyz(), Eigen::Vector3f(x, y, z)) << name;
  }
  EXPECT_EQ(ReadPcd(test::SharedData("pointclouds_pcl/bun0.pcd")).size(), 397u);  // README table
  EXPECT_EQ(ReadPcd(test::SharedData("pointclouds_pcl/bun4.pcd")).size(), 361u);
}

TEST(CloudIoRealData, LidarPairBinary) {
  LISFM_REQUIRE_SHARED_DATA("registration_lidar_pair/251370668.pcd");
  for (const std::string name : {"registration_lidar_pair/251370668.pcd", "registration_lidar_pair/251371071.pcd"}) {
    const std::string path = test::SharedData(name);
    const PointCloud cloud = ReadPcd(path);
    ASSERT_EQ(cloud.size(), PointsInHeader(path)) << name;
    // Binary x y z intensity float32: compare the last record byte for byte.
    const std::string bytes = Bytes(path);
    const size_t offset = std::stoul(PcdHeaderFields(path).at("@data_offset")) + (cloud.size() - 1) * 16;
    float raw[4];
    std::memcpy(raw, bytes.data() + offset, sizeof(raw));
    const LidarPoint& last = cloud.points.back();
    EXPECT_EQ(last.xyz(), Eigen::Vector3f(raw[0], raw[1], raw[2])) << name;
    EXPECT_EQ(last.intensity, raw[3]) << name;
    EXPECT_EQ(last.t, 0.f);
  }
}

TEST(CloudIoRealData, BalmScanWithNormals) {
  LISFM_REQUIRE_SHARED_DATA("lidar_balm_realworld_subset/scans/full30.pcd");
  const std::string path = test::SharedData("lidar_balm_realworld_subset/scans/full30.pcd");
  const PointCloud cloud = ReadPcd(path);
  ASSERT_EQ(cloud.size(), PointsInHeader(path));
  size_t lit = 0;
  for (const LidarPoint& p : cloud.points) lit += p.intensity != 0;
  EXPECT_GT(lit, cloud.size() / 2);  // the intensity field was found
}

TEST(CloudIoRealData, OrganisedBinaryCompressedKeepsNaN) {
  LISFM_REQUIRE_SHARED_DATA("pointclouds_pcl/office1.pcd");
  const std::string path = test::SharedData("pointclouds_pcl/office1.pcd");
  PointCloud cloud = ReadPcd(path);
  ASSERT_EQ(cloud.size(), PointsInHeader(path));
  EXPECT_EQ(cloud.size(), 640u * 480u);
  const size_t removed = RemoveNonFinite(&cloud);
  EXPECT_GT(removed, 0u);  // a Kinect frame has invalid pixels
  EXPECT_GT(cloud.size(), 0u);
}

// ---------------------------------------------------------------------------
// The direct binary / binary_compressed decoder against PCL's PCDReader.

// A valid LZF stream of literal runs only (<= 32 bytes per control byte), so
// that tests can write binary_compressed bodies without a compressor.
std::string LzfLiterals(const std::string& raw) {
  std::string out;
  for (size_t i = 0; i < raw.size(); i += 32) {
    const size_t n = std::min<size_t>(32, raw.size() - i);
    out.push_back(static_cast<char>(n - 1));
    out.append(raw, i, n);
  }
  return out;
}

template <typename T>
void Put(std::string* out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out->append(bytes, sizeof(T));
}

TEST(CloudIoDirectDecoder, MatchesPclReaderOnForeignLayouts) {
  test::TempDir dir;
  // Fields of every type the reader converts: double x, float y, int16 z, a COUNT 3
  // padding field, uint8 sensor_id, int32 ring, double t, uint16 intensity.
  // (PCL's compressed reader skips fields named "_", so the compressed file
  // names its COUNT 3 field "pad"; ReadPcd hands "_" + compressed to PCL.)
  auto header_common = [](const std::string& pad) {
    return "VERSION 0.7\nFIELDS x y " + pad + " z sensor_id ring t intensity\nSIZE 8 4 4 2 1 4 8 2\n"
           "TYPE F F F I U I F U\nCOUNT 1 1 3 1 1 1 1 1\nWIDTH 5\nHEIGHT 2\n"
           "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 10\n";
  };
  // One record per point (interleaved) and one block per field (compressed layout).
  std::string interleaved;
  std::vector<std::string> blocks(8);
  for (int i = 0; i < 10; ++i) {
    const double x = i == 3 ? std::numeric_limits<double>::quiet_NaN() : 0.1 * i - 2.5;
    Put(&interleaved, x);
    Put(&blocks[0], x);
    Put(&interleaved, -1.25f * i);
    Put(&blocks[1], -1.25f * i);
    for (int c = 0; c < 3; ++c) {
      Put(&interleaved, 7.f);
      Put(&blocks[2], 7.f);
    }
    Put(&interleaved, static_cast<int16_t>(-300 + 77 * i));
    Put(&blocks[3], static_cast<int16_t>(-300 + 77 * i));
    Put(&interleaved, static_cast<uint8_t>(25 * i));
    Put(&blocks[4], static_cast<uint8_t>(25 * i));
    Put(&interleaved, static_cast<int32_t>(6000 * i));
    Put(&blocks[5], static_cast<int32_t>(6000 * i));
    Put(&interleaved, 1e-3 * i);
    Put(&blocks[6], 1e-3 * i);
    Put(&interleaved, static_cast<uint16_t>(65535 - i));
    Put(&blocks[7], static_cast<uint16_t>(65535 - i));
  }
  std::string soa;
  for (const std::string& b : blocks) soa += b;
  ASSERT_EQ(soa.size(), interleaved.size());
  const std::string binary = dir.File("foreign_binary.pcd");
  WriteBytes(binary, header_common("_") + "DATA binary\n" + interleaved);
  const std::string packed = LzfLiterals(soa);
  std::string sizes;
  Put(&sizes, static_cast<uint32_t>(packed.size()));
  Put(&sizes, static_cast<uint32_t>(soa.size()));
  const std::string compressed = dir.File("foreign_compressed.pcd");
  WriteBytes(compressed, header_common("pad") + "DATA binary_compressed\n" + sizes + packed);
  for (const std::string& path : {binary, compressed}) {
    const PointCloud direct = ReadPcd(path);
    ASSERT_EQ(direct.size(), 10u) << path;
    ExpectSameCloud(ReadPcdWithPclReader(path), direct);
    // Independent spot checks of the conversions (the values written above).
    EXPECT_EQ(direct.points[2].x, static_cast<float>(0.1 * 2 - 2.5)) << path;
    EXPECT_TRUE(std::isnan(direct.points[3].x)) << path;  // organised: NaN kept
    EXPECT_EQ(direct.points[4].y, -5.f) << path;
    EXPECT_EQ(direct.points[9].z, static_cast<float>(-300 + 77 * 9)) << path;
    EXPECT_EQ(direct.points[9].sensor_id, 225) << path;
    EXPECT_EQ(direct.points[9].ring, 54000) << path;
    EXPECT_EQ(direct.points[7].t, static_cast<float>(7e-3)) << path;
    EXPECT_EQ(direct.points[1].intensity, 65534.f) << path;
  }
  // Range checks and the integer-t rule hold on the direct path too.
  std::string bad_ring = interleaved;
  const size_t ring_offset = 8 + 4 + 12 + 2 + 1;  // of record 0: after x y _ z sensor_id
  const int32_t minus_one = -1;
  std::memcpy(bad_ring.data() + ring_offset, &minus_one, 4);
  WriteBytes(binary, header_common("_") + "DATA binary\n" + bad_ring);
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPcd(binary); }, {binary, "record 0: ring = -1"}));
  const std::string int_t = dir.File("int_t.pcd");
  WriteBytes(int_t,
             "VERSION 0.7\nFIELDS x y z t\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
             "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n" + std::string(16, '\0'));
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadPcd(int_t); }, {int_t, "field t: expected float seconds"}));
  const std::string count3 = dir.File("count3.pcd");
  WriteBytes(count3,
             "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 2\n"
             "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n" + std::string(20, '\0'));
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPcd(count3); },
                                     {count3, "field intensity: expected COUNT 1, found 2"}));
}

// ascii PCD and PLY (ascii, binary little and big endian) are parsed by
// cloud_io too: the same clouds as PCL's readers on every numeric type, and
// elements before the vertices (with list properties) are skipped.
TEST(CloudIoDirectDecoder, MatchesPclReaderOnAsciiPcdAndPly) {
  test::TempDir dir;
  const std::string ascii_pcd = dir.File("foreign_ascii.pcd");
  std::string body;
  for (int i = 0; i < 6; ++i) {
    body += fmt::format("{} {} 7 7 7 {} {} {} {} {}\n", i == 3 ? "nan" : fmt::format("{:.17g}", 0.1 * i - 2.5),
                        -1.25 * i, -300 + 77 * i, 25 * i, 6000 * i, fmt::format("{:.17g}", 1e-3 * i),
                        65535 - i);
  }
  test::WriteText(ascii_pcd,
                  "VERSION 0.7\nFIELDS x y pad z sensor_id ring t intensity\nSIZE 8 4 4 2 1 4 8 2\n"
                  "TYPE F F F I U I F U\nCOUNT 1 1 3 1 1 1 1 1\nWIDTH 6\nHEIGHT 1\nPOINTS 6\nDATA ascii\n" +
                      body);
  const PointCloud pcd = ReadPcd(ascii_pcd);
  ASSERT_EQ(pcd.size(), 6u);
  ExpectSameCloud(ReadPcdWithPclReader(ascii_pcd), pcd);
  EXPECT_EQ(pcd.points[5].z, static_cast<float>(-300 + 77 * 5));
  EXPECT_EQ(pcd.points[5].ring, 30000);
  EXPECT_EQ(pcd.points[4].t, static_cast<float>(4e-3));

  // PLY: the same vertices; char .. double property types.
  const std::string props =
      "property double x\nproperty float y\nproperty short z\nproperty uchar sensor_id\n"
      "property int ring\nproperty double t\nproperty ushort intensity\n";
  std::string ascii, le, be;
  const auto put_be = [&be](auto v) {
    char b[sizeof(v)];
    std::memcpy(b, &v, sizeof(v));
    std::reverse(b, b + sizeof(v));
    be.append(b, sizeof(v));
  };
  for (int i = 0; i < 6; ++i) {
    const double x = 0.1 * i - 2.5;
    ascii += fmt::format("{:.17g} {} {} {} {} {:.17g} {}\n", x, -1.25 * i, -300 + 77 * i, 25 * i, 6000 * i,
                         1e-3 * i, 65535 - i);
    Put(&le, x), put_be(x);
    Put(&le, -1.25f * i), put_be(-1.25f * i);
    Put(&le, static_cast<int16_t>(-300 + 77 * i)), put_be(static_cast<int16_t>(-300 + 77 * i));
    Put(&le, static_cast<uint8_t>(25 * i)), put_be(static_cast<uint8_t>(25 * i));
    Put(&le, static_cast<int32_t>(6000 * i)), put_be(static_cast<int32_t>(6000 * i));
    Put(&le, 1e-3 * i), put_be(1e-3 * i);
    Put(&le, static_cast<uint16_t>(65535 - i)), put_be(static_cast<uint16_t>(65535 - i));
  }
  const std::string tail = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  std::string face_le, face_be;
  Put(&face_le, static_cast<uint8_t>(3));
  face_be += static_cast<char>(3);
  for (int32_t k : {0, 1, 2}) Put(&face_le, k), put_be(k);
  face_be += be.substr(be.size() - 12);  // the three indices, big endian
  be.resize(be.size() - 12);
  const std::map<std::string, std::string> files = {
      {"ascii.ply", "ply\nformat ascii 1.0\nelement vertex 6\n" + props + tail + ascii + "3 0 1 2\n"},
      {"le.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 6\n" + props + tail + le + face_le},
      {"be.ply", "ply\nformat binary_big_endian 1.0\nelement vertex 6\n" + props + tail + be + face_be},
  };
  for (const auto& [name, text] : files) {
    WriteBytes(dir.File(name), text);
    const PointCloud ply = ReadPly(dir.File(name));
    ASSERT_EQ(ply.size(), 6u) << name;
    ExpectSameCloud(ReadPlyWithPclReader(dir.File(name)), ply);
    for (size_t i = 0; i < 6; ++i) {
      EXPECT_EQ(ply.points[i].x, static_cast<float>(0.1 * i - 2.5)) << name << " " << i;
      EXPECT_EQ(ply.points[i].ring, 6000 * i) << name;
      EXPECT_EQ(ply.points[i].intensity, 65535.f - i) << name;
    }
  }
  // A face element before the vertices (list lengths decide its size).
  const std::string head = "element face 2\nproperty list uchar int vertex_indices\nproperty uchar flag\n"
                           "element vertex 6\n" + props + "end_header\n";
  std::string faces_le;
  for (int f = 0; f < 2; ++f) {
    Put(&faces_le, static_cast<uint8_t>(f + 3));
    for (int k = 0; k < f + 3; ++k) Put(&faces_le, static_cast<int32_t>(k));
    Put(&faces_le, static_cast<uint8_t>(9));
  }
  WriteBytes(dir.File("faces_first.ply"), "ply\nformat binary_little_endian 1.0\n" + head + faces_le + le);
  WriteBytes(dir.File("faces_first_ascii.ply"),
             "ply\nformat ascii 1.0\n" + head + "3 0 1 2 9\n4 0 1 2 3 9\n" + ascii);
  for (const std::string name : {"faces_first.ply", "faces_first_ascii.ply"}) {
    ExpectSameCloud(ReadPly(dir.File("le.ply")), ReadPly(dir.File(name)));
  }
  WriteBytes(dir.File("faces_cut.ply"),
             "ply\nformat binary_little_endian 1.0\n" + head + faces_le.substr(0, 10));
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPly(dir.File("faces_cut.ply")); },
                                     {dir.File("faces_cut.ply"), "truncated"}));
}

TEST(CloudIoDirectDecoder, MatchesPclReaderOnFilesWrittenByPcl) {
  ExpectSameCloud(ReadPcdWithPclReader(test::SourceDir() + "/tests/data/clouds/pcl_xyzi_compressed.pcd"),
                  ReadPcd(test::SourceDir() + "/tests/data/clouds/pcl_xyzi_compressed.pcd"));
  test::TempDir dir;
  const PointCloud cloud = RandomCloud(500, true);
  WritePcd(dir.File("ours.pcd"), cloud);
  ExpectSameCloud(ReadPcdWithPclReader(dir.File("ours.pcd")), ReadPcd(dir.File("ours.pcd")));
}

TEST(CloudIoDirectDecoderRealData, MatchesPclReader) {
  LISFM_REQUIRE_SHARED_DATA("lidar_balm_realworld_subset/scans/full30.pcd");
  // Binary LiDAR scans (x y z intensity [normals curvature]) and an organised
  // binary_compressed Kinect frame (LZF back references, NaN pixels).
  for (const std::string name : {"lidar_balm_realworld_subset/scans/full30.pcd",
                                 "registration_lidar_pair/251370668.pcd", "pointclouds_pcl/office1.pcd"}) {
    const std::string path = test::SharedData(name);
    if (path.empty()) continue;
    const PointCloud direct = ReadPcd(path);
    EXPECT_EQ(direct.size(), PointsInHeader(path)) << name;
    ExpectSameCloud(ReadPcdWithPclReader(path), direct);
  }
}

// ReadPointPositions (the registration's reader): exactly the finite positions of
// ReadPointCloud, on the direct-decoding path (binary, binary_compressed) and on
// the fallbacks (ascii PCD, PLY, "_" padding), with the non-finite count.
void ExpectPositionsOfCloud(const std::string& path) {
  const PointCloud cloud = ReadPointCloud(path);
  std::vector<Eigen::Vector3f> expected;
  for (const LidarPoint& p : cloud.points) {
    if (IsFinite(p)) expected.push_back(p.xyz());
  }
  size_t non_finite = 12345;
  const std::vector<Eigen::Vector3f> positions = ReadPointPositions(path, &non_finite);
  ASSERT_EQ(positions.size(), expected.size()) << path;
  EXPECT_EQ(non_finite, cloud.size() - expected.size()) << path;
  for (size_t i = 0; i < positions.size(); ++i) {
    ASSERT_EQ(positions[i], expected[i]) << path << " point " << i;
  }
}

TEST(CloudIo, PointPositionsAreTheFinitePointsOfReadPointCloud) {
  test::TempDir dir;
  PointCloud cloud = RandomCloud(300, true);
  for (const size_t i : {size_t{0}, size_t{17}, size_t{299}}) cloud.points[i].y = std::nanf("");
  cloud.points[40].z = std::numeric_limits<float>::infinity();
  WritePcd(dir.File("binary.pcd"), cloud, true);
  WritePcd(dir.File("ascii.pcd"), cloud, false);
  WritePly(dir.File("cloud.ply"), cloud);
  for (const std::string name : {"binary.pcd", "ascii.pcd", "cloud.ply"}) {
    ExpectPositionsOfCloud(dir.File(name));
  }
  size_t non_finite = 0;
  EXPECT_EQ(ReadPointPositions(dir.File("binary.pcd"), &non_finite).size(), 296u);
  EXPECT_EQ(non_finite, 4u);
  ExpectPositionsOfCloud(test::SourceDir() + "/tests/data/clouds/pcl_xyzi_compressed.pcd");
  // Truncated and unknown files: the same errors as ReadPointCloud.
  const std::string bytes = Bytes(dir.File("binary.pcd"));
  WriteBytes(dir.File("cut.pcd"), bytes.substr(0, bytes.size() - 50));
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPointPositions(dir.File("cut.pcd")); },
                                     {dir.File("cut.pcd"), "truncated"}));
  WriteBytes(dir.File("cloud.xyz"), "1 2 3\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPointPositions(dir.File("cloud.xyz")); },
                                     {dir.File("cloud.xyz"), "unknown point cloud extension"}));
}

TEST(CloudIoRealData, PointPositionsOfRealScans) {
  LISFM_REQUIRE_SHARED_DATA("lidar_balm_realworld_subset/scans/full30.pcd");
  // Binary LiDAR scans and an organised binary_compressed Kinect frame (NaN pixels).
  for (const std::string name : {"lidar_balm_realworld_subset/scans/full30.pcd",
                                 "registration_lidar_pair/251370668.pcd", "pointclouds_pcl/office1.pcd",
                                 "pointclouds_pcl/bun0.pcd"}) {
    const std::string path = test::SharedData(name);
    if (!path.empty()) ExpectPositionsOfCloud(path);
  }
}

// ---------------------------------------------------------------------------
// Bad input: one InputError naming the file, never a crash.

std::string ValidPcdHeader(const std::string& fields,
                           const std::string& size,
                           const std::string& type,
                           size_t points,
                           const std::string& data) {
  const std::string n = std::to_string(points);
  std::string count = "1";
  for (char c : fields) count += c == ' ' ? " 1" : "";
  return "VERSION 0.7\nFIELDS " + fields + "\nSIZE " + size + "\nTYPE " + type + "\nCOUNT " + count +
         "\nWIDTH " + n + "\nHEIGHT 1\nPOINTS " + n + "\nDATA " +
         data + "\n";
}

TEST(CloudIoBadInput, MissingEmptyAndGarbage) {
  test::TempDir dir;
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPcd(dir.File("missing.pcd")); },
                                     {dir.File("missing.pcd"), "not found"}));
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPly(dir.File("missing.ply")); },
                                     {dir.File("missing.ply"), "not found"}));
  for (const std::string name : {"empty.pcd", "empty.ply"}) {
    WriteBytes(dir.File(name), "");
    EXPECT_TRUE(test::ThrowsInputError([&] { ReadPointCloud(dir.File(name)); },
                                       {dir.File(name), "empty file"}));
  }
  test::WriteText(dir.File("text.pcd"), "garbage\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPcd(dir.File("text.pcd")); },
                                     {dir.File("text.pcd"), "line 1"}));
  test::WriteText(dir.File("comments.pcd"), "# only a comment\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPcd(dir.File("comments.pcd")); },
                                     {dir.File("comments.pcd"), "without a DATA line"}));
  std::string noise(4096, '\0');
  for (char& c : noise) c = static_cast<char>(test::Rng()() & 0xff);
  for (const std::string name : {"noise.pcd", "noise.ply"}) {
    WriteBytes(dir.File(name), noise);
    EXPECT_TRUE(test::ThrowsInputError([&] { ReadPointCloud(dir.File(name)); },
                                       {dir.File(name), "line 1"}));
  }
  test::WriteText(dir.File("cloud.xyz"), "1 2 3\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPointCloud(dir.File("cloud.xyz")); },
                                     {dir.File("cloud.xyz"), "extension"}));
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPointCloud(dir.File("noextension")); },
                                     {dir.File("noextension"), "extension"}));
}

TEST(CloudIoBadInput, TruncatedBinaryPcdAndPly) {
  test::TempDir dir;
  const PointCloud cloud = RandomCloud(100, false);
  WritePcd(dir.File("full.pcd"), cloud);
  WritePly(dir.File("full.ply"), cloud);
  for (const std::string ext : {"pcd", "ply"}) {
    const std::string bytes = Bytes(dir.File("full." + ext));
    const std::string path = dir.File("cut." + ext);
    // Cut inside the data, at the end of the header, and inside the header.
    for (size_t keep : {bytes.size() - 1, bytes.size() - 22 * 50, bytes.size() - 22 * 100, size_t{40}}) {
      WriteBytes(path, bytes.substr(0, keep));
      EXPECT_TRUE(test::ThrowsInputError([&] { ReadPointCloud(path); },
                                         {path, keep == 40 ? "" : "truncated"}));
    }
  }
}

TEST(CloudIoBadInput, TruncatedBinaryCompressedPcd) {
  LISFM_REQUIRE_SHARED_DATA("pointclouds_pcl/office1.pcd");
  test::TempDir dir;
  const std::string bytes = Bytes(test::SharedData("pointclouds_pcl/office1.pcd"));
  const std::string path = dir.File("office_cut.pcd");
  WriteBytes(path, bytes.substr(0, bytes.size() / 2));
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPcd(path); }, {path, "truncated"}));
  // Intact size words, corrupt LZF stream: PCL's decompressor must fail cleanly.
  std::string corrupt = bytes;
  const size_t data = std::stoul(PcdHeaderFields(test::SharedData("pointclouds_pcl/office1.pcd")).at("@data_offset"));
  for (size_t i = data + 8; i < corrupt.size(); i += 7) corrupt[i] = static_cast<char>(0xff);
  WriteBytes(path, corrupt);
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadPcd(path); }, {path}));
}

TEST(CloudIoBadInput, PcdHeaderMismatches) {
  test::TempDir dir;
  const std::string path = dir.File("bad.pcd");
  auto expect = [&](const std::string& text, const std::string& detail) {
    test::WriteText(path, text);
    EXPECT_TRUE(test::ThrowsInputError([&] { ReadPcd(path); }, {path, detail}));
  };
  // FIELDS / SIZE / TYPE / COUNT lengths disagree.
  expect(ValidPcdHeader("x y z intensity", "4 4 4", "F F F F", 1, "ascii") + "1 2 3 4\n",
         "line 3: SIZE has 3 entries but FIELDS has 4");
  expect(ValidPcdHeader("x y z intensity", "4 4 4 4", "F F F", 1, "ascii") + "1 2 3 4\n", "TYPE has 3 entries");
  expect("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1\nWIDTH 1\nDATA ascii\n1 2 3\n", "COUNT has 2 entries");
  // Invalid values.
  expect(ValidPcdHeader("x y z", "4 4 3", "F F F", 1, "ascii") + "1 2 3\n", "SIZE 3 is not valid for TYPE F");
  expect(ValidPcdHeader("x y z", "4 4 4", "F F Q", 1, "ascii") + "1 2 3\n", "expected F, I or U");
  expect(ValidPcdHeader("x y z", "4 4 4", "F F F", 1, "lzma") + "1 2 3\n", "expected ascii, binary");
  expect("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 3\nDATA ascii\n1 2 3\n",
         "line 6: POINTS = 3 but WIDTH * HEIGHT");
  expect("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH -2\nDATA ascii\n", "line 4: WIDTH");
  expect("FIELDS x y z\nFIELDS x y z\n", "line 2: FIELDS appears twice");
  expect("SIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n", "no FIELDS line");
  // A header line of white space only (PCL's reader would crash on it); an empty line is fine.
  expect("\r\n" + ValidPcdHeader("x y z", "4 4 4", "F F F", 1, "ascii") + "1 2 3\n",
         "line 1: a header line of white space only");
  expect("# .PCD v0.7\n \n" + ValidPcdHeader("x y z", "4 4 4", "F F F", 1, "ascii") + "1 2 3\n",
         "line 2: a header line of white space only");
  test::WriteText(path, "\n" + ValidPcdHeader("x y z", "4 4 4", "F F F", 1, "ascii") + "1 2 3\n");
  EXPECT_EQ(ReadPcd(path).size(), 1u);
  // Ascii bodies.
  expect(ValidPcdHeader("x y z", "4 4 4", "F F F", 2, "ascii") + "1 2 3\n", "expected 2 points, found 1");
  expect(ValidPcdHeader("x y z", "4 4 4", "F F F", 1, "ascii") + "1 2 3\n4 5 6\n", "line 11: more data lines");
  expect(ValidPcdHeader("x y z", "4 4 4", "F F F", 2, "ascii") + "1 2 3\n4 five 6\n",
         "line 11: value 2: expected a number, found 'five'");
  expect(ValidPcdHeader("x y z", "4 4 4", "F F F", 1, "ascii") + "1 2\n", "line 10: expected 3 values, found 2");
  expect(ValidPcdHeader("x y z ring", "4 4 4 2", "F F F U", 1, "ascii") + "1 2 3 1.5\n", "expected an integer");
  // Fields.
  expect(ValidPcdHeader("a b c", "4 4 4", "F F F", 1, "ascii") + "1 2 3\n", "no field 'x'");
  expect(ValidPcdHeader("a b c", "4 4 4", "F F F", 0, "ascii"), "no field 'x'");
  expect(ValidPcdHeader("x y z t", "4 4 4 4", "F F F U", 1, "ascii") + "1 2 3 100000\n",
         "field t: expected float seconds");
  expect(ValidPcdHeader("x y z ring", "4 4 4 4", "F F F I", 1, "ascii") + "1 2 3 -1\n",
         "record 0: ring = -1");
  expect(ValidPcdHeader("x y z sensor_id", "4 4 4 2", "F F F U", 1, "ascii") + "1 2 3 256\n",
         "sensor_id = 256");
}

TEST(CloudIoBadInput, PlyHeaderAndBody) {
  test::TempDir dir;
  const std::string path = dir.File("bad.ply");
  auto expect = [&](const std::string& text, const std::string& detail) {
    test::WriteText(path, text);
    EXPECT_TRUE(test::ThrowsInputError([&] { ReadPly(path); }, {path, detail}));
  };
  const std::string xyz = "element vertex 2\nproperty float x\nproperty float y\nproperty float z\n";
  expect("PLY\n", "line 1: expected the PLY magic");
  expect("ply\nformat ascii 1.0\n" + xyz, "without 'end_header'");
  expect("ply\n" + xyz + "end_header\n1 2 3\n4 5 6\n", "no 'format' line");
  expect("ply\nformat ascii 2.0x\n", "line 2");
  expect("ply\nformat ascii 1.0\nproperty float x\nend_header\n", "line 3: property before any element");
  expect("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n", "line 4");
  expect("ply\nformat ascii 1.0\nelement face 0\nend_header\n", "no 'element vertex'");
  expect("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n",
         "no property z");
  expect("ply\nformat ascii 1.0\n" + xyz + "end_header\n1 2 3\n", "expected 2 vertex lines, found 1");
  expect("ply\nformat ascii 1.0\n" + xyz + "end_header\n1 2 3\n4 5 foo\n", "line 9: property z");
  expect("ply\nformat ascii 1.0\n" + xyz + "end_header\n1 2 3 4\n4 5 6\n", "line 8: vertex 0: expected 3 values");
  expect("ply\nformat binary_little_endian 1.0\n" + xyz + "end_header\n" + std::string(20, 'a'), "truncated");
}

}  // namespace
}  // namespace lisfm
