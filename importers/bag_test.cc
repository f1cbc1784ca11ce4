// Bags written by the exporter (and by hand with rosbag_storage) read back by
// the importer: a lossless round trip of a simulated sequence folder, and one
// clear InputError per kind of bad bag.
#include "importers/bag.h"

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/rig_io.h"
#include "importers/sequence.h"
#include "sim/simulator.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

std::string PresetPath(const std::string& name) {
  return test::SourceDir() + "/configs/bags/" + name + ".yaml";
}

class BagTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    sim::SimulatorOptions options;
    options.duration = 2.0;
    options.camera_rate = 2;
    options.walk.num_stops = 2;
    options.walk.stationary_s = 0.3;
    options.error_sources = "none";
    options.output_path = dir_->File("seq");
    const Rig rig = ReadRigYaml(test::SourceDir() + "/configs/hilti2022.yaml");
    sim::Simulate(options, sim::PrepareRig(rig, "spinning"));
  }
  static void TearDownTestSuite() { delete dir_; }

  // Imports `bag` with `preset` into a fresh folder `name`; returns its path.
  std::string Import(const std::string& bag,
                     const BagPreset& preset,
                     const std::string& name,
                     double camera_rate_hz = 0) {
    const std::string out = dir_->File(name);
    fs::create_directories(out);
    BagImportOptions options;
    options.camera_rate_hz = camera_rate_hz;
    ImportBag(bag,
              ReadRigYaml(dir_->File("seq/rig.yaml")),
              ReadFile(dir_->File("seq/rig.yaml")),
              preset,
              options,
              out);
    return out;
  }

  // Expects ImportBag to throw an InputError containing every one of `needles`.
  void ExpectImportError(const std::string& bag,
                         const BagPreset& preset,
                         const std::vector<std::string>& needles) {
    const std::string out = dir_->File("bad_" + std::to_string(bad_counter_++));
    fs::create_directories(out);
    try {
      ImportBag(bag,
                ReadRigYaml(dir_->File("seq/rig.yaml")),
                ReadFile(dir_->File("seq/rig.yaml")),
                preset,
                BagImportOptions(),
                out);
      ADD_FAILURE() << "no error for " << bag;
    } catch (const InputError& e) {
      const std::string what = e.what();
      for (const std::string& n : needles) EXPECT_NE(what.find(n), std::string::npos) << what;
    }
  }

  static test::TempDir* dir_;
  int bad_counter_ = 0;
};
test::TempDir* BagTest::dir_ = nullptr;

