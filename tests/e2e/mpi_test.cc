// The MPI path (core/mpi/mpi_world.h) end to end: `lisfm pose_slam` and
// `lisfm database_importer` under `mpirun -np 2` and `mpirun --oversubscribe
// -np 3` on a short simulated walk write the same bytes as one process without
// MPI; a rank that hits a corrupt keyframe file ends the run with a non-zero
// exit code and an error naming the file, and no output folder appears.
// Skips when mpirun is missing. Sets the Open MPI variables a root CI needs.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/file_utils.h"
#include "tests/common/mpi_outputs.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

class MpiTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    have_mpirun_ = test::PrepareMpirun();
    if (!have_mpirun_) return;
    std::string out;
    dir_ = new test::TempDir();
    // 14 s of office at 1 rig frame per second, rests at the start, middle and
    // end: 5 keyframes; pairs between every two of them (min_index_step 1).
    ok_ = test::RunCommand(test::LisfmBinary() +
                               " simulate --scene office --duration 14 --Walk.num_stops 3 "
                               "--camera_rate 1 --quiet 1 --output_path " +
                               dir_->File("seq"),
                           &out) == 0;
    ok_ = ok_ && test::RunCommand(test::LisfmBinary() + " lio --quiet 1 --input_path " +
                                      dir_->File("seq") + " --output_path " + dir_->File("lio"),
                                  &out) == 0;
    if (!ok_) std::cerr << out;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    if (!have_mpirun_) GTEST_SKIP() << "mpirun not found (apt install openmpi-bin)";
    ASSERT_TRUE(ok_);
  }

  // `lisfm <args>`, under mpirun with `ranks` processes when ranks > 0.
  static int Lisfm(int ranks, const std::string& args, std::string* out) {
    std::string mpirun =
        ranks > 0 ? "mpirun --oversubscribe --bind-to none -np " + std::to_string(ranks) + " " : "";
    // Under AddressSanitizer (scripts/test.sh --sanitize) the ranks run without leak
    // checking: Open MPI's components (dlopen'ed, some allocating on its own threads) keep
    // allocations past MPI_Finalize whose stacks end in unloaded modules, which no
    // suppression can name. The single-process runs of this test stay leak-checked.
    const char* asan = std::getenv("ASAN_OPTIONS");
    if (ranks > 0 && asan != nullptr) {
      mpirun = "ASAN_OPTIONS='" + std::string(asan) + ":detect_leaks=0' " + mpirun;
    }
    return test::RunCommand(mpirun + test::LisfmBinary() + " " + args, out);
  }
  static std::string PoseSlamArgs(const std::string& lio, const std::string& output) {
    return "pose_slam --quiet 1 --input_path " + dir_->File("seq") + " --lio_path " + lio +
           " --output_path " + output + " --PoseSlam.min_index_step 1";
  }

  static test::TempDir* dir_;
  static bool have_mpirun_, ok_;
};
test::TempDir* MpiTest::dir_ = nullptr;
bool MpiTest::have_mpirun_ = false;
bool MpiTest::ok_ = false;

// Single process twice (run-to-run reproducibility), then 1, 2 and 3 ranks
// (mpirun changes the process's heap layout and environment: the covariances
// must not depend on them).
TEST_F(MpiTest, PoseSlamOutputsDoNotDependOnTheNumberOfRanks) {
  std::string out;
  const std::vector<std::pair<int, std::string>> runs = {
      {0, "ps"}, {0, "ps_again"}, {1, "ps_np1"}, {2, "ps_np2"}, {3, "ps_np3"}};
  for (const auto& [ranks, name] : runs) {
    ASSERT_EQ(Lisfm(ranks, PoseSlamArgs(dir_->File("lio"), dir_->File(name)), &out), 0)
        << name << "\n"
        << out;
  }
  const std::string one = dir_->File("ps");
  for (const auto& [ranks, name] : runs) {
    const std::string other = dir_->File(name);
    for (const char* f : {"trajectory.txt",
                          "keyframes.txt",
                          "constraints.txt",
                          "keyframe_covariances.txt",
                          "map.pcd"}) {
      EXPECT_TRUE(ReadFile(one + "/" + f) == ReadFile(other + "/" + f)) << name << ": " << f;
    }
    EXPECT_EQ(test::JsonWithoutSeconds(one + "/pose_slam_summary.json"),
              test::JsonWithoutSeconds(other + "/pose_slam_summary.json"))
        << name;
    EXPECT_EQ(test::ConfigWithoutOutputPath(one + "/pose_slam_config.yaml"),
              test::ConfigWithoutOutputPath(other + "/pose_slam_config.yaml"))
        << name;
  }
  // The run had pairs to split (else the test would prove nothing).
  EXPECT_GE(ReadFile(one + "/constraints.txt").size(), 1000u);
}

