// `lisfm model_evaluator` end to end: COLMAP models written here (a reference
// and a Sim(3)-moved copy with one rotation perturbed by a known angle), the
// JSON checked against those known errors, a mapper output folder with
// several models, the real Strecha reference, a simulated sequence folder as
// the reference (true capture times and extrinsics, the model's rig against
// truth/rig.yaml), and bad input -> exit 1 / 2.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "colmap_ext/io/model_io.h"
#include "core/geometry.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"
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

// A 4 s simulated office walk with 5 cameras at 1 Hz, no LiDAR, and the
// calibration error source only: rig.yaml's extrinsics and time shifts
// differ from truth/rig.yaml's (a few mm / tenths of a degree / ~1 ms).
class ModelEvaluatorSequence : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    std::string out;
    ok_ = RunCommand(LisfmBinary() +
                         " simulate --scene office --duration 4 --Walk.num_stops 2 "
                         "--camera_rate 1 --lidars none --error_sources calibration --quiet 1 "
                         "--output_path " +
                         Seq() + " 2>&1",
                     &out) == 0;
    if (!ok_) std::cerr << out;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string Seq() { return dir_->File("seq"); }

  // A model of every camera frame of the sequence, poses computed here from
  // the files as docs/FORMATS.md states them: world_from_cam =
  // world_from_imu(stamp + timeshift_cam_imu of `rig`) · cam_from_imu⁻¹ of
  // `rig` (rig.yaml's shifts are 0), with camera `perturbed_camera` (if >= 0)
  // rotated by `perturbation_deg` about its own y axis in every frame. With a
  // COLMAP 3.12 rig (reference cam0) whose cam_from_cam0 are those of `rig`,
  // camera `perturbed_camera`'s additionally rotated by `rig_perturbation_deg`
  // and its translation moved by 2 mm.
  static colmap::Reconstruction MakeSequenceModel(const Rig& rig,
                                                  int perturbed_camera,
                                                  double perturbation_deg,
                                                  double rig_perturbation_deg) {
    const Trajectory gt = ReadTum(Seq() + "/groundtruth.txt");
    colmap::Reconstruction model;
    for (size_t k = 0; k < rig.cameras.size(); ++k) {
      colmap::Camera camera;
      camera.camera_id = static_cast<colmap::camera_t>(k + 1);
      camera.model_id = static_cast<int>(colmap::CameraModelId::kPinhole);
      camera.width = rig.cameras[k].model.width;
      camera.height = rig.cameras[k].model.height;
      camera.params = {rig.cameras[k].model.fx, rig.cameras[k].model.fy, rig.cameras[k].model.cx,
                       rig.cameras[k].model.cy};
      model.AddCamera(camera);
    }
    colmap::image_t next_id = 1;
    for (size_t k = 0; k < rig.cameras.size(); ++k) {
      std::ifstream index(Seq() + "/cam" + std::to_string(k) + "/data.csv");
      std::string line;
      while (std::getline(index, line)) {
        if (line.empty() || line[0] == '#') continue;
        const std::string file = line.substr(line.find(',') + 1);
        const TimestampNs stamp = std::stoll(line.substr(0, line.find(',')));
        const TimestampNs t = std::clamp(stamp + SecondsToNs(rig.cameras[k].timeshift_cam_imu_s),
                                         gt.start_ns(), gt.end_ns());
        SE3 cam_from_world = (*gt.Interpolate(t) * rig.cameras[k].cam_from_imu.Inverse()).Inverse();
        if (static_cast<int>(k) == perturbed_camera) {
          cam_from_world =
              SE3(so3::Exp(Vec3(0, perturbation_deg * M_PI / 180, 0)), Vec3::Zero()) *
              cam_from_world;
        }
        colmap::Image image;
        image.image_id = next_id++;
        image.camera_id = static_cast<colmap::camera_t>(k + 1);
        image.name = "cam" + std::to_string(k) + "/data/" + file;
        image.SetCamFromWorld(cam_from_world);
        model.AddImage(image);
      }
    }
    colmap::ModelRig model_rig;
    model_rig.rig_id = 1;
    model_rig.has_ref_sensor = true;
    model_rig.ref_sensor = {colmap::SensorType::kCamera, 1};
    for (size_t k = 1; k < rig.cameras.size(); ++k) {
      SE3 cam_from_ref = rig.cameras[k].cam_from_imu * rig.cameras[0].cam_from_imu.Inverse();
      if (static_cast<int>(k) == perturbed_camera) {
        cam_from_ref =
            SE3(so3::Exp(Vec3(0, 0, rig_perturbation_deg * M_PI / 180)) * cam_from_ref.rotation(),
                cam_from_ref.translation() + Vec3(0.002, 0, 0));
      }
      colmap::RigSensor sensor;
      sensor.sensor = {colmap::SensorType::kCamera, static_cast<uint32_t>(k + 1)};
      sensor.has_pose = true;
      const Quat& q = cam_from_ref.rotation();
      sensor.qvec = Vec4(q.w(), q.x(), q.y(), q.z());
      sensor.tvec = cam_from_ref.translation();
      model_rig.sensors.push_back(sensor);
    }
    model.Rigs().push_back(model_rig);
    return model;
  }

  static int Evaluate(const std::string& model, const std::string& extra, std::string* out) {
    return RunCommand(LisfmBinary() + " model_evaluator --model_path " + model +
                          " --reference_path " + Seq() + " " + extra + " 2>&1",
                      out);
  }

  static TempDir* dir_;
  static bool ok_;
};
TempDir* ModelEvaluatorSequence::dir_ = nullptr;
bool ModelEvaluatorSequence::ok_ = false;

