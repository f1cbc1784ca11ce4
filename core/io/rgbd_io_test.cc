// RGB-D sequence readers on small generated fixtures of the three layouts (lisfm rgbd0/,
// TUM RGB-D, 7-Scenes), on the real 7-Scenes subset, and every documented input error.
#include "core/io/rgbd_io.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/trajectory_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;
using test::TempDir;
using test::ThrowsInputError;
using test::WriteText;

constexpr int kWidth = 8;
constexpr int kHeight = 6;

// Depth of pixel (x, y) of frame f in file units; 0 on the pixel (1, 1) (invalid).
uint16_t DepthUnits(int f, int x, int y) {
  if (x == 1 && y == 1) return 0;
  return static_cast<uint16_t>(1000 + 100 * f + 10 * y + x);
}
// Colour of pixel (x, y) of frame f in RGB order: distinct channels.
cv::Vec3b Rgb(int f, int x, int y) {
  return cv::Vec3b(static_cast<uint8_t>(10 * f + x),
                   static_cast<uint8_t>(100 + y),
                   static_cast<uint8_t>(200 + f));
}

void WriteFrameImages(int f,
                      const std::string& color_path,
                      const std::string& depth_path,
                      int width = kWidth,
                      int height = kHeight) {
  cv::Mat depth(height, width, CV_16UC1);
  cv::Mat bgr(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      depth.at<uint16_t>(y, x) = DepthUnits(f, x, y);
      const cv::Vec3b rgb = Rgb(f, x, y);
      bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(rgb[2], rgb[1], rgb[0]);
    }
  }
  fs::create_directories(fs::path(color_path).parent_path());
  fs::create_directories(fs::path(depth_path).parent_path());
  ASSERT_TRUE(cv::imwrite(depth_path, depth));
  ASSERT_TRUE(cv::imwrite(color_path, bgr));
}

// Expects LoadRgbdFrame(f) to hold the fixture's pixels scaled by m_per_unit.
void ExpectFixturePixels(const RgbdImage& image, int f, double m_per_unit) {
  ASSERT_EQ(image.width, kWidth);
  ASSERT_EQ(image.height, kHeight);
  ASSERT_EQ(image.depth_m.size(), static_cast<size_t>(kWidth * kHeight));
  ASSERT_EQ(image.rgb.size(), static_cast<size_t>(3 * kWidth * kHeight));
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const size_t i = static_cast<size_t>(y) * kWidth + x;
      EXPECT_FLOAT_EQ(image.depth_m[i], static_cast<float>(DepthUnits(f, x, y) * m_per_unit))
          << x << "," << y;
      const cv::Vec3b rgb = Rgb(f, x, y);
      EXPECT_EQ(image.rgb[3 * i + 0], rgb[0]);
      EXPECT_EQ(image.rgb[3 * i + 1], rgb[1]);
      EXPECT_EQ(image.rgb[3 * i + 2], rgb[2]);
    }
  }
}

constexpr TimestampNs kStart = 1700000000000000000LL;
constexpr TimestampNs kStep = 33333333;  // ~30 Hz

// The simulator's RGB-D extrinsic (sim/simulator.cc): optical axis along the IMU's x.
SE3 SimCamFromImu() {
  const Mat3 r = (Mat3() << 0, 1, 0, 0, 0, 1, 1, 0, 0).finished();
  return SE3(r, Vec3::Zero()) * SE3(Quat::Identity(), Vec3(-0.05, -0.05, 0.0));
}

std::string CameraYamlText(const std::string& depth_scale_line, const SE3* cam_from_imu) {
  std::string s = fmt::format("intrinsics: [5.5, 5.25, 3.5, 2.5]\nresolution: [{}, {}]\n{}",
                              kWidth,
                              kHeight,
                              depth_scale_line);
  if (cam_from_imu) {
    const Mat4 m = cam_from_imu->Matrix();
    s += "T_cam_imu:\n";
    for (int r = 0; r < 4; ++r) {
      s += fmt::format(
          "- [{:.17g}, {:.17g}, {:.17g}, {:.17g}]\n", m(r, 0), m(r, 1), m(r, 2), m(r, 3));
    }
  }
  return s;
}

