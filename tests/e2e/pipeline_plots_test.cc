// scripts/pipeline_plots.py on small synthetic inputs written here: a ground
// truth on a circle, a trajectory that is the same path in another frame (a
// rigid transform), one with a known constant offset in its own frame after
// half the time, and a COLMAP binary model written by our writer with known
// track lengths. Checks the three PNGs and the numbers the script prints, then
// bad input. Skips when /usr/bin/python3 lacks numpy or matplotlib.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "colmap_ext/io/model_io.h"
#include "core/geometry.h"
#include "core/io/trajectory_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

const char* kPython = "/usr/bin/python3";

std::string Script() { return test::SourceDir() + "/scripts/pipeline_plots.py"; }

bool HasMatplotlib() {
  std::string out;
  return test::RunCommand(std::string(kPython) + " -c 'import numpy, matplotlib' 2>&1", &out) == 0;
}

// True when `path` starts with the PNG signature and its IHDR size is at
// least min_width x min_height.
::testing::AssertionResult IsPng(const std::string& path, uint32_t min_width, uint32_t min_height) {
  std::ifstream in(path, std::ios::binary);
  unsigned char h[24];
  if (!in.read(reinterpret_cast<char*>(h), sizeof(h))) {
    return ::testing::AssertionFailure() << path << " missing or shorter than a PNG header";
  }
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (!std::equal(kSignature, kSignature + 8, h) || std::string(h + 12, h + 16) != "IHDR") {
    return ::testing::AssertionFailure() << path << " is not a PNG";
  }
  const auto be32 = [&](int at) {
    return (uint32_t{h[at]} << 24) | (uint32_t{h[at + 1]} << 16) | (uint32_t{h[at + 2]} << 8) |
           uint32_t{h[at + 3]};
  };
  const uint32_t width = be32(16), height = be32(20);
  if (width < min_width || height < min_height || width > 4000 || height > 4000) {
    return ::testing::AssertionFailure() << path << " is " << width << "x" << height;
  }
  return ::testing::AssertionSuccess();
}

// The number after "<label>" in the script's output (NaN when absent).
double NumberAfter(const std::string& out, const std::string& label) {
  const size_t at = out.find(label);
  if (at == std::string::npos) return std::nan("");
  return std::stod(out.substr(at + label.size()));
}

class PipelinePlots : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!HasMatplotlib()) {
      GTEST_SKIP() << kPython << " lacks numpy or matplotlib (Debian python3-numpy "
                   << "python3-matplotlib; scripts/install_deps.sh installs them)";
    }
    // Ground truth: 20 s on a circle of radius 3 m at 10 Hz, z gently varying.
    Trajectory gt, moved, offset;
    const SE3 other_from_world(so3::Exp(Vec3(0.02, -0.01, 1.2)), Vec3(5, -2, 0.3));
    for (int i = 0; i <= 200; ++i) {
      const TimestampNs t = 1700000000000000000LL + i * 100000000LL;
      const double a = 0.05 * i;
      const SE3 pose(so3::Exp(Vec3(0, 0, a)), Vec3(3 * std::cos(a), 3 * std::sin(a), 0.1 * a));
      gt.PushBack({t, pose});
      moved.PushBack({t, other_from_world * pose});
      // From 10 s on, 0.2 m off along the trajectory's world x: after the
      // best rigid fit the error is ~0.1 m everywhere.
      const Vec3 shift = i >= 100 ? Vec3(0.2, 0, 0) : Vec3::Zero();
      offset.PushBack({t, SE3(Quat::Identity(), shift) * other_from_world * pose});
    }
    WriteTum(dir_.File("gt.txt"), gt);
    WriteTum(dir_.File("moved.txt"), moved);
    WriteTum(dir_.File("offset.txt"), offset);

    // A model: 7 images of one camera, 42 points with track lengths 2..7 (7 each).
    colmap::Camera camera;
    camera.camera_id = 1;
    camera.model_id = static_cast<int>(colmap::CameraModelId::kOpenCVFisheye);
    camera.width = 720;
    camera.height = 540;
    camera.params = {350, 350, 360, 270, -0.03, -0.01, 0.005, -0.002};
    model_.AddCamera(camera);
    for (int i = 0; i < 7; ++i) {
      colmap::Image image;
      image.image_id = static_cast<colmap::image_t>(i + 1);
      image.camera_id = 1;
      image.name = "cam0/data/" + std::to_string(1000 + i) + ".png";
      const Vec3 centre(i * 0.5, 0, 0);
      image.SetCamFromWorld(SE3(Quat::Identity(), -centre));
      image.points2D.resize(42);
      for (auto& p : image.points2D) p.xy = Vec2(100, 100);
      model_.AddImage(image);
    }
    for (int j = 0; j < 42; ++j) {
      colmap::Point3D point;
      point.xyz = Vec3(0.1 * j, 0.05 * j, 5);
      point.error = 0.5;
      const int length = 2 + j % 6;
      for (int k = 0; k < length; ++k) {
        point.track.push_back(
            {static_cast<colmap::image_t>(k + 1), static_cast<colmap::point2D_t>(j)});
      }
      model_.AddPoint3DWithTrack(point);
    }
    colmap::WriteModelBinary(model_, dir_.File("sparse/0"));
  }

  int Run(const std::string& args, std::string* out) {
    return test::RunCommand(std::string(kPython) + " " + Script() + " " + args + " 2>&1", out);
  }

  test::TempDir dir_;
  colmap::Reconstruction model_;
};

