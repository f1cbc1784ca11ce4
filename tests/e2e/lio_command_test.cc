// `lisfm lio` end to end: a short simulated sequence, then broken copies of it.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/rig.h"
#include "sim/simulator.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

class LioCommandTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    sim::SimulatorOptions options;
    options.duration = 4.0;
    options.camera_rate = 0;
    options.walk.num_stops = 3;
    options.error_sources = "none";
    options.output_path = dir_->File("seq");
    sim::Simulate(options, sim::PrepareRig(Rig(), "spinning"));
  }
  static void TearDownTestSuite() { delete dir_; }

  // A copy of the sequence with `file` replaced by `edit(contents)`.
  std::string BrokenCopy(const std::string& name,
                         const std::string& file,
                         const std::function<std::string(const std::string&)>& edit) {
    const std::string copy = dir_->File(name);
    fs::copy(dir_->File("seq"), copy, fs::copy_options::recursive);
    const std::string path = copy + "/" + file;
    const std::string text = ReadFile(path);
    test::WriteText(path, edit(text));
    return copy;
  }

  static test::TempDir* dir_;
};
test::TempDir* LioCommandTest::dir_ = nullptr;

TEST_F(LioCommandTest, RunsAndWritesOutputs) {
  std::string out;
  const std::string o = dir_->File("out");
  ASSERT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + dir_->File("seq") +
                                 " --output_path " + o,
                             &out),
            0)
      << out;
  for (const char* f : {"trajectory.txt", "scans.csv", "map.pcd", "lio_config.yaml",
                        "keyframes/keyframes.csv"}) {
    EXPECT_TRUE(FileExists(o + "/" + f)) << f;
  }
  EXPECT_NE(out.find("lio summary"), std::string::npos) << out;
  EXPECT_FALSE(FileExists(o + "/calibration.yaml")) << "written only with the estimation on";
  EXPECT_FALSE(DirExists(o + "/keyframes.tmp"));
  EXPECT_TRUE(FileExists(o + "/" + kOutputMarkerName));
  // The map keeps the measured intensities (the simulator's are 0..255 from
  // the surface albedo and incidence, never all zero).
  const PointCloud map = ReadPcd(o + "/map.pcd");
  ASSERT_GT(map.size(), 100u);
  size_t with_intensity = 0;
  for (const LidarPoint& p : map.points) with_intensity += p.intensity > 0 ? 1 : 0;
  EXPECT_GT(with_intensity, map.size() / 2);
}

// Like `lisfm simulate`: an existing output is replaced only with --overwrite 1,
// and only when lisfm wrote it.
TEST_F(LioCommandTest, ExistingOutputFolders) {
  const std::string base = test::LisfmBinary() + " lio --input_path " + dir_->File("seq") +
                           " --max_scans 12 --output_path ";
  const std::string o = dir_->File("again");
  std::string out;
  ASSERT_EQ(test::RunCommand(base + o, &out), 0) << out;
  EXPECT_EQ(test::RunCommand(base + o, &out), 2) << out;
  EXPECT_NE(out.find("--overwrite 1"), std::string::npos) << out;
  ASSERT_EQ(test::RunCommand(base + o + " --overwrite 1", &out), 0) << out;
  EXPECT_TRUE(FileExists(o + "/trajectory.txt"));

  const std::string mine = dir_->File("not_lisfm");
  CreateDirs(mine);
  test::WriteText(mine + "/notes.txt", "mine");
  EXPECT_EQ(test::RunCommand(base + mine + " --overwrite 1", &out), 2) << out;
  EXPECT_NE(out.find("lisfm did not write"), std::string::npos) << out;
  EXPECT_EQ(ReadFile(mine + "/notes.txt"), "mine");
  EXPECT_FALSE(FileExists(mine + "/trajectory.txt"));

  const std::string file = dir_->File("a_file");
  test::WriteText(file, "x");
  EXPECT_EQ(test::RunCommand(base + file + " --overwrite 1", &out), 2) << out;
  EXPECT_NE(out.find("is a file"), std::string::npos) << out;
}

// The output location is checked before the work: nothing is read or processed.
TEST_F(LioCommandTest, UnwritableOutputFailsBeforeTheWork) {
  const std::string file = dir_->File("plain_file");
  test::WriteText(file, "x");
  std::string out;
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + dir_->File("seq") +
                                 " --output_path " + file + "/out",
                             &out),
            1);
  EXPECT_NE(out.find(file + "/out"), std::string::npos) << out;
  EXPECT_EQ(out.find("lio: reading"), std::string::npos) << out;
}

