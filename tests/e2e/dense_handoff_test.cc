// Dense hand-off: a `lisfm global_mapper` model of a simulated recording with
// the HILTI-like fisheye rig (OPENCV_FISHEYE cameras, as `lisfm
// database_importer` writes them) goes through stock `colmap
// image_undistorter --output_type COLMAP`, the entry point of COLMAP's MVS and
// of 3DGS / nerfstudio data loaders. The flow before it is the importer's
// (tests/e2e/database_importer_test.cc) on a 6 s walk with few pairs: simulate,
// lio, pose_slam, database_importer, stock feature_extractor +
// matches_importer, global_mapper.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <set>

#include "colmap_ext/io/camera_models.h"
#include "colmap_ext/io/model_io.h"
#include "colmap_ext/testing/stock_colmap.h"
#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

// Width and height from a PNG's IHDR chunk (big-endian at bytes 16 and 20);
// false when the file is not a PNG.
bool PngSize(const std::string& path, uint32_t* width, uint32_t* height) {
  std::ifstream in(path, std::ios::binary);
  unsigned char header[24];
  if (!in.read(reinterpret_cast<char*>(header), sizeof(header))) return false;
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (!std::equal(kSignature, kSignature + 8, header)) return false;
  const auto be32 = [&](int at) {
    return (uint32_t{header[at]} << 24) | (uint32_t{header[at + 1]} << 16) |
           (uint32_t{header[at + 2]} << 8) | uint32_t{header[at + 3]};
  };
  *width = be32(16);
  *height = be32(20);
  return true;
}

TEST(DenseHandOff, GlobalMapperModelThroughStockImageUndistorter) {
  REQUIRE_COLMAP();
  test::TempDir dir;
  const std::string seq = dir.File("seq");
  std::string out;
  const auto lisfm = [&](const std::string& args) {
    return test::RunCommand(test::LisfmBinary() + " " + args + " 2>&1", &out);
  };
  // 6 s of office (4 s leave lio one keyframe, pose_slam needs 2), 1 rig
  // frame per second (7 frames, the last outside lio's trajectory), default
  // error sources.
  ASSERT_EQ(lisfm("simulate --scene office --duration 6 --Walk.num_stops 2 --camera_rate 1 "
                  "--quiet 1 --output_path " +
                  seq),
            0)
      << out;
  ASSERT_EQ(lisfm("lio --quiet 1 --input_path " + seq + " --output_path " + dir.File("lio")), 0)
      << out;
  ASSERT_EQ(lisfm("pose_slam --input_path " + seq + " --lio_path " + dir.File("lio") +
                  " --output_path " + dir.File("ps")),
            0)
      << out;
  // Few pairs keep stock matching short: rig pairs, temporal neighbours and
  // (a 6 s walk has no LiDAR constraints) 2 prior neighbours per image.
  const std::string db_dir = dir.File("db");
  ASSERT_EQ(lisfm("database_importer --input_path " + seq + " --pose_slam_path " + dir.File("ps") +
                  " --lio_path " + dir.File("lio") + " --output_path " + db_dir +
                  " --DatabaseImporter.fallback_num_neighbors 2"),
            0)
      << out;
  const std::string db = dir.File("work.db");
  fs::copy_file(db_dir + "/database.db", db);
  colmap::test_stock::RunColmap("feature_extractor --database_path " + db + " --image_path " + seq +
                                " --image_list_path " + db_dir +
                                "/image_list.txt --SiftExtraction.use_gpu 0"
                                " --SiftExtraction.num_threads 2"
                                " --SiftExtraction.max_num_features 1024"
                                " --SiftExtraction.first_octave 0");
  colmap::test_stock::RunColmap("matches_importer --database_path " + db + " --match_list_path " +
                                db_dir +
                                "/pairs.txt --match_type pairs --SiftMatching.use_gpu 0"
                                " --SiftMatching.num_threads 2");
  ASSERT_EQ(lisfm("global_mapper --database_path " + db + " --image_path " + seq +
                  " --output_path " + dir.File("sparse") + " --rig_path " + db_dir +
                  "/rig.yaml --lidar_constraints_path " + db_dir + "/constraints.txt"),
            0)
      << out;
  const colmap::Reconstruction model = colmap::ReadModel(dir.File("sparse/0"));
  ASSERT_GE(model.NumImages(), 25u);  // at least 5 of the 6 frames inside lio's trajectory
  for (const colmap::Camera& camera : model.Cameras()) {
    EXPECT_EQ(camera.model_id, static_cast<int>(colmap::CameraModelId::kOpenCVFisheye))
        << "camera " << camera.camera_id;
  }

  // Stock undistortion to PINHOLE images and a sparse model beside them.
  const std::string dense = dir.File("dense");
  const std::string undistorter_out = colmap::test_stock::RunColmap(
      "image_undistorter --image_path " + seq + " --input_path " + dir.File("sparse/0") +
      " --output_path " + dense + " --output_type COLMAP");
  for (const char* f : {"sparse/cameras.bin",
                        "sparse/images.bin",
                        "sparse/points3D.bin",
                        "stereo/patch-match.cfg",
                        "run-colmap-geometric.sh"}) {
    EXPECT_TRUE(FileExists(dense + "/" + f)) << f << "\n" << undistorter_out;
  }
  const colmap::Reconstruction undistorted = colmap::ReadModel(dense + "/sparse");
  ASSERT_EQ(undistorted.NumImages(), model.NumImages());
  EXPECT_EQ(undistorted.NumPoints3D(), model.NumPoints3D());
  EXPECT_EQ(undistorted.NumCameras(), model.NumCameras());
  for (const colmap::Camera& camera : undistorted.Cameras()) {
    EXPECT_EQ(camera.model_id, static_cast<int>(colmap::CameraModelId::kPinhole))
        << "camera " << camera.camera_id;
  }
  std::set<std::string> names;
  for (const colmap::Image& image : model.Images()) names.insert(image.name);
  for (const colmap::Image& image : undistorted.Images()) {
    EXPECT_TRUE(names.count(image.name)) << image.name;
    // The pose is kept; the image is resampled to the camera's PINHOLE size.
    const colmap::Image& original = model.GetImage(image.image_id);
    EXPECT_LT((image.ProjectionCenter() - original.ProjectionCenter()).norm(), 1e-9);
    const colmap::Camera& camera = undistorted.GetCamera(image.camera_id);
    uint32_t width = 0, height = 0;
    ASSERT_TRUE(PngSize(dense + "/images/" + image.name, &width, &height)) << image.name;
    EXPECT_EQ(width, camera.width) << image.name;
    EXPECT_EQ(height, camera.height) << image.name;
  }
}

}  // namespace
}  // namespace lisfm