void ExpectSameFolder(const std::string& a_root, const std::string& b_root, bool exact_times) {
  const Sequence a = ReadSequence(a_root);
  const Sequence b = ReadSequence(b_root);
  ASSERT_EQ(a.imu.size(), b.imu.size());
  for (size_t i = 0; i < a.imu.size(); ++i) {
    ASSERT_EQ(a.imu[i].t_ns, b.imu[i].t_ns) << i;
    ASSERT_EQ(a.imu[i].gyro, b.imu[i].gyro) << i;
    ASSERT_EQ(a.imu[i].accel, b.imu[i].accel) << i;
  }
  ASSERT_EQ(a.lidar_scans.size(), b.lidar_scans.size());
  for (size_t k = 0; k < a.lidar_scans.size(); ++k) {
    ASSERT_EQ(a.lidar_scans[k].size(), b.lidar_scans[k].size());
    for (size_t i = 0; i < a.lidar_scans[k].size(); ++i) {
      ASSERT_EQ(a.lidar_scans[k][i].t_ns, b.lidar_scans[k][i].t_ns);
      const PointCloud ca = ReadPcd(a.lidar_scans[k][i].path);
      const PointCloud cb = ReadPcd(b.lidar_scans[k][i].path);
      ASSERT_EQ(ca.size(), cb.size());
      for (size_t j = 0; j < ca.size(); ++j) {
        ASSERT_EQ(ca.points[j].x, cb.points[j].x);
        ASSERT_EQ(ca.points[j].y, cb.points[j].y);
        ASSERT_EQ(ca.points[j].z, cb.points[j].z);
        ASSERT_EQ(ca.points[j].intensity, cb.points[j].intensity);
        ASSERT_EQ(ca.points[j].ring, cb.points[j].ring);
        if (exact_times) {
          ASSERT_EQ(ca.points[j].t, cb.points[j].t);
        } else {
          ASSERT_NEAR(ca.points[j].t, cb.points[j].t, 2.4e-7);  // float64 s at 1.7e9 s
        }
      }
    }
  }
  ASSERT_EQ(a.camera_frames.size(), b.camera_frames.size());
  for (size_t k = 0; k < a.camera_frames.size(); ++k) {
    ASSERT_EQ(a.camera_frames[k].size(), b.camera_frames[k].size());
    for (size_t i = 0; i < a.camera_frames[k].size(); ++i) {
      ASSERT_EQ(a.camera_frames[k][i].t_ns, b.camera_frames[k][i].t_ns);
      const cv::Mat ia = cv::imread(a.camera_frames[k][i].path, cv::IMREAD_UNCHANGED);
      const cv::Mat ib = cv::imread(b.camera_frames[k][i].path, cv::IMREAD_UNCHANGED);
      ASSERT_FALSE(ia.empty());
      ASSERT_EQ(ia.type(), ib.type());
      ASSERT_EQ(ia.size(), ib.size());
      ASSERT_EQ(cv::norm(ia, ib, cv::NORM_INF), 0.0);
    }
  }
  EXPECT_EQ(RigToYaml(a.rig), RigToYaml(b.rig));
}

TEST_F(BagTest, VelodyneLayoutRoundTripIsLossless) {
  const std::string bag = dir_->File("velodyne.bag");
  const BagPreset preset = ReadBagPreset(PresetPath("velodyne"));
  const BagExportSummary e = ExportBag(dir_->File("seq"), preset, bag);
  EXPECT_GT(e.num_imu, 100u);
  EXPECT_GT(e.num_scans, 10u);
  EXPECT_GT(e.num_images, 0u);
  ExpectSameFolder(dir_->File("seq"), Import(bag, preset, "velodyne_seq"), true);
}

TEST_F(BagTest, CompressedBagsRoundTripLosslessly) {
  // The first 5 scans and the IMU, no images (bz2 is slow).
  const std::string small = dir_->File("small");
  fs::create_directories(small + "/lidar0/data");
  fs::copy(dir_->File("seq/rig.yaml"), small + "/rig.yaml");
  fs::copy(dir_->File("seq/imu0"), small + "/imu0");
  std::string index = "#timestamp [ns],filename\n";
  const Sequence seq = ReadSequence(dir_->File("seq"));
  for (const SensorFile& f : seq.lidar_scans[0]) {
    if (std::count(index.begin(), index.end(), '\n') > 5) break;
    const std::string name = fs::path(f.path).filename().string();
    fs::copy(f.path, small + "/lidar0/data/" + name);
    index += std::to_string(f.t_ns) + "," + name + "\n";
  }
  test::WriteText(small + "/lidar0/data.csv", index);
  const BagPreset preset = ReadBagPreset(PresetPath("velodyne"));
  for (const std::string compression : {"lz4", "bz2"}) {
    const std::string bag = dir_->File(compression + ".bag");
    ExportBag(small, preset, bag, compression);
    ExpectSameFolder(small, Import(bag, preset, compression + "_seq"), true);
  }
}

TEST_F(BagTest, Hilti2022LayoutRoundTripKeepsEverythingButSubMicrosecondTimes) {
  const std::string bag = dir_->File("hilti.bag");
  const BagPreset preset = ReadBagPreset(PresetPath("hilti2022"));
  ExportBag(dir_->File("seq"), preset, bag);
  const std::string seq1 = Import(bag, preset, "hilti_seq");
  ExpectSameFolder(dir_->File("seq"), seq1, false);
  // bag -> folder -> bag -> folder: the second round changes nothing.
  const std::string bag2 = dir_->File("hilti2.bag");
  ExportBag(seq1, preset, bag2);
  ExpectSameFolder(seq1, Import(bag2, preset, "hilti_seq2"), true);
}

