// sim::Simulate end to end: folder layout, readability by the core readers,
// determinism, real trajectories.
#include "sim/simulator.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

namespace fs = std::filesystem;

int CountDataLines(const std::string& path) {
  LineReader reader(path);
  std::string line;
  int n = 0;
  while (reader.Next(&line)) {
    if (!line.empty() && line[0] != '#') ++n;
  }
  return n;
}

Rig TestRig() {
  if (!test::SharedData("hilti_exp4_small/calibration").empty()) {
    return LoadHiltiCalibration(test::SharedData("hilti_exp4_small/calibration"));
  }
  Rig rig;  // one pinhole camera when the real calibration is missing
  RigCamera cam;
  cam.name = "cam0";
  cam.model.width = 320;
  cam.model.height = 240;
  cam.model.fx = cam.model.fy = 200;
  cam.model.cx = 160;
  cam.model.cy = 120;
  cam.cam_from_imu = SE3((Mat3() << 0, 1, 0, 0, 0, 1, 1, 0, 0).finished(), Vec3::Zero());
  rig.cameras.push_back(cam);
  return rig;
}

TEST(Simulate, WritesACompleteSequenceFolder) {
  test::TempDir dir;
  SimulatorOptions options;
  options.duration = 8.0;  // long enough for three rests (control points)
  options.walk.num_stops = 3;
  options.error_sources = "none";
  options.camera_rate = 0.5;
  options.lidars = "spinning,livox";
  options.rgbd = true;
  options.rgbd_rate = 0.5;
  options.output_path = dir.File("seq");
  const Rig rig = TestRig();
  const SimulationSummary s = Simulate(options, rig);
  const std::string out = options.output_path;
  EXPECT_FALSE(fs::exists(out + ".tmp-" + std::to_string(getpid())));
  const Rig written = ReadRigYaml(JoinPaths(out, "rig.yaml"));
  ASSERT_EQ(written.lidars.size(), 2u);
  EXPECT_EQ(written.lidars[1].type, LidarType::kLivox);
  EXPECT_EQ(written.cameras.size(), rig.cameras.size());
  EXPECT_EQ(CountDataLines(JoinPaths(out, "imu0/data.csv")), 8 * 400 + 1);
  EXPECT_EQ(CountDataLines(JoinPaths(out, "lidar0/data.csv")), 80);
  EXPECT_EQ(CountDataLines(JoinPaths(out, "lidar1/data.csv")), 80);
  EXPECT_EQ(s.num_scans[0], 80u);
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    EXPECT_EQ(CountDataLines(JoinPaths(out, "cam" + std::to_string(c) + "/data.csv")), 5);
  }
  EXPECT_EQ(CountDataLines(JoinPaths(out, "rgbd0/data.csv")), 5);
  // A scan file is named by its stamp and readable; times are inside the period.
  LineReader reader(JoinPaths(out, "lidar0/data.csv"));
  std::string line;
  reader.Next(&line);
  reader.Next(&line);
  const auto fields = SplitString(line, ",");
  ASSERT_EQ(fields.size(), 2u);
  EXPECT_EQ(fields[1], fields[0] + ".pcd");
  const PointCloud cloud = ReadPcd(JoinPaths(out, "lidar0/data/" + fields[1]));
  EXPECT_GT(cloud.size(), 20000u);
  for (const LidarPoint& p : cloud.points) EXPECT_LT(p.t, 0.1f);
  const Trajectory gt = ReadTum(JoinPaths(out, "groundtruth.txt"));
  EXPECT_EQ(gt.size(), 801u);
  EXPECT_EQ(ReadEurocCsv(JoinPaths(out, "groundtruth.csv")).size(), 801u);
  EXPECT_EQ(ReadControlPoints(JoinPaths(out, "controlpoints.txt")).size(),
            s.num_control_points);
  EXPECT_EQ(s.num_control_points, 3u);
  EXPECT_TRUE(FileExists(JoinPaths(out, "scene.ply")));
  EXPECT_TRUE(FileExists(JoinPaths(out, "cam0/data/" + std::to_string(gt[0].t_ns) + ".png")));
}

