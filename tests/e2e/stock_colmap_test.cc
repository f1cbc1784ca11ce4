// Checks our model files against the stock `colmap` 3.8 binary: model_analyzer
// statistics and model_converter output. Skips when `colmap` is missing.
#include <cstdio>

#include <gtest/gtest.h>

#include "colmap_ext/io/database.h"
#include "colmap_ext/io/model_io.h"
#include "colmap_ext/testing/stock_colmap.h"
#include "colmap_ext/testing/synthetic.h"
#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

using namespace test_stock;  // NOLINT

TEST(StockColmap, ModelAnalyzerAndConverterAgreeOnOurModel) {
  REQUIRE_COLMAP();
  test::TempDir dir;
  SyntheticDatasetOptions options;
  options.num_frames = 12;
  options.num_cameras = 3;
  options.camera_models = {"PINHOLE", "OPENCV_FISHEYE", "OPENCV"};
  options.num_points = 400;
  options.track_length = 4;
  options.pixel_noise = 0.5;
  options.num_random_keypoints = 5;
  const Reconstruction model = SyntheticReconstruction(SynthesizeDataset(options));
  WriteModelBinary(model, dir.File("ours"));

  // Same counts and mean reprojection error from stock COLMAP, from our
  // library and from `lisfm model_analyzer` (printed with %f like COLMAP).
  const auto theirs = AnalyzerLines(RunColmap("model_analyzer --path " + dir.File("ours")));
  std::string out;
  ASSERT_EQ(test::RunCommand(test::LisfmBinary() + " model_analyzer --path " + dir.File("ours"),
                             &out),
            0)
      << out;
  const auto ours = AnalyzerLines(out);
  ASSERT_EQ(theirs.size(), 8u);
  EXPECT_EQ(ours, theirs);
  EXPECT_EQ(theirs.at("Points"), "400");
  EXPECT_EQ(theirs.at("Observations"), std::to_string(model.ComputeNumObservations()));
  char expected_error[64];
  std::snprintf(expected_error, sizeof(expected_error), "%fpx",
                model.ComputeMeanReprojectionError());
  EXPECT_EQ(theirs.at("Mean reprojection error"), expected_error);

  // colmap model_converter --output_type TXT on our files == our TXT writer.
  CreateDirs(dir.File("colmap_txt"));
  RunColmap("model_converter --input_path " + dir.File("ours") + " --output_path " +
            dir.File("colmap_txt") + " --output_type TXT");
  ExpectSameText(CamerasText(model), ReadFile(dir.File("colmap_txt/cameras.txt")), 1, "cameras");
  ExpectSameText(ImagesText(model), ReadFile(dir.File("colmap_txt/images.txt")), 2, "images");
  ExpectSameText(Points3DText(model), ReadFile(dir.File("colmap_txt/points3D.txt")), 1, "points");
  // And COLMAP's binary output of our text model reads back to the same values.
  WriteModelText(model, dir.File("ours_txt"));
  CreateDirs(dir.File("colmap_bin"));
  RunColmap("model_converter --input_path " + dir.File("ours_txt") + " --output_path " +
            dir.File("colmap_bin") + " --output_type BIN");
  const Reconstruction back = ReadModelBinary(dir.File("colmap_bin"));
  ASSERT_EQ(back.NumPoints3D(), model.NumPoints3D());
  for (const Image& image : model.Images()) {
    const Image& other = back.GetImage(image.image_id);
    EXPECT_EQ(other.qvec, image.qvec);
    EXPECT_EQ(other.tvec, image.tvec);
    ASSERT_EQ(other.points2D.size(), image.points2D.size());
    EXPECT_EQ(other.points2D.back().xy, image.points2D.back().xy);
  }
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
