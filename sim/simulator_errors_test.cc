// The `calibration` and `imu` error sources of sim::Simulate, checked on the
// written sequence folder against their definitions: rig.yaml vs
// truth/rig.yaml, LiDAR points and camera images made at the true capture
// time with the true extrinsic (also under the lidar and camera sources), IMU
// samples carrying truth/imu_errors.yaml, and zero-sized / noise_scale 0
// sources reproducing the clean recording.
#include "sim/simulator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"
#include "sim/camera_simulator.h"
#include "sim/imu_simulator.h"
#include "sim/motion.h"
#include "sim/scene.h"
#include "sim/texture.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

namespace fs = std::filesystem;

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

// The scene, walk and texture Simulate() makes for a generated walk, rebuilt
// from the same public functions (checked against groundtruth.txt below).
struct World {
  std::unique_ptr<Scene> scene;
  SplineTrajectory trajectory;
  TextureOptions texture;
};

World RebuildWorld(const SimulatorOptions& options) {
  SceneOptions scene_options = ResolveSceneOptions(options.scene);
  scene_options.seed = scene_options.seed * 1000003 + options.seed;
  World world;
  world.scene = Scene::Generate(scene_options);
  world.trajectory = GenerateWalking(world.scene->route(),
                                     options.duration,
                                     kDefaultStartNs,
                                     static_cast<uint32_t>(options.seed),
                                     options.walk,
                                     nullptr);
  world.texture = {static_cast<uint32_t>(scene_options.seed),
                   static_cast<float>(scene_options.texture_scale)};
  return world;
}

// Rows `t_ns, v1, ..., v6` of imu0/data.csv or imu0/bias_groundtruth.csv.
std::vector<std::pair<TimestampNs, Vec6>> ReadSixColumns(const std::string& path) {
  std::vector<std::pair<TimestampNs, Vec6>> rows;
  LineReader reader(path);
  std::string line;
  while (reader.Next(&line)) {
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> f = SplitString(line, ",");
    EXPECT_EQ(f.size(), 7u) << path << ": " << line;
    std::pair<TimestampNs, Vec6> row;
    EXPECT_TRUE(ParseInt64(f[0], &row.first));
    for (int i = 0; i < 6; ++i) EXPECT_TRUE(ParseDouble(f[i + 1], &row.second[i]));
    rows.push_back(row);
  }
  return rows;
}

// `t_ns,<name>` rows of a sensor's data.csv.
std::vector<TimestampNs> ReadStamps(const std::string& path) {
  std::vector<TimestampNs> stamps;
  LineReader reader(path);
  std::string line;
  while (reader.Next(&line)) {
    if (line.empty() || line[0] == '#') continue;
    TimestampNs t = 0;
    EXPECT_TRUE(ParseInt64(SplitString(line, ",")[0], &t));
    stamps.push_back(t);
  }
  return stamps;
}

// Every regular file under `root`, relative path -> contents.
std::map<std::string, std::string> FolderContents(const std::string& root) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    if (!entry.is_regular_file()) continue;
    files[fs::relative(entry.path(), root).string()] = ReadFile(entry.path().string());
  }
  return files;
}

double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

