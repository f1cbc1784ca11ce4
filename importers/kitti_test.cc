// A small generated KITTI odometry sequence (3 scans) -> a sequence folder;
// bad files are one InputError naming the file.
#include "importers/kitti.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

// Tr = cam0_from_velo of KITTI sequence 00 (rounded): x_cam = -y_velo, y_cam = -z_velo, z_cam =
// x_velo.
const char kCalib[] =
    "P0: 718.856 0 607.1928 0 0 718.856 185.2157 0 0 0 1 0\n"
    "P1: 718.856 0 607.1928 -386.1448 0 718.856 185.2157 0 0 0 1 0\n"
    "Tr: 0 -1 0 -0.004 0 0 -1 -0.076 1 0 0 -0.272\n";

void WriteScan(const std::string& path, const std::vector<std::vector<float>>& points) {
  std::ofstream out(path, std::ios::binary);
  for (const auto& p : points) out.write(reinterpret_cast<const char*>(p.data()), 16);
}

class KittiTest : public ::testing::Test {
 protected:
  void SetUp() override {
    seq_ = dir_.File("00");
    fs::create_directories(seq_ + "/velodyne");
    for (int i = 0; i < 3; ++i) {
      char name[32];
      std::snprintf(name, sizeof(name), "/velodyne/%06d.bin", i);
      WriteScan(seq_ + name,
                {{1.0f + i, 2.0f, 0.5f, 0.25f}, {-3.0f, 4.5f, -1.0f, 0.75f}, {10, 0, 0, 0}});
    }
    test::WriteText(seq_ + "/times.txt", "0.000000e+00\n1.035750e-01\n2.071500e-01\n");
    test::WriteText(seq_ + "/calib.txt", kCalib);
    test::WriteText(dir_.File("00.txt"),
                    "1 0 0 0 0 1 0 0 0 0 1 0\n"
                    "1 0 0 0.1 0 1 0 -0.01 0 0 1 1.2\n"
                    "0 0 1 0.3 0 1 0 0 -1 0 0 2.5\n");
  }

  std::string Import(const std::string& poses, TimestampNs origin = 0) {
    const std::string out = dir_.File("out" + std::to_string(counter_++));
    fs::create_directories(out);
    ImportKittiOdometry(seq_, poses, origin, out);
    return out;
  }

  std::string ErrorOf(const std::string& poses) {
    try {
      Import(poses);
    } catch (const InputError& e) {
      return e.what();
    }
    return "no InputError";
  }

  test::TempDir dir_;
  std::string seq_;
  int counter_ = 0;
};

TEST_F(KittiTest, ScansTimesCalibrationAndPosesBecomeASequenceFolder) {
  const std::string out = Import(dir_.File("00.txt"), 1000000000000000000);
  const std::string index = ReadFile(out + "/lidar0/data.csv");
  EXPECT_NE(index.find("1000000000103575000,1000000000103575000.pcd"), std::string::npos) << index;
  const PointCloud c = ReadPcd(out + "/lidar0/data/1000000000207150000.pcd");
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(c.points[0].x, 3.0f);
  EXPECT_EQ(c.points[1].y, 4.5f);
  EXPECT_EQ(c.points[1].intensity, 0.75f);
  EXPECT_EQ(c.points[1].t, 0.0f);
  const Rig rig = ReadRigYaml(out + "/rig.yaml");
  ASSERT_EQ(rig.lidars.size(), 1u);
  EXPECT_EQ(rig.lidars[0].rings, 64);
  // p_cam0 = Tr p_velo: the Velodyne's x axis is camera 0's z axis.
  const Vec3 p = rig.lidars[0].imu_from_lidar * Vec3(1, 0, 0);
  EXPECT_NEAR((p - Vec3(-0.004, -0.076, 0.728)).norm(), 0, 1e-9);
  const Trajectory gt = ReadTum(out + "/groundtruth.txt");
  ASSERT_EQ(gt.poses().size(), 3u);
  EXPECT_EQ(gt.poses()[1].t_ns, 1000000000103575000);
  EXPECT_NEAR((gt.poses()[1].pose.translation() - Vec3(0.1, -0.01, 1.2)).norm(), 0, 1e-12);
  EXPECT_NEAR((gt.poses()[2].pose * Vec3(1, 0, 0) - Vec3(0.3, 0, 1.5)).norm(), 0, 1e-12);
  // Without poses there is no groundtruth.txt.
  EXPECT_FALSE(fs::exists(Import("") + "/groundtruth.txt"));
}

TEST_F(KittiTest, BadFilesAreOneInputErrorNamingTheFile) {
  test::WriteText(dir_.File("short.txt"), "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0\n");
  EXPECT_NE(ErrorOf(dir_.File("short.txt")).find("short.txt:line 2: expected 12 numbers"),
            std::string::npos)
      << ErrorOf(dir_.File("short.txt"));
  test::WriteText(dir_.File("two.txt"), "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_NE(ErrorOf(dir_.File("two.txt")).find("2 poses for 3 scans"), std::string::npos);
  test::WriteText(seq_ + "/times.txt", "0\n0.2\n0.1\n");
  EXPECT_NE(ErrorOf("").find("times.txt:line 3: time not after"), std::string::npos);
  test::WriteText(seq_ + "/times.txt", "0\n0.1\n");
  EXPECT_NE(ErrorOf("").find("2 times for 3 scans"), std::string::npos);
  test::WriteText(seq_ + "/times.txt", "0\n0.1\n0.2\n");
  test::WriteText(seq_ + "/velodyne/000001.bin", "0123456789");
  EXPECT_NE(ErrorOf("").find("000001.bin: 10 bytes: not a multiple of 16"), std::string::npos)
      << ErrorOf("");
  test::WriteText(seq_ + "/calib.txt", "P0: 1 2 3\n");
  EXPECT_NE(ErrorOf("").find("calib.txt:Tr: no 'Tr:' line"), std::string::npos) << ErrorOf("");
}

}  // namespace
}  // namespace lisfm