// A corrupt scan in the middle of the sequence: the run fails naming the file
// and leaves no output folder, no temporary folder and no keyframes.tmp/.
TEST_F(LioCommandTest, FailureMidwayLeavesNoOutput) {
  const auto index = SplitString(ReadFile(dir_->File("seq/lidar0/data.csv")), "\n");
  ASSERT_GT(index.size(), 10u);
  const std::string middle = SplitString(index[index.size() / 2], ",").at(1);
  const std::string seq =
      BrokenCopy("bad_pcd", "lidar0/data/" + middle,
                 [](const std::string& t) { return t.substr(0, t.size() / 2); });
  const std::string parent = dir_->File("midway");
  CreateDirs(parent);
  std::string out;
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + seq +
                                 " --output_path " + parent + "/lio",
                             &out),
            1)
      << out;
  EXPECT_NE(out.find(middle), std::string::npos) << out;
  EXPECT_TRUE(fs::is_empty(parent)) << "left behind: " << fs::directory_iterator(parent)->path();
}

TEST_F(LioCommandTest, MalformedImuNamesFileAndLine) {
  const std::string seq = BrokenCopy("bad_imu", "imu0/data.csv", [](const std::string& t) {
    std::string s = t;
    const size_t line3 = s.find('\n', s.find('\n', s.find('\n') + 1) + 1);
    return s.substr(0, line3 + 1) + "12,abc,0,0,0,0,0\n" + s.substr(line3 + 1);
  });
  std::string out;
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + seq + " --output_path " +
                                 dir_->File("o1"),
                             &out),
            1);
  EXPECT_NE(out.find("imu0/data.csv:line 4"), std::string::npos) << out;
  EXPECT_FALSE(FileExists(dir_->File("o1/trajectory.txt")));
}

TEST_F(LioCommandTest, UnsortedScanIndexIsAnError) {
  const std::string seq = BrokenCopy("bad_index", "lidar0/data.csv", [](const std::string& t) {
    auto lines = SplitString(t, "\n");
    std::swap(lines[2], lines[3]);
    std::string s;
    for (const auto& l : lines) s += l + "\n";
    return s;
  });
  std::string out;
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + seq + " --output_path " +
                                 dir_->File("o2"),
                             &out),
            1);
  EXPECT_NE(out.find("lidar0/data.csv:line 4"), std::string::npos) << out;
  EXPECT_NE(out.find("not increasing"), std::string::npos) << out;
}

TEST_F(LioCommandTest, MissingLidarExtrinsicIsAnError) {
  const std::string seq = BrokenCopy("bad_rig", "rig.yaml", [](const std::string& t) {
    const size_t lidars = t.find("lidars:");
    const size_t key = t.find("T_imu_lidar", lidars);
    std::string s = t;
    s.replace(key, std::string("T_imu_lidar").size(), "T_imu_lidaX");
    return s;
  });
  std::string out;
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + seq + " --output_path " +
                                 dir_->File("o3"),
                             &out),
            1);
  EXPECT_NE(out.find("rig.yaml"), std::string::npos) << out;
  EXPECT_NE(out.find("T_imu_lidar"), std::string::npos) << out;
}

// With the online calibration on, calibration.yaml holds the estimate of the
// used LiDAR with its 1-sigma and the rig.yaml value it started from, and the
// summary names it.
TEST_F(LioCommandTest, OnlineCalibrationWritesCalibrationYaml) {
  std::string out;
  const std::string o = dir_->File("calibrated");
  ASSERT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + dir_->File("seq") +
                                 " --output_path " + o +
                                 " --Lio.estimate_extrinsic 1 --Lio.estimate_time_offset 1",
                             &out),
            0)
      << out;
  EXPECT_NE(out.find("lio calibration (calibration.yaml): lidar0: T_imu_lidar"), std::string::npos)
      << out;
  const std::string yaml = ReadFile(o + "/calibration.yaml");
  for (const char* key :
       {"lidars:\n  lidar0:\n    estimated: [extrinsic, time_offset]\n    T_imu_lidar:\n    - [",
        "\n    time_offset: ", "\n    rotation_std: [", "\n    translation_std: [",
        "\n    time_offset_std: ", "\n    T_imu_lidar_initial:\n    - [",
        "\n    time_offset_initial: 0\n"}) {
    EXPECT_NE(yaml.find(key), std::string::npos) << key << " missing in\n" << yaml;
  }
  EXPECT_NE(ReadFile(o + "/lio_config.yaml").find("Lio.estimate_extrinsic: 1"), std::string::npos);
}

TEST_F(LioCommandTest, UsageErrors) {
  std::string out;
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + dir_->File("seq") +
                                 " --output_path " + dir_->File("o4") + " --lidars 3",
                             &out),
            2);
  EXPECT_NE(out.find("--lidars"), std::string::npos) << out;
  // The LiDAR-only baseline has no IMU state to hold a calibration.
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + dir_->File("seq") +
                                 " --output_path " + dir_->File("o6") +
                                 " --method lidar_only --Lio.estimate_time_offset 1",
                             &out),
            2);
  EXPECT_NE(out.find("--Lio.estimate_time_offset need --method iekf"), std::string::npos) << out;
  EXPECT_FALSE(DirExists(dir_->File("o6")));
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path /nonexistent --output_path " +
                                 dir_->File("o5"),
                             &out),
            1);
  EXPECT_NE(out.find("/nonexistent"), std::string::npos) << out;
}

}  // namespace
}  // namespace lisfm
