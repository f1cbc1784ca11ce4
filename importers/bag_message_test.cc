// ROS1 message definitions parsed from the text a bag stores, serialized
// messages walked with them, and livox_ros_driver/CustomMsg encoded and decoded.
#include "importers/bag_message.h"

#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "core/errors.h"

namespace lisfm {
namespace {

template <typename T>
void Put(std::vector<uint8_t>* out, T v) {
  const size_t n = out->size();
  out->resize(n + sizeof(T));
  std::memcpy(out->data() + n, &v, sizeof(T));
}

PointCloud SampleCloud() {
  PointCloud c;
  c.stamp_ns = 1700000000123456789;
  for (int i = 0; i < 50; ++i) {
    LidarPoint p;
    p.x = 1.0f + 0.25f * static_cast<float>(i);
    p.y = -2.0f + 0.125f * static_cast<float>(i);
    p.z = 0.5f;
    p.intensity = static_cast<float>(i * 5);
    p.t = static_cast<float>(i) * 1e-3f;
    p.ring = static_cast<uint16_t>(i % 6);
    c.points.push_back(p);
  }
  return c;
}

std::string ThrownMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

TEST(BagMessageTest, ParsesTheLivoxDefinitionWithItsDependencies) {
  const RosMessageDefinition def(kLivoxCustomMsgType, kLivoxCustomMsgDefinition, "bag");
  ASSERT_TRUE(def.Has("std_msgs/Header"));
  ASSERT_TRUE(def.Has("livox_ros_driver/CustomPoint"));
  const std::vector<RosMsgField>& top = def.Fields(kLivoxCustomMsgType);
  ASSERT_EQ(top.size(), 6u);
  EXPECT_EQ(top[0].type, "std_msgs/Header");  // "Header" resolved
  EXPECT_EQ(top[4].name, "rsvd");
  EXPECT_TRUE(top[4].is_array);
  EXPECT_EQ(top[4].fixed_count, 3u);
  EXPECT_EQ(top[5].type, "livox_ros_driver/CustomPoint");  // same package
  EXPECT_EQ(top[5].fixed_count, 0u);
  EXPECT_EQ(def.FixedSize("livox_ros_driver/CustomPoint"), std::optional<size_t>(19));
  EXPECT_EQ(def.FixedSize("std_msgs/Header"), std::nullopt);  // string frame_id
  EXPECT_EQ(def.FieldOffset("livox_ros_driver/CustomPoint", "x"), std::optional<size_t>(4));
  EXPECT_EQ(def.FieldOffset("livox_ros_driver/CustomPoint", "line"), std::optional<size_t>(18));
  EXPECT_EQ(def.FieldOffset("std_msgs/Header", "stamp"), std::optional<size_t>(4));
}

TEST(BagMessageTest, CustomMsgRoundTripKeepsPointsAndTimesToOneNanosecond) {
  const PointCloud in = SampleCloud();
  const std::vector<uint8_t> bytes = EncodeLivoxCustomMsg(in, 7, "livox_frame", 1);
  // header 4+8+4+11, timebase 8, point_num 4, lidar_id 1, rsvd 3, count 4, points 19 each
  EXPECT_EQ(bytes.size(), 27u + 20u + 50u * 19u);
  const RosMessageDefinition def(kLivoxCustomMsgType, kLivoxCustomMsgDefinition, "bag");
  const std::map<std::string, RosFieldSpan> top =
      SplitRosMessage(def, bytes.data(), bytes.size(), "m");
  EXPECT_EQ(top.at("points").count, 50u);
  EXPECT_EQ(top.at("header").size, 27u);
  const PointCloud out = DecodeLivoxCustomMsg(def, bytes.data(), bytes.size(), "m");
  EXPECT_EQ(out.stamp_ns, in.stamp_ns);
  ASSERT_EQ(out.size(), in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    EXPECT_EQ(out.points[i].x, in.points[i].x);
    EXPECT_EQ(out.points[i].y, in.points[i].y);
    EXPECT_EQ(out.points[i].z, in.points[i].z);
    EXPECT_EQ(out.points[i].intensity, in.points[i].intensity);
    EXPECT_EQ(out.points[i].ring, in.points[i].ring);
    EXPECT_NEAR(out.points[i].t, in.points[i].t, 1e-9);
  }
}

TEST(BagMessageTest, DecodesByNameAnotherFieldOrderAndDropsOriginPoints) {
  // A CustomPoint with the fields reordered and an extra one; the stamp is the
  // earliest kept point (offset 5 ns), not the timebase.
  const std::string text =
      "Header header\nuint8 extra_flag\nCustomPoint[] points\nuint64 timebase\n"
      "===\nMSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n"
      "===\nMSG: livox_ros_driver/CustomPoint\n"
      "float32 z\nfloat32 y\nfloat32 x\nuint8 line\nuint8 tag\nuint8 reflectivity\n"
      "float64 range  # extra\nuint32 offset_time\nint8 CONSTANT=3\n";
  const RosMessageDefinition def(kLivoxCustomMsgType, text, "bag");
  std::vector<uint8_t> b;
  Put<uint32_t>(&b, 0);
  Put<uint32_t>(&b, 1700000000);
  Put<uint32_t>(&b, 0);
  Put<uint32_t>(&b, 0);  // empty frame_id
  Put<uint8_t>(&b, 1);
  Put<uint32_t>(&b, 3);  // points
  const float xyz[3][3] = {{0, 0, 0}, {1, 2, 3}, {4, 5, 6}};
  const uint32_t offsets[3] = {0, 9, 5};
  for (int i = 0; i < 3; ++i) {
    Put<float>(&b, xyz[i][2]);
    Put<float>(&b, xyz[i][1]);
    Put<float>(&b, xyz[i][0]);
    Put<uint8_t>(&b, static_cast<uint8_t>(i));       // line
    Put<uint8_t>(&b, 0);                             // tag
    Put<uint8_t>(&b, static_cast<uint8_t>(10 * i));  // reflectivity
    Put<double>(&b, 1.5);
    Put<uint32_t>(&b, offsets[i]);
  }
  Put<uint64_t>(&b, 1700000000000000000ULL);
  const PointCloud c = DecodeLivoxCustomMsg(def, b.data(), b.size(), "m");
  ASSERT_EQ(c.size(), 2u);  // the point at the origin is dropped
  EXPECT_EQ(c.stamp_ns, 1700000000000000005);
  EXPECT_EQ(c.points[0].x, 1.0f);
  EXPECT_EQ(c.points[0].z, 3.0f);
  EXPECT_EQ(c.points[0].ring, 1);
  EXPECT_EQ(c.points[0].intensity, 10.0f);
  EXPECT_NEAR(c.points[0].t, 4e-9, 1e-15);
  EXPECT_EQ(c.points[1].t, 0.0f);
  EXPECT_EQ(c.points[1].x, 4.0f);
}

TEST(BagMessageTest, BadDefinitionsAndBytesAreInputErrors) {
  EXPECT_NE(ThrownMessage([] {
              RosMessageDefinition(
                  kLivoxCustomMsgType, "Header header\nuint64 timebase\n", "b.bag");
            }).find("std_msgs/Header, which the definition does not hold"),
            std::string::npos);
  EXPECT_NE(ThrownMessage([] {
              RosMessageDefinition("a/B", "uint8\n", "b.bag");
            }).find("b.bag:message definition of a/B line 1"),
            std::string::npos);
  const RosMessageDefinition def(kLivoxCustomMsgType, kLivoxCustomMsgDefinition, "bag");
  std::vector<uint8_t> bytes = EncodeLivoxCustomMsg(SampleCloud(), 0, "f", 0);
  bytes.resize(bytes.size() - 3);
  EXPECT_NE(ThrownMessage([&] {
              DecodeLivoxCustomMsg(def, bytes.data(), bytes.size(), "T m 4");
            }).find("T m 4: message ends inside field points"),
            std::string::npos);
  bytes = EncodeLivoxCustomMsg(SampleCloud(), 0, "f", 0);
  bytes.push_back(0);
  EXPECT_NE(ThrownMessage([&] {
              DecodeLivoxCustomMsg(def, bytes.data(), bytes.size(), "m");
            }).find("1 bytes after the last field"),
            std::string::npos);
  // A definition without timebase.
  const RosMessageDefinition other(kLivoxCustomMsgType,
                                   "uint32 n\nCustomPoint[] points\n===\nMSG: "
                                   "livox_ros_driver/CustomPoint\nuint32 offset_time\n",
                                   "bag");
  std::vector<uint8_t> b;
  Put<uint32_t>(&b, 0);
  Put<uint32_t>(&b, 0);
  EXPECT_NE(ThrownMessage([&] {
              DecodeLivoxCustomMsg(other, b.data(), b.size(), "m");
            }).find("has no field uint64 timebase"),
            std::string::npos);
}

TEST(BagMessageTest, DefinitionsWithoutAFiniteSizeAreInputErrors) {
  // A type that contains itself, directly or through another type.
  EXPECT_NE(ThrownMessage([] {
              RosMessageDefinition("a/B", "uint8 x\nB self\n", "b.bag");
            }).find("b.bag:message definition of a/B: type a/B contains itself (field a/B.self)"),
            std::string::npos);
  EXPECT_NE(ThrownMessage([] {
              RosMessageDefinition("a/B", "C c\n===\nMSG: a/C\nB[] b\n", "b.bag");
            }).find("contains itself"),
            std::string::npos);
  // An array length beyond any message (std::stoul would overflow on the first).
  EXPECT_NE(ThrownMessage(
                [] { RosMessageDefinition("a/B", "uint8[99999999999999999999999] x\n", "b.bag"); })
                .find("b.bag:message definition of a/B line 1: array length in "
                      "'uint8[99999999999999999999999]' exceeds 100000000"),
            std::string::npos);
  // Nested fixed arrays whose byte size overflows 64 bits (8 * 1e8^3 bytes).
  const RosMessageDefinition nested("a/B",
                                    "C[100000000] c\n===\nMSG: a/C\nD[100000000] d\n"
                                    "===\nMSG: a/D\nuint64[100000000] x\n",
                                    "b.bag");
  EXPECT_NE(
      ThrownMessage([&] { nested.FixedSize("a/B"); }).find("holds more than 1099511627776 bytes"),
      std::string::npos);
  const uint8_t bytes[8] = {};
  EXPECT_THROW(SplitRosMessage(nested, bytes, sizeof(bytes), "m"), InputError);
}

}  // namespace
}  // namespace lisfm
