#include "colmap_ext/io/model_io.h"

#include <cstring>

#include <gtest/gtest.h>

#include "colmap_ext/testing/synthetic.h"
#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

// 8 images of 3 cameras (PINHOLE, OPENCV_FISHEYE, OPENCV), 150 points seen by
// 3 images each with 0.5 px noise, 5 keypoints per image without a point.
Reconstruction SmallModel() {
  SyntheticDatasetOptions options;
  options.num_frames = 8;
  options.num_cameras = 3;
  options.camera_models = {"PINHOLE", "OPENCV_FISHEYE", "OPENCV"};
  options.num_points = 150;
  options.track_length = 3;
  options.pixel_noise = 0.5;
  options.num_random_keypoints = 5;
  return SyntheticReconstruction(SynthesizeDataset(options));
}

// Exact equality of everything the files hold; `b` is read back from files
// written from `a`.
void ExpectSameModel(const Reconstruction& a, const Reconstruction& b) {
  ASSERT_EQ(a.NumCameras(), b.NumCameras());
  ASSERT_EQ(a.NumImages(), b.NumImages());
  ASSERT_EQ(a.NumPoints3D(), b.NumPoints3D());
  for (size_t i = 0; i < a.NumCameras(); ++i) {
    EXPECT_EQ(a.Cameras()[i].camera_id, b.Cameras()[i].camera_id);
    EXPECT_EQ(a.Cameras()[i].model_id, b.Cameras()[i].model_id);
    EXPECT_EQ(a.Cameras()[i].params, b.Cameras()[i].params);
  }
  for (size_t i = 0; i < a.NumImages(); ++i) {
    const Image& x = a.Images()[i];
    const Image& y = b.Images()[i];
    EXPECT_EQ(x.image_id, y.image_id);
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(QvecForWriting(x.qvec), y.qvec);  // `b` was read from our files
    EXPECT_EQ(x.tvec, y.tvec);
    ASSERT_EQ(x.points2D.size(), y.points2D.size());
    for (size_t j = 0; j < x.points2D.size(); ++j) {
      EXPECT_EQ(x.points2D[j].xy, y.points2D[j].xy);
      EXPECT_EQ(x.points2D[j].point3D_id, y.points2D[j].point3D_id);
    }
  }
  for (size_t i = 0; i < a.NumPoints3D(); ++i) {
    EXPECT_EQ(a.Points3D()[i].first, b.Points3D()[i].first);
    EXPECT_EQ(a.Points3D()[i].second.xyz, b.Points3D()[i].second.xyz);
    EXPECT_EQ(a.Points3D()[i].second.error, b.Points3D()[i].second.error);
    EXPECT_EQ(a.Points3D()[i].second.track.size(), b.Points3D()[i].second.track.size());
  }
}

TEST(ModelIo, SyntheticModelIsConsistent) {
  const Reconstruction model = SmallModel();
  EXPECT_NO_THROW(model.Validate("synthetic"));
  EXPECT_EQ(model.ComputeNumObservations(), 150u * 3u);
  EXPECT_DOUBLE_EQ(model.ComputeMeanTrackLength(), 3.0);
  // The stored errors are the true noise magnitudes; recomputing them from the
  // geometry must give the same numbers up to projection round-off.
  Reconstruction copy = model;
  copy.UpdatePointErrors();
  for (size_t i = 0; i < model.NumPoints3D(); ++i) {
    EXPECT_NEAR(copy.Points3D()[i].second.error, model.Points3D()[i].second.error, 1e-9);
  }
}

TEST(ModelIo, BinaryRoundTripIsByteIdentical) {
  test::TempDir dir;
  const Reconstruction model = SmallModel();
  WriteModelBinary(model, dir.File("a"));
  const Reconstruction read = ReadModelBinary(dir.File("a"));
  ExpectSameModel(model, read);
  WriteModelBinary(read, dir.File("b"));
  for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) {
    EXPECT_EQ(ReadFile(dir.File(std::string("a/") + f)), ReadFile(dir.File(std::string("b/") + f)))
        << f;
  }
  EXPECT_FALSE(FileExists(dir.File("a/rigs.bin")));
}

