// `lisfm database_importer` end to end on a short simulated recording at the
// simulator's default (realistic) calibration errors: lio, pose_slam, the importer, stock
// `colmap feature_extractor` + `colmap matches_importer --match_type pairs` on
// its database and pair list, then `lisfm global_mapper` with its rig and
// constraints, scored against the simulator's ground truth (truth/rig.yaml).
// Then bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "colmap_ext/io/database.h"
#include "colmap_ext/io/model_io.h"
#include "colmap_ext/sfm/lidar_constraints.h"
#include "colmap_ext/sfm/mapper_state.h"
#include "colmap_ext/sfm/sequence_reference.h"
#include "colmap_ext/sfm/sfm_evaluation.h"
#include "core/file_utils.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;
constexpr double kDegToRad = M_PI / 180.0;

// Copies the importer output's database.db (folder `o`) to `db` and runs stock
// COLMAP on it: CPU SIFT (max_features per image) for o/image_list.txt from
// image_path, then matching of the pairs in o/pairs.txt.
void StockFeaturesAndMatches(const std::string& o,
                             const std::string& image_path,
                             const std::string& db,
                             int max_features,
                             std::string* out) {
  const std::string env = "QT_QPA_PLATFORM=offscreen ";
  fs::copy_file(o + "/database.db", db);
  ASSERT_EQ(test::RunCommand(env + "colmap feature_extractor --database_path " + db +
                                 " --image_path " + image_path + " --image_list_path " + o +
                                 "/image_list.txt --SiftExtraction.use_gpu 0"
                                 " --SiftExtraction.num_threads 2"
                                 " --SiftExtraction.max_num_features " +
                                 std::to_string(max_features) +
                                 " --SiftExtraction.first_octave 0 2>&1",
                             out),
            0)
      << *out;
  ASSERT_EQ(test::RunCommand(env + "colmap matches_importer --database_path " + db +
                                 " --match_list_path " + o +
                                 "/pairs.txt --match_type pairs"
                                 " --SiftMatching.use_gpu 0 --SiftMatching.num_threads 2 2>&1",
                             out),
            0)
      << *out;
}

class DatabaseImporterTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    std::string out;
    // 14 s of office at 1 rig frame per second, default error sources, rests at
    // the start, middle and end.
    ok_ = test::RunCommand(test::LisfmBinary() +
                               " simulate --scene office --duration 14 --Walk.num_stops 3 "
                               "--camera_rate 1 --quiet 1 --output_path " +
                               Seq() + " 2>&1",
                           &out) == 0;
    ok_ = ok_ && test::RunCommand(test::LisfmBinary() + " lio --quiet 1 --input_path " + Seq() +
                                      " --output_path " + dir_->File("lio") + " 2>&1",
                                  &out) == 0;
    // The 14 s walk has ~5 keyframes: ICP pairs between every two of them
    // (the default smallest index step, 5, would leave none).
    ok_ = ok_ && test::RunCommand(test::LisfmBinary() + " pose_slam --quiet 1 --input_path " +
                                      Seq() + " --lio_path " + dir_->File("lio") +
                                      " --output_path " + dir_->File("ps") +
                                      " --PoseSlam.min_index_step 1 2>&1",
                                  &out) == 0;
    if (!ok_) std::cerr << out;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string Seq() { return dir_->File("seq"); }

  // Runs the importer; returns the exit code.
  static int Import(const std::string& output,
                    std::string* out,
                    const std::string& seq = "",
                    const std::string& ps = "",
                    const std::string& extra = "") {
    return test::RunCommand(
        test::LisfmBinary() + " database_importer --input_path " + (seq.empty() ? Seq() : seq) +
            " --pose_slam_path " + (ps.empty() ? dir_->File("ps") : ps) + " --lio_path " +
            dir_->File("lio") + " --output_path " + output + " " + extra + " 2>&1",
        out);
  }

  static test::TempDir* dir_;
  static bool ok_;
};
test::TempDir* DatabaseImporterTest::dir_ = nullptr;
bool DatabaseImporterTest::ok_ = false;

