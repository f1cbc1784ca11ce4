// Runs `lisfm model_converter`, `lisfm model_analyzer` and `lisfm
// database_info` like a user would, including bad input.
#include <gtest/gtest.h>

#include "colmap_ext/io/database.h"
#include "colmap_ext/io/model_io.h"
#include "colmap_ext/testing/synthetic.h"
#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

int Lisfm(const std::string& args, std::string* out) {
  return test::RunCommand(test::LisfmBinary() + " " + args, out);
}

TEST(ColmapCommands, ModelConverterRoundTripsBinTxtBinAndWritesPly) {
  test::TempDir dir;
  SyntheticDatasetOptions options;
  options.num_frames = 6;
  options.num_cameras = 2;
  options.camera_models = {"PINHOLE", "OPENCV_FISHEYE"};
  options.num_points = 80;
  options.track_length = 3;
  options.pixel_noise = 0.5;
  options.num_random_keypoints = 5;
  const Reconstruction model = SyntheticReconstruction(SynthesizeDataset(options));
  WriteModelBinary(model, dir.File("bin"));
  std::string out;
  ASSERT_EQ(Lisfm("model_converter --input_path " + dir.File("bin") + " --output_path " +
                      dir.File("txt") + " --output_type TXT",
                  &out),
            0)
      << out;
  EXPECT_EQ(ReadFile(dir.File("txt/images.txt")), ImagesText(model));
  ASSERT_EQ(Lisfm("model_converter --input_path " + dir.File("txt") + " --output_path " +
                      dir.File("bin2") + " --output_type BIN",
                  &out),
            0)
      << out;
  for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) {
    EXPECT_EQ(ReadFile(dir.File("bin/") + f), ReadFile(dir.File("bin2/") + f)) << f;
  }
  ASSERT_EQ(Lisfm("model_converter --input_path " + dir.File("bin") + " --output_path " +
                      dir.File("m.ply") + " --output_type PLY",
                  &out),
            0)
      << out;
  EXPECT_NE(ReadFile(dir.File("m.ply")).find("element vertex 80\n"), std::string::npos);
  // Bad input: one error line naming the file, exit code 1, nothing written.
  test::WriteText(dir.File("bin/points3D.bin"), "short");
  EXPECT_EQ(Lisfm("model_analyzer --path " + dir.File("bin"), &out), 1);
  EXPECT_NE(out.find("error: " + dir.File("bin/points3D.bin")), std::string::npos) << out;
  EXPECT_EQ(Lisfm("model_converter --input_path " + dir.File("bin") + " --output_path " +
                      dir.File("never") + " --output_type TXT",
                  &out),
            1);
  EXPECT_FALSE(DirExists(dir.File("never")));
  EXPECT_EQ(Lisfm("model_converter --input_path " + dir.File("bin") + " --output_path x " +
                      "--output_type XYZ",
                  &out),
            2);
}

TEST(ColmapCommands, DatabaseInfoReportsCountsAndRejectsForeignFiles) {
  test::TempDir dir;
  {
    Database db(dir.File("db.db"), Database::OpenMode::kCreate);
    Camera camera;
    camera.model_id = 0;
    camera.width = 100;
    camera.height = 100;
    camera.params = {100, 50, 50};
    camera.has_prior_focal_length = true;
    db.WriteCamera(camera);
    DbImage image;
    image.name = "a.png";
    image.camera_id = 1;
    image.has_prior_position = true;
    image.prior_position = Vec3(1, 2, 3);
    db.WriteImage(image);
  }
  std::string out;
  ASSERT_EQ(Lisfm("database_info --database_path " + dir.File("db.db"), &out), 0) << out;
  EXPECT_NE(out.find("user_version 3800"), std::string::npos) << out;
  EXPECT_NE(out.find("cameras: 1 rows"), std::string::npos) << out;
  EXPECT_NE(out.find("pose_priors: 1 rows"), std::string::npos) << out;
  EXPECT_NE(out.find("prior position: 1"), std::string::npos) << out;
  test::WriteText(dir.File("notes.db"), "these are not the tables you are looking for\n");
  EXPECT_EQ(Lisfm("database_info --database_path " + dir.File("notes.db"), &out), 1);
  EXPECT_NE(out.find("error: " + dir.File("notes.db")), std::string::npos) << out;
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