// A lisfm sequence: 3 frames at kStep, groundtruth.txt (world_from_imu) at 2 kStep over a
// longer span, camera.yaml with the simulator's extrinsic.
Trajectory WriteLisfmSequence(const std::string& root,
                              const std::string& depth_scale_line = "depth_scale: 1000\n") {
  const std::string dir = JoinPaths(root, "rgbd0");
  fs::create_directories(dir);
  std::string csv = "#timestamp [ns],rgb,depth\n";
  for (int f = 0; f < 3; ++f) {
    const TimestampNs t = kStart + f * kStep;
    const std::string name = std::to_string(t) + ".png";
    WriteFrameImages(f, JoinPaths(dir, "rgb/" + name), JoinPaths(dir, "depth/" + name));
    csv += fmt::format("{},rgb/{},depth/{}\n", t, name, name);
  }
  WriteText(JoinPaths(dir, "data.csv"), csv);
  const SE3 cam_from_imu = SimCamFromImu();
  WriteText(JoinPaths(dir, "camera.yaml"), CameraYamlText(depth_scale_line, &cam_from_imu));
  std::vector<StampedPose> gt;
  for (int k = -1; k < 4; ++k) gt.push_back({kStart + 2 * k * kStep, test::RandomPose(1.0, 3.0)});
  const Trajectory world_from_imu(gt);
  WriteTum(JoinPaths(root, "groundtruth.txt"), world_from_imu);
  return world_from_imu;
}

TEST(RgbdIo, ReadsTheLisfmSequenceLayout) {
  TempDir dir;
  const Trajectory world_from_imu = WriteLisfmSequence(dir.path());
  const Trajectory read_back = ReadTum(dir.File("groundtruth.txt"));  // as the reader sees it
  for (const std::string& path : {dir.path(), dir.File("rgbd0"), dir.File("rgbd0/")}) {
    const RgbdSequence seq = ReadRgbdSequence(path);
    EXPECT_EQ(seq.layout, RgbdLayout::kLisfm);
    EXPECT_EQ(seq.intrinsics.fx, 5.5);
    EXPECT_EQ(seq.intrinsics.fy, 5.25);
    EXPECT_EQ(seq.intrinsics.cx, 3.5);
    EXPECT_EQ(seq.intrinsics.cy, 2.5);
    EXPECT_EQ(seq.intrinsics.width, kWidth);
    EXPECT_EQ(seq.intrinsics.height, kHeight);
    EXPECT_DOUBLE_EQ(seq.depth_m_per_unit, 0.001);
    ASSERT_EQ(seq.frames.size(), 3u);
    ASSERT_EQ(seq.NumGivenPoses(), 3u);
    for (int f = 0; f < 3; ++f) {
      EXPECT_EQ(seq.frames[f].t_ns, kStart + f * kStep);
      // world_from_camera = world_from_imu(t) * (cam_from_imu)^-1, as the simulator renders.
      const SE3 expected = *read_back.Interpolate(kStart + f * kStep) * SimCamFromImu().Inverse();
      EXPECT_TRUE(test::PosesNear(*seq.frames[f].world_from_camera, expected, 1e-12, 1e-12));
      ExpectFixturePixels(LoadRgbdFrame(seq, f), f, 0.001);
    }
    // Frame 0 is on a ground-truth sample: the composition itself, independent of interpolation.
    EXPECT_TRUE(test::PosesNear(*seq.frames[0].world_from_camera,
                                world_from_imu[1].pose * SimCamFromImu().Inverse(),
                                1e-9,
                                1e-9));
    const Trajectory given = seq.GivenTrajectory();
    ASSERT_EQ(given.size(), 3u);
    EXPECT_EQ(given[2].t_ns, kStart + 2 * kStep);
  }
}