TEST_F(BagTest, ASplitBagReadsAsOne) {
  const BagPreset preset = ReadBagPreset(PresetPath("velodyne"));
  const std::string whole = dir_->File("whole.bag");
  ExportBag(dir_->File("seq"), preset, whole);
  // Split by receive time into three files, as `rosbag record --split` does.
  const std::string parts = dir_->File("parts");
  fs::create_directories(parts);
  {
    rosbag::Bag in(whole, rosbag::bagmode::Read);
    rosbag::View view(in);
    const double t0 = view.getBeginTime().toSec(), t1 = view.getEndTime().toSec();
    std::vector<std::unique_ptr<rosbag::Bag>> out;
    for (int i = 0; i < 3; ++i) {
      out.push_back(std::make_unique<rosbag::Bag>(parts + "/rec_" + std::to_string(i) + ".bag",
                                                  rosbag::bagmode::Write));
    }
    for (const rosbag::MessageInstance& m : view) {
      const int i = std::min(2, static_cast<int>(3 * (m.getTime().toSec() - t0) / (t1 - t0)));
      out[i]->write(m.getTopic(), m.getTime(), m);
    }
    for (auto& b : out) b->close();
  }
  const std::string direct = Import(whole, preset, "whole_seq");
  const std::string list = parts + "/rec_2.bag," + parts + "/rec_0.bag," + parts + "/rec_1.bag";
  EXPECT_EQ(ExpandBagPaths(parts).size(), 3u);
  EXPECT_EQ(ExpandBagPaths(parts + "/rec_*.bag"), ExpandBagPaths(parts));
  ExpectSameFolder(direct, Import(list, preset, "split_list_seq"), true);
  ExpectSameFolder(direct, Import(parts, preset, "split_folder_seq"), true);
  ExpectSameFolder(direct, Import(parts + "/rec_[0-2].bag", preset, "split_glob_seq"), true);
  EXPECT_THROW(ExpandBagPaths(parts + "/none_*.bag"), InputError);
  EXPECT_THROW(ExpandBagPaths(parts + "/rec_0.bag," + parts + "/rec_0.bag"), InputError);
  EXPECT_THROW(ExpandBagPaths(parts + "/rec_9.bag"), InputError);
}

TEST_F(BagTest, CameraRateKeepsFramesAtMostThatOften) {
  const std::string bag = dir_->File("rate.bag");
  const BagPreset preset = ReadBagPreset(PresetPath("velodyne"));
  ExportBag(dir_->File("seq"), preset, bag);
  const Sequence all = ReadSequence(dir_->File("seq"));
  const Sequence some = ReadSequence(Import(bag, preset, "rate_seq", 1.0));
  ASSERT_FALSE(all.camera_frames.empty());
  ASSERT_GE(all.camera_frames[0].size(), 4u);  // 2 Hz over 2 s
  for (size_t k = 0; k < some.camera_frames.size(); ++k) {
    EXPECT_EQ(some.camera_frames[k].size(), (all.camera_frames[k].size() + 1) / 2) << k;
    for (size_t i = 1; i < some.camera_frames[k].size(); ++i) {
      EXPECT_GE(some.camera_frames[k][i].t_ns - some.camera_frames[k][i - 1].t_ns, 900000000);
    }
  }
}