TEST(ModelIo, TextRoundTripIsExact) {
  test::TempDir dir;
  const Reconstruction model = SmallModel();
  WriteModelText(model, dir.File("t"));
  const Reconstruction read = ReadModelText(dir.File("t"));
  ExpectSameModel(model, read);
  EXPECT_EQ(ImagesText(read), ImagesText(model));
  EXPECT_EQ(Points3DText(read), Points3DText(model));
  EXPECT_EQ(ImagesBinary(read), ImagesBinary(model));
  ModelFormat format;
  ReadModel(dir.File("t"), &format);
  EXPECT_EQ(format, ModelFormat::kText);
}

TEST(ModelIo, TextLayoutMatchesCOLMAP) {
  Reconstruction model;
  Camera camera;
  camera.camera_id = 3;
  camera.model_id = 1;
  camera.width = 640;
  camera.height = 480;
  camera.params = {500, 500.25, 320.5, 0.1};
  model.AddCamera(camera);
  Image image;
  image.image_id = 9;
  image.camera_id = 3;
  image.name = "a/b.png";
  image.qvec = Vec4(2, 0, 0, 0);  // not unit: normalised on write, as COLMAP does
  image.tvec = Vec3(0.1, -2, 1e-20);
  image.points2D = {{Vec2(1.5, 2.25), 1}, {Vec2(3, 4), kInvalidPoint3DId}};
  model.AddImage(image);
  Point3D point;
  point.xyz = Vec3(1, 2, 3);
  point.color = {255, 0, 7};
  point.error = 0.5;
  point.track = {{9, 0}};
  model.AddPoint3D(1, point);
  EXPECT_EQ(CamerasText(model),
            "# Camera list with one line of data per camera:\n"
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
            "# Number of cameras: 1\n"
            "3 PINHOLE 640 480 500 500.25 320.5 0.10000000000000001\n");
  EXPECT_EQ(ImagesText(model),
            "# Image list with two lines of data per image:\n"
            "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
            "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
            "# Number of images: 1, mean observations per image: 1\n"
            "9 1 0 0 0 0.10000000000000001 -2 9.9999999999999995e-21 3 a/b.png\n"
            "1.5 2.25 1 3 4 -1\n");
  EXPECT_EQ(Points3DText(model),
            "# 3D point list with one line of data per point:\n"
            "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
            "# Number of points: 1, mean track length: 1\n"
            "1 1 2 3 255 0 7 0.5 9 0\n");
}

TEST(ModelIo, RigsAndFramesRoundTrip) {
  test::TempDir dir;
  Reconstruction model = SmallModel();
  ModelRig rig;
  rig.rig_id = 1;
  rig.has_ref_sensor = true;
  rig.ref_sensor = {SensorType::kCamera, 1};
  RigSensor s;
  s.sensor = {SensorType::kCamera, 2};
  s.has_pose = true;
  s.tvec = Vec3(0.1, 0, 0);
  rig.sensors = {s, RigSensor{{SensorType::kImu, 1}, false, Vec4(1, 0, 0, 0), Vec3::Zero()}};
  model.Rigs().push_back(rig);
  ModelFrame frame;
  frame.frame_id = 1;
  frame.rig_id = 1;
  frame.data = {{{SensorType::kCamera, 1}, 1}, {{SensorType::kCamera, 2}, 2}};
  model.Frames().push_back(frame);
  WriteModelBinary(model, dir.File("m"));
  const Reconstruction read = ReadModelBinary(dir.File("m"));
  ASSERT_EQ(read.Rigs().size(), 1u);
  ASSERT_EQ(read.Rigs()[0].sensors.size(), 2u);
  EXPECT_EQ(read.Rigs()[0].sensors[0].tvec, Vec3(0.1, 0, 0));
  EXPECT_FALSE(read.Rigs()[0].sensors[1].has_pose);
  ASSERT_EQ(read.Frames().size(), 1u);
  EXPECT_EQ(read.Frames()[0].data[1].data_id, 2u);
  EXPECT_EQ(RigsBinary(read), RigsBinary(model));
  EXPECT_EQ(FramesBinary(read), FramesBinary(model));
  // 8 + (4 + 4 + 8) + (4 + 4 + 1 + 56) + (4 + 4 + 1) bytes.
  EXPECT_EQ(RigsBinary(model).size(), 8u + 16u + 65u + 9u);
}