TEST_F(DatabaseImporterTest, StockColmapAndGlobalMapperOnTheDatabase) {
  ASSERT_TRUE(ok_);
  std::string out;
  if (test::RunCommand("colmap help > /dev/null 2>&1", &out) != 0) {
    GTEST_SKIP() << "colmap binary not found";
  }
  const std::string o = dir_->File("db");
  ASSERT_EQ(Import(o, &out), 0) << out;
  for (const char* f : {"database.db",
                        "image_list.txt",
                        "pairs.txt",
                        "rig.yaml",
                        "rig_config.json",
                        "constraints.txt",
                        "covisibility.csv",
                        "importer_summary.json",
                        "database_importer_config.yaml"}) {
    EXPECT_TRUE(FileExists(o + "/" + f)) << f;
  }
  // Before COLMAP: ids, names and priors.
  std::map<std::string, colmap::DbImage> before;
  {
    const colmap::Database db(o + "/database.db", colmap::Database::OpenMode::kReadOnly);
    for (const auto& image : db.ReadAllImages()) before[image.name] = image;
    EXPECT_EQ(db.NumCameras(), 5u);
  }
  ASSERT_GT(before.size(), 40u);

  // Every written constraint attaches to the database's rig frames.
  const Rig rig = ReadRigYaml(o + "/rig.yaml");
  const auto constraints = ReadLidarConstraints(o + "/constraints.txt");
  ASSERT_GT(constraints.size(), 5u);
  {
    const colmap::Database db(o + "/database.db", colmap::Database::OpenMode::kReadOnly);
    colmap::MapperState state = colmap::LoadMapperState(db, &rig, colmap::LoadMapperStateOptions());
    EXPECT_EQ(colmap::AttachLidarConstraints(
                  constraints, colmap::kDefaultLidarConstraintToleranceNs, &state),
              constraints.size());
  }

  // Stock COLMAP: features for the listed images, matches for the listed pairs.
  const std::string db = dir_->File("work.db");
  ASSERT_NO_FATAL_FAILURE(StockFeaturesAndMatches(o, Seq(), db, 1024, &out));
  std::set<std::pair<std::string, std::string>> listed;
  {
    std::ifstream pairs(o + "/pairs.txt");
    std::string a, b;
    while (pairs >> a >> b) listed.insert({std::min(a, b), std::max(a, b)});
  }
  {
    const colmap::Database database(db, colmap::Database::OpenMode::kReadOnly);
    const auto images = database.ReadAllImages();
    EXPECT_EQ(images.size(), before.size());  // nothing else under SEQ (e.g. no rgbd0/)
    std::map<colmap::image_t, std::string> names;
    for (const auto& image : images) {
      ASSERT_TRUE(before.count(image.name)) << image.name;
      const colmap::DbImage& b = before.at(image.name);
      EXPECT_EQ(image.image_id, b.image_id);
      EXPECT_EQ(image.camera_id, b.camera_id);
      EXPECT_TRUE(image.has_prior_position);
      EXPECT_LT((image.prior_position - b.prior_position).norm(), 1e-9);
      EXPECT_LT((image.prior_qvec - b.prior_qvec).norm(), 1e-9);
      EXPECT_GT(database.ReadKeypoints(image.image_id).rows(), 100);
      names[image.image_id] = image.name;
    }
    for (const auto& [pair_id, geometry] : database.ReadAllTwoViewGeometries()) {
      colmap::image_t a, b;
      colmap::PairIdToImagePair(pair_id, &a, &b);
      const std::pair<std::string, std::string> key(std::min(names[a], names[b]),
                                                    std::max(names[a], names[b]));
      EXPECT_TRUE(listed.count(key)) << key.first << " " << key.second;
    }
  }

  // lisfm global_mapper with the rig, the priors and the constraints; the
  // camera-in-rig poses refined (rig.yaml holds the believed calibration).
  ASSERT_EQ(
      test::RunCommand(test::LisfmBinary() + " global_mapper --database_path " + db +
                           " --image_path " + Seq() + " --output_path " + dir_->File("sparse") +
                           " --rig_path " + o + "/rig.yaml --lidar_constraints_path " + o +
                           "/constraints.txt --BundleAdjustment.refine_cam_from_rig 1 2>&1",
                       &out),
      0)
      << out;
  EXPECT_EQ(out.find("match no pair of frames"), std::string::npos) << out;
  const colmap::Reconstruction model = colmap::ReadModel(dir_->File("sparse/0"));
  EXPECT_EQ(model.NumImages(), before.size()) << out;

  // Ground truth: groundtruth.txt at the true capture time with the true
  // extrinsics (colmap_ext/sfm/sequence_reference.h); scored like `lisfm
  // model_evaluator --alignment se3` (centres aligned by Umeyama, rotations by
  // their geodesic mean: a 14 s walk is close to a line, whose roll the
  // centres alone do not fix).
  const colmap::SequenceReference truth = colmap::ReadSequenceReference(Seq());
  EXPECT_TRUE(truth.has_truth_rig_file);
  const std::vector<colmap::NamedPose> estimate = colmap::PosesFromReconstruction(model);
  double max_from_prior = 0;
  for (const colmap::Image& image : model.Images()) {
    max_from_prior = std::max(
        max_from_prior, (image.ProjectionCenter() - before.at(image.name).prior_position).norm());
  }
  colmap::SfmEvaluationOptions evaluation;
  evaluation.alignment = AlignmentType::kSE3;
  const colmap::SfmEvaluation e = colmap::EvaluatePoses(estimate, truth.poses, evaluation);
  EXPECT_EQ(e.num_registered, before.size());
  const double max_pos = e.position_error.max, max_rot_deg = e.rotation_error_deg.max;
  std::cout << "database_importer -> colmap -> global_mapper: " << model.NumImages()
            << " images, max error " << max_pos * 1000 << " mm, " << max_rot_deg
            << " deg (SE3 aligned); max distance to the priors " << max_from_prior * 1000
            << " mm\n";
  EXPECT_LT(max_pos, 0.01);
  EXPECT_LT(max_rot_deg, 0.1);
  // In the priors' (lio's) metric frame without alignment: the model may be off
  // by the priors' error, lio's drift over 14 s in the office (a few cm).
  EXPECT_LT(max_from_prior, 0.1);
}

