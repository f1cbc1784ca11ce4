#include "core/io/rig_io.h"

#include <cmath>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "core/errors.h"
#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using ::testing::HasSubstr;

const char kHiltiDir[] = "hilti_exp4_small/calibration";

Rig MakeRig() {
  Rig rig;
  RigCamera cam0;
  cam0.name = "cam0";
  cam0.rostopic = "/alphasense/cam0/image_raw";
  cam0.model.width = 720;
  cam0.model.height = 540;
  cam0.model.fx = 351.31400364193297;
  cam0.model.fy = 351.4911744656785;
  cam0.model.cx = 367.8522793375995;
  cam0.model.cy = 253.8402144980996;
  cam0.model.distortion = DistortionModel::kEquidistant;
  cam0.model.distortion_coeffs = {-0.0369, -0.0089, 0.0089, -0.0037};
  cam0.cam_from_imu = test::RandomPose(3.0, 0.2);
  cam0.timeshift_cam_imu_s = 0.0019071204237431304;
  RigCamera cam1 = cam0;
  cam1.name = "cam1";
  cam1.rostopic = "";
  cam1.model.distortion = DistortionModel::kRadtan;
  cam1.model.distortion_coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  cam1.cam_from_imu = test::RandomPose(3.0, 0.2);
  cam1.timeshift_cam_imu_s = -1e-7;
  RigCamera cam2 = cam0;
  cam2.name = "cam2";
  cam2.model.distortion = DistortionModel::kNone;
  cam2.model.distortion_coeffs.clear();
  cam2.cam_from_imu = test::RandomPose(3.0, 0.2);
  rig.cameras = {cam0, cam1, cam2};
  rig.imu.accelerometer_noise_density = 0.1 / 3.0;
  rig.imu.gyroscope_random_walk = 1.0 / 7.0 * 1e-5;
  rig.imu.update_rate = 200.0;
  rig.imu_rostopic = "/imu \"quoted\" \\ topic";
  RigLidar spinning;
  spinning.name = "lidar0";
  spinning.rostopic = "/os_cloud_node/points";
  spinning.imu_from_lidar = test::RandomPose(3.0, 0.5);
  spinning.time_offset_s = 0.0123456789;
  spinning.rings = 64;
  spinning.min_range = 0.3;
  spinning.max_range = 50.0;
  RigLidar livox;
  livox.name = "livox_front";
  livox.type = LidarType::kLivox;
  livox.imu_from_lidar = test::RandomPose(3.0, 0.5);
  livox.rings = 0;
  livox.min_range = 0.05;
  livox.max_range = 260.0;
  rig.lidars = {spinning, livox};
  return rig;
}