TEST(RgbdIo, DownsamplesEveryFactorthPixel) {
  TempDir dir;
  WriteLisfmSequence(dir.path());
  const RgbdSequence seq = ReadRgbdSequence(dir.path());
  const RgbdImage full = LoadRgbdFrame(seq, 1);
  for (int factor : {2, 3}) {
    const RgbdImage image = LoadRgbdFrame(seq, 1, factor);
    const RgbdIntrinsics k = DownsampleIntrinsics(seq.intrinsics, factor);
    EXPECT_EQ(image.width, k.width);
    EXPECT_EQ(image.height, k.height);
    EXPECT_EQ(k.width, (kWidth + factor - 1) / factor);
    EXPECT_EQ(k.height, (kHeight + factor - 1) / factor);
    EXPECT_DOUBLE_EQ(k.fx, 5.5 / factor);
    EXPECT_DOUBLE_EQ(k.cy, 2.5 / factor);
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        const size_t i = static_cast<size_t>(y) * image.width + x;
        const size_t j = static_cast<size_t>(y * factor) * kWidth + x * factor;
        EXPECT_EQ(image.depth_m[i], full.depth_m[j]);
        for (int c = 0; c < 3; ++c) EXPECT_EQ(image.rgb[3 * i + c], full.rgb[3 * j + c]);
        // The sample's pixel centre projects where the full-resolution one does.
        const double u_full = x * factor, u = x;
        EXPECT_NEAR((u - k.cx) / k.fx, (u_full - seq.intrinsics.cx) / seq.intrinsics.fx, 1e-12);
      }
    }
  }
}

TEST(RgbdIo, ReadsTheTumLayoutWithAssociation) {
  TempDir dir;
  // Colour at 0, 33, 66, 99 ms; depth at +5 ms except the last (60 ms later: unpaired).
  std::string rgb = "# color images\n# file: 'x.bag'\n# timestamp filename\n";
  std::string depth = "# depth maps\n# file: 'x.bag'\n# timestamp filename\n";
  const double t0 = 1305031102.175304;
  for (int f = 0; f < 4; ++f) {
    const double tc = t0 + 0.033 * f;
    const double td = tc + (f == 3 ? 0.060 : 0.005);
    const std::string cname = fmt::format("rgb/{:.6f}.png", tc);
    const std::string dname = fmt::format("depth/{:.6f}.png", td);
    WriteFrameImages(f, dir.File(cname), dir.File(dname));
    rgb += fmt::format("{:.6f} {}\n", tc, cname);
    depth += fmt::format("{:.6f} {}\n", td, dname);
  }
  WriteText(dir.File("rgb.txt"), rgb);
  WriteText(dir.File("depth.txt"), depth);
  {
    // No intrinsics in the folder: the TUM ROS default (640x480, which these 8x6 images
    // do not match: loading names both).
    const RgbdSequence seq = ReadRgbdSequence(dir.path());
    EXPECT_EQ(seq.layout, RgbdLayout::kTum);
    EXPECT_EQ(seq.intrinsics_source, "TUM ROS default");
    EXPECT_EQ(seq.intrinsics.fx, 525.0);
    EXPECT_EQ(seq.intrinsics.width, 640);
    EXPECT_DOUBLE_EQ(seq.depth_m_per_unit, 1.0 / 5000.0);
    EXPECT_EQ(seq.NumGivenPoses(), 0u);
    EXPECT_TRUE(seq.pose_source.empty());
    ASSERT_EQ(seq.frames.size(), 3u);
    EXPECT_TRUE(ThrowsInputError([&] { LoadRgbdFrame(seq, 0); },
                                 {seq.frames[0].depth_path, "8 x 6", "640 x 480"}));
  }
  WriteText(dir.File("camera.yaml"), CameraYamlText("", nullptr));
  // Ground truth covering frames 0..1 only (frame 2 lies beyond its end).
  std::vector<StampedPose> gt;
  TimestampNs t0_ns = 0;
  ASSERT_TRUE(ParseSecondsToNs("1305031102.175304", &t0_ns));
  for (int k = -2; k < 5; ++k) gt.push_back({t0_ns + k * 10000000LL, test::RandomPose()});
  WriteTum(dir.File("groundtruth.txt"), Trajectory(gt));
  const RgbdSequence seq = ReadRgbdSequence(dir.path());
  EXPECT_EQ(seq.intrinsics_source, dir.File("camera.yaml"));
  EXPECT_EQ(seq.intrinsics.fx, 5.5);
  EXPECT_DOUBLE_EQ(seq.depth_m_per_unit, 1.0 / 5000.0);
  ASSERT_EQ(seq.frames.size(), 3u);
  for (int f = 0; f < 3; ++f) {
    ExpectFixturePixels(LoadRgbdFrame(seq, f), f, 1.0 / 5000.0);
    EXPECT_NE(seq.frames[f].color_path.find("rgb/"), std::string::npos);
    EXPECT_NE(seq.frames[f].depth_path.find("depth/"), std::string::npos);
  }
  EXPECT_EQ(seq.frames[0].t_ns, t0_ns);  // the colour stamp, exact to the ns
  EXPECT_EQ(seq.frames[1].t_ns, t0_ns + 33000000);
  ASSERT_TRUE(seq.frames[0].world_from_camera.has_value());
  EXPECT_TRUE(test::PosesNear(*seq.frames[0].world_from_camera, gt[2].pose, 1e-12, 1e-12));
  EXPECT_TRUE(seq.frames[1].world_from_camera.has_value());
  EXPECT_FALSE(seq.frames[2].world_from_camera.has_value());
  EXPECT_EQ(seq.NumGivenPoses(), 2u);

  // A wider tolerance pairs the last colour image too; a depth scale option overrides.
  RgbdReadOptions options;
  options.association_max_dt_s = 0.1;
  options.depth_units_per_m = 1000;
  const RgbdSequence wide = ReadRgbdSequence(dir.path(), options);
  EXPECT_EQ(wide.frames.size(), 4u);
  EXPECT_DOUBLE_EQ(wide.depth_m_per_unit, 0.001);
}

