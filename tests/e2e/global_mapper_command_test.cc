// `lisfm global_mapper` as a user runs it: on a synthetic database and on the
// real Lund door images after stock COLMAP feature extraction and matching;
// every model is read by stock `colmap model_analyzer`; bad inputs fail with
// one clear error and leave no model behind.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "colmap_ext/io/model_io.h"
#include "colmap_ext/sfm/sfm_evaluation.h"
#include "colmap_ext/testing/stock_colmap.h"
#include "colmap_ext/testing/synthetic.h"
#include "core/file_utils.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/rig_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

std::string Lisfm(const std::string& args, int* rc) {
  std::string out;
  *rc = test::RunCommand(test::LisfmBinary() + " " + args + " 2>&1", &out);
  return out;
}

TEST(GlobalMapperCommand, SyntheticRigModelOpensInStockColmap) {
  REQUIRE_COLMAP();
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 8;
  o.with_rig = true;
  o.num_cameras = 3;
  o.trajectory = SyntheticTrajectory::kRoom;
  o.num_points = 1500;
  o.pixel_noise = 0.5;
  o.prior_position_noise = 0.02;
  o.prior_rotation_noise = 0.005;
  o.num_lidar_neighbors = 1;
  const SyntheticDataset dataset = SynthesizeDataset(o);
  WriteSyntheticDatabase(dataset, dir.File("db.db"));
  WriteRigYaml(dir.File("rig.yaml"), dataset.rig);
  WriteLidarConstraints(dataset.constraints, dir.File("constraints.txt"));
  int rc = 0;
  const std::string out =
      Lisfm("global_mapper --database_path " + dir.File("db.db") + " --output_path " +
                dir.File("sparse") + " --rig_path " + dir.File("rig.yaml") +
                " --lidar_constraints_path " + dir.File("constraints.txt"),
            &rc);
  ASSERT_EQ(rc, 0) << out;
  EXPECT_TRUE(FileExists(dir.File("sparse/0/cameras.bin")));
  EXPECT_TRUE(FileExists(dir.File("sparse/0/frames.bin")));
  EXPECT_TRUE(FileExists(dir.File("sparse/global_mapper_summary.json")));
  const std::string analyzer =
      test_stock::RunColmap("model_analyzer --path " + dir.File("sparse/0"));
  const auto lines = test_stock::AnalyzerLines(analyzer);
  ASSERT_TRUE(lines.count("Registered images")) << analyzer;
  EXPECT_EQ(std::stoi(lines.at("Registered images")), 24) << analyzer;
  const Reconstruction ours = ReadModel(dir.File("sparse/0"));
  EXPECT_EQ(std::stoul(lines.at("Points")), ours.NumPoints3D());
  EXPECT_EQ(std::stoul(lines.at("Observations")), ours.ComputeNumObservations());
}

TEST(GlobalMapperCommand, BadInputsFailCleanly) {
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 5;
  WriteSyntheticDatabase(SynthesizeDataset(o), dir.File("db.db"));
  int rc = 0;
  // Missing database.
  std::string out = Lisfm("global_mapper --database_path " + dir.File("none.db") +
                              " --output_path " + dir.File("out1"),
                          &rc);
  EXPECT_EQ(rc, 1) << out;
  EXPECT_NE(out.find("none.db"), std::string::npos) << out;
  // Malformed constraints file: one error naming file and line, no model.
  test::WriteText(dir.File("bad.txt"), "1000 2000 0 0 0 0 0 0 1\n");
  out = Lisfm("global_mapper --database_path " + dir.File("db.db") + " --output_path " +
                  dir.File("out2") + " --lidar_constraints_path " + dir.File("bad.txt"),
              &rc);
  EXPECT_EQ(rc, 1) << out;
  EXPECT_NE(out.find("bad.txt:line 1"), std::string::npos) << out;
  EXPECT_FALSE(DirExists(dir.File("out2/0")));
  // A database without two-view geometries.
  {
    Database database(dir.File("db.db"), Database::OpenMode::kReadWrite);
    database.ClearTwoViewGeometries();
  }
  out = Lisfm("global_mapper --database_path " + dir.File("db.db") + " --output_path " +
                  dir.File("out3"),
              &rc);
  EXPECT_EQ(rc, 1) << out;
  EXPECT_NE(out.find("two_view_geometries"), std::string::npos) << out;
  EXPECT_FALSE(DirExists(dir.File("out3/0")));
  // Unknown option: usage error with a suggestion.
  out = Lisfm("global_mapper --database_pth x --output_path y", &rc);
  EXPECT_EQ(rc, 2) << out;
}

// The output folder is checked before the work: an unusable --output_path
// fails at once, before the database is even read.
TEST(GlobalMapperCommand, UnwritableOutputFailsBeforeTheWork) {
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 5;
  WriteSyntheticDatabase(SynthesizeDataset(o), dir.File("db.db"));
  test::WriteText(dir.File("file"), "x");
  int rc = 0;
  const std::string out = Lisfm("global_mapper --database_path " + dir.File("db.db") +
                                    " --output_path " + dir.File("file/sparse"),
                                &rc);
  EXPECT_EQ(rc, 1) << out;
  EXPECT_NE(out.find(dir.File("file/sparse")), std::string::npos) << out;
  EXPECT_EQ(out.find("view graph"), std::string::npos) << out;  // no stage ran
}