TEST_F(ModelEvaluatorSequence, ExactTruthScoresZeroForBothAlignments) {
  ASSERT_TRUE(ok_);
  const Rig truth = ReadRigYaml(Seq() + "/truth/rig.yaml");
  colmap::WriteModelBinary(MakeSequenceModel(truth, -1, 0, 0), dir_->File("exact"));
  for (const std::string alignment : {"se3", "sim3"}) {
    std::string out;
    const std::string json = dir_->File("exact_" + alignment + ".json");
    ASSERT_EQ(Evaluate(dir_->File("exact"),
                       "--alignment " + alignment + " --output_path " + json, &out),
              0)
        << out;
    const nlohmann::json j = ReadJson(json);
    EXPECT_EQ(j["reference_format"], "sequence");  // auto-detected
    EXPECT_EQ(j["alignment"], alignment);
    EXPECT_EQ(j["num_reference_images"], 25);  // 5 cameras x 5 frames (0..4 s)
    EXPECT_EQ(j["num_registered"], 25);
    // Same formula, same files: only rounding (TUM's ~1e-9 m text and the
    // binary model's doubles).
    EXPECT_LT(j["rotation_error_deg"]["max"].get<double>(), 1e-6);
    EXPECT_LT(j["position_error"]["max"].get<double>(), 1e-6);
    ASSERT_EQ(j["rig"].size(), 5u);
    EXPECT_TRUE(j["rig"][0]["is_reference"].get<bool>());
    for (int k = 1; k < 5; ++k) {
      EXPECT_LT(j["rig"][k]["rotation_error_deg"].get<double>(), 1e-6) << k;
      EXPECT_LT(j["rig"][k]["translation_error_mm"].get<double>(), 1e-6) << k;
    }
    EXPECT_NE(out.find("rig extrinsics cam_from_cam0 against truth/rig.yaml"), std::string::npos)
        << out;
  }
}