// Writes `text` as <tmp>/rig.yaml and returns the InputError message of ReadRigYaml.
std::string ReadError(const test::TempDir& dir, const std::string& text) {
  const std::string path = dir.File("rig.yaml");
  test::WriteText(path, text);
  try {
    ReadRigYaml(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

// A valid camera section body (indented two spaces).
const char kCameraBody[] =
    "  camera_model: pinhole\n"
    "  intrinsics: [350.0, 351.0, 360.0, 270.0]\n"
    "  distortion_model: equidistant\n"
    "  distortion_coeffs: [-0.04, -0.005, 0.004, -0.002]\n"
    "  resolution: [720, 540]\n"
    "  T_cam_imu:\n"
    "  - [1, 0, 0, 0.1]\n"
    "  - [0, 1, 0, 0]\n"
    "  - [0, 0, 1, 0]\n"
    "  - [0, 0, 0, 1]\n";

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(RigIo, RoundTripIsExact) {
  const test::TempDir dir;
  const Rig rig = MakeRig();
  WriteRigYaml(dir.File("rig.yaml"), rig, "test rig\nsecond line");
  const Rig read = ReadRigYaml(dir.File("rig.yaml"));
  ASSERT_EQ(read.cameras.size(), rig.cameras.size());
  for (size_t i = 0; i < rig.cameras.size(); ++i) {
    const RigCamera& a = rig.cameras[i];
    const RigCamera& b = read.cameras[i];
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.rostopic, a.rostopic);
    EXPECT_EQ(b.model.width, a.model.width);
    EXPECT_EQ(b.model.height, a.model.height);
    // Shortest round-trip decimals: bit-exact.
    EXPECT_EQ(b.model.fx, a.model.fx);
    EXPECT_EQ(b.model.fy, a.model.fy);
    EXPECT_EQ(b.model.cx, a.model.cx);
    EXPECT_EQ(b.model.cy, a.model.cy);
    EXPECT_EQ(b.model.distortion, a.model.distortion);
    EXPECT_EQ(b.model.distortion_coeffs, a.model.distortion_coeffs);
    EXPECT_EQ(b.timeshift_cam_imu_s, a.timeshift_cam_imu_s);
    // Matrix written exactly, quaternion recovered by SVD + Eigen: ~1e-16.
    EXPECT_LT((b.cam_from_imu.Matrix() - a.cam_from_imu.Matrix()).cwiseAbs().maxCoeff(), 1e-12);
  }
  EXPECT_EQ(read.imu.accelerometer_noise_density, rig.imu.accelerometer_noise_density);
  EXPECT_EQ(read.imu.gyroscope_noise_density, rig.imu.gyroscope_noise_density);
  EXPECT_EQ(read.imu.accelerometer_random_walk, rig.imu.accelerometer_random_walk);
  EXPECT_EQ(read.imu.gyroscope_random_walk, rig.imu.gyroscope_random_walk);
  EXPECT_EQ(read.imu.update_rate, rig.imu.update_rate);
  EXPECT_EQ(read.imu_rostopic, rig.imu_rostopic);
  ASSERT_EQ(read.lidars.size(), 2u);
  for (size_t i = 0; i < rig.lidars.size(); ++i) {
    const RigLidar& a = rig.lidars[i];
    const RigLidar& b = read.lidars[i];
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.rostopic, a.rostopic);
    EXPECT_EQ(b.type, a.type);
    EXPECT_EQ(b.time_offset_s, a.time_offset_s);
    EXPECT_EQ(b.rings, a.rings);
    EXPECT_EQ(b.min_range, a.min_range);
    EXPECT_EQ(b.max_range, a.max_range);
    EXPECT_EQ(b.scan_rate, a.scan_rate);
    EXPECT_LT((b.imu_from_lidar.Matrix() - a.imu_from_lidar.Matrix()).cwiseAbs().maxCoeff(), 1e-12);
  }
  EXPECT_EQ(ReadFile(dir.File("rig.yaml")).rfind("# test rig\n# second line\n", 0), 0u);
  EXPECT_EQ(read.FindCamera("cam2"), &read.cameras[2]);
  EXPECT_EQ(read.FindLidar("livox_front"), &read.lidars[1]);
  EXPECT_EQ(read.FindLidar("lidar7"), nullptr);
}

TEST(RigIo, ExampleFixtureParsesWithDefaultsAndAliases) {
  // tests/data/rig/example_rig.yaml: radtan + none cameras, Kalibr "imu0" with
  // only two fields, LiDARs as a list (one named, one default-named).
  const Rig rig = ReadRigYaml(test::SourceDir() + "/tests/data/rig/example_rig.yaml");
  ASSERT_EQ(rig.cameras.size(), 2u);
  EXPECT_EQ(rig.cameras[0].model.distortion, DistortionModel::kRadtan);
  EXPECT_EQ(rig.cameras[1].model.distortion, DistortionModel::kNone);
  EXPECT_TRUE(rig.cameras[1].model.distortion_coeffs.empty());
  EXPECT_EQ(rig.cameras[1].timeshift_cam_imu_s, 0.0);  // absent -> 0
  EXPECT_EQ(rig.imu.accelerometer_noise_density, 0.08);
  EXPECT_EQ(rig.imu.gyroscope_noise_density, 0.004);
  EXPECT_EQ(rig.imu.accelerometer_random_walk, ImuNoise().accelerometer_random_walk);
  EXPECT_EQ(rig.imu.update_rate, ImuNoise().update_rate);
  EXPECT_EQ(rig.imu_rostopic, "/imu0");
  ASSERT_EQ(rig.lidars.size(), 2u);
  EXPECT_EQ(rig.lidars[0].name, "ouster");
  EXPECT_EQ(rig.lidars[0].type, LidarType::kSpinning);
  EXPECT_EQ(rig.lidars[0].rings, 64);
  EXPECT_EQ(rig.lidars[1].name, "lidar1");
  EXPECT_EQ(rig.lidars[1].type, LidarType::kLivox);
  EXPECT_EQ(rig.lidars[1].rings, 0);  // livox default
  EXPECT_EQ(rig.lidars[1].time_offset_s, -0.002);
  // The 90 deg rotation about z of the fixture's T_imu_lidar.
  EXPECT_LT((rig.lidars[1].imu_from_lidar.RotationMatrix() -
             (Mat3() << 0, -1, 0, 1, 0, 0, 0, 0, 1).finished())
                .cwiseAbs()
                .maxCoeff(),
            1e-15);
}

TEST(RigIo, MissingImuSectionUsesBmi085Defaults) {
  const test::TempDir dir;
  test::WriteText(dir.File("rig.yaml"), std::string("cam0:\n") + kCameraBody);
  const Rig rig = ReadRigYaml(dir.File("rig.yaml"));
  ASSERT_EQ(rig.cameras.size(), 1u);
  EXPECT_EQ(rig.imu.accelerometer_noise_density, 1.7e-3);
  EXPECT_EQ(rig.imu.gyroscope_noise_density, 2.4e-4);
  EXPECT_EQ(rig.imu.accelerometer_random_walk, 4.0e-4);
  EXPECT_EQ(rig.imu.gyroscope_random_walk, 2.0e-5);
  EXPECT_EQ(rig.imu.update_rate, 400.0);
  EXPECT_TRUE(rig.lidars.empty());
}

TEST(RigIo, BadInputNamesFileFieldAndLine) {
  const test::TempDir dir;
  const std::string cam = kCameraBody;
  const std::string three_cams = "cam0:\n" + cam + "cam1:\n" + cam + "cam2:\n" + cam;
  // Missing intrinsics in cam2 (its fields start at line 24).
  std::string e = ReadError(dir, "cam0:\n" + cam + "cam1:\n" + cam + "cam2:\n" +
                                     Replace(cam, "  intrinsics: [350.0, 351.0, 360.0, 270.0]\n", ""));
  EXPECT_THAT(e, HasSubstr("rig.yaml:cam2.intrinsics: missing"));
  EXPECT_THAT(e, HasSubstr("(section at line 24)"));
  // Wrong-length distortion_coeffs: line 5 of the file.
  e = ReadError(dir, "cam0:\n" + Replace(cam, "[-0.04, -0.005, 0.004, -0.002]", "[-0.04, -0.005]"));
  EXPECT_THAT(e, HasSubstr("rig.yaml:cam0.distortion_coeffs: expected 4 numbers"));
  EXPECT_THAT(e, HasSubstr("found 2 (line 5)"));
  // Non-rigid T_cam_imu: a 10 % scale.
  e = ReadError(dir, "cam0:\n" + Replace(cam, "- [1, 0, 0, 0.1]", "- [1.1, 0, 0, 0.1]"));
  EXPECT_THAT(e, HasSubstr("rig.yaml:cam0.T_cam_imu: not a rigid transform"));
  EXPECT_THAT(e, HasSubstr("not orthonormal"));
  EXPECT_THAT(e, HasSubstr("line 8"));
  // A reflection is orthonormal but not a rotation.
  e = ReadError(dir, "cam0:\n" + Replace(cam, "- [1, 0, 0, 0.1]", "- [-1, 0, 0, 0.1]"));
  EXPECT_THAT(e, HasSubstr("cam0.T_cam_imu: not a rigid transform: rotation block is a reflection"));
  e = ReadError(dir, "cam0:\n" + Replace(cam, "- [0, 0, 0, 1]", "- [0, 0, 1, 1]"));
  EXPECT_THAT(e, HasSubstr("cam0.T_cam_imu: not a rigid transform: last row"));
  e = ReadError(dir, "cam0:\n" + Replace(cam, "  - [0, 0, 0, 1]\n", ""));
  EXPECT_THAT(e, HasSubstr("cam0.T_cam_imu: expected a 4x4 matrix"));
  // Unknown distortion model.
  e = ReadError(dir, "cam0:\n" + Replace(cam, "distortion_model: equidistant", "distortion_model: fisheye"));
  EXPECT_THAT(e, HasSubstr("rig.yaml:cam0.distortion_model: unknown distortion model 'fisheye'"));
  EXPECT_THAT(e, HasSubstr("line 4"));
  // A non-number, a bad resolution, an unsupported camera model.
  e = ReadError(dir, "cam0:\n" + Replace(cam, "351.0", "abc"));
  EXPECT_THAT(e, HasSubstr("rig.yaml:cam0.intrinsics[1]: expected a number, found 'abc' (line 3)"));
  e = ReadError(dir, "cam0:\n" + Replace(cam, "[720, 540]", "[720]"));
  EXPECT_THAT(e, HasSubstr("cam0.resolution: expected [width height]"));
  e = ReadError(dir, "cam0:\n" + Replace(cam, "[720, 540]", "[720, -5]"));
  EXPECT_THAT(e, HasSubstr("cam0.resolution: expected positive"));
  e = ReadError(dir, "cam0:\n" + Replace(cam, "[350.0,", "[-350.0,"));
  EXPECT_THAT(e, HasSubstr("cam0.intrinsics: expected focal lengths"));
  e = ReadError(dir, "cam0:\n" + Replace(cam, "camera_model: pinhole", "camera_model: omni"));
  EXPECT_THAT(e, HasSubstr("cam0.camera_model: unsupported camera model 'omni'"));
  // Cameras must be cam0..camN-1.
  e = ReadError(dir, "cam0:\n" + cam + "cam2:\n" + cam);
  EXPECT_THAT(e, HasSubstr("rig.yaml:cam2: cameras must be numbered cam0..camN-1 without gaps; cam1 is missing"));
  // Unknown LiDAR type, and the other LiDAR checks.
  const std::string lidar =
      "lidars:\n"
      "  lidar0:\n"
      "    type: spinning\n"
      "    T_imu_lidar: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n"
      "    rings: 32\n";
  EXPECT_NO_THROW(test::WriteText(dir.File("ok.yaml"), three_cams + lidar));
  EXPECT_EQ(ReadRigYaml(dir.File("ok.yaml")).lidars.size(), 1u);
  e = ReadError(dir, three_cams + Replace(lidar, "type: spinning", "type: solid_state"));
  EXPECT_THAT(e, HasSubstr("rig.yaml:lidars.lidar0.type: unknown lidar type 'solid_state'"));
  EXPECT_THAT(e, HasSubstr("line 36"));
  e = ReadError(dir, three_cams + Replace(lidar, "    type: spinning\n", ""));
  EXPECT_THAT(e, HasSubstr("rig.yaml:lidars.lidar0.type: missing"));
  e = ReadError(dir, three_cams + Replace(lidar, "rings: 32", "rings: 0"));
  EXPECT_THAT(e, HasSubstr("lidars.lidar0.rings: expected a positive ring count"));
  e = ReadError(dir, three_cams + lidar + "    min_range: 5\n    max_range: 1\n");
  EXPECT_THAT(e, HasSubstr("lidars.lidar0.max_range: expected a finite value > min_range"));
  e = ReadError(dir, three_cams + Replace(lidar, "[0, 1, 0, 0], [0, 0, 1, 0]", "[0, 1, 0, 0], [0, 1, 1, 0]"));
  EXPECT_THAT(e, HasSubstr("lidars.lidar0.T_imu_lidar: not a rigid transform"));
  // Time offsets must convert to int64 nanoseconds.
  e = ReadError(dir, three_cams + lidar + "    time_offset: 1e10\n");
  EXPECT_THAT(e, HasSubstr("lidars.lidar0.time_offset: expected finite seconds within"));
  e = ReadError(dir, "cam0:\n" + cam + "  timeshift_cam_imu: -2e10\n");
  EXPECT_THAT(e, HasSubstr("cam0.timeshift_cam_imu: expected seconds within"));
  e = ReadError(dir, three_cams + "lidars: 5\n");
  EXPECT_THAT(e, HasSubstr("rig.yaml:lidars: expected a list or map of LiDARs"));
  // Bad IMU values.
  e = ReadError(dir, three_cams + "imu:\n  gyroscope_noise_density: -1\n");
  EXPECT_THAT(e, HasSubstr("rig.yaml:imu.gyroscope_noise_density: expected a positive number"));
  // Malformed YAML: the parser's line.
  e = ReadError(dir, "cam0:\n  intrinsics: [1, 2\n  resolution: [3, 4]\n");
  EXPECT_THAT(e, HasSubstr("rig.yaml:line "));
  EXPECT_THAT(e, HasSubstr("malformed YAML"));
  e = ReadError(dir, "- just\n- a list\n");
  EXPECT_THAT(e, HasSubstr("rig.yaml: expected a map with cam0.., imu and lidars sections"));
  // A missing file.
  EXPECT_THROW(ReadRigYaml(dir.File("absent.yaml")), InputError);
}

TEST(RigIo, KalibrFileNamesGiveTheRigIndices) {
  EXPECT_EQ(KalibrFileCameraIndices("/a/calib_3_cam0-1-camchain-imucam.yaml"), (std::vector<int>{0, 1}));
  EXPECT_EQ(KalibrFileCameraIndices("calib_3_cam2-camchain-imucam.yaml"), (std::vector<int>{2}));
  EXPECT_EQ(KalibrFileCameraIndices("/cam9/camchain-imucam.yaml"), (std::vector<int>{}));
  EXPECT_EQ(KalibrFileCameraIndices("x_cam10-11-12-camchain.yaml"), (std::vector<int>{10, 11, 12}));
}

TEST(RigIo, KalibrLoaderRemapsAndChecksIndices) {
  const test::TempDir dir;
  const std::string cam = kCameraBody;
  test::WriteText(dir.File("k_cam1-camchain-imucam.yaml"),
                  "cam0:\n" + Replace(cam, "0.1]", "0.3]"));
  test::WriteText(dir.File("k_cam0-camchain-imucam.yaml"), "cam0:\n" + cam);
  // Files given out of order: the rig order follows the file-name indices.
  const Rig rig = LoadKalibrRig({dir.File("k_cam1-camchain-imucam.yaml"),
                                 dir.File("k_cam0-camchain-imucam.yaml")},
                                "");
  ASSERT_EQ(rig.cameras.size(), 2u);
  EXPECT_EQ(rig.cameras[0].name, "cam0");
  EXPECT_EQ(rig.cameras[1].name, "cam1");
  EXPECT_EQ(rig.cameras[0].cam_from_imu.translation().x(), 0.1);
  EXPECT_EQ(rig.cameras[1].cam_from_imu.translation().x(), 0.3);
  EXPECT_TRUE(rig.lidars.empty());
  // Two files claiming cam0.
  test::WriteText(dir.File("other_cam0-camchain-imucam.yaml"), "cam0:\n" + cam);
  EXPECT_TRUE(test::ThrowsInputError(
      [&] {
        LoadKalibrRig(
            {dir.File("k_cam0-camchain-imucam.yaml"), dir.File("other_cam0-camchain-imucam.yaml")},
            "");
      },
      {"other_cam0-camchain-imucam.yaml:cam0: rig camera cam0 already "
       "defined"}));
  // The name says two cameras, the file holds one.
  test::WriteText(dir.File("k_cam2-3-camchain-imucam.yaml"), "cam0:\n" + cam);
  EXPECT_THROW(LoadKalibrRig({dir.File("k_cam2-3-camchain-imucam.yaml")}, ""), InputError);
  // A gap: only cam1.
  EXPECT_THROW(LoadKalibrRig({dir.File("k_cam1-camchain-imucam.yaml")}, ""), InputError);
  // Errors inside a Kalibr file name the in-file section.
  test::WriteText(dir.File("bad_cam0-camchain-imucam.yaml"),
                  "cam0:\n" + Replace(cam, "[720, 540]", "[720, x]"));
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { LoadKalibrRig({dir.File("bad_cam0-camchain-imucam.yaml")}, ""); },
      {"bad_cam0-camchain-imucam.yaml:cam0.resolution[1]: expected an "
       "integer"}));
  // A LiDAR calibration whose LiDAR is not relative to the IMU.
  test::WriteText(dir.File("lidar.yaml"),
                  "sensors:\n  PandarXT-32:\n    parent: base_link\n    extrinsics:\n"
                  "      quaternion: [0, 0, 0, 1]\n      translation: [0, 0, 0]\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadLidarCalibration(dir.File("lidar.yaml")); },
                                     {"lidar.yaml:sensors.PandarXT-32.parent: expected 'imu'"}));
}