TEST_F(PipelinePlots, WritesTheThreePlots) {
  std::string out;
  const std::string plots = dir_.File("plots");
  ASSERT_EQ(Run("--output_dir " + plots + " --trajectory lio=" + dir_.File("moved.txt") +
                    " --trajectory pose_slam=" + dir_.File("offset.txt") + " --groundtruth " +
                    dir_.File("gt.txt") + " --model_path " + dir_.File("sparse/0"),
                &out),
            0)
      << out;
  for (const char* png : {"trajectories.png", "errors.png", "model.png"}) {
    EXPECT_TRUE(IsPng(plots + "/" + png, 400, 300)) << out;
  }
  // Only the three PNGs (no temporary files left).
  EXPECT_EQ(std::distance(fs::directory_iterator(plots), fs::directory_iterator()), 3) << out;
  // A rigid copy of the ground truth aligns exactly (TUM text rounding only).
  EXPECT_LT(NumberAfter(out, "lio: 201 poses, position error after SE(3) alignment: RMSE "), 1e-6)
      << out;
  // Half the path 0.2 m off: the rigid fit splits it, ~0.1 m each side (the
  // circle's rotation freedom absorbs a little of it).
  const double offset_rmse =
      NumberAfter(out, "pose_slam: 201 poses, position error after SE(3) alignment: RMSE ");
  EXPECT_GT(offset_rmse, 0.05) << out;
  EXPECT_LT(offset_rmse, 0.11) << out;
  // Model read back: 7 images, 42 points, mean track length (2+...+7)/6 = 4.5.
  EXPECT_NE(out.find("7 images, 42 points, mean track length 4.500"), std::string::npos) << out;
}

TEST_F(PipelinePlots, WithoutGroundTruthNoErrorPlot) {
  std::string out;
  const std::string plots = dir_.File("plots");
  ASSERT_EQ(Run("--output_dir " + plots + " --trajectory lio=" + dir_.File("moved.txt"), &out), 0)
      << out;
  EXPECT_TRUE(IsPng(plots + "/trajectories.png", 400, 300)) << out;
  EXPECT_FALSE(fs::exists(plots + "/errors.png"));
  EXPECT_FALSE(fs::exists(plots + "/model.png"));
}

TEST_F(PipelinePlots, BadInput) {
  std::string out;
  const std::string plots = dir_.File("bad");
  // A missing ground truth: named, exit 1, nothing written.
  EXPECT_EQ(Run("--output_dir " + plots + " --trajectory lio=" + dir_.File("moved.txt") +
                    " --groundtruth " + dir_.File("nothing.txt"),
                &out),
            1)
      << out;
  EXPECT_NE(out.find("error: " + dir_.File("nothing.txt") + ": file not found"), std::string::npos)
      << out;
  EXPECT_FALSE(fs::exists(plots));
  // A malformed TUM line names the file and line.
  test::WriteText(dir_.File("bad.txt"), "# t x y z qx qy qz qw\n1 0 0 0 0 0 0 1\n2 0 0 0\n");
  EXPECT_EQ(Run("--output_dir " + plots + " --trajectory x=" + dir_.File("bad.txt"), &out), 1)
      << out;
  EXPECT_NE(out.find(dir_.File("bad.txt") + ":line 3: expected 8 columns"), std::string::npos)
      << out;
  // NAME=PATH without a name.
  EXPECT_EQ(Run("--output_dir " + plots + " --trajectory " + dir_.File("moved.txt"), &out), 1)
      << out;
  EXPECT_NE(out.find("expected NAME=PATH"), std::string::npos) << out;
  // A model folder without points3D.bin.
  fs::remove(dir_.File("sparse/0/points3D.bin"));
  EXPECT_EQ(Run("--output_dir " + plots + " --model_path " + dir_.File("sparse/0"), &out), 1)
      << out;
  EXPECT_NE(out.find("points3D.bin: file not found"), std::string::npos) << out;
  // Nothing to plot: usage error (argparse), exit 2.
  EXPECT_EQ(Run("--output_dir " + plots, &out), 2) << out;
  EXPECT_FALSE(fs::exists(plots));
}

}  // namespace
}  // namespace lisfm
