// `lisfm bag_exporter` then `lisfm bag_importer` on a short simulated
// recording: `lisfm lio` on the round-tripped folder writes the same
// trajectory.txt, byte for byte, as on the original folder; bad input is one
// `error:` line, a non-zero exit and no output folder.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

TEST(BagCommandsTest, ExportImportThenLioGivesTheSameTrajectory) {
  test::TempDir dir;
  const std::string bin = test::LisfmBinary();
  std::string out;
  ASSERT_EQ(test::RunCommand(bin +
                                 " simulate --duration 4 --camera_rate 1 --error_sources none "
                                 "--Walk.num_stops 3 --output_path " +
                                 dir.File("seq"),
                             &out),
            0)
      << out;
  ASSERT_EQ(test::RunCommand(bin + " bag_exporter --preset velodyne --input_path " +
                                 dir.File("seq") + " --output_path " + dir.File("rec.bag"),
                             &out),
            0)
      << out;
  ASSERT_EQ(test::RunCommand(bin + " bag_importer --preset velodyne --input_path " +
                                 dir.File("rec.bag") + " --rig_path " + dir.File("seq/rig.yaml") +
                                 " --output_path " + dir.File("back"),
                             &out),
            0)
      << out;
  EXPECT_NE(out.find("/velodyne_points"), std::string::npos) << out;  // the per-topic summary
  for (const std::string s : {"seq", "back"}) {
    ASSERT_EQ(test::RunCommand(bin + " lio --input_path " + dir.File(s) + " --output_path " +
                                   dir.File("lio_" + s),
                               &out),
              0)
        << out;
  }
  const std::string a = ReadFile(dir.File("lio_seq/trajectory.txt"));
  const std::string b = ReadFile(dir.File("lio_back/trajectory.txt"));
  EXPECT_GT(a.size(), 1000u);
  EXPECT_EQ(a, b);

  // --topics replaces the preset's topics: topics that are in the bag import
  // ...
  const std::string rig = " --rig_path " + dir.File("seq/rig.yaml");
  ASSERT_EQ(test::RunCommand(bin + " bag_importer --preset velodyne --input_path " +
                                 dir.File("rec.bag") + rig + " --output_path " +
                                 dir.File("renamed") +
                                 " --topics imu=/imu/data,cam1=/cam1/image_raw",
                             &out),
            0)
      << out;
  // ... and a renamed topic that is not in the bag is the usual missing-topic error.
  EXPECT_EQ(test::RunCommand(bin + " bag_importer --preset velodyne --input_path " +
                                 dir.File("rec.bag") + rig + " --output_path " +
                                 dir.File("o") + " --topics imu=/alphasense/imu",
                             &out),
            1);
  EXPECT_NE(out.find("topic /alphasense/imu"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir.File("o")));
  for (const std::string bad : {"gyro=/x", "imu", "lidar3=/x", "camx=/x"}) {
    EXPECT_EQ(test::RunCommand(bin + " bag_importer --preset velodyne --input_path " +
                                   dir.File("rec.bag") + " --output_path " + dir.File("o") +
                                   " --topics " + bad,
                               &out),
              2)
        << bad;
    EXPECT_NE(out.find("error: --topics"), std::string::npos) << bad << ": " << out;
    EXPECT_FALSE(fs::exists(dir.File("o")));
  }
}

TEST(BagCommandsTest, BadInputIsOneErrorAndNoOutputFolder) {
  test::TempDir dir;
  const std::string bin = test::LisfmBinary();
  std::string out;
  test::WriteText(dir.File("text.bag"), "not a bag\n");
  EXPECT_EQ(test::RunCommand(bin + " bag_importer --input_path " + dir.File("text.bag") +
                                 " --output_path " + dir.File("o"),
                             &out),
            1);
  EXPECT_NE(out.find("error: " + dir.File("text.bag") + ": not a readable ROS1 bag"),
            std::string::npos)
      << out;
  EXPECT_FALSE(fs::exists(dir.File("o")));
  EXPECT_EQ(test::RunCommand(bin + " bag_importer --preset moon --input_path " +
                                 dir.File("text.bag") + " --output_path " + dir.File("o"),
                             &out),
            2);
  EXPECT_NE(out.find("--preset moon"), std::string::npos) << out;
  EXPECT_EQ(test::RunCommand(bin + " bag_exporter --input_path " + dir.File("nothing") +
                                 " --output_path " + dir.File("o.bag"),
                             &out),
            1);
  EXPECT_FALSE(fs::exists(dir.File("o.bag")));
}

}  // namespace
}  // namespace lisfm