// A map or list used as a map key is valid YAML; every reader rejects it as an InputError
// naming the file, the section and the line (never an escaping yaml-cpp exception).
TEST(RigIo, NonScalarMapKeysAreInputErrors) {
  const test::TempDir dir;
  const std::string cam = kCameraBody;
  test::WriteText(dir.File("key_cam0-camchain-imucam.yaml"),
                  "cam0:\n" + cam + "? {a: 1}\n: 2\n");
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { LoadKalibrRig({dir.File("key_cam0-camchain-imucam.yaml")}, ""); },
      {"key_cam0-camchain-imucam.yaml:top level: expected a name as map key, found a map",
       "(line 12)"}));
  test::WriteText(dir.File("field_cam0-camchain-imucam.yaml"),
                  "cam0:\n" + cam + "  ? [1, 2]\n  : 3\n");
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { LoadKalibrRig({dir.File("field_cam0-camchain-imucam.yaml")}, ""); },
      {"field_cam0-camchain-imucam.yaml:cam0: expected a name as map key, found a list"}));
  test::WriteText(dir.File("lidar_key.yaml"), "sensors:\n  ? {PandarXT-32: 1}\n  : 2\n");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadLidarCalibration(dir.File("lidar_key.yaml")); },
                             {"lidar_key.yaml:sensors: expected a name as map key, found a map"}));
  EXPECT_NE(ReadError(dir, "cam0:\n" + cam + "lidars:\n  ? [x]\n  : {}\n")
                .find("rig.yaml:lidars: expected a name as map key, found a list"),
            std::string::npos);
}