TEST_F(BagTest, CameraTimeShiftIsAppliedOnceAtImport) {
  const std::string bag = dir_->File("shift.bag");
  const BagPreset preset = ReadBagPreset(PresetPath("velodyne"));
  ExportBag(dir_->File("seq"), preset, bag);
  Rig rig = ReadRigYaml(dir_->File("seq/rig.yaml"));
  ASSERT_FALSE(rig.cameras.empty());
  for (size_t k = 0; k < rig.cameras.size(); ++k) rig.cameras[k].timeshift_cam_imu_s = 0.002 * k;
  const std::string out = dir_->File("shift_seq");
  fs::create_directories(out);
  ImportBag(bag,
            rig,
            FolderRigYaml(rig, ReadFile(dir_->File("seq/rig.yaml"))),
            preset,
            BagImportOptions(),
            out);
  const Sequence a = ReadSequence(dir_->File("seq"));
  const Sequence b = ReadSequence(out);
  for (size_t k = 0; k < b.camera_frames.size(); ++k) {
    EXPECT_EQ(b.rig.cameras[k].timeshift_cam_imu_s, 0.0) << k;  // not applied a second time
    ASSERT_EQ(a.camera_frames[k].size(), b.camera_frames[k].size());
    for (size_t i = 0; i < a.camera_frames[k].size(); ++i) {
      EXPECT_EQ(b.camera_frames[k][i].t_ns, a.camera_frames[k][i].t_ns + 2000000 * int64_t(k));
    }
  }
  ASSERT_EQ(a.lidar_scans[0].size(), b.lidar_scans[0].size());
  EXPECT_EQ(a.lidar_scans[0][3].t_ns, b.lidar_scans[0][3].t_ns);
  // Without shifts the calibration file is copied as it is.
  EXPECT_EQ(FolderRigYaml(a.rig, "text"), "text");
}

// Walks the top-level records of the bag bytes `bytes` and calls `patch(data_at,
// data_len)` (data_at: the record's first data byte) for each record whose header has
// op `op` until it returns true; returns whether one did.
bool PatchFirstRecord(std::string* bytes,
                      char op,
                      const std::function<bool(size_t, uint32_t)>& patch) {
  size_t pos = bytes->find('\n') + 1;
  while (pos + 8 <= bytes->size()) {
    uint32_t header_len = 0, data_len = 0;
    std::memcpy(&header_len, bytes->data() + pos, 4);
    const std::string header = bytes->substr(pos + 4, header_len);
    std::memcpy(&data_len, bytes->data() + pos + 4 + header_len, 4);
    if (header.find(std::string("op=") + op) != std::string::npos &&
        patch(pos + 8 + header_len, data_len)) {
      return true;
    }
    pos += 8 + size_t{header_len} + data_len;
  }
  return false;
}