double Quantile(std::vector<double> v, double q) {
  const size_t k = static_cast<size_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

class SimulatorErrorsTest : public ::testing::Test {
 protected:
  // One sequence with both sources on, with calibration errors large enough
  // to see in every check, and the same sequence without error sources.
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    options_ = new SimulatorOptions();
    options_->scene = "office";
    options_->duration = 8.0;
    options_->camera_rate = 1.0;
    options_->lidars = "spinning";
    options_->seed = 7;
    options_->walk.num_stops = 3;  // the walk these checks were set on
    options_->error_sources = "calibration,imu";
    CalibrationErrorOptions& c = options_->calibration_error;
    c.lidar_translation_sigma_m = c.camera_translation_sigma_m = 0.02;
    c.lidar_rotation_sigma_deg = c.camera_rotation_sigma_deg = 1.0;
    c.lidar_time_offset_sigma_s = c.camera_time_offset_sigma_s = 0.02;
    c.camera_time_offset_spread_s = 0.002;
    options_->output_path = dir_->File("errors");
    Simulate(*options_, TestRig());
    SimulatorOptions clean = *options_;
    clean.error_sources = "none";
    clean.output_path = dir_->File("clean");
    Simulate(clean, TestRig());
  }
  static void TearDownTestSuite() {
    delete dir_;
    delete options_;
  }

  void SetUp() override {
    world_ = RebuildWorld(*options_);
    // The rebuilt walk is Simulate()'s: groundtruth.txt holds it to the last bit.
    const Trajectory gt = ReadTum(File("groundtruth.txt"));
    ASSERT_GT(gt.size(), 700u);
    for (const StampedPose& p : gt.poses()) {
      ASSERT_TRUE(test::PosesNear(p.pose, world_.trajectory.Pose(p.t_ns), 1e-12, 1e-12))
          << "the test's rebuild of Simulate()'s scene and walk is out of date";
    }
    believed_ = ReadRigYaml(File("rig.yaml"));
    truth_ = ReadRigYaml(File("truth/rig.yaml"));
  }

  static std::string File(const std::string& name) { return dir_->File("errors/" + name); }

  static TimestampNs OffsetError(double truth_s, double believed_s) {
    return SecondsToNs(truth_s) - SecondsToNs(believed_s);
  }

  static test::TempDir* dir_;
  static SimulatorOptions* options_;
  World world_;
  Rig believed_, truth_;
};

test::TempDir* SimulatorErrorsTest::dir_ = nullptr;
SimulatorOptions* SimulatorErrorsTest::options_ = nullptr;

// rig.yaml is the input rig (what the user believes); truth/rig.yaml differs
// from it by exactly the drawn errors.
TEST_F(SimulatorErrorsTest, TruthRigDiffersFromRigYamlByTheDrawnErrors) {
  const Rig input = PrepareRig(TestRig(), options_->lidars);
  const CalibrationErrors drawn = DrawCalibrationErrors(options_->calibration_error,
                                                        options_->noise_scale,
                                                        static_cast<uint64_t>(options_->seed),
                                                        input.lidars.size(),
                                                        input.cameras.size());
  ASSERT_EQ(believed_.lidars.size(), 1u);
  ASSERT_EQ(truth_.lidars.size(), 1u);
  ASSERT_EQ(truth_.cameras.size(), input.cameras.size());
  auto expect_error = [](const SE3& believed,
                         const SE3& truth,
                         const SensorCalibrationError& e,
                         const std::string& what) {
    EXPECT_LT(
        (so3::Log(believed.rotation().conjugate() * truth.rotation()) - e.rotation_rad).norm(),
        1e-9)
        << what;
    EXPECT_LT((truth.translation() - believed.translation() - e.translation_m).norm(), 1e-12)
        << what;
  };
  EXPECT_TRUE(test::PosesNear(
      believed_.lidars[0].imu_from_lidar, input.lidars[0].imu_from_lidar, 1e-12, 1e-12));
  EXPECT_EQ(believed_.lidars[0].time_offset_s, 0.0);
  expect_error(believed_.lidars[0].imu_from_lidar,
               truth_.lidars[0].imu_from_lidar,
               drawn.lidars[0],
               "lidar0");
  EXPECT_EQ(OffsetError(truth_.lidars[0].time_offset_s, believed_.lidars[0].time_offset_s),
            drawn.lidars[0].time_offset_ns);
  for (size_t c = 0; c < input.cameras.size(); ++c) {
    EXPECT_TRUE(test::PosesNear(
        believed_.cameras[c].cam_from_imu, input.cameras[c].cam_from_imu, 1e-12, 1e-12));
    EXPECT_EQ(believed_.cameras[c].timeshift_cam_imu_s, 0.0);
    expect_error(believed_.cameras[c].cam_from_imu.Inverse(),
                 truth_.cameras[c].cam_from_imu.Inverse(),
                 drawn.cameras[c],
                 "cam" + std::to_string(c));
    EXPECT_EQ(OffsetError(truth_.cameras[c].timeshift_cam_imu_s,
                          believed_.cameras[c].timeshift_cam_imu_s),
              drawn.cameras[c].time_offset_ns);
    EXPECT_EQ(truth_.cameras[c].model.fx, believed_.cameras[c].model.fx);
  }
}