// Reads a 4x4 Kalibr matrix straight with yaml-cpp (independent of rig_io).
Mat4 KalibrMatrix(const std::string& path, const std::string& cam, const std::string& key) {
  const YAML::Node node = YAML::LoadFile(path)[cam][key];
  Mat4 m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = node[r][c].as<double>();
  }
  return m;
}

TEST(RigIo, RealHiltiCalibrationLoadsOneFiveCameraRig) {
  LISFM_REQUIRE_SHARED_DATA(std::string(kHiltiDir) + "/lidar_calibration.yaml");
  const std::string dir = test::SharedData(kHiltiDir);
  const Rig rig = LoadHiltiCalibration(dir);
  ASSERT_EQ(rig.cameras.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    const RigCamera& camera = rig.cameras[i];
    EXPECT_EQ(camera.name, "cam" + std::to_string(i));
    EXPECT_EQ(camera.rostopic, "/alphasense/cam" + std::to_string(i) + "/image_raw");
    EXPECT_EQ(camera.model.distortion, DistortionModel::kEquidistant);
    EXPECT_EQ(camera.model.width, 720);
    EXPECT_EQ(camera.model.height, 540);
    EXPECT_GT(camera.timeshift_cam_imu_s, 0.0017);  // all ~1.7-1.9 ms in the files
    EXPECT_LT(camera.timeshift_cam_imu_s, 0.0020);
  }
  // cam1 is the second entry of the cam0-1 file; the file's matrices are
  // orthonormal to ~1e-15, so the SVD projection changes nothing above 1e-12.
  const Mat4 cam1 = KalibrMatrix(dir + "/calib_3_cam0-1-camchain-imucam.yaml", "cam1", "T_cam_imu");
  EXPECT_LT((rig.cameras[1].cam_from_imu.Matrix() - cam1).cwiseAbs().maxCoeff(), 1e-12);
  // cam2 is named "cam0" inside its own file: the index comes from the file name.
  const Mat4 cam2 = KalibrMatrix(dir + "/calib_3_cam2-camchain-imucam.yaml", "cam0", "T_cam_imu");
  EXPECT_LT((rig.cameras[2].cam_from_imu.Matrix() - cam2).cwiseAbs().maxCoeff(), 1e-12);
  const YAML::Node cam4 = YAML::LoadFile(dir + "/calib_3_cam4-camchain-imucam.yaml")["cam0"];
  EXPECT_EQ(rig.cameras[4].model.fx, cam4["intrinsics"][0].as<double>());
  EXPECT_EQ(rig.cameras[4].model.cy, cam4["intrinsics"][3].as<double>());
  EXPECT_EQ(rig.cameras[4].model.distortion_coeffs[3], cam4["distortion_coeffs"][3].as<double>());
  // IMU noise is in no file: BMI085 defaults.
  EXPECT_EQ(rig.imu.gyroscope_noise_density, ImuNoise().gyroscope_noise_density);
  EXPECT_EQ(rig.imu_rostopic, "/alphasense/imu");
  ASSERT_EQ(rig.lidars.size(), 1u);
  EXPECT_EQ(rig.lidars[0].name, "lidar0");
  EXPECT_EQ(rig.lidars[0].type, LidarType::kSpinning);
  EXPECT_EQ(rig.lidars[0].rings, 32);
  EXPECT_EQ(rig.lidars[0].min_range, 0.05);
  EXPECT_EQ(rig.lidars[0].max_range, 120.0);
  EXPECT_EQ(rig.lidars[0].scan_rate, 10.0);
  EXPECT_EQ(rig.lidars[0].rostopic, "/hesai/pandar");
  EXPECT_EQ(rig.lidars[0].imu_from_lidar.translation(), Vec3(-0.001, -0.00855, 0.055));

  // The written rig reads back to the same rig.
  const test::TempDir tmp;
  WriteRigYaml(tmp.File("hilti.yaml"), rig);
  const Rig again = ReadRigYaml(tmp.File("hilti.yaml"));
  ASSERT_EQ(again.cameras.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_TRUE(test::PosesNear(again.cameras[i].cam_from_imu, rig.cameras[i].cam_from_imu, 1e-12, 1e-12));
  }
}