// A 7-Scenes folder: frames/ with frame-XXXXXX.{color.jpg|color.png, depth.png, pose.txt},
// camera-intrinsics.txt beside frames/.
std::vector<SE3> WriteSevenScenes(const std::string& root, int num_frames = 3) {
  std::vector<SE3> poses;
  for (int f = 0; f < num_frames; ++f) {
    const std::string stem = JoinPaths(root, fmt::format("frames/frame-{:06d}", f));
    // PNG colour for frame 1 (lossless, so pixels can be compared); JPEG otherwise.
    WriteFrameImages(f, stem + (f == 1 ? ".color.png" : ".color.jpg"), stem + ".depth.png");
    poses.push_back(test::RandomPose());
    const Mat4 m = poses.back().Matrix();
    std::string text;
    for (int r = 0; r < 4; ++r) {
      text += fmt::format("{:.18e} {:.18e} {:.18e} {:.18e}\n", m(r, 0), m(r, 1), m(r, 2), m(r, 3));
    }
    WriteText(stem + ".pose.txt", text);
  }
  WriteText(JoinPaths(root, "camera-intrinsics.txt"),
            "5.85e+00 0.0 3.2e+00\n0.0 5.85e+00 2.4e+00\n0.0 0.0 1.0\n");
  return poses;
}

TEST(RgbdIo, ReadsTheSevenScenesLayout) {
  TempDir dir;
  const std::vector<SE3> poses = WriteSevenScenes(dir.path());
  // 65535 is invalid in 7-Scenes as 0 is.
  cv::Mat depth = cv::imread(dir.File("frames/frame-000001.depth.png"), cv::IMREAD_UNCHANGED);
  depth.at<uint16_t>(2, 3) = 65535;
  ASSERT_TRUE(cv::imwrite(dir.File("frames/frame-000001.depth.png"), depth));
  // camera-intrinsics.txt beside frames/ is found from frames/ too, with or without a
  // trailing separator.
  for (const std::string& path : {dir.path(), dir.File("frames"), dir.File("frames/")}) {
    const RgbdSequence seq = ReadRgbdSequence(path);
    EXPECT_EQ(seq.layout, RgbdLayout::kSevenScenes);
    EXPECT_EQ(seq.intrinsics.fx, 5.85);
    EXPECT_EQ(seq.intrinsics.cx, 3.2);
    EXPECT_EQ(seq.intrinsics.cy, 2.4);
    EXPECT_EQ(seq.intrinsics.width, kWidth);
    EXPECT_EQ(seq.intrinsics.height, kHeight);
    EXPECT_DOUBLE_EQ(seq.depth_m_per_unit, 0.001);
    ASSERT_EQ(seq.frames.size(), 3u);
    ASSERT_EQ(seq.NumGivenPoses(), 3u);
    for (int f = 0; f < 3; ++f) {
      EXPECT_EQ(seq.frames[f].t_ns, SecondsToNs(f / 30.0));
      EXPECT_TRUE(test::PosesNear(*seq.frames[f].world_from_camera, poses[f], 1e-12, 1e-12));
    }
    RgbdImage image = LoadRgbdFrame(seq, 1);
    EXPECT_EQ(image.depth_m[2 * kWidth + 3], 0.f);
    image.depth_m[2 * kWidth + 3] = DepthUnits(1, 3, 2) * 0.001f;
    ExpectFixturePixels(image, 1, 0.001);
    EXPECT_EQ(LoadRgbdFrame(seq, 0).depth_m[2 * kWidth + 3], DepthUnits(0, 3, 2) * 0.001f);
  }
}