// Dropped frames are reported on the terminal with the reason, not only in
// the summary JSON.
TEST(GlobalMapperCommand, DroppedFramesAreWarnedWithTheReason) {
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 8;
  o.num_points = 600;
  WriteSyntheticDatabase(SynthesizeDataset(o), dir.File("db.db"));
  int rc = 0;
  // More observations than any frame has: every frame is dropped after BA.
  const std::string out = Lisfm("global_mapper --database_path " + dir.File("db.db") +
                                    " --output_path " + dir.File("sparse") +
                                    " --Mapper.min_frame_observations 100000",
                                &rc);
  EXPECT_EQ(rc, 1) << out;  // no model
  EXPECT_NE(out.find("dropped frame image_0001.png: it sees"), std::string::npos) << out;
  EXPECT_NE(out.find("fewer than Mapper.min_frame_observations = 100000"), std::string::npos)
      << out;
  // Small view-graph components are named as well.
  const std::string small = Lisfm("global_mapper --database_path " + dir.File("db.db") +
                                      " --output_path " + dir.File("sparse2") +
                                      " --Mapper.min_component_frames 100",
                                  &rc);
  EXPECT_NE(small.find("8 frame(s) not reconstructed"), std::string::npos) << small;
  EXPECT_NE(small.find("min_component_frames = 100"), std::string::npos) << small;
}

// One image with a wrong prior focal length (its own camera, 10x the true
// one, as a bad EXIF entry gives): its frame is dropped, and the warning
// blames the focal length against what bundle adjustment gave the others.
TEST(GlobalMapperCommand, DroppedFrameWithAWrongFocalLengthSaysSo) {
  test::TempDir dir;
  SyntheticDatasetOptions o;
  o.num_frames = 10;
  o.pixel_noise = 0.5;
  const SyntheticDataset dataset = SynthesizeDataset(o);
  WriteSyntheticDatabase(dataset, dir.File("db.db"));
  {
    Database database(dir.File("db.db"), Database::OpenMode::kReadWrite);
    Camera wrong = dataset.cameras.begin()->second;
    wrong.params[0] *= 10;
    wrong.params[1] *= 10;
    const camera_t wrong_id = database.WriteCamera(wrong);
    DbImage image = database.ReadImage(4);
    image.camera_id = wrong_id;
    database.UpdateImage(image);
  }
  int rc = 0;
  const std::string out = Lisfm("global_mapper --database_path " + dir.File("db.db") +
                                    " --output_path " + dir.File("sparse"),
                                &rc);
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("dropped frame image_0004.png"), std::string::npos) << out;
  EXPECT_NE(out.find("the registered cameras of this image size (a wrong EXIF/prior focal"),
            std::string::npos)
      << out;
}

// Real images: stock COLMAP extracts and matches (reduced SIFT settings to keep
// the test short), our mapper reconstructs, and the cameras agree with the
// reference model shipped with the data.
TEST(GlobalMapperCommand, LundDoorAgainstReferenceModel) {
  LISFM_REQUIRE_SHARED_DATA("sfm_lund_door/images");
  REQUIRE_COLMAP();
  test::TempDir dir;
  const std::string images = test::SharedData("sfm_lund_door/images");
  const std::string db = dir.File("db.db");
  // The reference camera (SIMPLE_RADIAL f, cx, cy, k) as known intrinsics.
  test_stock::RunColmap("feature_extractor --database_path " + db + " --image_path " + images +
                        " --ImageReader.single_camera 1 --ImageReader.camera_model SIMPLE_RADIAL"
                        " --ImageReader.camera_params 2435.38,648,968,-0.0336422"
                        " --SiftExtraction.use_gpu 0 --SiftExtraction.max_image_size 1000"
                        " --SiftExtraction.max_num_features 2048 --SiftExtraction.num_threads 2");
  test_stock::RunColmap("exhaustive_matcher --database_path " + db +
                        " --SiftMatching.use_gpu 0 --SiftMatching.num_threads 2");
  int rc = 0;
  const std::string out = Lisfm("global_mapper --database_path " + db + " --image_path " +
                                    images + " --output_path " + dir.File("sparse"),
                                &rc);
  ASSERT_EQ(rc, 0) << out;
  const Reconstruction model = ReadModel(dir.File("sparse/0"));
  EXPECT_EQ(model.NumImages(), 12u);
  const Reconstruction reference = ReadModel(test::SharedData("sfm_lund_door/colmap_ground_truth"));
  SfmEvaluationOptions eval_options;  // Sim3: the model has no metric scale
  const SfmEvaluation eval = EvaluatePoses(PosesFromReconstruction(model),
                                           PosesFromReconstruction(reference), eval_options);
  // The reference is itself an SfM result; our cameras should agree with it
  // to a fraction of a degree.
  EXPECT_LT(eval.rotation_error_deg.max, 0.5);
  ASSERT_GE(eval.auc.size(), 2u);
  EXPECT_GT(eval.auc[1], 0.9);  // AUC at 5 deg
  const std::string analyzer = test_stock::RunColmap("model_analyzer --path " + dir.File("sparse/0"));
  EXPECT_NE(analyzer.find("Registered images: 12"), std::string::npos) << analyzer;
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
