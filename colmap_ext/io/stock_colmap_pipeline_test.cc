// A database we create, filled by stock COLMAP 3.8 (feature_extractor,
// matches_importer with our pair list) and mapped by stock `colmap mapper`;
// we read everything back and write the mapper's model again byte for byte.
// Skips when `colmap` or ../shared/data is missing. ~25 s on 2 cores.
#include <cstdio>

#include <gtest/gtest.h>

#include "colmap_ext/io/database.h"
#include "colmap_ext/io/model_io.h"
#include "colmap_ext/testing/stock_colmap.h"
#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

using namespace test_stock;  // NOLINT

TEST(StockColmap, OurDatabaseThroughFeatureExtractionMatchingAndMapper) {
  REQUIRE_COLMAP();
  LISFM_REQUIRE_SHARED_DATA("sfm_lund_door/images/DSC_0005.JPG");
  test::TempDir dir;
  const std::string images_dir = dir.File("images");
  CreateDirs(images_dir);
  // Five Lund door images (1296 x 1936): enough for the 3.8 mapper to
  // register all of them in a few seconds at 1000 px / 2048 features.
  std::vector<std::string> names;
  for (int i = 1; i <= 5; ++i) {
    const std::string name = "DSC_000" + std::to_string(i) + ".JPG";
    names.push_back(name);
    WriteFileAtomically(JoinPaths(images_dir, name),
                        ReadFile(test::SharedData("sfm_lund_door/images/" + name)));
  }
  const std::string db_path = dir.File("database.db");
  {
    Database db(db_path, Database::OpenMode::kCreate);
    Camera pinhole;
    pinhole.camera_id = 3;
    pinhole.model_id = static_cast<int>(CameraModelId::kPinhole);
    pinhole.width = 1296;
    pinhole.height = 1936;
    pinhole.params = {2435.38, 2435.38, 648, 968};
    pinhole.has_prior_focal_length = true;
    db.WriteCamera(pinhole, true);
    Camera fisheye = pinhole;
    fisheye.camera_id = 8;
    fisheye.model_id = static_cast<int>(CameraModelId::kOpenCVFisheye);
    fisheye.params = {2435.38, 2435.38, 648, 968, 0, 0, 0, 0};
    db.WriteCamera(fisheye, true);
    for (int i = 0; i < 5; ++i) {
      DbImage image;
      image.image_id = static_cast<image_t>(10 + i);
      image.name = names[i];
      image.camera_id = i < 4 ? 3 : 8;
      image.has_prior_rotation = true;
      image.has_prior_position = true;
      image.prior_position = Vec3(0.5 * i, 0, 0);  // i = 0 is moved off the origin
      image.prior_position_covariance = Mat3::Identity() * 0.04;
      db.WriteImage(image, true);
    }
  }
  const std::string common = " --SiftExtraction.use_gpu 0 --SiftExtraction.max_image_size 1000 "
                             "--SiftExtraction.max_num_features 2048";
  RunColmap("feature_extractor --database_path " + db_path + " --image_path " + images_dir +
            common);
  std::string pairs;
  size_t num_pairs = 0;
  for (int i = 0; i < 5; ++i)
    for (int j = i + 1; j < 5; ++j, ++num_pairs) pairs += names[i] + " " + names[j] + "\n";
  test::WriteText(dir.File("pairs.txt"), pairs);
  RunColmap("matches_importer --database_path " + db_path + " --match_list_path " +
            dir.File("pairs.txt") + " --match_type pairs --SiftMatching.use_gpu 0");

  {
    Database db(db_path, Database::OpenMode::kReadOnly);
    // Our camera and image rows were reused, ids and priors untouched.
    const auto cameras = db.ReadAllCameras();
    ASSERT_EQ(cameras.size(), 2u);
    EXPECT_EQ(cameras[0].camera_id, 3u);
    EXPECT_EQ(cameras[1].ModelName(), "OPENCV_FISHEYE");
    const auto images = db.ReadAllImages();
    ASSERT_EQ(images.size(), 5u);
    for (int i = 0; i < 5; ++i) {
      EXPECT_EQ(images[i].image_id, static_cast<image_t>(10 + i));
      EXPECT_TRUE(images[i].has_prior_position);
      EXPECT_EQ(images[i].prior_position.y(), 0.0);
      EXPECT_EQ(images[i].prior_position_covariance(1, 1), 0.04);
      const KeypointsBlob keypoints = db.ReadKeypoints(images[i].image_id);
      const DescriptorsBlob descriptors = db.ReadDescriptors(images[i].image_id);
      EXPECT_GT(keypoints.rows(), 100);
      EXPECT_EQ(keypoints.cols(), 6);  // 3.8 stores affine shapes
      EXPECT_EQ(descriptors.rows(), keypoints.rows());
      EXPECT_EQ(descriptors.cols(), 128);
    }
    EXPECT_EQ(db.CountRows("matches"), num_pairs);
    for (int i = 0; i < 5; ++i) {
      for (int j = i + 1; j < 5; ++j) {
        const image_t a = images[i].image_id, b = images[j].image_id;
        ASSERT_TRUE(db.ExistsMatches(a, b)) << names[i] << " " << names[j];
        ASSERT_TRUE(db.ExistsTwoViewGeometry(b, a));
        const MatchesBlob matches = db.ReadMatches(b, a);
        const TwoViewGeometry g = db.ReadTwoViewGeometry(a, b);
        EXPECT_GT(matches.rows(), 0);
        const auto na = db.ReadKeypoints(a).rows(), nb = db.ReadKeypoints(b).rows();
        for (Eigen::Index k = 0; k < matches.rows(); ++k) {
          ASSERT_LT(matches(k, 0), nb);  // (b, a) order: column 0 indexes image b
          ASSERT_LT(matches(k, 1), na);
        }
        if (g.inlier_matches.rows() >= 15) {
          // Both cameras have prior_focal_length = 1, so 3.8 estimates E for
          // the PINHOLE pairs. Pairs with the (deliberately mis-modelled,
          // zero-distortion) fisheye camera may fall back to UNCALIBRATED
          // when F explains more matches than E.
          if (j < 4) {
            EXPECT_EQ(g.config, static_cast<int>(TwoViewConfig::kCalibrated))
                << names[i] << " " << names[j];
          } else {
            EXPECT_TRUE(g.config == static_cast<int>(TwoViewConfig::kCalibrated) ||
                        g.config == static_cast<int>(TwoViewConfig::kUncalibrated));
          }
          EXPECT_GT(g.F.norm(), 0.0);
          EXPECT_GT(g.E.norm(), 0.0);
          for (Eigen::Index k = 0; k < g.inlier_matches.rows(); ++k) {
            ASSERT_LT(g.inlier_matches(k, 0), na);
            ASSERT_LT(g.inlier_matches(k, 1), nb);
          }
        }
      }
    }
  }

  // Stock mapper on our database; read its model and write it back.
  const std::string sparse = dir.File("sparse");
  CreateDirs(sparse);
  RunColmap("mapper --database_path " + db_path + " --image_path " + images_dir +
            " --output_path " + sparse);
  ASSERT_TRUE(HasModel(JoinPaths(sparse, "0"), ModelFormat::kBinary));
  const Reconstruction model = ReadModelBinary(JoinPaths(sparse, "0"));
  EXPECT_GE(model.NumImages(), 3u);
  EXPECT_GT(model.NumPoints3D(), 100u);
  WriteModelBinary(model, dir.File("rewritten"));
  for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) {
    EXPECT_TRUE(ReadFile(JoinPaths(JoinPaths(sparse, "0"), f)) ==
                ReadFile(JoinPaths(dir.File("rewritten"), f)))
        << f << " differs after read + write";
  }
  // TXT: ours equals colmap model_converter's, and reads back to the same model.
  CreateDirs(dir.File("colmap_txt"));
  RunColmap("model_converter --input_path " + JoinPaths(sparse, "0") + " --output_path " +
            dir.File("colmap_txt") + " --output_type TXT");
  ExpectSameText(CamerasText(model), ReadFile(dir.File("colmap_txt/cameras.txt")), 1, "cameras");
  ExpectSameText(ImagesText(model), ReadFile(dir.File("colmap_txt/images.txt")), 2, "images");
  ExpectSameText(Points3DText(model), ReadFile(dir.File("colmap_txt/points3D.txt")), 1, "points");
  WriteModelText(model, dir.File("ours_txt"));
  const Reconstruction from_txt = ReadModelText(dir.File("ours_txt"));
  EXPECT_EQ(ImagesBinary(from_txt), ImagesBinary(model));
  EXPECT_EQ(Points3DBinary(from_txt), Points3DBinary(model));
  EXPECT_EQ(CamerasBinary(from_txt), CamerasBinary(model));
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