TEST(ModelIo, TruncatedBinaryNamesFileAndRecord) {
  test::TempDir dir;
  WriteModelBinary(SmallModel(), dir.File("m"));
  const std::string path = dir.File("m/points3D.bin");
  std::string data = ReadFile(path);
  // Cut inside the third point (each point here is 51 + 3 * 8 = 75 bytes).
  test::WriteText(path, data.substr(0, 8 + 2 * 75 + 30));
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadModelBinary(dir.File("m")); },
                                     {path, "record 2", "truncated"}));
  // A count larger than the file can hold.
  std::string bad_count = data;
  const uint64_t huge = 1ull << 40;
  std::memcpy(&bad_count[0], &huge, 8);
  test::WriteText(path, bad_count);
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadModelBinary(dir.File("m")); },
                                     {path, "record 150", "truncated", "1099511627776"}));
  // A count smaller than the records in the file.
  std::string small_count = data;
  const uint64_t fewer = 149;
  std::memcpy(&small_count[0], &fewer, 8);
  test::WriteText(path, small_count);
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadModelBinary(dir.File("m")); }, {path, "extra bytes"}));
}

TEST(ModelIo, BadCameraModelInBinaryIsInputError) {
  test::TempDir dir;
  WriteModelBinary(SmallModel(), dir.File("m"));
  const std::string path = dir.File("m/cameras.bin");
  std::string data = ReadFile(path);
  const int32_t model = 42;
  std::memcpy(&data[8 + 4], &model, 4);
  test::WriteText(path, data);
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadModelBinary(dir.File("m")); }, {path, "record 0", "42"}));
}

TEST(ModelIo, MalformedTextNamesFileAndLine) {
  test::TempDir dir;
  WriteModelText(SmallModel(), dir.File("t"));
  const std::string images = dir.File("t/images.txt");
  std::string text = ReadFile(images);
  // Line 6 is the 2D point line of the first image (4 header lines).
  std::vector<std::string> lines = SplitString(text, "\n", false);
  lines[5] = "1.0 2.0";
  std::string joined;
  for (const auto& l : lines) joined += l + "\n";
  test::WriteText(images, joined);
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadModelText(dir.File("t")); }, {images, "line 6", "triples"}));
  lines = SplitString(text, "\n", false);
  lines[4] = "1 0.5 zero 0 0 0 0 0 1 x.png";
  joined.clear();
  for (const auto& l : lines) joined += l + "\n";
  test::WriteText(images, joined);
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadModelText(dir.File("t")); }, {images, "line 5", "'zero'"}));
  const std::string cameras = dir.File("t/cameras.txt");
  test::WriteText(cameras, "1 PINHOLE 640 480 500 500 320\n");
  Reconstruction partial;
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadCamerasText(cameras, &partial); }, {cameras, "line 1"}));
}

TEST(ModelIo, InconsistentTracksAreInputErrors) {
  test::TempDir dir;
  Reconstruction model = SmallModel();
  model.MutableImages()[0].points2D[0].point3D_id = 99999;
  WriteModelBinary(model, dir.File("m"));
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadModel(dir.File("m")); },
                                     {dir.File("m"), "image 1 point2D 0"}));
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadModel(dir.File("missing")); }, {dir.File("missing")}));
}

TEST(ModelIo, PlyHasOneVertexPerPoint) {
  test::TempDir dir;
  const Reconstruction model = SmallModel();
  WritePly(model, dir.File("p.ply"));
  const std::string ply = ReadFile(dir.File("p.ply"));
  const size_t header_end = ply.find("end_header\n") + 11;
  EXPECT_NE(ply.find("element vertex 150\n"), std::string::npos);
  EXPECT_EQ(ply.size() - header_end, 150u * 15u);
  float x;
  std::memcpy(&x, ply.data() + header_end, 4);
  EXPECT_EQ(x, static_cast<float>(model.Points3D()[0].second.xyz.x()));
}

TEST(ModelIo, ReadsLundDoorReferenceModel) {
  LISFM_REQUIRE_SHARED_DATA("sfm_lund_door/colmap_ground_truth/cameras.txt");
  const Reconstruction model =
      ReadModelText(test::SharedData("sfm_lund_door/colmap_ground_truth"));
  EXPECT_EQ(model.NumCameras(), 1u);
  EXPECT_EQ(model.NumImages(), 12u);
  EXPECT_EQ(model.Cameras()[0].ModelName(), "SIMPLE_RADIAL");
  EXPECT_GT(model.NumPoints3D(), 1000u);
  // A write + read of our own text form reproduces the model exactly.
  test::TempDir dir;
  WriteModelText(model, dir.File("t"));
  ExpectSameModel(model, ReadModelText(dir.File("t")));
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
