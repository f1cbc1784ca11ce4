#include "colmap_ext/io/database.h"

#include <cstring>

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "core/errors.h"
#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

void RawExec(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  char* error = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error);
  EXPECT_EQ(rc, SQLITE_OK) << (error ? error : "");
  sqlite3_free(error);
  sqlite3_close(db);
}

Camera MakeCamera(int model_id, std::vector<double> params) {
  Camera camera;
  camera.model_id = model_id;
  camera.width = 1296;
  camera.height = 1936;
  camera.params = std::move(params);
  camera.has_prior_focal_length = true;
  return camera;
}

TEST(Database, PairIdsFollowCOLMAP) {
  EXPECT_EQ(ImagePairToPairId(1, 2), 2147483647ull + 2);
  EXPECT_EQ(ImagePairToPairId(2, 1), 2147483647ull + 2);
  image_t a, b;
  PairIdToImagePair(ImagePairToPairId(70000, 3), &a, &b);
  EXPECT_EQ(a, 3u);
  EXPECT_EQ(b, 70000u);
}

TEST(Database, CreatesCOLMAP38SchemaAndRoundTripsEverything) {
  test::TempDir dir;
  const std::string path = dir.File("db.db");
  {
    Database db(path, Database::OpenMode::kCreate);
    EXPECT_EQ(db.schema().user_version, 3800);
    EXPECT_TRUE(db.schema().images_have_prior_columns);
    EXPECT_EQ(db.schema().pose_priors_layout, "3.11");
    EXPECT_FALSE(db.schema().has_rigs);
    DatabaseTransaction transaction(&db);
    const camera_t c1 = db.WriteCamera(MakeCamera(1, {2435, 2436, 648.5, 968.5}));
    Camera fisheye = MakeCamera(5, {300, 301, 648, 968, 0.1, -0.01, 0.001, 0});
    fisheye.camera_id = 7;
    fisheye.has_prior_focal_length = false;
    EXPECT_EQ(db.WriteCamera(fisheye, true), 7u);
    EXPECT_EQ(c1, 1u);
    DbImage image;
    image.name = "cam0/data/1.png";
    image.camera_id = c1;
    image.has_prior_rotation = true;
    image.prior_qvec = Vec4(0.5, 0.5, -0.5, 0.5);
    image.has_prior_position = true;
    image.prior_position = Vec3(1.5, -2, 3);
    image.prior_position_covariance = Mat3::Identity() * 0.01;
    image.prior_position_covariance(0, 1) = 0.002;
    EXPECT_EQ(db.WriteImage(image), 1u);
    DbImage origin = image;
    origin.name = "cam1/data/1.png";
    origin.camera_id = 7;
    origin.prior_position = Vec3(0, 0, 5);  // 3.8's spatial_matcher would skip it
    origin.image_id = 5;
    EXPECT_EQ(db.WriteImage(origin, true), 5u);
    DbImage no_prior;
    no_prior.name = "x.png";
    no_prior.camera_id = 7;
    EXPECT_EQ(db.WriteImage(no_prior), 6u);
    // More than 8192 keypoints (stock 3.8 writes 10-14k), 6 columns as 3.8.
    KeypointsBlob keypoints(10000, 6);
    for (int i = 0; i < keypoints.size(); ++i) keypoints.data()[i] = 0.25f * i;
    db.WriteKeypoints(1, keypoints);
    DescriptorsBlob descriptors(10000, 128);
    for (int i = 0; i < descriptors.size(); ++i) descriptors.data()[i] = i % 251;
    db.WriteDescriptors(1, descriptors);
    MatchesBlob matches(3, 2);
    matches << 0, 10, 1, 11, 2, 12;
    db.WriteMatches(5, 1, matches);  // stored swapped (1, 5)
    TwoViewGeometry g;
    g.config = static_cast<int>(TwoViewConfig::kCalibrated);
    g.inlier_matches = matches;
    g.F << 0, -1, 2, 1, 0, -3, -2, 3, 0;
    g.E << 0, -0.1, 0.2, 0.1, 0, -0.3, -0.2, 0.3, 0;
    g.H << 1, 0.1, 5, 0, 1.1, -2, 0, 0.001, 1;
    const Quat q = so3::Exp(Vec3(0.1, -0.2, 0.05));
    g.qvec = Vec4(q.w(), q.x(), q.y(), q.z());
    g.tvec = Vec3(1, 0.1, -0.2).normalized();
    db.WriteTwoViewGeometry(1, 5, g);
    transaction.Commit();

    // Read back in both orders.
    EXPECT_EQ(db.ReadMatches(5, 1), matches);
    MatchesBlob swapped(3, 2);
    swapped << 10, 0, 11, 1, 12, 2;
    EXPECT_EQ(db.ReadMatches(1, 5), swapped);
    // Match counts without the blobs: one pair with 3 matches.
    const auto counts = db.ReadAllNumMatches();
    ASSERT_EQ(counts.size(), 1u);
    EXPECT_EQ(counts.at(ImagePairToPairId(1, 5)), 3u);
    EXPECT_EQ(counts.at(ImagePairToPairId(1, 5)),
              static_cast<size_t>(db.ReadAllMatches().front().second.rows()));
    const TwoViewGeometry same = db.ReadTwoViewGeometry(1, 5);
    EXPECT_EQ(same.F, g.F);
    EXPECT_EQ(same.qvec, g.qvec);
    EXPECT_EQ(same.inlier_matches, matches);
    const TwoViewGeometry inv = db.ReadTwoViewGeometry(5, 1);
    EXPECT_EQ(inv.F, g.F.transpose());
    EXPECT_EQ(inv.inlier_matches, swapped);
    EXPECT_TRUE((inv.H * g.H - Mat3::Identity()).norm() < 1e-12);
    // Composing the relative pose with its inverse gives the identity.
    const SE3 fwd(q, g.tvec);
    const SE3 back(Quat(inv.qvec(0), inv.qvec(1), inv.qvec(2), inv.qvec(3)), inv.tvec);
    EXPECT_TRUE(test::PosesNear(back * fwd, SE3::Identity(), 1e-12, 1e-12));
  }
  Database db(path, Database::OpenMode::kReadOnly);
  const auto cameras = db.ReadAllCameras();
  ASSERT_EQ(cameras.size(), 2u);
  EXPECT_EQ(cameras[1].camera_id, 7u);
  EXPECT_EQ(cameras[1].ModelName(), "OPENCV_FISHEYE");
  EXPECT_FALSE(cameras[1].has_prior_focal_length);
  EXPECT_TRUE(cameras[0].has_prior_focal_length);
  const auto images = db.ReadAllImages();
  ASSERT_EQ(images.size(), 3u);
  EXPECT_TRUE(images[0].has_prior_rotation);
  EXPECT_EQ(images[0].prior_qvec, Vec4(0.5, 0.5, -0.5, 0.5));
  EXPECT_EQ(images[0].prior_position, Vec3(1.5, -2, 3));
  EXPECT_EQ(images[0].prior_position_covariance(0, 1), 0.002);
  EXPECT_EQ(images[1].image_id, 5u);
  EXPECT_EQ(images[1].prior_position, Vec3(kPriorOriginOffset, 0, 5));
  EXPECT_FALSE(images[2].has_prior_position);
  EXPECT_FALSE(images[2].has_prior_rotation);
  EXPECT_FALSE(images[2].prior_position_covariance.allFinite());
  const KeypointsBlob keypoints = db.ReadKeypoints(1);
  ASSERT_EQ(keypoints.rows(), 10000);
  EXPECT_EQ(keypoints(9999, 5), 0.25f * 59999);
  EXPECT_EQ(db.ReadDescriptors(1)(9999, 127), (9999 * 128 + 127) % 251);
  EXPECT_EQ(db.ReadKeypoints(6).rows(), 0);
  EXPECT_EQ(db.SumRowsColumn("keypoints"), 10000u);
  EXPECT_EQ(db.CountRows("pose_priors"), 2u);
  EXPECT_EQ(db.FindImageId("x.png"), 6u);
  EXPECT_EQ(db.FindImageId("nope.png"), kInvalidImageId);
}

