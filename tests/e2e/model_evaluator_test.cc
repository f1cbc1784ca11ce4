// `lisfm model_evaluator` end to end: COLMAP models written here (a reference
// and a Sim(3)-moved copy with one rotation perturbed by a known angle), the
// JSON checked against those known errors, a mapper output folder with
// several models, the real Strecha reference, and bad input -> exit 1 / 2.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "colmap_ext/io/model_io.h"
#include "core/geometry.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using test::LisfmBinary;
using test::RunCommand;
using test::TempDir;

constexpr double kPerturbationDeg = 2.0;

// `n` images on an arc looking at the origin; world moved by `est_from_ref`
// and image `perturbed` (if >= 0) rotated by kPerturbationDeg about its centre.
colmap::Reconstruction MakeModel(int n, const Sim3& est_from_ref, int perturbed) {
  colmap::Reconstruction model;
  colmap::Camera camera;
  camera.camera_id = 1;
  camera.model_id = static_cast<int>(colmap::CameraModelId::kPinhole);
  camera.width = 640;
  camera.height = 480;
  camera.params = {500, 500, 320, 240};
  model.AddCamera(camera);
  for (int i = 0; i < n; ++i) {
    const double a = 0.25 * i;
    const Vec3 centre_ref(4 * std::sin(a), 0.3 * i * i * 0.1, -4 * std::cos(a));
    const Quat ref_rotation = so3::Exp(Vec3(0.05 * i, -a, 0.02));  // cam_from_world
    Quat rotation = ref_rotation * est_from_ref.pose.rotation().conjugate();
    if (i == perturbed) rotation = so3::Exp(Vec3(0, kPerturbationDeg * M_PI / 180, 0)) * rotation;
    const Vec3 centre = est_from_ref * centre_ref;
    colmap::Image image;
    image.image_id = static_cast<colmap::image_t>(i + 1);
    image.camera_id = 1;
    image.name = "frame_" + std::to_string(i) + ".png";
    image.SetCamFromWorld(SE3(rotation, -(rotation * centre)));
    model.AddImage(image);
  }
  return model;
}

