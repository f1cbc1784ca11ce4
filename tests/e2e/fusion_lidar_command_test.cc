// `lisfm fusion --mode lidar` end to end on a short simulated recording (`lisfm
// simulate`, XT-32-like LiDAR, no calibration/IMU errors, 1 cm range noise; `lisfm
// lio` keyframes every 0.5 m): fused with the ground-truth poses the surfels lie on
// the scene mesh; the written trajectory read back gives the same map; bad input
// fails with exit 1 (input) or 2 (usage) and leaves no output folder.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/file_utils.h"
#include "core/geometry.h"
#include "tests/common/fusion_outputs.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using test::LisfmBinary;
using test::RunCommand;
using test::TempDir;

class FusionLidarCommand : public ::testing::Test {
 protected:
  // One 8 s recording and its lio output for all tests.
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    std::string out;
    ASSERT_EQ(RunCommand(LisfmBinary() + " simulate --output_path " + dir_->File("seq") +
                             " --duration 8 --camera_rate 0 --error_sources none "
                             "--Walk.stationary_s 0.5 --Walk.num_stops 2",
                         &out),
              0)
        << out;
    ASSERT_EQ(RunCommand(LisfmBinary() + " lio --input_path " + dir_->File("seq") +
                             " --output_path " + dir_->File("lio") + " --Lio.keyframe_distance 0.5",
                         &out),
              0)
        << out;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string Seq() { return dir_->File("seq"); }
  static std::string Lio() { return dir_->File("lio"); }
  static std::string Fusion(const std::string& args) {
    return LisfmBinary() + " fusion --mode lidar --input_path " + Seq() + " " + args;
  }
  static void ExpectFails(const std::string& args,
                          int code,
                          const std::string& message,
                          const std::string& output_path) {
    test::ExpectCommandFails(Fusion(args), code, message, output_path);
  }
  static TempDir* dir_;
};

TempDir* FusionLidarCommand::dir_ = nullptr;

// Ground-truth poses: the surfels lie on the scene mesh. The range noise is 1 cm
// (1-sigma, more at grazing incidence) before averaging; a keyframe misplaced by
// its 0.5 m spacing or a wrong extrinsic would put the median at decimetres.
TEST_F(FusionLidarCommand, GroundTruthPosesPutSurfelsOnTheScene) {
  TempDir tmp;
  const std::string out_dir = tmp.File("out");
  std::string out;
  ASSERT_EQ(RunCommand(Fusion("--lio_path " + Lio() + " --output_path " + out_dir +
                              " --pose_source groundtruth"),
                       &out),
            0)
      << out;
  EXPECT_NE(out.find("range image 2000x32"), std::string::npos) << out;
  for (const char* f : {"trajectory.txt",
                        "surfels.ply",
                        "fusion_summary.json",
                        "normals_first_keyframe.png",
                        "normals_last_keyframe.png",
                        "config.yaml"}) {
    EXPECT_TRUE(FileExists(out_dir + "/" + f)) << f;
  }
  const std::string summary = ReadFile(out_dir + "/fusion_summary.json");
  for (const char* key : {"\"mode\": \"lidar\"",
                          "\"keyframes\"",
                          "\"compression_ratio\"",
                          "\"bytes_per_surfel\": 44",
                          "\"stage_ms\"",
                          "\"surfels\""}) {
    EXPECT_NE(summary.find(key), std::string::npos) << key << "\n" << summary;
  }
  // One pose per lio keyframe.
  const std::string csv = ReadFile(Lio() + "/keyframes/keyframes.csv");
  const size_t keyframes = std::count(csv.begin(), csv.end(), '\n') - 1;
  ASSERT_GE(keyframes, 4u);
  const std::string trajectory = ReadFile(out_dir + "/trajectory.txt");
  size_t poses = 0;
  for (const std::string& line : SplitString(trajectory, "\n")) {
    poses += !line.empty() && line[0] != '#' ? 1 : 0;
  }
  EXPECT_EQ(poses, keyframes);

  const std::vector<double> distances =
      test::SurfelDistancesToScene(out_dir + "/surfels.ply", Seq() + "/scene.ply", 53, 20000);
  ASSERT_FALSE(distances.empty());
  const double median = distances[distances.size() / 2];
  EXPECT_LT(median, 0.01);
  RecordProperty("median_surface_distance_m", std::to_string(median));
  RecordProperty("p95_surface_distance_m", std::to_string(distances[distances.size() * 95 / 100]));

  // The written trajectory read back as --pose_source trajectory gives the same map.
  const std::string again = tmp.File("again");
  ASSERT_EQ(RunCommand(Fusion("--lio_path " + Lio() + " --output_path " + again +
                              " --pose_source trajectory --trajectory_path " + out_dir +
                              "/trajectory.txt"),
                       &out),
            0)
      << out;
  EXPECT_EQ(ReadFile(again + "/surfels.ply"), ReadFile(out_dir + "/surfels.ply"));

  // A trajectory without the stamp of keyframe 2 is bad input naming the stamp.
  std::string kept, missing_stamp;
  int n = 0;
  for (const std::string& line : SplitString(trajectory, "\n")) {
    if (line.empty()) continue;
    if (line[0] != '#' && ++n == 3) {
      missing_stamp = line.substr(0, line.find(' '));
      continue;
    }
    kept += line + "\n";
  }
  test::WriteText(tmp.File("gap.txt"), kept);
  const std::string stamp_s = missing_stamp.substr(0, missing_stamp.find('.') + 7);
  ExpectFails(
      "--lio_path " + Lio() + " --pose_source trajectory --trajectory_path " + tmp.File("gap.txt"),
      1,
      "expected a pose at keyframe 2",
      tmp.File("gap_out"));
  ExpectFails(
      "--lio_path " + Lio() + " --pose_source trajectory --trajectory_path " + tmp.File("gap.txt"),
      1,
      stamp_s,
      tmp.File("gap_out2"));
}

