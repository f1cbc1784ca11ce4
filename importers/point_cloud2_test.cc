#include "importers/point_cloud2.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "core/errors.h"

namespace lisfm {
namespace {

// Writes `v` at `p` in little- or big-endian byte order.
template <typename T>
void PutBytes(uint8_t* p, T v, bool big_endian) {
  uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  for (size_t i = 0; i < sizeof(T); ++i) p[i] = big_endian ? b[sizeof(T) - 1 - i] : b[i];
}

struct TestPoint {
  float x, y, z, intensity;
  double t;  // in the unit and reference of the layout
  uint16_t ring;
};

const std::vector<TestPoint> kPoints = {
    {1.5f, -2.25f, 0.125f, 10.f, 0.0, 3},
    {-4.f, 5.5f, 6.75f, 200.f, 0.05, 31},
    {7.f, 8.f, -9.f, 0.f, 0.0999, 0},
    {0.5f, 0.25f, 0.75f, 1.f, 0.02, 7},
};

TEST(PointCloud2Test, BigEndianOrganisedWithRowPadding) {
  // Ouster-like: x y z (float32), t (uint32 ns since the stamp), ring (uint16),
  // intensity (float64); point_step 40 (padding), two rows of two points, 8
  // bytes of padding at the end of each row.
  RawPointCloud2 msg;
  msg.header_stamp_ns = 1700000000123456789;
  msg.height = 2;
  msg.width = 2;
  msg.is_bigendian = true;
  msg.point_step = 40;
  msg.row_step = 2 * 40 + 8;
  msg.fields = {{"x", 0, 7, 1},
                {"y", 4, 7, 1},
                {"z", 8, 7, 1},
                {"t", 12, 6, 1},
                {"ring", 16, 4, 1},
                {"intensity", 24, 8, 1}};
  std::vector<uint8_t> data(msg.height * msg.row_step, 0xAB);
  for (size_t i = 0; i < kPoints.size(); ++i) {
    uint8_t* p = data.data() + (i / 2) * msg.row_step + (i % 2) * msg.point_step;
    const TestPoint& q = kPoints[i];
    PutBytes<float>(p + 0, q.x, true);
    PutBytes<float>(p + 4, q.y, true);
    PutBytes<float>(p + 8, q.z, true);
    PutBytes<uint32_t>(p + 12, static_cast<uint32_t>(std::llround(q.t * 1e9)), true);
    PutBytes<uint16_t>(p + 16, q.ring, true);
    PutBytes<double>(p + 24, q.intensity, true);
  }
  msg.data = data.data();
  msg.data_size = data.size();
  PointCloud2Mapping mapping;
  mapping.time.name = "t";
  mapping.time.unit = PointTimeField::Unit::kNanoseconds;
  const PointCloud cloud = DecodePointCloud2(msg, mapping, "test");
  ASSERT_EQ(cloud.size(), kPoints.size());
  EXPECT_EQ(cloud.stamp_ns, msg.header_stamp_ns);  // the first point is at the stamp
  for (size_t i = 0; i < kPoints.size(); ++i) {
    EXPECT_EQ(cloud.points[i].x, kPoints[i].x) << i;
    EXPECT_EQ(cloud.points[i].y, kPoints[i].y) << i;
    EXPECT_EQ(cloud.points[i].z, kPoints[i].z) << i;
    EXPECT_EQ(cloud.points[i].intensity, kPoints[i].intensity) << i;
    EXPECT_EQ(cloud.points[i].ring, kPoints[i].ring) << i;
    EXPECT_EQ(cloud.points[i].t, static_cast<float>(std::llround(kPoints[i].t * 1e9) * 1e-9)) << i;
  }
}

TEST(PointCloud2Test, LittleEndianPaddedVelodyneLayoutShiftsStampToFirstPoint) {
  // Velodyne-like: x y z at 0..12, pad, intensity 16, ring 20, time 24 (float32
  // seconds since the stamp), point_step 32. The earliest point is 0.01 s after
  // the stamp: the scan stamp moves there and the times follow.
  RawPointCloud2 msg;
  msg.header_stamp_ns = 1000000000;
  msg.width = kPoints.size();
  msg.point_step = 32;
  msg.row_step = msg.width * 32;
  msg.fields = {{"x", 0, 7, 1},
                {"y", 4, 7, 1},
                {"z", 8, 7, 1},
                {"intensity", 16, 7, 1},
                {"ring", 20, 4, 1},
                {"time", 24, 7, 1}};
  std::vector<uint8_t> data(msg.row_step, 0);
  for (size_t i = 0; i < kPoints.size(); ++i) {
    uint8_t* p = data.data() + i * 32;
    PutBytes<float>(p + 0, kPoints[i].x, false);
    PutBytes<float>(p + 4, kPoints[i].y, false);
    PutBytes<float>(p + 8, kPoints[i].z, false);
    PutBytes<float>(p + 16, kPoints[i].intensity, false);
    PutBytes<uint16_t>(p + 20, kPoints[i].ring, false);
    PutBytes<float>(p + 24, static_cast<float>(kPoints[i].t + 0.01), false);
  }
  msg.data = data.data();
  msg.data_size = data.size();
  PointCloud2Mapping mapping;
  mapping.time.name = "time";
  const PointCloud cloud = DecodePointCloud2(msg, mapping, "test");
  ASSERT_EQ(cloud.size(), kPoints.size());
  EXPECT_EQ(cloud.stamp_ns, 1010000000);
  for (size_t i = 0; i < kPoints.size(); ++i) {
    EXPECT_EQ(cloud.points[i].x, kPoints[i].x);
    EXPECT_EQ(cloud.points[i].ring, kPoints[i].ring);
    EXPECT_NEAR(cloud.points[i].t, kPoints[i].t, 1e-7) << i;
    EXPECT_GE(cloud.points[i].t, 0.f);
  }
}

TEST(PointCloud2Test, HesaiAbsoluteTimesRoundTripThroughTheEncoder) {
  PointCloud in;
  in.stamp_ns = 1700000000599950001;
  for (const TestPoint& q : kPoints) {
    LidarPoint p;
    p.x = q.x, p.y = q.y, p.z = q.z, p.intensity = q.intensity, p.ring = q.ring;
    p.t = static_cast<float>(q.t);
    in.points.push_back(p);
  }
  PointCloud2Mapping mapping;
  mapping.time.name = "timestamp";
  mapping.time.datatype = 8;
  mapping.time.reference = PointTimeField::Reference::kAbsolute;
  std::vector<uint8_t> data;
  RawPointCloud2 msg;
  msg.fields = EncodePointCloud2(in, mapping, &data, &msg.point_step);
  EXPECT_EQ(msg.point_step, 32u);  // Hesai XT32: timestamp at 16, ring at 24
  EXPECT_EQ(msg.fields[4].offset, 16u);
  EXPECT_EQ(msg.fields[5].offset, 24u);
  msg.header_stamp_ns = in.stamp_ns;
  msg.width = in.size();
  msg.row_step = msg.width * msg.point_step;
  msg.data = data.data();
  msg.data_size = data.size();
  const PointCloud out = DecodePointCloud2(msg, mapping, "test");
  EXPECT_EQ(out.stamp_ns, in.stamp_ns);
  for (size_t i = 0; i < in.size(); ++i) {
    EXPECT_EQ(out.points[i].x, in.points[i].x);
    // float64 absolute seconds at 1.7e9 s resolve 2^-22 s.
    EXPECT_NEAR(out.points[i].t, in.points[i].t, 2.4e-7) << i;
    EXPECT_GE(out.points[i].t, 0.f);
  }

  // The same cloud with relative float32 times comes back bit-exactly.
  mapping = PointCloud2Mapping();
  mapping.time.name = "time";
  msg.fields = EncodePointCloud2(in, mapping, &data, &msg.point_step);
  msg.row_step = msg.width * msg.point_step;
  msg.data = data.data();
  msg.data_size = data.size();
  const PointCloud exact = DecodePointCloud2(msg, mapping, "test");
  EXPECT_EQ(exact.stamp_ns, in.stamp_ns);
  for (size_t i = 0; i < in.size(); ++i) EXPECT_EQ(exact.points[i].t, in.points[i].t);
}

TEST(PointCloud2Test, NonDenseCloudKeepsNanPointsAndTimesFromFiniteOnes) {
  RawPointCloud2 msg;
  msg.header_stamp_ns = 5000;
  msg.width = 2;
  msg.point_step = 16;
  msg.row_step = 32;
  msg.is_dense = false;
  msg.fields = {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}, {"t", 12, 7, 1}};
  std::vector<uint8_t> data(32, 0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  PutBytes<float>(data.data() + 0, nan, false);
  PutBytes<float>(data.data() + 12, -1.f, false);  // a NaN point's time is ignored
  PutBytes<float>(data.data() + 16, 1.f, false);
  PutBytes<float>(data.data() + 28, 0.f, false);
  msg.data = data.data();
  msg.data_size = data.size();
  const PointCloud cloud = DecodePointCloud2(msg, PointCloud2Mapping(), "test");
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_TRUE(std::isnan(cloud.points[0].x));
  EXPECT_EQ(cloud.stamp_ns, 5000);
  EXPECT_EQ(cloud.points[1].x, 1.f);
  EXPECT_EQ(cloud.points[1].ring, 0);  // no ring field
}

TEST(PointCloud2Test, BadLayoutsAreInputErrorsNamingThePlace) {
  RawPointCloud2 msg;
  msg.header_stamp_ns = 1;
  msg.width = 1;
  msg.point_step = 16;
  msg.row_step = 16;
  std::vector<uint8_t> data(16, 0);
  msg.data = data.data();
  msg.data_size = data.size();
  auto expect_error = [&](const std::string& needle) {
    try {
      DecodePointCloud2(msg, PointCloud2Mapping(), "b.bag: topic /p message 3");
      ADD_FAILURE() << "no error for " << needle;
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("b.bag: topic /p message 3"), std::string::npos) << what;
      EXPECT_NE(what.find(needle), std::string::npos) << what;
    }
  };
  msg.fields = {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}};
  expect_error("no per-point time field 't'");
  msg.fields = {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"t", 12, 7, 1}};
  expect_error("no z field");
  msg.fields = {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}, {"t", 14, 7, 1}};
  expect_error("ends past point_step");
  msg.fields = {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}, {"t", 12, 9, 1}};
  expect_error("unknown datatype");
  msg.fields = {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}, {"t", 12, 7, 1}};
  msg.row_step = 8;
  expect_error("row_step");
  msg.row_step = 16;
  msg.data_size = 15;
  expect_error("data bytes");
}