TEST(RgbdIo, ReadsTheRealSevenScenesSubset) {
  LISFM_REQUIRE_SHARED_DATA("rgbd_7scenes_subset");
  const RgbdSequence seq = ReadRgbdSequence(test::SharedData("rgbd_7scenes_subset"));
  EXPECT_EQ(seq.layout, RgbdLayout::kSevenScenes);
  // camera-intrinsics.txt of the data set: fx = fy = 585, cx = 320, cy = 240.
  EXPECT_EQ(seq.intrinsics.fx, 585.0);
  EXPECT_EQ(seq.intrinsics.fy, 585.0);
  EXPECT_EQ(seq.intrinsics.cx, 320.0);
  EXPECT_EQ(seq.intrinsics.cy, 240.0);
  EXPECT_EQ(seq.intrinsics.width, 640);
  EXPECT_EQ(seq.intrinsics.height, 480);
  ASSERT_EQ(seq.frames.size(), 200u);
  EXPECT_EQ(seq.NumGivenPoses(), 200u);
  EXPECT_EQ(seq.frames.back().t_ns, SecondsToNs(199 / 30.0));
  // frame-000000.pose.txt, translation column.
  EXPECT_NEAR(seq.frames[0].world_from_camera->translation().x(), -0.34045634, 1e-8);
  EXPECT_NEAR(seq.frames[0].world_from_camera->translation().z(), 0.29656917, 1e-8);
  // Hand-held at 30 Hz: consecutive poses within 5 cm and 3 degrees.
  for (size_t i = 1; i < seq.frames.size(); ++i) {
    const SE3 d = seq.frames[i - 1].world_from_camera->Inverse() * *seq.frames[i].world_from_camera;
    EXPECT_LT(d.translation().norm(), 0.05) << i;
    EXPECT_LT(d.Log().head<3>().norm(), 3.0 * M_PI / 180.0) << i;
  }
  const RgbdImage image = LoadRgbdFrame(seq, 0, 2);
  EXPECT_EQ(image.width, 320);
  EXPECT_EQ(image.height, 240);
  size_t valid = 0;
  float max_depth = 0;
  for (float d : image.depth_m) {
    if (d > 0) ++valid;
    max_depth = std::max(max_depth, d);
  }
  // A Kinect v1 indoor frame: most pixels valid, nothing beyond its ~4 m range
  // (the data set's README: max ~3.5 m in frame 0).
  EXPECT_GT(valid, image.depth_m.size() / 2);
  EXPECT_GT(max_depth, 1.0f);
  EXPECT_LT(max_depth, 4.5f);
}

TEST(RgbdIo, IntrinsicsOverride) {
  TempDir dir;
  WriteSevenScenes(dir.path());
  WriteText(dir.File("k.txt"), "2 0 1\n0 3 1.5\n0 0 1\n");
  RgbdReadOptions options;
  options.intrinsics_path = dir.File("k.txt");
  const RgbdSequence seq = ReadRgbdSequence(dir.path(), options);
  EXPECT_EQ(seq.intrinsics.fx, 2.0);
  EXPECT_EQ(seq.intrinsics.fy, 3.0);
  EXPECT_EQ(seq.intrinsics.width, kWidth);
  EXPECT_EQ(seq.intrinsics_source, dir.File("k.txt"));
  options.layout = RgbdLayout::kTum;  // forced layout: its files must be there
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path(), options); },
                               {dir.File("rgb.txt"), "not found"}));
}

TEST(RgbdIo, LayoutNames) {
  for (RgbdLayout l :
       {RgbdLayout::kAuto, RgbdLayout::kLisfm, RgbdLayout::kTum, RgbdLayout::kSevenScenes}) {
    EXPECT_EQ(ParseRgbdLayout(RgbdLayoutName(l)), l);
  }
  EXPECT_THROW(ParseRgbdLayout("kinect"), UsageError);
}