// lio's own keyframe poses are the default pose source.
TEST_F(FusionLidarCommand, LioPosesByDefault) {
  TempDir tmp;
  std::string out;
  ASSERT_EQ(RunCommand(Fusion("--lio_path " + Lio() + " --output_path " + tmp.File("out")), &out),
            0)
      << out;
  EXPECT_NE(out.find("poses: lio"), std::string::npos) << out;
  EXPECT_NE(ReadFile(tmp.File("out/config.yaml")).find("pose_source: lio"), std::string::npos);
}

TEST_F(FusionLidarCommand, BadInputFailsCleanly) {
  TempDir tmp;
  // Usage errors: exit 2.
  ExpectFails("", 2, "--mode lidar needs --lio_path", tmp.File("o1"));
  ExpectFails("--lio_path " + Lio() + " --pose_source icp", 2, "not icp", tmp.File("o2"));
  ExpectFails("--lio_path " + Lio() + " --pose_source trajectory",
              2,
              "--pose_source trajectory needs --trajectory_path",
              tmp.File("o3"));
  ExpectFails(
      "--lio_path " + Lio() + " --LidarFusion.max_range_m 0.1", 2, "LidarFusion.m", tmp.File("o4"));
  // A missing lio folder: exit 1.
  ExpectFails("--lio_path " + tmp.File("no_lio"), 1, tmp.File("no_lio"), tmp.File("o5"));
  // A keyframe cloud missing from the lio folder: exit 1, naming it.
  std::string out;
  const std::string lio = tmp.File("lio");
  ASSERT_EQ(RunCommand("cp -r " + Lio() + " " + lio, &out), 0) << out;
  std::vector<std::string> clouds;
  for (const auto& entry : std::filesystem::directory_iterator(lio + "/keyframes")) {
    if (entry.path().extension() == ".pcd") clouds.push_back(entry.path().string());
  }
  ASSERT_FALSE(clouds.empty());
  std::sort(clouds.begin(), clouds.end());
  const std::string removed = clouds[clouds.size() / 2];
  ASSERT_EQ(std::remove(removed.c_str()), 0);
  const std::string name = std::filesystem::path(removed).filename().string();
  ExpectFails("--lio_path " + lio, 1, name, tmp.File("o6"));
  // A damaged (truncated) keyframe cloud: exit 1, naming it.
  const std::string cloud = clouds.front();
  const std::string data = ReadFile(cloud);
  test::WriteText(cloud, data.substr(0, data.size() / 2));
  ASSERT_EQ(RunCommand("cp " + Lio() + "/keyframes/" +
                           std::filesystem::path(removed).filename().string() + " " + removed,
                       &out),
            0)
      << out;
  ExpectFails(
      "--lio_path " + lio, 1, std::filesystem::path(cloud).filename().string(), tmp.File("o7"));
}

}  // namespace
}  // namespace lisfm
