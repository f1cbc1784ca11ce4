// `lisfm simulate` on bad configuration: one clear error, non-zero exit, no output.
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

TEST(SimulateCommand, BadConfigurationFailsClearly) {
  test::TempDir dir;
  const std::string bin = test::LisfmBinary();
  std::string out;
  const std::string common = " --duration 2 --camera_rate 0 --output_path " + dir.File("o");
  EXPECT_NE(test::RunCommand(bin + " simulate --scene moon" + common, &out), 0);
  EXPECT_NE(out.find("moon"), std::string::npos) << out;
  EXPECT_NE(test::RunCommand(bin + " simulate --camera_rate -1 --output_path " + dir.File("o"),
                             &out), 0);
  EXPECT_NE(out.find("camera_rate"), std::string::npos) << out;
  // A rig YAML missing a required field.
  test::WriteText(dir.File("rig.yaml"),
                  "cam0:\n  distortion_model: equidistant\n  distortion_coeffs: [0, 0, 0, 0]\n"
                  "  resolution: [720, 540]\n  T_cam_imu: [[1,0,0,0],[0,1,0,0],[0,0,1,0],"
                  "[0,0,0,1]]\n");
  EXPECT_NE(test::RunCommand(bin + " simulate --rig_path " + dir.File("rig.yaml") + common,
                             &out), 0);
  EXPECT_NE(out.find("intrinsics"), std::string::npos) << out;
  // A trajectory file with unsorted times.
  test::WriteText(dir.File("bad.txt"),
                  "10.0 0 0 1 0 0 0 1\n10.2 0 0 1 0 0 0 1\n10.1 0 0 1 0 0 0 1\n");
  EXPECT_NE(test::RunCommand(bin + " simulate --trajectory_path " + dir.File("bad.txt") +
                                 " --scene hall" + common, &out), 0);
  EXPECT_NE(out.find("line 3"), std::string::npos) << out;
  // Error sources: an unknown token, a negative size, too few stops, a site
  // driven by a recorded trajectory (the site is built around its own route).
  const std::vector<std::pair<std::string, std::string>> bad = {
      {" --error_sources dynamics,rain", "error_sources"},
      {" --error_sources none,dynamics", "error_sources"},
      {" --Dynamics.people_per_100m -1", "Dynamics.people_per_100m"},
      {" --Dynamics.speed 0", "Dynamics.speed"},
      {" --Walk.num_stops 1", "Walk.num_stops"},
      {" --scene site --trajectory_path " + dir.File("bad.txt"), "site"},
  };
  for (const auto& [args, name] : bad) {
    EXPECT_NE(test::RunCommand(bin + " simulate" + args + common, &out), 0) << args;
    EXPECT_NE(out.find(name), std::string::npos) << args << ": " << out;
    if (name != "site") {  // option values are refused before any work
      EXPECT_EQ(out.find("scene and motion"), std::string::npos) << args << ": " << out;
    }
  }
  EXPECT_FALSE(fs::exists(dir.File("o")));
}

