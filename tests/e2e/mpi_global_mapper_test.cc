// `lisfm global_mapper` under MPI (core/mpi/mpi_world.h) end to end, on a
// synthetic rig database with pose priors and LiDAR constraints (the Ceres
// bundle adjustment path, as in the pipeline): two single-process runs and
// runs under `mpirun -np 2` and `mpirun --oversubscribe -np 3` (the view
// graph's pairs split across the ranks) write the same model bytes; a pair
// whose inlier match names a keypoint its image does not have fails the rank
// that processes it, and with it the whole run: non-zero exit, the error names
// the database and the pair, no output folder. Skips when mpirun is missing.
// Sets the Open MPI variables a root CI needs.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "colmap_ext/io/database.h"
#include "colmap_ext/testing/synthetic.h"
#include "core/file_utils.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/rig_io.h"
#include "tests/common/mpi_outputs.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

namespace fs = std::filesystem;

class MpiGlobalMapperTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    have_mpirun_ = test::PrepareMpirun();
    if (!have_mpirun_) return;
    dir_ = new test::TempDir();
    // 10 frames of a 3-camera rig in a room, noisy keypoints, wrong matches in
    // some pairs, position/rotation priors and LiDAR constraints.
    SyntheticDatasetOptions o;
    o.num_frames = 10;
    o.with_rig = true;
    o.num_cameras = 3;
    o.trajectory = SyntheticTrajectory::kRoom;
    o.num_points = 1500;
    o.pixel_noise = 0.5;
    o.outlier_match_ratio = 0.1;
    o.prior_position_noise = 0.02;
    o.prior_rotation_noise = 0.005;
    o.num_lidar_neighbors = 1;
    const SyntheticDataset dataset = SynthesizeDataset(o);
    num_pairs_ = WriteSyntheticDatabase(dataset, dir_->File("db.db")).num_pairs;
    WriteRigYaml(dir_->File("rig.yaml"), dataset.rig);
    WriteLidarConstraints(dataset.constraints, dir_->File("constraints.txt"));
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    if (!have_mpirun_) GTEST_SKIP() << "mpirun not found (apt install openmpi-bin)";
  }

  // `lisfm global_mapper` on `database`, under mpirun with `ranks` processes
  // when ranks > 0.
  static int Run(int ranks,
                 const std::string& database,
                 const std::string& output,
                 std::string* out) {
    std::string mpirun =
        ranks > 0 ? "mpirun --oversubscribe --bind-to none -np " + std::to_string(ranks) + " " : "";
    // Under AddressSanitizer the ranks run without leak checking (Open MPI's
    // allocations in unloaded modules; see mpi_test.cc).
    const char* asan = std::getenv("ASAN_OPTIONS");
    if (ranks > 0 && asan != nullptr) {
      mpirun = "ASAN_OPTIONS='" + std::string(asan) + ":detect_leaks=0' " + mpirun;
    }
    return test::RunCommand(
        mpirun + test::LisfmBinary() + " global_mapper --quiet 1" + " --database_path " + database +
            " --rig_path " + dir_->File("rig.yaml") + " --lidar_constraints_path " +
            dir_->File("constraints.txt") +
            " --BundleAdjustment.refine_cam_from_rig 1 --output_path " + output + " 2>&1",
        out);
  }

  static test::TempDir* dir_;
  static bool have_mpirun_;
  static size_t num_pairs_;
};
test::TempDir* MpiGlobalMapperTest::dir_ = nullptr;
bool MpiGlobalMapperTest::have_mpirun_ = false;
size_t MpiGlobalMapperTest::num_pairs_ = 0;

// Single process twice (run-to-run reproducibility with all threads), then 2
// and 3 ranks.
TEST_F(MpiGlobalMapperTest, ModelsDoNotDependOnTheNumberOfRanks) {
  // The view graph has pairs to split (else the test would prove nothing).
  ASSERT_GE(num_pairs_, 20u);
  std::string out;
  const std::vector<std::pair<int, std::string>> runs = {
      {0, "gm"}, {0, "gm_again"}, {2, "gm_np2"}, {3, "gm_np3"}};
  for (const auto& [ranks, name] : runs) {
    ASSERT_EQ(Run(ranks, dir_->File("db.db"), dir_->File(name), &out), 0) << name << "\n" << out;
  }
  const std::string one = dir_->File("gm");
  ASSERT_TRUE(FileExists(one + "/0/images.bin"));
  for (const auto& [ranks, name] : runs) {
    const std::string other = dir_->File(name);
    EXPECT_FALSE(FileExists(other + "/1/images.bin")) << name;
    for (const char* f : {"cameras.bin", "images.bin", "points3D.bin", "frames.bin", "rigs.bin"}) {
      EXPECT_TRUE(ReadFile(one + "/0/" + f) == ReadFile(other + "/0/" + f)) << name << ": " << f;
    }
    EXPECT_EQ(test::JsonWithoutSeconds(one + "/global_mapper_summary.json"),
              test::JsonWithoutSeconds(other + "/global_mapper_summary.json"))
        << name;
    EXPECT_EQ(test::ConfigWithoutOutputPath(one + "/global_mapper_config.yaml"),
              test::ConfigWithoutOutputPath(other + "/global_mapper_config.yaml"))
        << name;
  }
}

// The last pair of the list (the last rank's share) names keypoint 10^6.
TEST_F(MpiGlobalMapperTest, BadMatchOnOneRankFailsTheWholeRun) {
  const std::string db = dir_->File("bad.db");
  fs::copy_file(dir_->File("db.db"), db);
  image_pair_t pair_id = 0;
  {
    Database database(db, Database::OpenMode::kReadWrite);
    auto geometries = database.ReadAllTwoViewGeometries();
    ASSERT_FALSE(geometries.empty());
    auto& [id, geometry] = geometries.back();
    ASSERT_GT(geometry.inlier_matches.rows(), 0);
    geometry.inlier_matches(0, 0) = 1000000;
    image_t image_id1 = 0, image_id2 = 0;
    PairIdToImagePair(id, &image_id1, &image_id2);
    database.WriteTwoViewGeometry(image_id1, image_id2, geometry);
    pair_id = id;
  }
  for (int ranks : {0, 2, 3}) {
    const std::string output = dir_->File("gm_bad_np" + std::to_string(ranks));
    std::string out;
    EXPECT_NE(Run(ranks, db, output, &out), 0) << out;
    EXPECT_NE(out.find("two_view_geometries pair_id " + std::to_string(pair_id)), std::string::npos)
        << out;
    EXPECT_NE(out.find("bad.db"), std::string::npos) << out;
    if (ranks > 0) {
      EXPECT_NE(out.find("(MPI rank " + std::to_string(ranks - 1)), std::string::npos) << out;
    }
    EXPECT_FALSE(fs::exists(output)) << out;
  }
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