TEST(Database, BadFilesAreInputErrorsNamingTheFile) {
  test::TempDir dir;
  const std::string garbage = dir.File("garbage.db");
  test::WriteText(garbage, std::string(4096, 'x'));
  EXPECT_TRUE(test::ThrowsInputError([&] { Database(garbage, Database::OpenMode::kReadOnly); },
                                     {garbage, "not a COLMAP database"}));
  EXPECT_TRUE(
      test::ThrowsInputError([&] { Database(garbage, Database::OpenMode::kCreate); }, {garbage}));
  const std::string other = dir.File("other.db");
  RawExec(other, "CREATE TABLE foo(a INTEGER)");
  EXPECT_TRUE(test::ThrowsInputError([&] { Database(other, Database::OpenMode::kReadWrite); },
                                     {other, "not a COLMAP database", "foo"}));
  const std::string old_schema = dir.File("old.db");
  RawExec(old_schema,
          "CREATE TABLE cameras(camera_id INTEGER, model INTEGER, width INTEGER, height "
          "INTEGER, params BLOB, prior_focal_length INTEGER); CREATE TABLE images(image_id "
          "INTEGER, name TEXT, camera_id INTEGER); CREATE TABLE keypoints(image_id INTEGER, "
          "rows INTEGER, data BLOB)");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { Database(old_schema, Database::OpenMode::kReadOnly); },
                             {old_schema, "table keypoints", "unknown COLMAP schema", "'cols'"}));
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { Database(dir.File("missing.db"), Database::OpenMode::kReadOnly); },
      {dir.File("missing.db")}));
  const std::string empty = dir.File("empty.db");
  test::WriteText(empty, "");
  EXPECT_TRUE(test::ThrowsInputError([&] { Database(empty, Database::OpenMode::kReadOnly); },
                                     {empty, "not a COLMAP database"}));
}

