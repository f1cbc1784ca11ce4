// `lisfm lio` end to end: a short simulated sequence, then broken copies of it.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/file_utils.h"
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
  EXPECT_FALSE(DirExists(o + "/keyframes.tmp"));
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

TEST_F(LioCommandTest, UsageErrors) {
  std::string out;
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path " + dir_->File("seq") +
                                 " --output_path " + dir_->File("o4") + " --lidars 3",
                             &out),
            2);
  EXPECT_NE(out.find("--lidars"), std::string::npos) << out;
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " lio --input_path /nonexistent --output_path " +
                                 dir_->File("o5"),
                             &out),
            1);
  EXPECT_NE(out.find("/nonexistent"), std::string::npos) << out;
}

}  // namespace
}  // namespace lisfm