// Each point, cast again from the true LiDAR pose at its true capture time
// (stamp + t + truth offset - rig.yaml offset), hits the scene at its range up
// to the range noise (sigma 1 cm: median |residual| 0.674 sigma; 99 % within
// 2.58 sigma); from the pose rig.yaml implies it does not. Read with rig.yaml's
// timing, a point is displaced by its velocity times the time offset.
TEST_F(SimulatorErrorsTest, LidarPointsAreMeasuredAtTheTrueTimeWithTheTrueExtrinsic) {
  const RigLidar& lt = truth_.lidars[0];
  const RigLidar& lb = believed_.lidars[0];
  const TimestampNs d = OffsetError(lt.time_offset_s, lb.time_offset_s);
  ASSERT_GT(std::abs(d), 5000000) << "seed 7 draws a LiDAR time offset error of " << d << " ns";
  std::vector<double> residual_true, residual_believed;
  double max_shift_error = 0, max_shift = 0;
  const std::vector<TimestampNs> stamps = ReadStamps(File("lidar0/data.csv"));
  ASSERT_GT(stamps.size(), 70u);
  for (size_t s = 0; s < stamps.size(); s += 4) {
    // The scan's stamp is its data.csv row (and file name).
    const PointCloud cloud = ReadPcd(File("lidar0/data/" + std::to_string(stamps[s]) + ".pcd"));
    for (size_t i = 0; i < cloud.size(); i += 11) {
      const LidarPoint& p = cloud.points[i];
      const Vec3 x_lidar(p.x, p.y, p.z);
      const double range = x_lidar.norm();
      const TimestampNs t_read = stamps[s] + SecondsToNs(p.t);
      const SE3 true_pose = world_.trajectory.Pose(t_read + d) * lt.imu_from_lidar;
      const SE3 believed_pose = world_.trajectory.Pose(t_read) * lb.imu_from_lidar;
      for (const auto& [pose, out] :
           {std::pair<const SE3*, std::vector<double>*>{&true_pose, &residual_true},
            std::pair<const SE3*, std::vector<double>*>{&believed_pose, &residual_believed}}) {
        const RayHit hit = world_.scene->Intersect(
            pose->translation(), pose->rotation() * (x_lidar / range), 0.0, 200.0);
        out->push_back(hit.hit ? std::abs(range - hit.distance) : 1e3);
      }
      // x(t + d) - x(t) = d * (velocity of the point) + O(d^3) about t + d / 2.
      const Vec3 x_imu = lt.imu_from_lidar * x_lidar;
      const TrajectorySample mid = world_.trajectory.Evaluate(t_read + d / 2);
      const Vec3 point_velocity = mid.velocity_world + mid.world_from_imu.rotation() *
                                                           mid.angular_velocity_body.cross(x_imu);
      const Vec3 shift =
          world_.trajectory.Pose(t_read + d) * x_imu - world_.trajectory.Pose(t_read) * x_imu;
      max_shift_error = std::max(max_shift_error, (shift - NsToSeconds(d) * point_velocity).norm());
      max_shift = std::max(max_shift, shift.norm());
    }
  }
  ASSERT_GT(residual_true.size(), 50000u);
  std::printf(
      "LiDAR time offset error %.2f ms; median |range residual| at the true pose %.2f mm, "
      "at rig.yaml's %.2f mm; largest shift v * d %.1f mm\n",
      1e-6 * static_cast<double>(d),
      1e3 * Median(residual_true),
      1e3 * Median(residual_believed),
      1e3 * max_shift);
  const double sigma = 0.01;
  EXPECT_NEAR(Median(residual_true), 0.6745 * sigma, 0.1 * 0.6745 * sigma);
  EXPECT_LT(Quantile(residual_true, 0.99), 3 * sigma);
  EXPECT_GT(Median(residual_believed), 3 * Median(residual_true));
  EXPECT_LT(max_shift_error, 2e-4);
  EXPECT_GT(max_shift, 0.01);  // m: the walk moves the points by v * d
}