TEST(RigIo, HiltiFrontCamerasFormAStereoPair) {
  LISFM_REQUIRE_SHARED_DATA(std::string(kHiltiDir) + "/lidar_calibration.yaml");
  const std::string dir = test::SharedData(kHiltiDir);
  const Rig rig = LoadHiltiCalibration(dir);
  const SE3 cam1_from_cam0 = rig.cameras[1].cam_from_imu * rig.cameras[0].cam_from_imu.Inverse();
  const Vec3 t = cam1_from_cam0.translation();
  // Measured: 0.108177 m, almost entirely along cam0's x axis.
  EXPECT_NEAR(t.norm(), 0.108, 0.002);
  EXPECT_GT(std::abs(t.x()) / t.norm(), 0.999);
  // Optical axes parallel to within 0.5 deg (measured 0.30 deg).
  const Vec3 z1_in_cam0 = cam1_from_cam0.Inverse().rotation() * Vec3::UnitZ();
  EXPECT_LT(std::acos(z1_in_cam0.z()), 0.5 * M_PI / 180.0);
  // Kalibr's own cam1-from-cam0 estimate (T_cn_cnm1) in the same file agrees:
  // the composition of two 16-digit matrices is exact to ~1e-15.
  const Mat4 kalibr = KalibrMatrix(dir + "/calib_3_cam0-1-camchain-imucam.yaml", "cam1", "T_cn_cnm1");
  EXPECT_LT((cam1_from_cam0.Matrix() - kalibr).cwiseAbs().maxCoeff(), 1e-9);
  // The front pair looks along +x of the IMU (forward); side cameras along +-y.
  EXPECT_GT((rig.cameras[0].cam_from_imu.rotation().conjugate() * Vec3::UnitZ()).x(), 0.99);
  EXPECT_GT((rig.cameras[3].cam_from_imu.rotation().conjugate() * Vec3::UnitZ()).y(), 0.99);
  EXPECT_LT((rig.cameras[4].cam_from_imu.rotation().conjugate() * Vec3::UnitZ()).y(), -0.99);
}

