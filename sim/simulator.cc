#include "sim/simulator.h"

#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <memory>
#include <random>
#include <sstream>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "core/io/image_codec.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"
#include "core/logging.h"
#include "core/option_check.h"
#include "core/progress.h"
#include "sim/camera_simulator.h"
#include "sim/imu_simulator.h"
#include "sim/lidar_simulator.h"
#include "sim/motion.h"
#include "sim/scene.h"

namespace lisfm {
namespace sim {
namespace {


// Fastest lossless PNG: zlib level 0 (stored blocks). Measured on a noisy
// 720x540 render: 4.5 ms and 390 KB per image, against 9.2 ms / 287 KB for
// level 1 Huffman-only and 13.9 ms / 308 KB for level 1 default; sensor noise
// leaves little to compress, and the LiDAR clouds dominate the folder size.
constexpr int kPngCompression = 0;

// CPU time of the calling thread, s.
double ThreadCpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Sums per-task CPU seconds from concurrent tasks.
class CpuAccumulator {
 public:
  void Add(double seconds) { micros_ += static_cast<int64_t>(seconds * 1e6); }
  double Seconds() const { return 1e-6 * static_cast<double>(micros_.load()); }

 private:
  std::atomic<int64_t> micros_{0};
};

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

std::vector<std::string> SplitList(const std::string& s) {
  std::vector<std::string> out;
  for (const std::string& t : SplitString(s, ",", true)) out.push_back(Trim(t));
  return out;
}

RigLidar DefaultLidar(LidarType type) {
  RigLidar lidar;
  lidar.type = type;
  if (type == LidarType::kSpinning) {
    // HILTI 2022 lidar_calibration.yaml, PandarXT-32: quaternion (x, y, z, w).
    lidar.rostopic = "/hesai/pandar";
    lidar.imu_from_lidar = SE3(Quat(0.0, 0.7071068, -0.7071068, 0.0).normalized(),
                               Vec3(-0.001, -0.00855, 0.055));
    lidar.rings = 32;
    lidar.min_range = 0.05;
    lidar.max_range = 120.0;
    lidar.scan_rate = 10.0;
  } else {
    // Livox MID-70-like, looking forward: lidar x = imu x, lidar z = up = -imu z,
    // 12 cm in front of and 6 cm above the IMU.
    lidar.rostopic = "/livox/lidar";
    lidar.imu_from_lidar = SE3(Mat3(Vec3(1, -1, -1).asDiagonal()), Vec3(0.12, 0.0, -0.06));
    lidar.rings = 0;
    lidar.min_range = 0.05;
    lidar.max_range = 90.0;
    lidar.scan_rate = 10.0;
  }
  return lidar;
}

bool IsLidarList(const std::string& lidars) {
  for (const std::string& l : SplitList(lidars)) {
    if (l != "spinning" && l != "livox" && l != "none") return false;
  }
  return true;
}

bool IsErrorSource(const std::string& token) {
  const std::vector<std::string>& names = ErrorSourceNames();
  return std::find(names.begin(), names.end(), token) != names.end();
}

bool HasLidar(const std::string& lidars) {
  for (const std::string& l : SplitList(lidars)) {
    if (l != "none") return true;
  }
  return false;
}

// Whether `token` is named in the list itself (not through "all").
bool ErrorSourceNamed(const std::string& list, const std::string& token) {
  const std::vector<std::string> tokens = SplitList(list);
  return std::find(tokens.begin(), tokens.end(), token) != tokens.end();
}

// "all", "none", or a comma list of error source tokens.
bool IsErrorSourceList(const std::string& list) {
  const std::vector<std::string> tokens = SplitList(list);
  if (tokens.empty()) return false;
  for (const std::string& t : tokens) {
    if (t == "all" || t == "none") {
      if (tokens.size() != 1) return false;
    } else if (!IsErrorSource(t)) {
      return false;
    }
  }
  return true;
}

std::string ErrorSourceRequirement() {
  std::string names;
  for (const std::string& n : ErrorSourceNames()) names += (names.empty() ? "" : ", ") + n;
  return "all, none, or a comma list of " + names;
}

// A source named explicitly (not through "all") must have a sensor to act on.
void CheckErrorSourcesHaveSensors(const SimulatorOptions& options, const Rig& rig) {
  for (const std::string& t : SplitList(options.error_sources)) {
    if (t == "calibration" && rig.lidars.empty() &&
        (rig.cameras.empty() || options.camera_rate <= 0)) {
      throw UsageError(
          "--error_sources calibration: the simulated rig has no LiDAR and no "
          "camera to miscalibrate (--lidars none, and no cameras or "
          "--camera_rate 0)");
    }
    if (t == "camera" && rig.cameras.empty()) {
      throw UsageError("--error_sources camera: the rig has no cameras");
    }
    if (t == "dynamics" && rig.lidars.empty() &&
        (rig.cameras.empty() || options.camera_rate <= 0) && !options.rgbd) {
      throw UsageError(
          "--error_sources dynamics: the simulated rig has no LiDAR, camera or RGB-D "
          "camera to see the people (--lidars none, no cameras or --camera_rate 0, "
          "--rgbd 0)");
    }
  }
}

// The calibration errors as one log line: per sensor mm, deg, ms.
std::string DescribeCalibrationErrors(const Rig& rig, const CalibrationErrors& errors) {
  std::string text;
  auto add = [&](const std::string& name, const SensorCalibrationError& e) {
    text += fmt::format("{}{} {:.1f} mm {:.2f} deg {:.2f} ms",
                        text.empty() ? "" : "; ",
                        name,
                        1e3 * e.translation_m.norm(),
                        e.rotation_rad.norm() * 180 / M_PI,
                        1e-6 * static_cast<double>(e.time_offset_ns));
  };
  for (size_t i = 0; i < errors.lidars.size(); ++i) add(rig.lidars[i].name, errors.lidars[i]);
  for (size_t i = 0; i < errors.cameras.size(); ++i) add(rig.cameras[i].name, errors.cameras[i]);
  return text;
}

}  // namespace

const std::vector<std::string>& ErrorSourceNames() {
  static const std::vector<std::string> kNames = {"calibration", "imu", "lidar", "camera", "dynamics"};
  return kNames;
}

bool ErrorSourceEnabled(const std::string& error_sources, const std::string& source) {
  THROW_CHECK_MSG(IsErrorSource(source), "unknown error source '" << source << "'");
  for (const std::string& t : SplitList(error_sources)) {
    if (t == "all" || t == source) return true;
  }
  return false;
}

std::vector<ControlPoint> SurveyControlPoints(const SplineTrajectory& trajectory,
                                              const std::vector<StationaryPeriod>& stationary,
                                              TimestampNs start_ns,
                                              TimestampNs end_ns) {
  std::vector<ControlPoint> points;
  for (const StationaryPeriod& p : stationary) {
    if (p.end_ns > end_ns || p.start_ns < start_ns) continue;
    const TimestampNs t = p.start_ns + (p.end_ns - p.start_ns) / 2;
    points.push_back({t, trajectory.Pose(t) * kPoleTipInImu});
  }
  return points;
}

bool SimulatorOptions::Check() const {
  CHECK_OPTION_MSG(output_path, !output_path.empty(), "a folder name (required)");
  CHECK_OPTION_LE(duration, 1e5);
  CHECK_OPTION_MSG(duration, !trajectory_path.empty() || duration > 0.5,
                   "> 0.5 s without a trajectory_path");
  CHECK_OPTION_MSG(camera_rate, camera_rate >= 0 && camera_rate <= 100, "in [0, 100] Hz");
  CHECK_OPTION_MSG(noise_scale, noise_scale >= 0 && noise_scale <= 100, "in [0, 100]");
  CHECK_OPTION_MSG(supersampling, supersampling >= 1 && supersampling <= 8, "in [1, 8]");
  CHECK_OPTION_MSG(rgbd_rate, rgbd_rate > 0 && rgbd_rate <= 100, "in (0, 100] Hz");
  CHECK_OPTION_MSG(lidars, IsLidarList(lidars), "a comma list of spinning, livox, none");
  CHECK_OPTION_MSG(error_sources, IsErrorSourceList(error_sources), ErrorSourceRequirement());
  CHECK_OPTION_MSG(error_sources,
                   !ErrorSourceNamed(error_sources, "lidar") || HasLidar(lidars),
                   "without lidar: the source lidar needs a LiDAR (--lidars is none)");
  CHECK_OPTION_MSG(error_sources, !ErrorSourceNamed(error_sources, "camera") || camera_rate > 0,
                   "without camera: the source camera needs images (--camera_rate is 0)");
  CHECK_OPTION_NESTED(calibration_error);
  CHECK_OPTION_NESTED(imu_error);
  CHECK_OPTION_NESTED(lidar_errors);
  CHECK_OPTION_NESTED(camera_errors);
  CHECK_OPTION_NESTED(materials);
  CHECK_OPTION_NESTED(walk);
  CHECK_OPTION_NESTED(dynamics);
  return true;
}

Rig PrepareRig(const Rig& input, const std::string& lidars) {
  Rig rig = input;
  rig.lidars.clear();
  for (const std::string& name : SplitList(lidars)) {
    if (name == "none") continue;
    const LidarType type = ParseLidarType(name);
    RigLidar lidar = DefaultLidar(type);
    for (const RigLidar& l : input.lidars) {
      if (l.type == type) {
        lidar = l;
        break;
      }
    }
    lidar.name = "lidar" + std::to_string(rig.lidars.size());
    lidar.time_offset_s = 0.0;
    rig.lidars.push_back(lidar);
  }
  for (RigCamera& cam : rig.cameras) cam.timeshift_cam_imu_s = 0.0;
  return rig;
}

SimulationSummary Simulate(const SimulatorOptions& options,
                           const Rig& input_rig,
                           const std::function<void(const std::string&)>& before_commit) {
  THROW_CHECK_OPTIONS(options);
  const auto t_start = std::chrono::steady_clock::now();
  SimulationSummary summary;
  const Rig rig = PrepareRig(input_rig, options.lidars);
  CheckErrorSourcesHaveSensors(options, rig);
  // Before the work: refuses an unusable output location at once.
  OutputFolder output(options.output_path, options.overwrite);
  const std::string& temp = output.path();
  // Error sources in effect (every one is off with noise_scale 0).
  const bool calibration_on =
      options.noise_scale > 0 && ErrorSourceEnabled(options.error_sources, "calibration");
  const bool imu_errors_on =
      options.noise_scale > 0 && ErrorSourceEnabled(options.error_sources, "imu");
  // The rig the data are made with: `rig` (what rig.yaml says) unless calibration is on.
  Rig true_rig = rig;
  CalibrationErrors calibration;
  calibration.lidars.resize(rig.lidars.size());
  calibration.cameras.resize(rig.cameras.size());
  if (calibration_on) {
    calibration = DrawCalibrationErrors(options.calibration_error,
                                        options.noise_scale,
                                        static_cast<uint64_t>(options.seed),
                                        rig.lidars.size(),
                                        rig.cameras.size());
    true_rig = ApplyCalibrationErrors(rig, calibration);
    LogInfo("calibration errors (true - rig.yaml): {}",
            DescribeCalibrationErrors(rig, calibration));
  }
  const bool lidar_errors =
      options.noise_scale > 0 && ErrorSourceEnabled(options.error_sources, "lidar");
  const bool camera_errors =
      options.noise_scale > 0 && ErrorSourceEnabled(options.error_sources, "camera");
  const bool dynamics_on =
      options.noise_scale > 0 && ErrorSourceEnabled(options.error_sources, "dynamics");

  // ---- scene and motion ----
  LogStage("scene and motion");
  SceneOptions scene_options = ResolveSceneOptions(options.scene);
  scene_options.seed = scene_options.seed * 1000003 + options.seed;
  SplineTrajectory trajectory;
  std::vector<StationaryPeriod> stationary;
  std::unique_ptr<Scene> scene;
  TimestampNs start_ns = 0, end_ns = 0;
  if (!options.trajectory_path.empty()) {
    if (scene_options.type == "staircase" || scene_options.type == "site") {
      throw UsageError("--trajectory_path needs --scene office or hall (the " +
                       scene_options.type + " is built around its own route)");
    }
    const Trajectory samples = ReadTum(options.trajectory_path);
    if (samples.size() < 10) {
      throw InputError(options.trajectory_path, "line 1",
                       "expected at least 10 poses, found " + std::to_string(samples.size()));
    }
    trajectory = SplineTrajectory::Fit(samples, 0.1);
    // Place it: footprint centre at the scene centre, 5th percentile height at
    // 1.4 m above the floor; grow the scene to contain it with 3 m margin.
    std::vector<double> zs;
    Eigen::AlignedBox3d box;
    for (const StampedPose& p : samples.poses()) {
      box.extend(p.pose.translation());
      zs.push_back(p.pose.translation().z());
    }
    std::sort(zs.begin(), zs.end());
    const double z05 = zs[zs.size() / 20];
    const Vec3 extent = box.max() - box.min();
    scene_options.length = std::max(scene_options.length, extent.x() + 6.0);
    scene_options.width = std::max(scene_options.width, extent.y() + 6.0);
    scene_options.height = std::max(scene_options.height, (box.max().z() - z05) + 1.4 + 1.0);
    const Vec3 offset(scene_options.length / 2 - box.center().x(),
                      scene_options.width / 2 - box.center().y(), 1.4 - z05);
    trajectory.TransformWorld(SE3(Quat::Identity(), offset));
    start_ns = trajectory.start_ns();
    end_ns = trajectory.end_ns();
    if (options.duration > 0) end_ns = std::min(end_ns, start_ns + SecondsToNs(options.duration));
    std::vector<Vec3> keep_clear;
    for (TimestampNs t = start_ns; t <= end_ns; t += 50000000) {
      keep_clear.push_back(trajectory.Pose(t).translation());
    }
    scene = Scene::Generate(scene_options, keep_clear);
    stationary = FindStationaryPeriods(trajectory);
  } else {
    scene = Scene::Generate(scene_options);
    start_ns = kDefaultStartNs;
    trajectory = GenerateWalking(scene->route(), options.duration, start_ns,
                                 static_cast<uint32_t>(options.seed), options.walk,
                                 &stationary);
    end_ns = start_ns + SecondsToNs(options.duration);
  }
  scene->AssignMaterials(options.materials.texture_poor_fraction);
  if (dynamics_on) {
    // People walk the device's route; with real motion, the recorded path
    // (sampled every metre, walked out and back).
    WalkingRoute people_route = scene->route();
    if (people_route.waypoints.empty()) {
      for (TimestampNs t = start_ns; t <= end_ns; t += 50000000) {
        const Vec3 p = trajectory.Pose(t).translation();
        if (people_route.waypoints.empty() || (p - people_route.waypoints.back()).norm() >= 1.0) {
          people_route.waypoints.push_back(p);
        }
      }
    }
    scene->SetPeople(GeneratePeople(*scene, people_route, options.dynamics, start_ns,
                                    static_cast<uint32_t>(scene_options.seed)));
  }
  summary.scene_type = scene_options.type;
  summary.num_triangles = scene->triangles().size();
  summary.num_people = scene->people().size();
  summary.duration_s = NsToSeconds(end_ns - start_ns);
  const TextureOptions texture{static_cast<uint32_t>(scene_options.seed),
                               static_cast<float>(scene_options.texture_scale)};
  summary.seconds_scene = Seconds(t_start);

  // ---- rig and scene ----
  if (!calibration_on) {
    WriteRigYaml(JoinPaths(temp, "rig.yaml"),
                 rig,
                 "lisfm simulate: the rig of this sequence (time offsets 0: stamps are on the "
                 "IMU clock)");
  } else {
    WriteRigYaml(JoinPaths(temp, "rig.yaml"),
                 rig,
                 "lisfm simulate: the calibration a user of this sequence has (time offsets 0:\n"
                 "stamps are read on the IMU clock). The data were made with truth/rig.yaml.");
    CreateDirs(JoinPaths(temp, "truth"));
    WriteRigYaml(JoinPaths(temp, "truth/rig.yaml"),
                 true_rig,
                 "lisfm simulate: the TRUE calibration this sequence was made with (error source\n"
                 "calibration). A sensor stamp t was captured at IMU time\n"
                 "t + (truth time offset - rig.yaml time offset).");
  }
  scene->WritePly(JoinPaths(temp, "scene.ply"));

  // ---- ground truth (100 Hz) and control points ----
  {
    Trajectory gt;
    for (TimestampNs t = start_ns; t <= end_ns; t += 10000000) {
      gt.PushBack({t, trajectory.Pose(t)});
    }
    WriteTum(JoinPaths(temp, "groundtruth.txt"), gt);
    WriteEurocCsv(JoinPaths(temp, "groundtruth.csv"), gt);
    for (size_t i = 1; i < gt.size(); ++i) {
      summary.path_length_m +=
          (gt[i].pose.translation() - gt[i - 1].pose.translation()).norm();
    }
    std::ostringstream cp;
    cp << "# timestamp_s x y z qx qy qz qw: HILTI-style control points, the pole tip "
          "world_from_imu * (0.059, -0.00855, 0.1964) in the middle of each rest\n";
    for (const ControlPoint& p : SurveyControlPoints(trajectory, stationary, start_ns, end_ns)) {
      cp << FormatNsAsSeconds(p.t_ns) << std::setprecision(17) << " " << p.position.x() << " "
         << p.position.y() << " " << p.position.z() << " 0 0 0 1\n";
      ++summary.num_control_points;
    }
    WriteFileAtomically(JoinPaths(temp, "controlpoints.txt"), cp.str());
  }
  if (!scene->people().empty()) {
    // The people's tracks at 10 Hz: feet position and heading.
    std::ostringstream tracks;
    tracks << std::setprecision(10)
           << "#timestamp [ns],person,x [m],y [m],z [m],yaw [rad]   (feet, scene frame)\n";
    for (TimestampNs t = start_ns; t <= end_ns; t += 100000000) {
      for (size_t i = 0; i < scene->people().size(); ++i) {
        Vec3 feet;
        double yaw;
        scene->people()[i].Locate(t, &feet, &yaw);
        tracks << t << "," << i << "," << feet.x() << "," << feet.y() << "," << feet.z() << ","
               << yaw << "\n";
      }
    }
    CreateDirs(JoinPaths(temp, "truth"));
    WriteFileAtomically(JoinPaths(temp, "truth/people.csv"), tracks.str());
  }

  // ---- IMU ----
  LogStage("IMU");
  auto t_phase = std::chrono::steady_clock::now();
  {
    ImuSimOptions imu_options;
    imu_options.noise_scale = options.noise_scale;
    imu_options.seed = static_cast<uint64_t>(options.seed);
    std::unique_ptr<ImuErrors> imu_errors;
    if (imu_errors_on) {
      imu_errors = std::make_unique<ImuErrors>(DrawImuErrors(options.imu_error,
                                                             options.noise_scale,
                                                             static_cast<uint64_t>(options.seed),
                                                             start_ns,
                                                             end_ns));
      CreateDirs(JoinPaths(temp, "truth"));
      WriteImuErrorsYaml(JoinPaths(temp, "truth/imu_errors.yaml"), *imu_errors);
    }
    std::vector<ImuBias> biases;
    const std::vector<ImuSample> imu =
        SimulateImu(trajectory, rig.imu, start_ns, end_ns, imu_options, imu_errors.get(), &biases);
    summary.num_imu = imu.size();
    CreateDirs(JoinPaths(temp, "imu0"));
    std::ostringstream s, b;
    s << std::setprecision(10);
    b << std::setprecision(10);
    s << "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
         "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
    b << "#timestamp [ns],b_w_x [rad s^-1],b_w_y [rad s^-1],b_w_z [rad s^-1],"
         "b_a_x [m s^-2],b_a_y [m s^-2],b_a_z [m s^-2]\n";
    for (size_t i = 0; i < imu.size(); ++i) {
      const ImuSample& m = imu[i];
      s << m.t_ns << "," << m.gyro.x() << "," << m.gyro.y() << "," << m.gyro.z() << ","
        << m.accel.x() << "," << m.accel.y() << "," << m.accel.z() << "\n";
      const ImuBias& q = biases[i];
      b << q.t_ns << "," << q.gyro.x() << "," << q.gyro.y() << "," << q.gyro.z() << ","
        << q.accel.x() << "," << q.accel.y() << "," << q.accel.z() << "\n";
    }
    WriteFileAtomically(JoinPaths(temp, "imu0/data.csv"), s.str());
    WriteFileAtomically(JoinPaths(temp, "imu0/bias_groundtruth.csv"), b.str());
  }
  summary.seconds_imu = Seconds(t_phase);

  // ---- work list: LiDAR scans and rig frames ----
  std::vector<std::vector<TimestampNs>> scan_starts(rig.lidars.size());
  size_t total_units = 0;
  for (size_t k = 0; k < rig.lidars.size(); ++k) {
    const double period = 1.0 / rig.lidars[k].scan_rate;
    for (int64_t i = 0;; ++i) {
      const TimestampNs t0 = start_ns + SecondsToNs(i * period);
      if (t0 + SecondsToNs(period) > end_ns) break;
      scan_starts[k].push_back(t0);
    }
    total_units += scan_starts[k].size();
  }
  std::vector<TimestampNs> frame_times;
  if (options.camera_rate > 0 && !rig.cameras.empty()) {
    for (int64_t i = 0;; ++i) {
      const TimestampNs t = start_ns + SecondsToNs(i / options.camera_rate);
      if (t > end_ns) break;
      frame_times.push_back(t);
    }
  }
  total_units += frame_times.size() * rig.cameras.size();
  ProgressReporter progress("simulate", static_cast<int64_t>(total_units));

  // ---- LiDARs ----
  LogStage("LiDAR");
  CpuAccumulator lidar_cast, lidar_write, camera_render, camera_write;
  t_phase = std::chrono::steady_clock::now();
  for (size_t k = 0; k < rig.lidars.size(); ++k) {
    // The true LiDAR: its extrinsic, and its time offset in the stamps.
    const RigLidar& lidar = true_rig.lidars[k];
    const std::string dir = JoinPaths(temp, lidar.name);
    CreateDirs(JoinPaths(dir, "data"));
    LidarSimOptions lidar_options;
    lidar_options.noise_scale = options.noise_scale;
    lidar_options.seed = static_cast<uint64_t>(options.seed) * 31 + k;
    lidar_options.errors_enabled = lidar_errors;
    lidar_options.errors = options.lidar_errors;
    const LidarSimulator simulator(*scene, trajectory, lidar, texture, lidar_options);
    std::vector<TimestampNs> stamps(scan_starts[k].size());
    std::vector<size_t> counts(scan_starts[k].size());
    tbb::parallel_for(size_t{0}, scan_starts[k].size(), [&](size_t i) {
      const double c0 = ThreadCpuSeconds();
      PointCloud cloud = simulator.SimulateScan(scan_starts[k][i], static_cast<int64_t>(i));
      const double c1 = ThreadCpuSeconds();
      stamps[i] = cloud.stamp_ns;
      counts[i] = cloud.size();
      WritePcd(JoinPaths(dir, "data/" + std::to_string(cloud.stamp_ns) + ".pcd"), cloud, true);
      lidar_cast.Add(c1 - c0);
      lidar_write.Add(ThreadCpuSeconds() - c1);
      progress.Add(1);
    });
    std::ostringstream csv;
    csv << "#timestamp [ns],filename\n";
    size_t points = 0;
    for (size_t i = 0; i < stamps.size(); ++i) {
      csv << stamps[i] << "," << stamps[i] << ".pcd\n";
      points += counts[i];
    }
    WriteFileAtomically(JoinPaths(dir, "data.csv"), csv.str());
    summary.num_scans.push_back(stamps.size());
    summary.num_points.push_back(points);
  }
  summary.seconds_lidar = Seconds(t_phase);

  // ---- cameras ----
  LogStage("cameras");
  t_phase = std::chrono::steady_clock::now();
  CameraSimOptions camera_options;
  camera_options.supersampling = options.supersampling;
  camera_options.color = options.color;
  camera_options.noise_scale = options.noise_scale;
  if (!frame_times.empty()) {
    std::unique_ptr<SceneLighting> lighting;
    if (camera_errors) {
      camera_options.errors_enabled = true;
      camera_options.errors = options.camera_errors;
      lighting = std::make_unique<SceneLighting>(
          scene->Bounds(), static_cast<uint32_t>(scene_options.seed), options.camera_errors);
    }
    std::vector<std::unique_ptr<CameraRenderer>> renderers;
    for (const RigCamera& cam : rig.cameras) {
      renderers.push_back(std::make_unique<CameraRenderer>(*scene, cam.model, texture,
                                                           camera_options, lighting.get()));
      CreateDirs(JoinPaths(temp, cam.name + "/data"));
    }
    const size_t num_cams = rig.cameras.size();
    // Auto exposure: each camera's controller runs at ae_rate_hz on the
    // metered radiance of its previous update; a frame uses the setting of
    // the last update at or before it.
    const double ae_dt = 1.0 / options.camera_errors.ae_rate_hz;
    std::vector<std::vector<ExposureSetting>> ae_settings(num_cams);
    if (camera_errors) {
      const size_t ticks =
          static_cast<size_t>(std::floor(NsToSeconds(end_ns - start_ns) / ae_dt)) + 1;
      std::vector<double> metered(ticks * num_cams);
      tbb::parallel_for(size_t{0}, metered.size(), [&](size_t i) {
        const size_t j = i / num_cams, c = i % num_cams;
        // Metered at the true capture time with the true extrinsic.
        const TimestampNs t =
            start_ns + SecondsToNs(j * ae_dt) + calibration.cameras[c].time_offset_ns;
        metered[i] = renderers[c]->MeterRadiance(
            trajectory.Pose(t) * true_rig.cameras[c].cam_from_imu.Inverse(), j * ae_dt, t);
      });
      for (size_t c = 0; c < num_cams; ++c) {
        AutoExposure ae(options.camera_errors);
        ae.Reset(metered[c]);
        ae_settings[c].push_back(ae.setting());
        for (size_t j = 1; j < ticks; ++j) {
          ae.Update(metered[(j - 1) * num_cams + c], ae_dt);
          ae_settings[c].push_back(ae.setting());
        }
      }
    }
    std::atomic<bool> write_failed{false};
    tbb::parallel_for(size_t{0}, frame_times.size() * num_cams, [&](size_t job) {
      const size_t f = job / num_cams, c = job % num_cams;
      const RigCamera& cam = rig.cameras[c];
      // Captured at the true time with the true extrinsic; stamped frame_times[f].
      const TimestampNs capture_ns = frame_times[f] + calibration.cameras[c].time_offset_ns;
      const SE3 imu_from_true_cam = true_rig.cameras[c].cam_from_imu.Inverse();
      const SE3 world_from_cam =
          trajectory.Pose(capture_ns) * imu_from_true_cam;
      const uint64_t noise_seed = static_cast<uint64_t>(options.seed) * 1000003 + job * 7919 + 1;
      const double c0 = ThreadCpuSeconds();
      cv::Mat image;
      if (camera_errors) {
        CameraExposure exposure;
        exposure.time_s = NsToSeconds(frame_times[f] - start_ns);
        const size_t tick = std::min(ae_settings[c].size() - 1,
                                     static_cast<size_t>(std::floor(exposure.time_s / ae_dt)));
        exposure.setting = ae_settings[c][tick];
        // Alphasense stamps are the middle of the exposure (true capture time).
        const TimestampNs half = SecondsToNs(0.5 * exposure.setting.exposure_s);
        exposure.world_from_cam_start = trajectory.Pose(capture_ns - half) * imu_from_true_cam;
        exposure.world_from_cam_end = trajectory.Pose(capture_ns + half) * imu_from_true_cam;
        image = renderers[c]->Render(world_from_cam, exposure, noise_seed, capture_ns);
      } else {
        image = renderers[c]->Render(world_from_cam, noise_seed, capture_ns);
      }
      const double c1 = ThreadCpuSeconds();
      const std::string path = JoinPaths(
          temp, cam.name + "/data/" + std::to_string(frame_times[f]) + ".png");
      if (!WritePngFile(path, image, kPngCompression)) write_failed = true;
      camera_render.Add(c1 - c0);
      camera_write.Add(ThreadCpuSeconds() - c1);
      progress.Add(1);
    });
    if (write_failed) throw InputError(temp, "camera images", "cannot write a PNG image");
    for (const RigCamera& cam : rig.cameras) {
      std::ostringstream csv;
      csv << "#timestamp [ns],filename\n";
      for (TimestampNs t : frame_times) csv << t << "," << t << ".png\n";
      WriteFileAtomically(JoinPaths(temp, cam.name + "/data.csv"), csv.str());
    }
    summary.num_images = frame_times.size() * num_cams;
  }
  progress.Finish();

  // ---- RGB-D ----
  if (options.rgbd) {
    LogStage("RGB-D");
    // Kinect-v1-like pinhole 640x480 looking forward, 5 cm right of the IMU.
    CameraModel model;
    model.width = 640;
    model.height = 480;
    model.fx = model.fy = 525.0;
    model.cx = 319.5;
    model.cy = 239.5;
    model.distortion = DistortionModel::kNone;
    const Mat3 cam_from_imu_rot = (Mat3() << 0, 1, 0, 0, 0, 1, 1, 0, 0).finished();
    const SE3 cam_from_imu = SE3(cam_from_imu_rot, Vec3::Zero()) *
                             SE3(Quat::Identity(), Vec3(-0.05, -0.05, 0.0));
    CameraSimOptions rgbd_options = camera_options;
    rgbd_options.color = true;
    rgbd_options.errors_enabled = false;  // the camera error sources model the rig's cameras
    const CameraRenderer renderer(*scene, model, texture, rgbd_options);
    const std::string dir = JoinPaths(temp, "rgbd0");
    CreateDirs(JoinPaths(dir, "rgb"));
    CreateDirs(JoinPaths(dir, "depth"));
    std::vector<TimestampNs> times;
    for (int64_t i = 0;; ++i) {
      const TimestampNs t = start_ns + SecondsToNs(i / options.rgbd_rate);
      if (t > end_ns) break;
      times.push_back(t);
    }
    tbb::parallel_for(size_t{0}, times.size(), [&](size_t i) {
      const SE3 world_from_cam = trajectory.Pose(times[i]) * cam_from_imu.Inverse();
      const cv::Mat rgb = renderer.Render(world_from_cam, 77 + i, times[i]);
      const cv::Mat depth = renderer.RenderDepth(world_from_cam, times[i]);
      // Depth noise of a structured-light sensor (Nguyen et al. 2012):
      // sigma_z = 1.2 mm + 1.9 mm * (z - 0.4)^2; holes below 0.4 m, beyond
      // 6 m, at 1 % random pixels and along depth discontinuities.
      std::mt19937 rng(static_cast<uint32_t>(options.seed * 7717 + i));
      std::normal_distribution<float> normal(0.f, 1.f);
      std::uniform_real_distribution<float> uniform(0.f, 1.f);
      cv::Mat depth_mm(depth.rows, depth.cols, CV_16UC1, cv::Scalar(0));
      for (int y = 1; y + 1 < depth.rows; ++y) {
        for (int x = 1; x + 1 < depth.cols; ++x) {
          const float z = depth.at<float>(y, x);
          if (z < 0.4f || z > 6.0f || uniform(rng) < 0.01f) continue;
          const float dz = std::max(std::fabs(depth.at<float>(y, x + 1) - z),
                                    std::fabs(depth.at<float>(y + 1, x) - z));
          if (dz > 0.05f * z) continue;  // discontinuity shadow
          const float sigma = static_cast<float>(options.noise_scale) *
                              (0.0012f + 0.0019f * (z - 0.4f) * (z - 0.4f));
          depth_mm.at<uint16_t>(y, x) =
              cv::saturate_cast<uint16_t>(1000.f * (z + sigma * normal(rng)));
        }
      }
      WritePngFile(JoinPaths(dir, "rgb/" + std::to_string(times[i]) + ".png"), rgb, kPngCompression);
      WritePngFile(
          JoinPaths(dir, "depth/" + std::to_string(times[i]) + ".png"), depth_mm, kPngCompression);
    });
    std::ostringstream csv;
    csv << "#timestamp [ns],rgb,depth\n";
    for (TimestampNs t : times) csv << t << ",rgb/" << t << ".png,depth/" << t << ".png\n";
    WriteFileAtomically(JoinPaths(dir, "data.csv"), csv.str());
    std::ostringstream cam;
    cam << std::setprecision(17)
        << "# RGB-D camera: pinhole, no distortion; depth PNG uint16 in mm (0 = missing),\n"
           "# depth = z along the optical axis; rgb and depth registered (same pixel grid).\n"
        << "intrinsics: [" << model.fx << ", " << model.fy << ", " << model.cx << ", "
        << model.cy << "]\nresolution: [640, 480]\ndepth_scale: 1000\nT_cam_imu:\n";
    const Mat4 m = cam_from_imu.Matrix();
    for (int r = 0; r < 4; ++r) {
      cam << "- [" << m(r, 0) << ", " << m(r, 1) << ", " << m(r, 2) << ", " << m(r, 3) << "]\n";
    }
    WriteFileAtomically(JoinPaths(dir, "camera.yaml"), cam.str());
    summary.num_rgbd = times.size();
  }
  summary.seconds_cameras = Seconds(t_phase);
  summary.cpu_lidar_cast = lidar_cast.Seconds();
  summary.cpu_lidar_write = lidar_write.Seconds();
  summary.cpu_camera_render = camera_render.Seconds();
  summary.cpu_camera_write = camera_write.Seconds();
  LogInfo("CPU breakdown (s, summed over threads): LiDAR ray casting {:.1f}, PCD writing "
          "{:.1f}; camera rendering {:.1f}, PNG encoding+writing {:.1f}",
          summary.cpu_lidar_cast, summary.cpu_lidar_write, summary.cpu_camera_render,
          summary.cpu_camera_write);

  if (before_commit) before_commit(temp);
  output.Commit();
  summary.seconds_total = Seconds(t_start);
  return summary;
}

}  // namespace sim
}  // namespace lisfm