// ---- input errors ----

TEST(RgbdIo, UnknownFolderIsAnError) {
  TempDir dir;
  WriteText(dir.File("readme.txt"), "nothing here\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {dir.path(), "no RGB-D layout", "rgb.txt"}));
  EXPECT_TRUE(
      ThrowsInputError([&] { ReadRgbdSequence(dir.File("missing")); }, {dir.File("missing")}));
}

TEST(RgbdIo, MissingFrameFileNamesTheListLine) {
  TempDir dir;
  WriteLisfmSequence(dir.path());
  const RgbdSequence seq = ReadRgbdSequence(dir.path());
  fs::remove(seq.frames[1].depth_path);
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {dir.File("rgbd0/data.csv"),
                                "line 3",
                                "depth image",
                                seq.frames[1].depth_path,
                                "not found"}));
  // Read before the file went away: loading names the file.
  EXPECT_TRUE(ThrowsInputError([&] { LoadRgbdFrame(seq, 1); }, {seq.frames[1].depth_path}));

  TempDir seven;
  WriteSevenScenes(seven.path());
  fs::remove(seven.File("frames/frame-000002.color.jpg"));
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(seven.path()); },
                               {"frame-000002.color.jpg", "not found"}));
}

TEST(RgbdIo, MalformedDataCsvLines) {
  TempDir dir;
  WriteLisfmSequence(dir.path());
  const std::string csv = dir.File("rgbd0/data.csv");
  const std::string good = ReadFile(csv);
  WriteText(csv, good + "123,rgb/x.png\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {csv, "line 5", "expected 3 columns", "found 2"}));
  WriteText(csv, "#timestamp [ns],rgb,depth\n12x,a,b\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); }, {csv, "line 2", "'12x'"}));
}

TEST(RgbdIo, DecreasingStampsAreAnError) {
  TempDir dir;
  WriteLisfmSequence(dir.path());
  const std::string csv = dir.File("rgbd0/data.csv");
  std::vector<std::string> lines = SplitString(ReadFile(csv), "\n");
  std::swap(lines[2], lines[3]);
  std::string text;
  for (const std::string& l : lines) text += l + "\n";
  WriteText(csv, text);
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {csv, "line 4", "strictly increasing"}));
}

TEST(RgbdIo, UnknownOrZeroDepthScaleIsAnError) {
  for (const std::string& line :
       {std::string(""), std::string("depth_scale: 0\n"), std::string("depth_scale: mm\n")}) {
    TempDir dir;
    WriteLisfmSequence(dir.path(), line);
    EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                                 {dir.File("rgbd0/camera.yaml"), "depth_scale"}))
        << "'" << line << "'";
    // An explicit scale option makes the missing one usable.
    if (line.empty()) {
      RgbdReadOptions options;
      options.depth_units_per_m = 1000;
      EXPECT_DOUBLE_EQ(ReadRgbdSequence(dir.path(), options).depth_m_per_unit, 0.001);
    }
  }
}