TEST(RigIo, HiltiLidarSpinAxisIsVertical) {
  LISFM_REQUIRE_SHARED_DATA(std::string(kHiltiDir) + "/lidar_calibration.yaml");
  const Rig rig = LoadHiltiCalibration(test::SharedData(kHiltiDir));
  const RigLidar& lidar = rig.lidars[0];
  const Vec3 spin_axis_in_imu = lidar.imu_from_lidar.rotation() * Vec3::UnitZ();
  // x,y,z,w quaternion order: the spin axis is -z of the IMU (exactly, up to
  // the 7-digit quaternion of the file).
  EXPECT_LT((spin_axis_in_imu - Vec3(0, 0, -1)).norm(), 1e-6);
  EXPECT_LT(lidar.imu_from_lidar.translation().norm(), 0.1);  // mounted next to the IMU

  // Independent check with the HILTI 2022 ground truth (IMU frame, z-up world):
  // the spin axis must be vertical on average over exp04.
  const std::string gt =
      "hilti2022_groundtruth/exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt";
  if (test::SharedData(gt).empty()) GTEST_SKIP() << "no HILTI ground truth";
  std::ifstream in(test::SharedData(gt));
  std::string line;
  double sum_cos = 0.0;
  int count = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    double t, x, y, z, qx, qy, qz, qw;
    std::istringstream s(line);
    ASSERT_TRUE(static_cast<bool>(s >> t >> x >> y >> z >> qx >> qy >> qz >> qw));
    const Vec3 axis_in_world = Quat(qw, qx, qy, qz).normalized() * spin_axis_in_imu;
    sum_cos += axis_in_world.z();
    ++count;
  }
  ASSERT_GT(count, 1000);
  // Handheld sway tilts the device by up to ~15 deg; on average the spin axis
  // is within 10 deg of world up (measured: mean cos 0.997, ~4.4 deg).
  EXPECT_GT(sum_cos / count, std::cos(10.0 * M_PI / 180.0));
  // The w,x,y,z reading would put the axis on the horizon: cos ~ 0.
  const Quat wxyz_misread(0.7071068, -0.7071068, 0.0, 0.0);  // Eigen (w, x, y, z)
  EXPECT_LT(std::abs((wxyz_misread * Vec3::UnitZ()).dot(Vec3(0, 0, -1))), 1e-6);
}