TEST(Simulate, DeterministicForASeed) {
  test::TempDir dir;
  SimulatorOptions options;
  options.duration = 1.5;
  options.camera_rate = 0.0;
  const Rig rig = TestRig();
  options.output_path = dir.File("a");
  Simulate(options, rig);
  options.output_path = dir.File("b");
  Simulate(options, rig);
  EXPECT_EQ(ReadFile(dir.File("a/imu0/data.csv")), ReadFile(dir.File("b/imu0/data.csv")));
  EXPECT_EQ(ReadFile(dir.File("a/lidar0/data.csv")), ReadFile(dir.File("b/lidar0/data.csv")));
  LineReader reader(dir.File("a/lidar0/data.csv"));
  std::string line;
  reader.Next(&line);
  reader.Next(&line);
  const std::string name = SplitString(line, ",")[1];
  EXPECT_EQ(ReadFile(dir.File("a/lidar0/data/" + name)),
            ReadFile(dir.File("b/lidar0/data/" + name)));
  options.seed = 2;
  options.output_path = dir.File("c");
  Simulate(options, rig);
  EXPECT_NE(ReadFile(dir.File("a/imu0/data.csv")), ReadFile(dir.File("c/imu0/data.csv")));
}

// --noise_scale 0 turns every error source off: with error_sources all and
// none the folders hold the same bytes. With noise the lidar and camera
// sources change the LiDAR scans and the images, and not the IMU data.
TEST(Simulate, NoiseScaleZeroTurnsTheErrorSourcesOff) {
  test::TempDir dir;
  SimulatorOptions options;
  options.duration = 1.5;
  options.camera_rate = 2.0;
  const Rig rig = TestRig();
  auto run = [&](const std::string& name, double noise_scale, const std::string& sources) {
    options.noise_scale = noise_scale;
    options.error_sources = sources;
    options.output_path = dir.File(name);
    Simulate(options, rig);
  };
  run("exact_all", 0.0, "all");
  run("exact_none", 0.0, "none");
  run("noisy_lidar_camera", 1.0, "lidar,camera");
  run("noisy_none", 1.0, "none");
  LineReader reader(dir.File("exact_all/lidar0/data.csv"));
  std::string line;
  reader.Next(&line);
  reader.Next(&line);
  const std::string scan = "lidar0/data/" + SplitString(line, ",")[1];
  const Trajectory gt = ReadTum(dir.File("exact_all/groundtruth.txt"));
  const std::string image = "cam0/data/" + std::to_string(gt[50].t_ns) + ".png";
  for (const std::string& file : {std::string("imu0/data.csv"), std::string("lidar0/data.csv"),
                                 std::string("cam0/data.csv"), scan, image}) {
    EXPECT_EQ(ReadFile(dir.File("exact_all/" + file)), ReadFile(dir.File("exact_none/" + file)))
        << file;
  }
  EXPECT_EQ(ReadFile(dir.File("noisy_lidar_camera/imu0/data.csv")),
            ReadFile(dir.File("noisy_none/imu0/data.csv")));
  EXPECT_NE(ReadFile(dir.File("noisy_lidar_camera/" + image)),
            ReadFile(dir.File("noisy_none/" + image)));
  const PointCloud with = ReadPcd(dir.File("noisy_lidar_camera/" + scan));
  const PointCloud without = ReadPcd(dir.File("noisy_none/" + scan));
  EXPECT_LT(with.size(), without.size());  // dropouts and range limits
}

