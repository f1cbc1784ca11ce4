// `lisfm lio`: FAST-LIO2-style LiDAR-inertial odometry on a sequence folder.
#include <algorithm>
#include <chrono>
#include <fstream>
#include <sstream>
#include <map>
#include <memory>
#include <numeric>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/trajectory_io.h"
#include "core/logging.h"
#include "core/options.h"
#include "core/progress.h"
#include "importers/lidar_frames.h"
#include "importers/sequence.h"
#include "lio/lidar_only_odometry.h"
#include "lio/imu_feeder.h"
#include "lio/lio_odometry.h"

namespace lisfm {

namespace {

std::vector<int> ParseLidarList(const std::string& text, size_t num_lidars) {
  std::vector<int> ids;
  if (text == "all") {
    for (size_t i = 0; i < num_lidars; ++i) ids.push_back(static_cast<int>(i));
    return ids;
  }
  for (const auto& tok : SplitString(text, ",")) {
    int64_t v = -1;
    std::string t = Trim(tok);
    if (t.rfind("lidar", 0) == 0) t = t.substr(5);
    if (!ParseInt64(t, &v) || v < 0 || v >= static_cast<int64_t>(num_lidars)) {
      throw UsageError(fmt::format("lisfm lio: --lidars: '{}' is not a LiDAR of the rig (it has {})",
                                   tok, num_lidars));
    }
    ids.push_back(static_cast<int>(v));
  }
  if (ids.empty()) throw UsageError("lisfm lio: --lidars is empty");
  return ids;
}

// Shortest round-trip decimal; -0 as 0 (as the rig.yaml writer does).
std::string YamlNumber(double v) { return fmt::format("{}", v == 0.0 ? 0.0 : v); }

std::string YamlMatrix(const std::string& indent, const Mat4& m) {
  std::string out;
  for (int r = 0; r < 4; ++r) {
    out += fmt::format("{}- [{}, {}, {}, {}]\n", indent, YamlNumber(m(r, 0)), YamlNumber(m(r, 1)),
                       YamlNumber(m(r, 2)), YamlNumber(m(r, 3)));
  }
  return out;
}

// calibration.yaml (docs/FORMATS.md): the online LiDAR–IMU calibration of the
// used LiDARs next to the rig.yaml values it started from.
std::string CalibrationYaml(const Rig& rig,
                            const std::vector<int>& used,
                            const std::vector<LidarCalibrationEstimate>& estimates) {
  std::string out =
      "# lisfm lio: LiDAR-IMU calibration estimated online. T_imu_lidar (imu_from_lidar) and\n"
      "# time_offset (s, t_imu = t_lidar + time_offset) as in rig.yaml; *_initial: the rig.yaml\n"
      "# values (the prior); *_std: 1-sigma of the filter covariance after the last update\n"
      "# (rotation: about the LiDAR axes, rad, T = T_hat * Exp(d); translation: IMU frame, m).\n"
      "lidars:\n";
  for (const int k : used) {
    const RigLidar& lidar = rig.lidars[k];
    const LidarCalibrationEstimate& e = estimates[k];
    std::vector<std::string> what;
    if (e.extrinsic_estimated) what.push_back("extrinsic");
    if (e.time_offset_estimated) what.push_back("time_offset");
    out += fmt::format("  {}:\n    estimated: [{}]\n    T_imu_lidar:\n", lidar.name,
                       fmt::join(what, ", "));
    out += YamlMatrix("    ", e.imu_from_lidar.Matrix());
    out += fmt::format("    time_offset: {}\n", e.time_offset_s);
    out += fmt::format("    rotation_std: [{}, {}, {}]\n", e.rotation_std_rad.x(),
                       e.rotation_std_rad.y(), e.rotation_std_rad.z());
    out += fmt::format("    translation_std: [{}, {}, {}]\n", e.translation_std_m.x(),
                       e.translation_std_m.y(), e.translation_std_m.z());
    out += fmt::format("    time_offset_std: {}\n    T_imu_lidar_initial:\n", e.time_offset_std_s);
    out += YamlMatrix("    ", lidar.imu_from_lidar.Matrix());
    out += fmt::format("    time_offset_initial: {}\n", lidar.time_offset_s);
  }
  return out;
}

// One summary sentence per used LiDAR: the change from rig.yaml and its 1-sigma.
std::string CalibrationSummary(const Rig& rig,
                               const std::vector<int>& used,
                               const std::vector<LidarCalibrationEstimate>& estimates) {
  std::vector<std::string> parts;
  for (const int k : used) {
    const RigLidar& lidar = rig.lidars[k];
    const LidarCalibrationEstimate& e = estimates[k];
    std::string part = lidar.name + ":";
    if (e.extrinsic_estimated) {
      const SE3 change = lidar.imu_from_lidar.Inverse() * e.imu_from_lidar;
      part += fmt::format(
          " T_imu_lidar {:.2f} mm / {:.3f} deg from rig.yaml (1-sigma {:.2f} mm / {:.3f} deg)",
          1e3 * (e.imu_from_lidar.translation() - lidar.imu_from_lidar.translation()).norm(),
          so3::AngularDistance(change.rotation(), Quat::Identity()) * 180 / M_PI,
          1e3 * e.translation_std_m.norm(), e.rotation_std_rad.norm() * 180 / M_PI);
    }
    if (e.time_offset_estimated) {
      part += fmt::format("{} time offset {:.3f} ms (rig.yaml {:.3f} ms, 1-sigma {:.3f} ms)",
                          e.extrinsic_estimated ? ";" : "", 1e3 * e.time_offset_s,
                          1e3 * lidar.time_offset_s, 1e3 * e.time_offset_std_s);
    }
    parts.push_back(part);
  }
  return fmt::format("{}", fmt::join(parts, "; "));
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t i = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
  return v[i];
}

}  // namespace

int RunLio(int argc, char** argv) {
  std::string input_path, output_path, lidars = "all", method = "iekf";
  int max_scans = 0;
  bool write_keyframes = true;
  bool overwrite = false;
  double map_voxel = 0.2;
  LioOptions lio;
  OptionManager options("lisfm lio",
                        "LiDAR-inertial odometry (iterated EKF, per-point de-skew, iVox map) on a "
                        "sequence folder; writes trajectory.txt, keyframes/, map.pcd, scans.csv");
  options.AddRequiredString("input_path", &input_path, "sequence folder (rig.yaml, imu0/, lidarK/)");
  options.AddRequiredString("output_path", &output_path, "output folder");
  options.AddBool("overwrite", &overwrite, "replace an earlier lisfm output at --output_path");
  options.AddString("lidars", &lidars, "LiDARs to use: all, or a list like 0 / 1 / 0,1");
  options.AddChoice("method", &method, {"iekf", "lidar_only"},
                    "iekf: LiDAR-inertial filter; lidar_only: frame-to-map ICP baseline without "
                    "the IMU (first LiDAR only)");
  options.AddInt("max_scans", &max_scans, "stop after this many frames (0 = all)",
                 OptionRange::AtLeast(0));
  options.AddBool("write_keyframes", &write_keyframes, "write keyframe clouds (PCD)");
  options.AddDouble("map_voxel_size", &map_voxel,
                    "m, voxel size of the written map.pcd (0 = no downsampling)",
                    OptionRange::AtLeast(0));
  AddLioOptions(&options, &lio);
  if (!options.Parse(argc, argv)) return 0;

  const bool calibrate = lio.estimate_extrinsic || lio.estimate_time_offset;
  if (calibrate && method != "iekf") {
    throw UsageError(
        "lisfm lio: --Lio.estimate_extrinsic / --Lio.estimate_time_offset need --method iekf");
  }
  OutputFolder output(output_path, overwrite);  // checked before the work

  const auto t0 = std::chrono::steady_clock::now();
  LogStage("lio: reading " + input_path);
  const Sequence seq = ReadSequence(input_path);
  if (seq.rig.lidars.empty()) throw InputError(input_path + "/rig.yaml", "lidars", "the rig has no LiDAR");
  const std::vector<int> used = ParseLidarList(lidars, seq.rig.lidars.size());
  std::vector<SE3> extrinsics;
  std::vector<double> offsets;
  for (const auto& l : seq.rig.lidars) {
    extrinsics.push_back(l.imu_from_lidar);
    offsets.push_back(l.time_offset_s);
  }
  LioOdometry odom(lio, seq.rig.imu, extrinsics, offsets);
  const int primary = used.front();
  std::unique_ptr<LidarOnlyOdometry> lidar_only;
  if (method == "lidar_only") {
    lidar_only = std::make_unique<LidarOnlyOdometry>(lio, extrinsics[primary], offsets[primary]);
    if (used.size() > 1) LogWarning("lio: --method lidar_only uses {} only", seq.rig.lidars[primary].name);
  }
  const auto& primary_scans = seq.lidar_scans[primary];
  if (primary_scans.empty()) throw InputError(input_path, seq.rig.lidars[primary].name, "no scans");
  LogInfo("lio: {} IMU samples, {} frames from {}{}", seq.imu.size(), primary_scans.size(),
          seq.rig.lidars[primary].name, used.size() > 1 ? fmt::format(" + {} more LiDAR(s)", used.size() - 1) : "");

  const std::string kf_dir = output.File("keyframes");
  if (write_keyframes) CreateDirs(kf_dir);

  Trajectory trajectory;
  std::vector<StampedPose> keyframe_poses;
  std::vector<double> times_ms;
  int processed = 0, skipped = 0, degenerate = 0;
  std::ostringstream scans_csv;
  scans_csv << "#t_ns,processed,raw_points,downsampled,matched,iterations,time_ms,num_weak,"
               "min_eigenvalue,keyframe,message\n";
  // lidar_only uses the primary LiDAR alone.
  LidarFrameReader reader(seq, lidar_only ? std::vector<int>{primary} : used);
  ImuFeeder imu_feeder(seq.imu);
  const size_t num_frames = max_scans > 0 ? std::min<size_t>(max_scans, reader.num_frames())
                                          : reader.num_frames();
  ProgressReporter progress("lio", static_cast<int64_t>(num_frames));
  LidarFrame frame;
  for (size_t f = 0; f < num_frames && reader.Next(&frame); ++f) {
    imu_feeder.FeedUntil(frame.end_ns, &odom);
    const LioFrameResult r =
        lidar_only ? lidar_only->ProcessScan(frame.clouds.front()) : odom.ProcessFrame(frame.Inputs());
    if (r.processed) {
      ++processed;
      times_ms.push_back(r.time_ms);
      if (trajectory.empty() || r.t_ns > trajectory.end_ns()) trajectory.PushBack({r.t_ns, r.world_from_imu});
      if (r.degeneracy.num_weak > 0) ++degenerate;
    } else {
      ++skipped;
      if (odom.initialized()) LogWarning("lio: frame at {} ns skipped: {}", r.t_ns, r.message);
    }
    for (auto& kf : odom.TakeKeyframes()) {
      keyframe_poses.push_back({kf.t_ns, kf.world_from_imu});
      if (write_keyframes) {
        WritePcd(JoinPaths(kf_dir, std::to_string(kf.t_ns) + ".pcd"), kf.cloud_in_imu);
      }
    }
    scans_csv << r.t_ns << "," << (r.processed ? 1 : 0) << "," << r.num_raw_points << ","
              << r.num_downsampled << "," << r.num_matched << "," << r.iterations << ","
              << fmt::format("{:.3f}", r.time_ms) << "," << r.degeneracy.num_weak << ","
              << fmt::format("{:.6g}", r.degeneracy.eigenvalues(0)) << "," << (r.is_keyframe ? 1 : 0)
              << ",\"" << r.message << "\"\n";
    progress.Add();
  }
  progress.Finish();
  if (trajectory.empty()) {
    throw InputError(input_path, "", "lio produced no pose (no frame could be processed)");
  }

  // Outputs.
  WriteTum(output.File("trajectory.txt"), trajectory);
  WriteFileAtomically(output.File("scans.csv"), scans_csv.str());
  {
    std::ostringstream kf;
    kf << "#t_ns,tx,ty,tz,qx,qy,qz,qw (world_from_imu; cloud keyframes/<t_ns>.pcd in the IMU frame)\n";
    for (const auto& k : keyframe_poses) {
      const auto& q = k.pose.rotation();
      const auto& t = k.pose.translation();
      kf << k.t_ns << fmt::format(",{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f}\n", t.x(), t.y(),
                                  t.z(), q.x(), q.y(), q.z(), q.w());
    }
    if (write_keyframes) WriteFileAtomically(JoinPaths(kf_dir, "keyframes.csv"), kf.str());
  }
  const PointCloud map_cloud =
      VoxelDownsample((lidar_only ? lidar_only->map() : odom.map()).ToCloud(), map_voxel);
  WritePcd(output.File("map.pcd"), map_cloud);
  options.WriteConfig(output.File("lio_config.yaml"));
  const std::vector<LidarCalibrationEstimate> calibration = odom.LidarCalibration();
  if (calibrate) {
    WriteFileAtomically(output.File("calibration.yaml"),
                        CalibrationYaml(seq.rig, used, calibration));
  }
  output.Commit();

  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double data_s = NsToSeconds(trajectory.end_ns() - primary_scans.front().t_ns);
  const double proc_s = std::accumulate(times_ms.begin(), times_ms.end(), 0.0) / 1000.0;
  LogInfo(
      "lio summary: {} frames processed, {} skipped, {} with weak directions; per-frame time median "
      "{:.2f} ms, p95 {:.2f} ms ({:.1f}x real time for the filter, {:.1f}x with I/O); {} keyframes; "
      "map {} points; path {:.2f} m over {:.1f} s; outputs in {} (trajectory.txt, keyframes/, map.pcd, "
      "scans.csv)",
      processed, skipped, degenerate, Percentile(times_ms, 0.5), Percentile(times_ms, 0.95),
      proc_s > 0 ? data_s / proc_s : 0.0, wall_s > 0 ? data_s / wall_s : 0.0, keyframe_poses.size(),
      map_cloud.size(), trajectory.PathLength(), data_s, output_path);
  if (calibrate) {
    LogInfo("lio calibration (calibration.yaml): {}",
            CalibrationSummary(seq.rig, used, calibration));
  }
  if (lio.estimate_gyro_scale) {
    const Mat3& E = odom.gyro_scale_error();
    LogInfo(
        "lio gyro intrinsics: measured = (I + E) true + bias, E (%) = [{:.3f} {:.3f} {:.3f}; "
        "{:.3f} {:.3f} {:.3f}; {:.3f} {:.3f} {:.3f}]",
        100 * E(0, 0),
        100 * E(0, 1),
        100 * E(0, 2),
        100 * E(1, 0),
        100 * E(1, 1),
        100 * E(1, 2),
        100 * E(2, 0),
        100 * E(2, 1),
        100 * E(2, 2));
  }
  return 0;
}

}  // namespace lisfm