TEST_F(BagTest, BadBagsAreOneInputErrorNamingBagTopicAndMessage) {
  const BagPreset velodyne = ReadBagPreset(PresetPath("velodyne"));
  const std::string good = dir_->File("good.bag");
  ExportBag(dir_->File("seq"), velodyne, good);

  // Not a bag at all.
  const std::string text = dir_->File("not_a.bag");
  test::WriteText(text, "hello, I am not a bag\n");
  ExpectImportError(text, velodyne, {text, "not a readable ROS1 bag"});

  // Truncated: the first 60 % of a valid bag (no index at the end).
  const std::string truncated = dir_->File("truncated.bag");
  {
    const std::string bytes = ReadFile(good);
    test::WriteText(truncated, bytes.substr(0, bytes.size() * 6 / 10));
  }
  ExpectImportError(truncated, velodyne, {truncated, "truncated, unindexed or corrupted"});

  // A record length past the end of the file (rosbag_storage would allocate it):
  // the bag header record at byte 13, after "#ROSBAG V2.0\n", announces 4 GiB.
  const std::string huge_record = dir_->File("huge_record.bag");
  {
    std::string bytes = ReadFile(good);
    bytes.replace(13, 4, "\xf0\xff\xff\xff");
    test::WriteText(huge_record, bytes);
  }
  ExpectImportError(huge_record,
                    velodyne,
                    {huge_record,
                     "truncated, unindexed or corrupted",
                     "record at byte 13: header of 4294967280 bytes"});

  // A version line that does not end after "V2.0" (rosbag_storage reads up to the
  // newline): the records after it are checked all the same.
  const std::string long_version = dir_->File("long_version.bag");
  {
    std::string bytes = ReadFile(good);
    bytes.replace(12, 1, "\xfa\n");
    bytes.replace(14, 4, "\xf0\xff\xff\xff");
    test::WriteText(long_version, bytes);
  }
  ExpectImportError(
      long_version, velodyne, {long_version, "record at byte 14: header of 4294967280 bytes"});

  // Another format version.
  const std::string old_version = dir_->File("old_version.bag");
  {
    std::string bytes = ReadFile(good);
    bytes.replace(9, 3, "1.2");
    test::WriteText(old_version, bytes);
  }
  ExpectImportError(old_version, velodyne, {old_version, "bag format version 1.2"});

  // The bag header's index_pos pointing into the middle of a record (rosbag_storage
  // would read a record length from there).
  const std::string bad_index = dir_->File("bad_index_pos.bag");
  {
    std::string bytes = ReadFile(good);
    const size_t key = bytes.find("index_pos=");
    ASSERT_NE(key, std::string::npos);
    uint64_t index_pos = 0;
    std::memcpy(&index_pos, bytes.data() + key + 10, 8);
    index_pos += 3;
    std::memcpy(bytes.data() + key + 10, &index_pos, 8);
    test::WriteText(bad_index, bytes);
  }
  ExpectImportError(bad_index,
                    velodyne,
                    {bad_index, "record at byte 13: index_pos", "is not the start of a record"});

  // An index entry whose message offset is not a record start inside its (uncompressed)
  // chunk: rosbag_storage would parse a record header from the middle of one.
  const std::string moved_offset = dir_->File("moved_offset.bag");
  {
    std::string bytes = ReadFile(good);
    ASSERT_TRUE(PatchFirstRecord(&bytes, '\x04', [&](size_t data_at, uint32_t data_len) {
      if (data_len < 12) return false;
      const size_t at = data_at + 8;  // the first entry's offset
      uint32_t offset = 0;
      std::memcpy(&offset, bytes.data() + at, 4);
      ++offset;
      std::memcpy(bytes.data() + at, &offset, 4);
      return true;
    }));
    test::WriteText(moved_offset, bytes);
  }
  ExpectImportError(moved_offset,
                    velodyne,
                    {moved_offset, "message offset", "is not a record start in its chunk"});

  // A header field length past its record's header inside an uncompressed chunk
  // (ros::Header::parse would read past the chunk's buffer).
  const std::string long_field = dir_->File("long_field.bag");
  {
    std::string bytes = ReadFile(good);
    ASSERT_TRUE(PatchFirstRecord(&bytes, '\x05', [&](size_t data_at, uint32_t) {
      // chunk data: u32 inner header length, then the inner header's first field length
      const uint32_t too_long = 60000;
      std::memcpy(bytes.data() + data_at + 4, &too_long, 4);
      return true;
    }));
    test::WriteText(long_field, bytes);
  }
  ExpectImportError(long_field,
                    velodyne,
                    {long_field,
                     "record at chunk offset 0: header field of 60000 bytes past "
                     "the header"});

  // A header that ends inside a field length (ros::Header::parse reads all 4 bytes): the
  // bag header record at byte 13 keeps its first field and 2 bytes of the next one.
  const std::string cut_field = dir_->File("cut_field.bag");
  {
    std::string bytes = ReadFile(good);
    uint32_t first_field = 0;
    std::memcpy(&first_field, bytes.data() + 17, 4);
    const uint32_t header_len = 4 + first_field + 2;
    std::memcpy(bytes.data() + 13, &header_len, 4);
    test::WriteText(cut_field, bytes);
  }
  ExpectImportError(cut_field,
                    velodyne,
                    {cut_field, "record at byte 13: header ends 2 bytes into a field length"});

  // A corrupted lz4 chunk in the middle of a bag.
  const std::string corrupted = dir_->File("corrupted.bag");
  {
    ExportBag(dir_->File("seq"), velodyne, corrupted, "lz4");
    std::string bytes = ReadFile(corrupted);
    for (size_t i = bytes.size() / 2; i < bytes.size() / 2 + 4096; ++i) {
      bytes[i] = static_cast<char>(bytes[i] * 7 + 13);
    }
    test::WriteText(corrupted, bytes);
  }
  ExpectImportError(corrupted, velodyne, {corrupted, "lz4 data does not decompress to the"});

  // A preset whose IMU topic the bag does not have.
  BagPreset no_imu = velodyne;
  no_imu.imu_topic = "/alphasense/imu";
  ExpectImportError(good, no_imu, {good, "/alphasense/imu", "not in the bag"});

  // A preset expecting Hesai's `timestamp` on a Velodyne-layout bag.
  BagPreset no_time = velodyne;
  no_time.lidar_fields.time.name = "timestamp";
  ExpectImportError(
      good, no_time, {good, "topic /velodyne_points message 0", "no per-point time field"});

  // Hand-written bags: an unsupported image encoding, IMU out of order.
  const std::string hand = dir_->File("hand.bag");
  {
    rosbag::Bag bag(hand, rosbag::bagmode::Write);
    for (int i = 0; i < 3; ++i) {
      sensor_msgs::Imu m;
      m.header.stamp = ros::Time(100, i == 2 ? 0 : 1000 * (i + 1));  // message 2 goes back
      bag.write("/imu/data", ros::Time(100, 1000 * (i + 1)), m);
    }
    sensor_msgs::Image image;
    image.header.stamp = ros::Time(100, 500);
    image.width = 2;
    image.height = 2;
    image.encoding = "16UC1";
    image.step = 4;
    image.data.assign(8, 0);
    bag.write("/cam0/image_raw", ros::Time(100, 500), image);
    bag.write("/cam0/image_raw", ros::Time(100, 600), image);
    bag.close();
  }
  BagPreset imu_only = velodyne;
  imu_only.lidar_topics.clear();
  imu_only.camera_topics.clear();
  ExpectImportError(hand, imu_only, {hand, "topic /imu/data message 2", "not after the previous"});
  BagPreset with_camera = imu_only;
  with_camera.camera_topics = {"/cam0/image_raw"};
  ExpectImportError(hand,
                    with_camera,
                    {hand, "topic /cam0/image_raw message 0", "encoding '16UC1' not supported"});

  // A topic of the wrong type.
  BagPreset wrong_type = imu_only;
  wrong_type.imu_topic = "/cam0/image_raw";
  ExpectImportError(hand, wrong_type, {hand, "/cam0/image_raw", "expected sensor_msgs/Imu"});
}