Sim3 Moved() {
  Sim3 s;
  s.scale = 0.3;
  s.pose = SE3(so3::Exp(Vec3(-0.4, 0.9, 1.7)), Vec3(2, 3, -1));
  return s;
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

TEST(ModelEvaluatorCli, ScoresAKnownPerturbation) {
  TempDir dir;
  colmap::WriteModelText(MakeModel(8, Sim3(), -1), dir.File("reference"));
  colmap::WriteModelBinary(MakeModel(8, Moved(), 5), dir.File("estimate"));
  std::string out;
  ASSERT_EQ(RunCommand(LisfmBinary() + " model_evaluator --model_path " + dir.File("estimate") +
                           " --reference_path " + dir.File("reference") + " --output_path " +
                           dir.File("out/metrics.json"),
                       &out),
            0)
      << out;
  EXPECT_NE(out.find("registered 8 / 8"), std::string::npos) << out;
  const nlohmann::json j = ReadJson(dir.File("out/metrics.json"));
  EXPECT_EQ(j["reference_format"], "colmap");
  EXPECT_EQ(j["alignment"], "sim3");
  EXPECT_EQ(j["num_registered"], 8);
  // Sim(3) of the centres (rotations do not enter the alignment): the scale
  // is recovered to rounding, image 5 has exactly the injected 2 deg error
  // (up to the %.17g text round trip, ~1e-12), the others none.
  EXPECT_NEAR(j["reference_from_estimate"]["scale"].get<double>(), 1.0 / 0.3, 1e-9);
  EXPECT_NEAR(j["rotation_error_deg"]["max"].get<double>(), kPerturbationDeg, 1e-6);
  EXPECT_NEAR(j["rotation_error_deg"]["median"].get<double>(), 0.0, 1e-6);
  EXPECT_LT(j["position_error"]["max"].get<double>(), 1e-9);
  EXPECT_NEAR(j["images"][5]["rotation_error_deg"].get<double>(), kPerturbationDeg, 1e-6);
  // 7 of 28 pairs include image 5 (error 2 deg), 21 have none:
  // AUC@1 = 21/28 exactly (the 2-deg pairs are above 1 deg).
  EXPECT_NEAR(j["auc"]["1"].get<double>(), 21.0 / 28.0, 1e-6);
  EXPECT_GT(j["auc"]["5"].get<double>(), 21.0 / 28.0);
}

TEST(ModelEvaluatorCli, PicksTheLargestModelOfAMapperOutput) {
  TempDir dir;
  colmap::WriteModelBinary(MakeModel(8, Sim3(), -1), dir.File("reference"));
  colmap::Reconstruction small = MakeModel(3, Moved(), -1);
  colmap::WriteModelBinary(small, dir.File("sparse/0"));
  colmap::WriteModelBinary(MakeModel(6, Moved(), -1), dir.File("sparse/1"));
  std::string out;
  ASSERT_EQ(RunCommand(LisfmBinary() + " model_evaluator --model_path " + dir.File("sparse") +
                           " --reference_path " + dir.File("reference") +
                           " --alignment se3 --output_path " + dir.File("m.json"),
                       &out),
            0)
      << out;
  const nlohmann::json j = ReadJson(dir.File("m.json"));
  EXPECT_EQ(j["num_registered"], 6);
  EXPECT_EQ(j["alignment"], "se3");
  // SE(3) cannot undo the 0.3 scale: positions are off, rotations exact.
  EXPECT_GT(j["position_error"]["mean"].get<double>(), 0.1);
  EXPECT_LT(j["rotation_error_deg"]["max"].get<double>(), 1e-6);
}

TEST(ModelEvaluatorCli, StrechaGroundTruthAgainstItself) {
  LISFM_REQUIRE_SHARED_DATA("sfm_strecha/Herz-Jesus-P8/gt_dense_cameras/0000.jpg.camera");
  TempDir dir;
  const std::string reference = test::SharedData("sfm_strecha/Herz-Jesus-P8");
  std::string out;
  // A COLMAP model of the ground-truth cameras, written from the .camera
  // files by hand here: R is world_from_cam, so cam_from_world = R^T.
  colmap::Reconstruction model;
  colmap::Camera camera;
  camera.camera_id = 1;
  camera.model_id = static_cast<int>(colmap::CameraModelId::kPinhole);
  camera.width = 1536;
  camera.height = 1024;
  camera.params = {1379.74, 1382.08, 760.345, 503.405};
  model.AddCamera(camera);
  for (int i = 0; i < 8; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%04d.jpg", i);
    std::ifstream in(reference + "/gt_dense_cameras/" + name + ".camera");
    double v[26];
    for (double& x : v) ASSERT_TRUE(in >> x);
    Mat3 r;
    r << v[12], v[13], v[14], v[15], v[16], v[17], v[18], v[19], v[20];
    Eigen::JacobiSVD<Mat3> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Mat3 rotation = (svd.matrixU() * svd.matrixV().transpose()).transpose();
    colmap::Image image;
    image.image_id = static_cast<colmap::image_t>(i + 1);
    image.camera_id = 1;
    image.name = name;
    image.SetCamFromWorld(SE3(rotation, -rotation * Vec3(v[21], v[22], v[23])));
    model.AddImage(image);
  }
  colmap::WriteModelBinary(model, dir.File("model"));
  ASSERT_EQ(RunCommand(LisfmBinary() + " model_evaluator --model_path " + dir.File("model") +
                           " --reference_path " + reference + " --output_path " +
                           dir.File("m.json"),
                       &out),
            0)
      << out;
  const nlohmann::json j = ReadJson(dir.File("m.json"));
  EXPECT_EQ(j["reference_format"], "strecha");
  EXPECT_EQ(j["num_registered"], 8);
  // Both sides come from the same numbers: rounding noise only.
  EXPECT_LT(j["rotation_error_deg"]["max"].get<double>(), 1e-6);
  EXPECT_LT(j["position_error"]["max"].get<double>(), 1e-6);  // metres
  EXPECT_GT(j["auc"]["1"].get<double>(), 1.0 - 1e-6);
}

TEST(ModelEvaluatorCli, BadInput) {
  TempDir dir;
  colmap::WriteModelBinary(MakeModel(4, Sim3(), -1), dir.File("reference"));
  std::string out;
  // Missing model folder: input error, exit 1, naming the path.
  EXPECT_EQ(RunCommand(LisfmBinary() + " model_evaluator --model_path " + dir.File("nothing") +
                           " --reference_path " + dir.File("reference"),
                       &out),
            1)
      << out;
  EXPECT_NE(out.find("error:"), std::string::npos) << out;
  EXPECT_NE(out.find("nothing"), std::string::npos) << out;
  // Unknown alignment: usage error, exit 2.
  EXPECT_EQ(RunCommand(LisfmBinary() + " model_evaluator --model_path " + dir.File("reference") +
                           " --reference_path " + dir.File("reference") + " --alignment affine",
                       &out),
            2)
      << out;
  // A COLMAP folder read as Strecha: no .camera files.
  EXPECT_EQ(RunCommand(LisfmBinary() + " model_evaluator --model_path " + dir.File("reference") +
                           " --reference_path " + dir.File("reference") +
                           " --reference_format strecha",
                       &out),
            1)
      << out;
  EXPECT_NE(out.find(".camera"), std::string::npos) << out;
  // No image in common.
  colmap::Reconstruction other = MakeModel(4, Sim3(), -1);
  for (auto& image : other.MutableImages()) image.name = "x" + image.name;
  colmap::WriteModelBinary(other, dir.File("other"));
  EXPECT_EQ(RunCommand(LisfmBinary() + " model_evaluator --model_path " + dir.File("other") +
                           " --reference_path " + dir.File("reference") + " --output_path " +
                           dir.File("m.json"),
                       &out),
            1)
      << out;
  EXPECT_NE(out.find("matches a reference image"), std::string::npos) << out;
  std::ifstream no_output(dir.File("m.json"));
  EXPECT_FALSE(no_output.good()) << "metrics written despite the error";
}

}  // namespace
}  // namespace lisfm