TEST(RigIo, ShippedConfigsParseAndHilti2022MatchesTheSourceFiles) {
  const Rig rig2021 = ReadRigYaml(test::SourceDir() + "/configs/hilti2021.yaml");
  EXPECT_EQ(rig2021.cameras.size(), 5u);
  ASSERT_EQ(rig2021.lidars.size(), 2u);
  EXPECT_EQ(rig2021.lidars[0].rings, 64);
  EXPECT_EQ(rig2021.lidars[1].type, LidarType::kLivox);
  const Rig shipped = ReadRigYaml(test::SourceDir() + "/configs/hilti2022.yaml");
  ASSERT_EQ(shipped.cameras.size(), 5u);
  ASSERT_EQ(shipped.lidars.size(), 1u);
  LISFM_REQUIRE_SHARED_DATA(std::string(kHiltiDir) + "/lidar_calibration.yaml");
  // configs/hilti2022.yaml must be what LoadHiltiCalibration gives today.
  const Rig rig = LoadHiltiCalibration(test::SharedData(kHiltiDir));
  for (int i = 0; i < 5; ++i) {
    const RigCamera& a = rig.cameras[i];
    const RigCamera& b = shipped.cameras[i];
    EXPECT_EQ(b.model.fx, a.model.fx);
    EXPECT_EQ(b.model.cy, a.model.cy);
    EXPECT_EQ(b.model.distortion_coeffs, a.model.distortion_coeffs);
    EXPECT_EQ(b.timeshift_cam_imu_s, a.timeshift_cam_imu_s);
    EXPECT_EQ(b.rostopic, a.rostopic);
    EXPECT_TRUE(test::PosesNear(b.cam_from_imu, a.cam_from_imu, 1e-12, 1e-12));
  }
  EXPECT_TRUE(test::PosesNear(shipped.lidars[0].imu_from_lidar, rig.lidars[0].imu_from_lidar, 1e-12, 1e-12));
  EXPECT_EQ(shipped.lidars[0].rings, 32);
  EXPECT_EQ(shipped.imu_rostopic, "/alphasense/imu");
}

}  // namespace
}  // namespace lisfm