TEST_F(DatabaseImporterTest, EmptyConstraintsFallBackToPriorPairs) {
  ASSERT_TRUE(ok_);
  const std::string ps = dir_->File("ps_empty");
  fs::copy(dir_->File("ps"), ps, fs::copy_options::recursive);
  test::WriteText(ps + "/constraints.txt", "");
  std::string out;
  ASSERT_EQ(Import(dir_->File("db_empty"), &out, "", ps), 0) << out;
  EXPECT_NE(out.find("holds no constraints"), std::string::npos) << out;
  const std::string summary = ReadFile(dir_->File("db_empty/importer_summary.json"));
  EXPECT_NE(summary.find("\"priors_fallback\": true"), std::string::npos) << summary;
  EXPECT_GT(fs::file_size(dir_->File("db_empty/pairs.txt")), 100u);
}

TEST_F(DatabaseImporterTest, MissingConstraintsFileIsAnError) {
  ASSERT_TRUE(ok_);
  const std::string ps = dir_->File("ps_missing");
  fs::copy(dir_->File("ps"), ps, fs::copy_options::recursive);
  fs::remove(ps + "/constraints.txt");
  std::string out;
  EXPECT_EQ(Import(dir_->File("db_missing"), &out, "", ps), 1) << out;
  EXPECT_NE(out.find("constraints.txt"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir_->File("db_missing")));
}

TEST_F(DatabaseImporterTest, CameraTimesOutsideTheTrajectory) {
  ASSERT_TRUE(ok_);
  // A trajectory of two poses long before every image.
  const std::string ps = dir_->File("ps_time");
  fs::copy(dir_->File("ps"), ps, fs::copy_options::recursive);
  test::WriteText(ps + "/trajectory.txt", "1000.0 0 0 0 0 0 0 1\n1001.0 0 0 0 0 0 0 1\n");
  std::string out;
  EXPECT_EQ(Import(dir_->File("db_time"), &out, "", ps), 1) << out;
  EXPECT_NE(out.find("no camera time lies within the trajectory"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir_->File("db_time")));
}

// A sequence folder with rig.yaml and links to the camera folders.
std::string LinkedSequence(const std::string& seq, const std::string& copy) {
  fs::create_directories(copy);
  fs::copy_file(seq + "/rig.yaml", copy + "/rig.yaml");
  for (int k = 0; k < 5; ++k) {
    const std::string cam = "cam" + std::to_string(k);
    fs::create_directory_symlink(seq + "/" + cam, copy + "/" + cam);
  }
  return copy;
}