// HILTI 2021 rig, Ouster-like + Livox-like LiDARs: Ouster PointCloud2 (`t`
// uint32 ns) -> lidar0, Livox CustomMsg (timebase + offset_time, reflectivity
// uint8) -> lidar1.
void ExpectSameHilti2021Folder(const std::string& a_root, const std::string& b_root) {
  const Sequence a = ReadSequence(a_root);
  const Sequence b = ReadSequence(b_root);
  ASSERT_EQ(a.imu.size(), b.imu.size());
  for (size_t i = 0; i < a.imu.size(); ++i) {
    ASSERT_EQ(a.imu[i].t_ns, b.imu[i].t_ns) << i;
    ASSERT_EQ(a.imu[i].gyro, b.imu[i].gyro) << i;
  }
  ASSERT_EQ(a.lidar_scans.size(), 2u);
  ASSERT_EQ(b.lidar_scans.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    ASSERT_EQ(a.lidar_scans[k].size(), b.lidar_scans[k].size()) << k;
    ASSERT_GT(a.lidar_scans[k].size(), 5u) << k;
    for (size_t i = 0; i < a.lidar_scans[k].size(); ++i) {
      ASSERT_EQ(a.lidar_scans[k][i].t_ns, b.lidar_scans[k][i].t_ns) << k << " " << i;
      const PointCloud ca = ReadPcd(a.lidar_scans[k][i].path);
      const PointCloud cb = ReadPcd(b.lidar_scans[k][i].path);
      ASSERT_EQ(ca.size(), cb.size());
      for (size_t j = 0; j < ca.size(); ++j) {
        ASSERT_EQ(ca.points[j].x, cb.points[j].x);
        ASSERT_EQ(ca.points[j].y, cb.points[j].y);
        ASSERT_EQ(ca.points[j].z, cb.points[j].z);
        ASSERT_EQ(ca.points[j].ring, cb.points[j].ring);
        // 1 ns integer times, then float32 seconds (half an ulp: 3.7 ns at 0.1 s)
        ASSERT_NEAR(ca.points[j].t, cb.points[j].t, 5e-9) << k << " " << i << " " << j;
        if (k == 0) {
          ASSERT_EQ(ca.points[j].intensity, cb.points[j].intensity);
        } else {  // Livox reflectivity is a uint8
          ASSERT_NEAR(ca.points[j].intensity, cb.points[j].intensity, 0.5);
          ASSERT_EQ(cb.points[j].intensity, std::round(cb.points[j].intensity));
        }
      }
    }
  }
}