TEST_F(MpiTest, DatabaseImporterOutputsDoNotDependOnTheNumberOfRanks) {
  std::string out;
  ASSERT_EQ(Lisfm(0, PoseSlamArgs(dir_->File("lio"), dir_->File("ps_for_db")), &out), 0) << out;
  for (const std::string source : {"map", "constraints"}) {
    const std::string args = "database_importer --quiet 1 --input_path " + dir_->File("seq") +
                             " --pose_slam_path " + dir_->File("ps_for_db") + " --lio_path " +
                             dir_->File("lio") + " --DatabaseImporter.covisibility_source " +
                             source + " --output_path ";
    const std::string one = dir_->File("db_" + source);
    ASSERT_EQ(Lisfm(0, args + one, &out), 0) << out;
    for (int ranks : {2, 3}) {
      const std::string other = one + "_np" + std::to_string(ranks);
      ASSERT_EQ(Lisfm(ranks, args + other, &out), 0) << source << " " << ranks << "\n" << out;
      for (const char* f : {"database.db",
                            "image_list.txt",
                            "pairs.txt",
                            "rig.yaml",
                            "rig_config.json",
                            "constraints.txt",
                            "covisibility.csv"}) {
        EXPECT_TRUE(ReadFile(one + "/" + f) == ReadFile(other + "/" + f))
            << source << ", " << ranks << " ranks: " << f;
      }
      EXPECT_EQ(test::JsonWithoutSeconds(one + "/importer_summary.json"),
                test::JsonWithoutSeconds(other + "/importer_summary.json"))
          << source << ", " << ranks << " ranks";
    }
    // Co-visibility voted for pairs (else the test would prove nothing).
    EXPECT_NE(ReadFile(one + "/covisibility.csv").find("covisibility"), std::string::npos)
        << source;
  }
}

// The last keyframe's cloud cut to its header: the ranks registering a pair
// with it fail; every rank exits non-zero, the error names the file, and no
// output folder appears.
TEST_F(MpiTest, CorruptKeyframeFailsTheWholeRun) {
  const std::string lio = dir_->File("lio_corrupt");
  fs::copy(dir_->File("lio"), lio, fs::copy_options::recursive);
  std::string last;
  for (const auto& entry : fs::directory_iterator(lio + "/keyframes")) {
    const std::string path = entry.path().string();
    if (entry.path().extension() == ".pcd" && path > last) last = path;
  }
  ASSERT_FALSE(last.empty());
  const std::string contents = ReadFile(last);
  const size_t data = contents.find("DATA binary");
  ASSERT_NE(data, std::string::npos);
  test::WriteText(last, contents.substr(0, data + 12) + "xyz");
  for (int ranks : {2, 3}) {
    const std::string output = dir_->File("ps_corrupt_np" + std::to_string(ranks));
    std::string out;
    EXPECT_NE(Lisfm(ranks, PoseSlamArgs(lio, output), &out), 0) << out;
    EXPECT_NE(out.find(fs::path(last).filename().string()), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(output)) << out;
  }
}

}  // namespace
}  // namespace lisfm