// Every image equals a noise-free render from the camera's ground truth:
// groundtruth at stamp + (truth - rig.yaml timeshift) composed with the true
// extrinsic, up to the pixel noise (sigma 2 DN, bounded at 3.47 sigma) and
// rounding. The pose rig.yaml implies gives a different image.
TEST_F(SimulatorErrorsTest, CameraImagesAreRenderedAtTheTrueCapturePose) {
  CameraSimOptions render_options;
  render_options.noise_scale = 0;
  for (size_t c = 0; c < truth_.cameras.size(); ++c) {
    const RigCamera& ct = truth_.cameras[c];
    const RigCamera& cb = believed_.cameras[c];
    const TimestampNs d = OffsetError(ct.timeshift_cam_imu_s, cb.timeshift_cam_imu_s);
    const CameraRenderer renderer(*world_.scene, ct.model, world_.texture, render_options);
    const std::vector<TimestampNs> stamps = ReadStamps(File(ct.name + "/data.csv"));
    ASSERT_EQ(stamps.size(), 9u);
    // Frames while walking (the walk rests at 0-1.3 s, 3.3-4.7 s and from 6.7 s).
    for (const size_t f : {2, 3, 5, 6}) {
      const cv::Mat image = cv::imread(
          File(ct.name + "/data/" + std::to_string(stamps[f]) + ".png"), cv::IMREAD_UNCHANGED);
      ASSERT_FALSE(image.empty());
      const SE3 true_pose = world_.trajectory.Pose(stamps[f] + d) * ct.cam_from_imu.Inverse();
      const SE3 believed_pose = world_.trajectory.Pose(stamps[f]) * cb.cam_from_imu.Inverse();
      cv::Mat diff;
      cv::absdiff(image, renderer.Render(true_pose, 0), diff);
      double max_diff = 0;
      cv::minMaxLoc(diff, nullptr, &max_diff);
      EXPECT_LE(max_diff, 8.0) << ct.name << " frame " << f;
      cv::absdiff(image, renderer.Render(believed_pose, 0), diff);
      const double far = cv::countNonZero(diff > 8) / static_cast<double>(diff.total());
      EXPECT_GT(far, 0.02) << ct.name << " frame " << f;
      std::printf(
          "%s frame %zu: time offset error %.2f ms; max |image - render at the true "
          "pose| %.0f DN; %.1f %% of pixels differ > 8 DN at rig.yaml's pose\n",
          ct.name.c_str(),
          f,
          1e-6 * static_cast<double>(d),
          max_diff,
          100 * far);
    }
  }
}

// Pearson correlation of two single-channel images of the same size.
double ImageCorrelation(const cv::Mat& a, const cv::Mat& b) {
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  const double n = static_cast<double>(a.total());
  for (int y = 0; y < a.rows; ++y) {
    for (int x = 0; x < a.cols; ++x) {
      const double u = a.at<uint8_t>(y, x), v = b.at<uint8_t>(y, x);
      sa += u;
      sb += v;
      saa += u * u;
      sbb += v * v;
      sab += u * v;
    }
  }
  return (sab - sa * sb / n) / std::sqrt((saa - sa * sa / n) * (sbb - sb * sb / n));
}