// A source named explicitly for a sensor the rig does not have is refused
// and leaves no folder; "all" applies to the sensors there are.
TEST(Simulate, CameraSourceWithoutCamerasIsAnError) {
  test::TempDir dir;
  SimulatorOptions options;
  options.duration = 1.0;
  options.error_sources = "camera";
  options.output_path = dir.File("seq");
  EXPECT_THROW(Simulate(options, PrepareRig(Rig(), "spinning")), UsageError);
  EXPECT_FALSE(fs::exists(dir.File("seq")));
  options.error_sources = "all";
  Simulate(options, PrepareRig(Rig(), "spinning"));
  EXPECT_TRUE(fs::exists(dir.File("seq/lidar0/data.csv")));
}

// Error source `dynamics`: people change what the LiDAR sees, never the
// motion or the IMU; their tracks are in truth/people.csv (10 Hz rows per
// person). With --error_sources none or --noise_scale 0 there are none.
TEST(Simulate, PeopleAppearInTheScansOnlyWithDynamics) {
  test::TempDir dir;
  SimulatorOptions options;
  options.duration = 4.0;
  options.camera_rate = 0.0;
  options.error_sources = "dynamics";
  options.output_path = dir.File("people");
  const SimulationSummary with = Simulate(options, TestRig());
  options.error_sources = "none";
  options.output_path = dir.File("none");
  const SimulationSummary without = Simulate(options, TestRig());
  options.error_sources = "all";
  options.noise_scale = 0;
  options.output_path = dir.File("exact");
  EXPECT_EQ(Simulate(options, TestRig()).num_people, 0u);
  EXPECT_EQ(without.num_people, 0u);
  ASSERT_EQ(with.num_people, 2u);  // 2 per 100 m of the 76 m office loop
  EXPECT_FALSE(FileExists(dir.File("none/truth/people.csv")));
  EXPECT_EQ(CountDataLines(dir.File("people/truth/people.csv")), 41 * 2);
  for (const std::string file : {"imu0/data.csv", "groundtruth.txt", "controlpoints.txt",
                                 "lidar0/data.csv"}) {
    EXPECT_EQ(ReadFile(dir.File("people/" + file)), ReadFile(dir.File("none/" + file))) << file;
  }
  int differing = 0;
  LineReader reader(dir.File("none/lidar0/data.csv"));
  std::string line;
  while (reader.Next(&line)) {
    if (line.empty() || line[0] == '#') continue;
    const std::string name = SplitString(line, ",")[1];
    differing += ReadFile(dir.File("people/lidar0/data/" + name)) !=
                 ReadFile(dir.File("none/lidar0/data/" + name));
  }
  EXPECT_GT(differing, 10);
}

// Real motion: the ground truth is the TUM trajectory, translated into the scene.
TEST(Simulate, FollowsARealTumTrajectory) {
  LISFM_REQUIRE_SHARED_DATA(
      "hilti2022_groundtruth/exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt");
  const std::string tum = test::SharedData(
      "hilti2022_groundtruth/exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt");
  test::TempDir dir;
  SimulatorOptions options;
  options.trajectory_path = tum;
  options.scene = "hall";
  options.duration = 20.0;
  options.camera_rate = 0.0;
  options.error_sources = "none";
  options.output_path = dir.File("real");
  Simulate(options, TestRig());
  const Trajectory input = ReadTum(tum);
  const Trajectory gt = ReadTum(dir.File("real/groundtruth.txt"));
  EXPECT_EQ(gt.start_ns(), input.start_ns());
  const Vec3 offset = gt[0].pose.translation() - input[0].pose.translation();
  // The spline fit (0.1 s knots, light smoothing) stays within 3 cm / 1 deg
  // of 10 Hz handheld samples.
  for (size_t i = 2; i < 190; ++i) {
    const auto p = gt.Interpolate(input[i].t_ns);
    ASSERT_TRUE(p.has_value());
    const SE3 expected(input[i].pose.rotation(), input[i].pose.translation() + offset);
    EXPECT_TRUE(test::PosesNear(*p, expected, M_PI / 180, 0.03)) << "sample " << i;
  }
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