TEST(PointCloud2Test, PointTimesBeyondTheInt64StampRangeAreInputErrors) {
  // x y z t float64 (absolute seconds); the stamp is the earliest point, and
  // times ~1e10 s (317 years) from header.stamp have no int64 ns stamp.
  RawPointCloud2 msg;
  msg.header_stamp_ns = 1700000000000000000;
  msg.width = 1;
  msg.point_step = 32;
  msg.row_step = 32;
  msg.fields = {{"x", 0, 8, 1}, {"y", 8, 8, 1}, {"z", 16, 8, 1}, {"t", 24, 8, 1}};
  std::vector<uint8_t> data(32, 0);
  msg.data = data.data();
  msg.data_size = data.size();
  PointCloud2Mapping mapping;
  mapping.time.reference = PointTimeField::Reference::kAbsolute;
  for (const double t : {1.0e10, -1.0e10, 1e300}) {
    PutBytes<double>(data.data() + 24, t, false);
    try {
      DecodePointCloud2(msg, mapping, "b.bag: topic /p message 0");
      ADD_FAILURE() << "no error for t = " << t;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("from header.stamp is out of range"), std::string::npos)
          << e.what();
    }
  }
  // 7e9 s after the epoch still has a stamp (~2191).
  PutBytes<double>(data.data() + 24, 7.0e9, false);
  EXPECT_EQ(DecodePointCloud2(msg, mapping, "m").stamp_ns, 7000000000000000000);
}

}  // namespace
}  // namespace lisfm