TEST(RgbdIo, MalformedCameraYamlIsAnError) {
  TempDir dir;
  WriteLisfmSequence(dir.path());
  const std::string yaml = dir.File("rgbd0/camera.yaml");
  WriteText(yaml, "intrinsics: [5, 5, 3]\nresolution: [8, 6]\ndepth_scale: 1000\n");
  EXPECT_TRUE(
      ThrowsInputError([&] { ReadRgbdSequence(dir.path()); }, {yaml, "intrinsics", "4 numbers"}));
  WriteText(yaml, "intrinsics: [0, 5, 3, 2]\nresolution: [8, 6]\ndepth_scale: 1000\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); }, {yaml, "fx = 0"}));
  WriteText(yaml, "intrinsics: [5, 5, 3, 2]\nresolution: [8, 6]\ndepth_scale: 1000\n");
  // Ground truth beside it but no extrinsic: no camera poses can be given.
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); }, {yaml, "T_cam_imu"}));
  WriteText(yaml,
            "intrinsics: [5, 5, 3, 2]\nresolution: [8, 6]\ndepth_scale: 1000\nT_cam_imu:\n"
            "- [2, 0, 0, 0]\n- [0, 1, 0, 0]\n- [0, 0, 1, 0]\n- [0, 0, 0, 1]\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {yaml, "T_cam_imu", "not a rotation"}));
  WriteText(yaml, "intrinsics: [5, 5, 3, 2\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); }, {yaml, "line"}));
}

TEST(RgbdIo, MalformedPoseIsAnError) {
  TempDir dir;
  WriteSevenScenes(dir.path());
  const std::string pose = dir.File("frames/frame-000001.pose.txt");
  WriteText(pose, "1 0 0 0\n0 1 0 0\n0 0 1\n0 0 0 1\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {pose, "line 3", "expected 4 numbers", "found 3"}));
  WriteText(pose, "1 0 0 0\n0 1 0 0\n0 0 1 x\n0 0 0 1\n");
  EXPECT_TRUE(
      ThrowsInputError([&] { ReadRgbdSequence(dir.path()); }, {pose, "line 3", "column 4", "'x'"}));
  WriteText(pose, "1 0 0 0\n0 1 0 0\n0 0 1 0\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {pose, "expected 4 rows", "found 3"}));
  WriteText(pose, "1 0 0 0\n0 1 0 0\n0 0.5 1 0\n0 0 0 1\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); }, {pose, "not a rotation"}));
  WriteText(pose, "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n");
  EXPECT_TRUE(
      ThrowsInputError([&] { ReadRgbdSequence(dir.path()); }, {pose, "last row must be 0 0 0 1"}));
  fs::remove(dir.File("camera-intrinsics.txt"));
  WriteText(pose, "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {"camera-intrinsics.txt", "not found"}));
}

TEST(RgbdIo, ImageErrorsNameTheFiles) {
  TempDir dir;
  WriteLisfmSequence(dir.path());
  const RgbdSequence seq = ReadRgbdSequence(dir.path());
  // Colour and depth of different sizes.
  ASSERT_TRUE(cv::imwrite(seq.frames[0].color_path, cv::Mat(kHeight, kWidth + 2, CV_8UC3)));
  EXPECT_TRUE(
      ThrowsInputError([&] { LoadRgbdFrame(seq, 0); },
                       {seq.frames[0].color_path, "10 x 6", seq.frames[0].depth_path, "8 x 6"}));
  // An 8-bit depth image.
  ASSERT_TRUE(cv::imwrite(seq.frames[1].depth_path, cv::Mat(kHeight, kWidth, CV_8UC1)));
  EXPECT_TRUE(ThrowsInputError([&] { LoadRgbdFrame(seq, 1); },
                               {seq.frames[1].depth_path, "16-bit single-channel", "8 bits"}));
  // Not an image at all.
  WriteText(seq.frames[2].depth_path, "not a png");
  EXPECT_TRUE(ThrowsInputError([&] { LoadRgbdFrame(seq, 2); },
                               {seq.frames[2].depth_path, "cannot be read"}));
}

TEST(RgbdIo, TumListErrors) {
  TempDir dir;
  WriteFrameImages(0, dir.File("rgb/1.png"), dir.File("depth/1.png"));
  WriteText(dir.File("rgb.txt"), "# c\n1.0 rgb/1.png\n1.1 rgb/2.png\n");
  WriteText(dir.File("depth.txt"), "1.0 depth/1.png\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {dir.File("rgb.txt"), "line 3", "rgb/2.png", "not found"}));
  WriteText(dir.File("rgb.txt"), "1.0 rgb/1.png extra\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {dir.File("rgb.txt"), "line 1", "expected 2 columns"}));
  WriteText(dir.File("rgb.txt"), "5.0 rgb/1.png\n");
  EXPECT_TRUE(ThrowsInputError([&] { ReadRgbdSequence(dir.path()); },
                               {dir.File("depth.txt"), "no depth image within"}));
}

TEST(RgbdIo, OptionsCheck) {
  RgbdReadOptions options;
  EXPECT_TRUE(options.Check());
  options.association_max_dt_s = 0;
  EXPECT_FALSE(options.Check());
  options = RgbdReadOptions();
  options.depth_units_per_m = -1;
  EXPECT_FALSE(options.Check());
}

}  // namespace
}  // namespace lisfm