TEST_F(ModelEvaluatorSequence, ScoresThePerturbationAndTheBelievedCalibration) {
  ASSERT_TRUE(ok_);
  const Rig truth = ReadRigYaml(Seq() + "/truth/rig.yaml");
  const Rig believed = ReadRigYaml(Seq() + "/rig.yaml");
  constexpr double kImageDeg = 0.3, kRigDeg = 0.5;
  colmap::WriteModelBinary(MakeSequenceModel(truth, 2, kImageDeg, kRigDeg), dir_->File("moved"));
  std::string out;
  ASSERT_EQ(Evaluate(dir_->File("moved"),
                     "--reference_format sequence --alignment se3 --output_path " +
                         dir_->File("moved.json"),
                     &out),
            0)
      << out;
  const nlohmann::json j = ReadJson(dir_->File("moved.json"));
  // The rotation alignment is the geodesic L1 mean over the 25 images, so the
  // 5 rotated images keep their whole error and the others none.
  EXPECT_NEAR(j["rotation_error_deg"]["max"].get<double>(), kImageDeg, 1e-6);
  EXPECT_NEAR(j["rotation_error_deg"]["median"].get<double>(), 0.0, 1e-6);
  EXPECT_LT(j["position_error"]["max"].get<double>(), 1e-6);
  // The rig: camera 2 off by 0.5 deg and 2 mm, the others exact; rig.yaml's
  // believed extrinsics differ from the truth by the simulated calibration
  // error, computed here independently.
  EXPECT_NEAR(j["rig"][2]["rotation_error_deg"].get<double>(), kRigDeg, 1e-6);
  EXPECT_NEAR(j["rig"][2]["translation_error_mm"].get<double>(), 2.0, 1e-6);
  EXPECT_LT(j["rig"][1]["rotation_error_deg"].get<double>(), 1e-6);
  for (int k = 1; k < 5; ++k) {
    const SE3 b = believed.cameras[k].cam_from_imu * believed.cameras[0].cam_from_imu.Inverse();
    const SE3 t = truth.cameras[k].cam_from_imu * truth.cameras[0].cam_from_imu.Inverse();
    const double rot_deg = so3::Log(b.rotation() * t.rotation().conjugate()).norm() * 180 / M_PI;
    EXPECT_NEAR(j["rig"][k]["believed_rotation_error_deg"].get<double>(), rot_deg, 1e-9) << k;
    EXPECT_NEAR(j["rig"][k]["believed_translation_error_mm"].get<double>(),
                (b.translation() - t.translation()).norm() * 1000, 1e-9)
        << k;
    EXPECT_GT(rot_deg, 1e-4) << "the calibration error source is on";
  }
}

TEST_F(ModelEvaluatorSequence, PosesAtTheStampsWithTheBelievedRigAreOff) {
  ASSERT_TRUE(ok_);
  // rig.yaml's extrinsics and zero time shifts: what a user would compute
  // without the truth. The evaluation must see the calibration error.
  colmap::WriteModelBinary(MakeSequenceModel(ReadRigYaml(Seq() + "/rig.yaml"), -1, 0, 0),
                           dir_->File("believed"));
  std::string out;
  ASSERT_EQ(Evaluate(dir_->File("believed"), "--alignment se3 --output_path " +
                                                 dir_->File("believed.json"),
                     &out),
            0)
      << out;
  const nlohmann::json j = ReadJson(dir_->File("believed.json"));
  EXPECT_GT(j["rotation_error_deg"]["max"].get<double>(), 0.01);
  EXPECT_GT(j["position_error"]["max"].get<double>(), 1e-4);
}

TEST_F(ModelEvaluatorSequence, SequenceWithoutTruthIsAnError) {
  ASSERT_TRUE(ok_);
  const Rig truth = ReadRigYaml(Seq() + "/truth/rig.yaml");
  colmap::WriteModelBinary(MakeSequenceModel(truth, -1, 0, 0), dir_->File("model"));
  const std::string copy = dir_->File("seq_no_truth");
  std::filesystem::create_directories(copy);
  for (const char* f : {"rig.yaml", "groundtruth.txt"}) {
    std::filesystem::copy_file(Seq() + "/" + f, copy + "/" + f);
  }
  std::string out;
  EXPECT_EQ(RunCommand(LisfmBinary() + " model_evaluator --model_path " + dir_->File("model") +
                           " --reference_path " + copy + " --output_path " +
                           dir_->File("no_truth.json") + " 2>&1",
                       &out),
            1)
      << out;
  EXPECT_NE(out.find("seq_no_truth"), std::string::npos) << out;
  EXPECT_NE(out.find("no truth/ folder"), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(dir_->File("no_truth.json")));
  // A malformed camera index names its file and line.
  std::filesystem::create_directories(copy + "/truth");
  std::filesystem::create_directories(copy + "/cam0/data");
  test::WriteText(copy + "/cam0/data.csv", "#timestamp [ns],filename\nabc,1.png\n");
  EXPECT_EQ(RunCommand(LisfmBinary() + " model_evaluator --model_path " + dir_->File("model") +
                           " --reference_path " + copy + " 2>&1",
                       &out),
            1)
      << out;
  EXPECT_NE(out.find("cam0/data.csv:line 2"), std::string::npos) << out;
}

}  // namespace
}  // namespace lisfm