TEST(Database, WrongBlobSizesNameTableAndRecord) {
  test::TempDir dir;
  const std::string path = dir.File("db.db");
  {
    Database db(path, Database::OpenMode::kCreate);
    db.WriteCamera(MakeCamera(1, {1, 1, 1, 1}));
    DbImage image;
    image.name = "a.png";
    image.camera_id = 1;
    db.WriteImage(image);
  }
  RawExec(path,
          "INSERT INTO keypoints VALUES(1, 5, 6, zeroblob(100));"
          "INSERT INTO matches VALUES(2147483649, 2, 2, zeroblob(12));"
          "INSERT INTO two_view_geometries VALUES(2147483649, 0, 2, NULL, 2, zeroblob(8), NULL, "
          "NULL, NULL, NULL);"
          "UPDATE cameras SET params = zeroblob(24) WHERE camera_id = 1;");
  Database db(path, Database::OpenMode::kReadOnly);
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { db.ReadKeypoints(1); },
      {path, "table keypoints, image_id 1", "expected 120 bytes", "found 100"}));
  EXPECT_TRUE(test::ThrowsInputError([&] { db.ReadMatches(1, 2); },
                                     {path, "table matches, pair_id 2147483649"}));
  EXPECT_TRUE(test::ThrowsInputError([&] { db.ReadAllTwoViewGeometries(); },
                                     {path, "table two_view_geometries", "F blob"}));
  EXPECT_TRUE(test::ThrowsInputError([&] { db.ReadAllCameras(); },
                                     {path, "table cameras, camera_id 1", "expected 32 bytes"}));
}

// Stock COLMAP leaves its databases in WAL mode; reading one must not leave
// `-wal` / `-shm` files beside it, nor change its content.
TEST(Database, ReadingAWalDatabaseLeavesNoSideFiles) {
  test::TempDir dir;
  const std::string path = dir.File("wal.db");
  {
    Database db(path, Database::OpenMode::kCreate);
    db.WriteCamera(MakeCamera(1, {1, 2, 3, 4}));
  }
  RawExec(path, "PRAGMA journal_mode=WAL");
  ASSERT_FALSE(FileExists(path + "-wal"));  // sqlite3 checkpoints and removes them on close
  const std::string before = ReadFile(path);
  {
    const Database db(path, Database::OpenMode::kReadOnly);
    EXPECT_EQ(db.NumCameras(), 1u);
    EXPECT_EQ(db.ReadCamera(1).params[3], 4.0);
    EXPECT_THROW(db.ReadCamera(7), InputError);
  }
  EXPECT_FALSE(FileExists(path + "-wal"));
  EXPECT_FALSE(FileExists(path + "-shm"));
  EXPECT_EQ(ReadFile(path), before);
}