TEST(BagHilti2021Test, OusterAndLivoxRoundTrip) {
  test::TempDir dir;
  sim::SimulatorOptions options;
  options.duration = 1.0;
  options.camera_rate = 0;
  options.error_sources = "none";
  options.output_path = dir.File("seq");
  options.lidars = "spinning,livox";
  sim::Simulate(options, ReadRigYaml(test::SourceDir() + "/configs/hilti2021.yaml"));
  const BagPreset preset = ReadBagPreset(PresetPath("hilti2021"));
  ASSERT_EQ(preset.lidar_types.size(), 2u);
  EXPECT_EQ(preset.lidar_types[1], "livox_ros_driver/CustomMsg");
  const std::string bag = dir.File("h21.bag");
  const BagExportSummary e = ExportBag(dir.File("seq"), preset, bag, "lz4");
  {
    rosbag::Bag b(bag, rosbag::bagmode::Read);
    rosbag::View view(b);
    std::map<std::string, std::string> types;
    for (const rosbag::ConnectionInfo* c : view.getConnections()) types[c->topic] = c->datatype;
    EXPECT_EQ(types["/livox/lidar"], "livox_ros_driver/CustomMsg");
    EXPECT_EQ(types["/os_cloud_node/points"], "sensor_msgs/PointCloud2");
    EXPECT_EQ(types["/alphasense/imu"], "sensor_msgs/Imu");
  }
  const Sequence seq = ReadSequence(dir.File("seq"));
  EXPECT_EQ(e.num_scans, seq.lidar_scans[0].size() + seq.lidar_scans[1].size());
  auto import = [&](const std::string& from, const std::string& name) {
    const std::string out = dir.File(name);
    fs::create_directories(out);
    ImportBag(from,
              ReadRigYaml(dir.File("seq/rig.yaml")),
              ReadFile(dir.File("seq/rig.yaml")),
              preset,
              BagImportOptions(),
              out);
    return out;
  };
  const std::string seq1 = import(bag, "seq1");
  ExpectSameHilti2021Folder(dir.File("seq"), seq1);
  const std::string bag2 = dir.File("h21b.bag");
  ExportBag(seq1, preset, bag2);
  ExpectSameHilti2021Folder(seq1, import(bag2, "seq2"));
}

TEST(BagPresetTest, BadPresetsNameFileAndKey) {
  test::TempDir dir;
  const std::string path = dir.File("p.yaml");
  test::WriteText(path, "imu_topic: /imu\nlidar_fields: {time_unit: ms}\n");
  try {
    ReadBagPreset(path);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lidar_fields.time_unit"), std::string::npos) << e.what();
  }
  test::WriteText(path, "lidar_topics: [/p]\n");
  EXPECT_THROW(ReadBagPreset(path), InputError);  // no imu_topic
  // A preset cut after "lidar_fields:" (no mapping) must not fall back to the defaults.
  test::WriteText(path, "imu_topic: /imu\nlidar_topics: [/p]\nlidar_fields:\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadBagPreset(path); },
                                     {path, "lidar_fields", "expected a mapping"}));
}

}  // namespace
}  // namespace lisfm