// Error sources: an unknown token, a negative size and a source for a sensor
// the rig does not have are one clear usage error each, and leave no folder.
TEST(SimulateCommand, BadErrorSourceConfigurationFailsClearly) {
  test::TempDir dir;
  const std::string bin = test::LisfmBinary();
  const std::string common = " --duration 2 --camera_rate 0 --output_path " + dir.File("o");
  std::string out;
  EXPECT_EQ(test::RunCommand(bin + " simulate --error_sources imu,weather" + common, &out), 2);
  EXPECT_NE(out.find("--error_sources imu,weather"), std::string::npos) << out;
  EXPECT_NE(out.find("calibration"), std::string::npos) << out;  // lists the valid tokens
  EXPECT_EQ(test::RunCommand(
                bin + " simulate --CalibrationError.lidar_rotation_sigma_deg -1" + common, &out),
            2);
  EXPECT_NE(out.find("--CalibrationError.lidar_rotation_sigma_deg -1"), std::string::npos) << out;
  EXPECT_EQ(test::RunCommand(bin + " simulate --ImuError.temperature_sigma_k -0.5" + common, &out),
            2);
  EXPECT_NE(out.find("--ImuError.temperature_sigma_k"), std::string::npos) << out;
  EXPECT_EQ(
      test::RunCommand(bin + " simulate --error_sources calibration --lidars none" + common, &out),
      2);
  EXPECT_NE(out.find("no LiDAR and no camera"), std::string::npos) << out;
  EXPECT_EQ(out.find("scene and motion"), std::string::npos) << out;  // before any work
  EXPECT_EQ(
      test::RunCommand(bin + " simulate --error_sources dynamics --lidars none" + common, &out),
      2);
  EXPECT_NE(out.find("--error_sources dynamics: the simulated rig has no LiDAR, camera or RGB-D"),
            std::string::npos)
      << out;
  EXPECT_EQ(out.find("scene and motion"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir.File("o")));
  // -h documents every source and cites where its size comes from.
  EXPECT_EQ(test::RunCommand(bin + " simulate -h", &out), 0);
  for (const char* text : {"--error_sources",
                           "--CalibrationError.camera_time_offset_sigma_s",
                           "--ImuError.gyro_scale_sigma_percent",
                           "--LidarErrors.incidence_noise_gain",
                           "--CameraErrors.motion_blur",
                           "--Materials.texture_poor_fraction",
                           "--Dynamics.people_per_100m",
                           "--Walk.num_stops",
                           "BMI085 datasheet",
                           "HILTI 2022"}) {
    EXPECT_NE(out.find(text), std::string::npos) << text;
  }
}

// Error sources: an unknown source, a negative size, a source for a sensor the
// recording does not have, an unknown material in a scene file: one error
// naming the option or file, a non-zero exit, no output folder.
TEST(SimulateCommand, BadErrorSourcesFailClearly) {
  test::TempDir dir;
  const std::string bin = test::LisfmBinary() + " simulate";
  const std::string common = " --duration 2 --camera_rate 0 --output_path " + dir.File("o");
  std::string out;
  EXPECT_EQ(test::RunCommand(bin + " --error_sources lidar,weather" + common, &out), 2);
  EXPECT_NE(out.find("--error_sources lidar,weather"), std::string::npos) << out;
  EXPECT_EQ(test::RunCommand(bin + " --LidarErrors.beam_divergence_mrad -1" + common, &out), 2);
  EXPECT_NE(out.find("--LidarErrors.beam_divergence_mrad -1 is out of range"),
            std::string::npos)
      << out;
  EXPECT_EQ(test::RunCommand(bin + " --CameraErrors.read_noise_e -2" + common, &out), 2);
  EXPECT_NE(out.find("CameraErrors.read_noise_e"), std::string::npos) << out;
  EXPECT_EQ(test::RunCommand(bin + " --error_sources lidar --lidars none" + common, &out), 2);
  EXPECT_NE(out.find("needs a LiDAR"), std::string::npos) << out;
  EXPECT_EQ(test::RunCommand(bin + " --error_sources camera" + common, &out), 2);
  EXPECT_NE(out.find("needs images"), std::string::npos) << out;
  test::WriteText(dir.File("sim_bad.yaml"),
                  "type: office\nmaterials:\n  wall: [painted_plaster, unobtanium]\n");
  EXPECT_EQ(test::RunCommand(bin + " --scene " + dir.File("sim_bad.yaml") + common, &out), 1);
  EXPECT_NE(out.find("sim_bad.yaml"), std::string::npos) << out;
  EXPECT_NE(out.find("materials.wall"), std::string::npos) << out;
  EXPECT_NE(out.find("unknown material 'unobtanium'"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir.File("o")));
}

// --overwrite 1 replaces only a folder lisfm wrote: a user's folder is refused
// before any simulation work, and left as it was.
TEST(SimulateCommand, OverwriteNeverRemovesAFolderLisfmDidNotWrite) {
  test::TempDir dir;
  fs::create_directories(dir.File("mine"));
  test::WriteText(dir.File("mine/notes.txt"), "keep me");
  std::string out;
  EXPECT_EQ(test::RunCommand(test::LisfmBinary() + " simulate --duration 2 --camera_rate 0 " +
                                 "--output_path " + dir.File("mine") + " --overwrite 1",
                             &out),
            2);
  EXPECT_NE(out.find("lisfm did not write"), std::string::npos) << out;
  EXPECT_EQ(out.find("scene and motion"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(dir.File("mine/notes.txt")));
}

}  // namespace
}  // namespace lisfm