// The lidar and camera sources act on data made at the true capture time with
// the true extrinsic: with calibration, lidar and camera on together, LiDAR
// points cast again from the true pose hit the scene near their range
// (incidence noise, mixed pixels and range limits spread the residuals, so
// the check is the median) and far from it at rig.yaml's pose; each image
// (exposure, blur, lighting, noise) correlates with a clean render at the true
// capture pose at least 1.5 times as well as with one at rig.yaml's pose
// (measured 1.9-4.8 times over the 5 cameras; about 1 if the pose were wrong).
TEST(SimulatorErrors, LidarAndCameraSourcesUseTheTrueCalibration) {
  test::TempDir dir;
  SimulatorOptions options;
  options.duration = 8.0;
  options.camera_rate = 1.0;
  options.lidars = "spinning";
  options.seed = 7;
  options.walk.num_stops = 3;
  options.error_sources = "calibration,lidar,camera";
  CalibrationErrorOptions& c = options.calibration_error;
  c.lidar_translation_sigma_m = c.camera_translation_sigma_m = 0.02;
  c.lidar_rotation_sigma_deg = c.camera_rotation_sigma_deg = 1.0;
  c.lidar_time_offset_sigma_s = c.camera_time_offset_sigma_s = 0.02;
  c.camera_time_offset_spread_s = 0.002;
  options.output_path = dir.File("seq");
  Simulate(options, TestRig());
  const World world = RebuildWorld(options);
  const Rig believed = ReadRigYaml(dir.File("seq/rig.yaml"));
  const Rig truth = ReadRigYaml(dir.File("seq/truth/rig.yaml"));

  // |range - cast range| of every 11th point of every 4th scan, cast from the
  // pose of `lidar` (time offset `d` after the read time).
  auto residuals = [&](const std::string& folder, const RigLidar& lidar, TimestampNs d) {
    std::vector<double> out;
    const std::vector<TimestampNs> stamps = ReadStamps(dir.File(folder + "/lidar0/data.csv"));
    for (size_t s = 0; s < stamps.size(); s += 4) {
      const PointCloud cloud =
          ReadPcd(dir.File(folder + "/lidar0/data/" + std::to_string(stamps[s]) + ".pcd"));
      for (size_t i = 0; i < cloud.size(); i += 11) {
        const LidarPoint& p = cloud.points[i];
        const Vec3 x_lidar(p.x, p.y, p.z);
        const double range = x_lidar.norm();
        const SE3 pose =
            world.trajectory.Pose(stamps[s] + SecondsToNs(p.t) + d) * lidar.imu_from_lidar;
        const RayHit hit = world.scene->Intersect(pose.translation(),
                                                  pose.rotation() * (x_lidar / range), 0.0, 200.0);
        out.push_back(hit.hit ? std::abs(range - hit.distance) : 1e3);
      }
    }
    return out;
  };
  const RigLidar& lt = truth.lidars[0];
  const RigLidar& lb = believed.lidars[0];
  const std::vector<double> residual_true =
      residuals("seq", lt, SecondsToNs(lt.time_offset_s) - SecondsToNs(lb.time_offset_s));
  const std::vector<double> residual_believed = residuals("seq", lb, 0);
  // The same walk and LiDAR seed with the lidar source alone (no calibration
  // error): the residuals the error model gives at the pose the data were made at.
  options.error_sources = "lidar";
  options.camera_rate = 0;
  options.output_path = dir.File("lidar_only");
  Simulate(options, TestRig());
  const std::vector<double> residual_alone = residuals("lidar_only", lb, 0);
  ASSERT_GT(residual_true.size(), 20000u);
  std::printf(
      "median |range residual|: at the true pose %.2f mm, at rig.yaml's %.2f mm; lidar source "
      "alone %.2f mm\n",
      1e3 * Median(residual_true), 1e3 * Median(residual_believed), 1e3 * Median(residual_alone));
  EXPECT_NEAR(Median(residual_true), Median(residual_alone), 0.1 * Median(residual_alone));
  EXPECT_GT(Median(residual_believed), 2 * Median(residual_true));

  CameraSimOptions render_options;
  render_options.noise_scale = 0;
  for (size_t k = 0; k < truth.cameras.size(); ++k) {
    const RigCamera& ct = truth.cameras[k];
    const RigCamera& cb = believed.cameras[k];
    const TimestampNs dc =
        SecondsToNs(ct.timeshift_cam_imu_s) - SecondsToNs(cb.timeshift_cam_imu_s);
    const CameraRenderer renderer(*world.scene, ct.model, world.texture, render_options);
    const std::vector<TimestampNs> frames = ReadStamps(dir.File("seq/" + ct.name + "/data.csv"));
    ASSERT_EQ(frames.size(), 9u);
    for (const size_t f : {2, 3, 5, 6}) {  // while walking
      const cv::Mat image =
          cv::imread(dir.File("seq/" + ct.name + "/data/" + std::to_string(frames[f]) + ".png"),
                     cv::IMREAD_UNCHANGED);
      ASSERT_FALSE(image.empty());
      const double at_true = ImageCorrelation(
          image, renderer.Render(world.trajectory.Pose(frames[f] + dc) * ct.cam_from_imu.Inverse(),
                                 0));
      const double at_believed = ImageCorrelation(
          image,
          renderer.Render(world.trajectory.Pose(frames[f]) * cb.cam_from_imu.Inverse(), 0));
      std::printf("%s frame %zu: correlation with the render at the true pose %.3f, at "
                  "rig.yaml's %.3f\n",
                  ct.name.c_str(), f, at_true, at_believed);
      EXPECT_GT(at_true, 1.5 * at_believed) << ct.name << " frame " << f;
    }
  }
}