TEST(Database, ReadsNewerSchemaElements) {
  test::TempDir dir;
  const std::string path = dir.File("db.db");
  {
    Database db(path, Database::OpenMode::kCreate);
    db.WriteCamera(MakeCamera(1, {1, 1, 1, 1}));
    db.WriteCamera(MakeCamera(1, {1, 1, 1, 1}));
    for (int i = 0; i < 2; ++i) {
      DbImage image;
      image.name = std::to_string(i) + ".png";
      image.camera_id = 1 + i;
      db.WriteImage(image);
    }
  }
  // COLMAP 4.x: pose_priors keyed by data, plus the 3.12 rig tables.
  Eigen::Matrix<double, 7, 1> pose;
  pose << 1, 0, 0, 0, 0.2, 0, 0;
  std::string hex;
  for (int i = 0; i < 7 * 8; ++i) {
    char b[3];
    std::snprintf(b, sizeof(b), "%02X", reinterpret_cast<const unsigned char*>(pose.data())[i]);
    hex += b;
  }
  const Vec3 position(4, 5, 6);
  std::string pos_hex;
  for (int i = 0; i < 24; ++i) {
    char b[3];
    std::snprintf(b, sizeof(b), "%02X", reinterpret_cast<const unsigned char*>(position.data())[i]);
    pos_hex += b;
  }
  RawExec(path,
          "DROP TABLE pose_priors; CREATE TABLE pose_priors(pose_prior_id INTEGER PRIMARY KEY, "
          "corr_data_id INTEGER, corr_sensor_id INTEGER, corr_sensor_type INTEGER, position "
          "BLOB, position_covariance BLOB, gravity BLOB, coordinate_system INTEGER);"
          "INSERT INTO pose_priors VALUES(1, 2, 2, 0, X'" + pos_hex + "', NULL, NULL, 1);"
          "CREATE TABLE rigs(rig_id INTEGER, ref_sensor_id INTEGER, ref_sensor_type INTEGER);"
          "CREATE TABLE rig_sensors(rig_id INTEGER, sensor_id INTEGER, sensor_type INTEGER, "
          "sensor_from_rig BLOB);"
          "CREATE TABLE frames(frame_id INTEGER, rig_id INTEGER);"
          "CREATE TABLE frame_data(frame_id INTEGER, data_id INTEGER, sensor_id INTEGER, "
          "sensor_type INTEGER);"
          "INSERT INTO rigs VALUES(1, 1, 0); INSERT INTO rig_sensors VALUES(1, 2, 0, X'" + hex +
          "'); INSERT INTO frames VALUES(1, 1); INSERT INTO frame_data VALUES(1, 1, 1, 0);"
          "INSERT INTO frame_data VALUES(1, 2, 2, 0);");
  Database db(path, Database::OpenMode::kReadOnly);
  EXPECT_EQ(db.schema().pose_priors_layout, "4.0");
  EXPECT_TRUE(db.schema().has_rigs);
  const auto images = db.ReadAllImages();
  EXPECT_FALSE(images[0].has_prior_position);
  ASSERT_TRUE(images[1].has_prior_position);
  EXPECT_EQ(images[1].prior_position, position);
  const auto rigs = db.ReadRigs();
  ASSERT_EQ(rigs.size(), 1u);
  ASSERT_EQ(rigs[0].sensors.size(), 1u);
  EXPECT_EQ(rigs[0].sensors[0].tvec, Vec3(0.2, 0, 0));
  const auto frames = db.ReadFrames();
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].data.size(), 2u);
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