TEST_F(DatabaseImporterTest, MissingImageIsAnErrorNamingTheIndex) {
  ASSERT_TRUE(ok_);
  const std::string copy = LinkedSequence(Seq(), dir_->File("seq_missing"));
  fs::remove(copy + "/cam2");
  fs::create_directories(copy + "/cam2/data");
  const std::string index = ReadFile(Seq() + "/cam2/data.csv");
  test::WriteText(copy + "/cam2/data.csv", index);  // rows without their images
  std::string out;
  EXPECT_EQ(Import(dir_->File("db_img"), &out, copy), 1) << out;
  EXPECT_NE(out.find("cam2/data.csv:line 2"), std::string::npos) << out;
  EXPECT_NE(out.find("missing file"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir_->File("db_img")));
}

TEST_F(DatabaseImporterTest, ImageSizeThatDisagreesWithTheRig) {
  ASSERT_TRUE(ok_);
  const std::string copy = LinkedSequence(Seq(), dir_->File("seq_size"));
  Rig rig = ReadRigYaml(copy + "/rig.yaml");
  rig.cameras[1].model.width = 640;
  rig.cameras[1].model.cx = 319.5;
  fs::remove(copy + "/rig.yaml");
  WriteRigYaml(copy + "/rig.yaml", rig);
  std::string out;
  EXPECT_EQ(Import(dir_->File("db_size"), &out, copy), 1) << out;
  EXPECT_NE(out.find("image size 720x540, but rig.yaml cam1.resolution is [640, 540]"),
            std::string::npos)
      << out;
  EXPECT_FALSE(fs::exists(dir_->File("db_size")));
}

TEST_F(DatabaseImporterTest, ExistingOutputIsRefusedAndKept) {
  ASSERT_TRUE(ok_);
  const std::string o = dir_->File("db_existing");
  fs::create_directories(o);
  test::WriteText(o + "/database.db", "a user's database");
  std::string out;
  EXPECT_EQ(Import(o, &out), 2) << out;
  EXPECT_NE(out.find("--output_path"), std::string::npos) << out;
  EXPECT_EQ(ReadFile(o + "/database.db"), "a user's database");
}

// The HILTI 2022 extract GTSFM ships: real images, the real rig, FAST-LIO2
// poses as priors and GTSFM's constraints; stock COLMAP features and matches on
// the pair list, then global_mapper registers every real image with the rig.
TEST(DatabaseImporterHilti, RealImagesRegisterWithTheRealRig) {
  LISFM_REQUIRE_SHARED_DATA("hilti_exp4_small/images/0.jpg");
  std::string out;
  if (test::RunCommand("colmap help > /dev/null 2>&1", &out) != 0) {
    GTEST_SKIP() << "colmap binary not found";
  }
  test::TempDir dir;
  const std::string o = dir.File("import");
  ASSERT_EQ(test::RunCommand(
                test::LisfmBinary() + " database_importer --input_type hilti_gtsfm --input_path " +
                    test::SharedData("hilti_exp4_small") + " --output_path " + o + " 2>&1",
                &out),
            0)
      << out;
  // 16 images: 3 keyframes of 5 cameras (15.jpg has no complete keyframe).
  {
    const colmap::Database db(o + "/database.db", colmap::Database::OpenMode::kReadOnly);
    const auto images = db.ReadAllImages();
    ASSERT_EQ(images.size(), 15u);
    for (const auto& image : images) {
      EXPECT_TRUE(image.has_prior_position) << image.name;
      EXPECT_TRUE(FileExists(o + "/images/" + image.name)) << image.name;
    }
  }
  EXPECT_EQ(ReadLidarConstraints(o + "/constraints.txt").size(), 3u);
  const std::string db = dir.File("work.db");
  ASSERT_NO_FATAL_FAILURE(StockFeaturesAndMatches(o, o + "/images", db, 2048, &out));
  ASSERT_EQ(test::RunCommand(
                test::LisfmBinary() + " global_mapper --database_path " + db + " --image_path " +
                    o + "/images --output_path " + dir.File("sparse") + " --rig_path " + o +
                    "/rig.yaml --lidar_constraints_path " + o + "/constraints.txt 2>&1",
                &out),
            0)
      << out;
  EXPECT_EQ(out.find("match no pair of frames"), std::string::npos) << out;
  const colmap::Reconstruction model = colmap::ReadModel(dir.File("sparse/0"));
  EXPECT_EQ(model.NumImages(), 15u) << out;
  EXPECT_GT(model.NumPoints3D(), 30u);
}

}  // namespace
}  // namespace lisfm