// Same seed with and without the sources: the IMU draws are the same, so the
// samples differ by (M - I) * exact + c * dT(t) and the recorded biases by
// c * dT(t), with M, c, dT from truth/imu_errors.yaml. The CSV files carry 10
// significant digits (|accel| < 20 m/s^2: rounding < 1e-8).
TEST_F(SimulatorErrorsTest, ImuSamplesCarryTheErrorsOfTheTruthFile) {
  const ImuErrors e = ReadImuErrorsYaml(File("truth/imu_errors.yaml"));
  const auto with = ReadSixColumns(File("imu0/data.csv"));
  const auto without = ReadSixColumns(dir_->File("clean/imu0/data.csv"));
  const auto bias_with = ReadSixColumns(File("imu0/bias_groundtruth.csv"));
  const auto bias_without = ReadSixColumns(dir_->File("clean/imu0/bias_groundtruth.csv"));
  ASSERT_EQ(with.size(), without.size());
  ASSERT_EQ(with.size(), 8u * 400 + 1);
  const Mat3 mg = e.gyro.Matrix() - Mat3::Identity(), ma = e.accel.Matrix() - Mat3::Identity();
  double max_error = 0, max_bias_error = 0, max_effect = 0;
  for (size_t i = 0; i < with.size(); ++i) {
    ASSERT_EQ(with[i].first, without[i].first);
    const ImuSample exact = ExactImu(world_.trajectory, with[i].first);
    const double dT = e.temperature.At(with[i].first);
    Vec6 drift, expected;
    drift << dT * e.gyro.temperature_coefficient, dT * e.accel.temperature_coefficient;
    expected << mg * exact.gyro, ma * exact.accel;
    expected += drift;
    max_error =
        std::max(max_error, (with[i].second - without[i].second - expected).cwiseAbs().maxCoeff());
    max_bias_error =
        std::max(max_bias_error,
                 (bias_with[i].second - bias_without[i].second - drift).cwiseAbs().maxCoeff());
    max_effect = std::max(max_effect, expected.cwiseAbs().maxCoeff());
  }
  EXPECT_LT(max_error, 2e-8);
  EXPECT_LT(max_bias_error, 1e-11);
  EXPECT_GT(max_effect, 1e-2);  // the errors are far above the file precision
}

// The sources at size 0 change no data byte (only rig.yaml's comment and the
// truth/ files are added); noise_scale 0 turns every source off.
TEST(SimulatorErrors, ZeroSizedSourcesAndNoiseScaleZeroReproduceTheCleanRecording) {
  test::TempDir dir;
  SimulatorOptions options;
  options.duration = 3.0;
  options.camera_rate = 1.0;
  options.lidars = "spinning,livox";
  options.error_sources = "none";
  options.output_path = dir.File("none");
  Simulate(options, TestRig());
  options.error_sources = "calibration,imu";
  options.calibration_error = CalibrationErrorOptions{0, 0, 0, 0, 0, 0, 0};
  options.imu_error = ImuErrorOptions{0, 0, 0, 0, 0, 0, 0, 60.0};
  options.output_path = dir.File("zero");
  Simulate(options, TestRig());
  auto none = FolderContents(dir.File("none"));
  auto zero = FolderContents(dir.File("zero"));
  EXPECT_EQ(none.count("truth/rig.yaml"), 0u);
  EXPECT_EQ(zero.count("truth/rig.yaml"), 1u);
  EXPECT_EQ(zero.count("truth/imu_errors.yaml"), 1u);
  EXPECT_EQ(ReadRigYaml(dir.File("zero/truth/rig.yaml")).lidars[1].time_offset_s, 0.0);
  for (const char* name : {"rig.yaml", "truth/rig.yaml", "truth/imu_errors.yaml"}) {
    none.erase(name);
    zero.erase(name);
  }
  ASSERT_EQ(none.size(), zero.size());
  EXPECT_GT(none.size(), 50u);
  for (const auto& [name, contents] : none) {
    ASSERT_EQ(zero.count(name), 1u) << name;
    EXPECT_TRUE(zero[name] == contents) << name << " differs";
  }
  options.noise_scale = 0;
  options.error_sources = "all";
  options.calibration_error = CalibrationErrorOptions();
  options.imu_error = ImuErrorOptions();
  options.output_path = dir.File("exact_all");
  Simulate(options, TestRig());
  options.error_sources = "none";
  options.output_path = dir.File("exact_none");
  Simulate(options, TestRig());
  EXPECT_TRUE(FolderContents(dir.File("exact_all")) == FolderContents(dir.File("exact_none")));
  EXPECT_FALSE(fs::exists(dir.File("exact_all/truth")));
}

TEST(SimulatorErrors, ErrorSourceTokens) {
  EXPECT_TRUE(ErrorSourceEnabled("all", "imu"));
  EXPECT_TRUE(ErrorSourceEnabled("calibration, imu", "imu"));
  EXPECT_FALSE(ErrorSourceEnabled("calibration", "imu"));
  EXPECT_FALSE(ErrorSourceEnabled("none", "calibration"));
  EXPECT_THROW(ErrorSourceEnabled("all", "weather"), InternalError);
  SimulatorOptions options;
  options.output_path = "out";
  for (const char* bad : {"", "weather", "imu,weather", "all,imu", "none,imu"}) {
    options.error_sources = bad;
    EXPECT_FALSE(options.Check()) << "'" << bad << "'";
  }
  for (const char* good : {"all", "none", "imu", "calibration,imu"}) {
    options.error_sources = good;
    EXPECT_TRUE(options.Check()) << good;
  }
}

// A source named explicitly needs a sensor it acts on; `all` does not.
TEST(SimulatorErrors, CalibrationWithoutLidarOrCameraIsAUsageError) {
  test::TempDir dir;
  SimulatorOptions options;
  options.duration = 1.0;
  options.camera_rate = 0;
  options.lidars = "none";
  options.error_sources = "calibration";
  options.output_path = dir.File("seq");
  EXPECT_THROW(Simulate(options, TestRig()), UsageError);
  EXPECT_FALSE(fs::exists(dir.File("seq")));
  options.error_sources = "all";
  Simulate(options, TestRig());
  EXPECT_TRUE(fs::exists(dir.File("seq/imu0/data.csv")));
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
