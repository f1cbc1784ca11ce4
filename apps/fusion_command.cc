// `lisfm fusion`: dense RGB-D SLAM with projective point-to-plane ICP (frame to
// model) and point-based (surfel) fusion, on a lisfm sequence (rgbd0/), a TUM RGB-D
// folder or a 7-Scenes folder.
//
// Outputs (one folder, written completely or not at all):
//   trajectory.txt         TUM `t x y z qx qy qz qw`, world_from_camera at the frame stamps
//   surfels.ply            binary little-endian PLY: x y z nx ny nz (float) red green blue
//                          (uchar) radius confidence (float); surfels with confidence >=
//                          Fusion.output_min_confidence
//   fusion_summary.json    frames, surfels, compression ratio, per-stage ms, bytes per surfel
//   normals_first_camera.png, normals_last_camera.png
//                          the fused model's normals (camera frame, RGB = 255 (n + 1) / 2)
//                          rendered from the first and last camera poses
//   config.yaml            the effective options
// --mode lidar (lio's de-skewed keyframes, spherical range images of lidar0, given poses):
// trajectory.txt holds world_from_imu at the keyframe stamps, the PNGs are
// normals_{first,last}_keyframe.png (spherical, LiDAR frame); docs/FORMATS.md.
#include <fmt/format.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "core/io/image_codec.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/rgbd_io.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"
#include "core/logging.h"
#include "core/options.h"
#include "core/progress.h"
#include "icp/lidar_fusion.h"
#include "icp/rgbd_fusion.h"
#include "icp/surfel_map.h"
#include "lio/pose_slam/pose_slam.h"

namespace lisfm {

namespace {

double Seconds(std::chrono::steady_clock::time_point a) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
}

// The pose of every frame from a TUM file: a pose stamped within 1 ms of each
// frame time (the stamps lisfm fusion writes); a frame without one is an error.
std::vector<SE3> PosesFromTrajectory(const std::string& path,
                                     const RgbdSequence& sequence,
                                     size_t num_frames) {
  const Trajectory trajectory = ReadTum(path);
  if (trajectory.empty()) throw InputError(path, "", "expected poses, found none");
  std::vector<SE3> poses;
  poses.reserve(num_frames);
  for (size_t i = 0; i < num_frames; ++i) {
    const TimestampNs t = sequence.frames[i].t_ns;
    const int k = trajectory.Nearest(t, 1000000);
    if (k < 0) {
      throw InputError(path,
                       "",
                       fmt::format("expected a pose at the time of frame {} ({:.6f} s, within 1 "
                                   "ms), found none (the trajectory covers {:.6f} to {:.6f} s)",
                                   i,
                                   NsToSeconds(t),
                                   NsToSeconds(trajectory.start_ns()),
                                   NsToSeconds(trajectory.end_ns())));
    }
    poses.push_back(trajectory[k].pose);
  }
  return poses;
}

std::vector<SE3> GivenPoses(const RgbdSequence& sequence, size_t num_frames) {
  std::vector<SE3> poses;
  poses.reserve(num_frames);
  for (size_t i = 0; i < num_frames; ++i) {
    const RgbdFrameInfo& f = sequence.frames[i];
    if (!f.world_from_camera) {
      throw InputError(sequence.pose_source.empty() ? sequence.path : sequence.pose_source,
                       fmt::format("frame {} ({:.6f} s)", i, NsToSeconds(f.t_ns)),
                       sequence.pose_source.empty()
                           ? "--pose_source groundtruth: the data set has no poses"
                           : "--pose_source groundtruth: no given pose at this frame time");
    }
    poses.push_back(*f.world_from_camera);
  }
  return poses;
}

// Binary little-endian PLY of the stable surfels (SurfelMap::Stable).
void WriteSurfelsPly(const std::string& path, const SurfelMap& map) {
  size_t n = 0;
  for (const Surfel& s : map.surfels()) n += map.Stable(s) ? 1 : 0;
  AtomicOutputFile file(path, /*binary=*/true);
  std::ofstream& out = file.stream();
  out << "ply\nformat binary_little_endian 1.0\ncomment lisfm fusion surfels (world frame, m)\n"
      << "element vertex " << n << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property float nx\nproperty float ny\nproperty float nz\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      << "property float radius\nproperty float confidence\nend_header\n";
  // x86-64 and arm64 are little-endian: the floats are written as they are in memory.
  static_assert(sizeof(float) == 4);
  std::vector<char> buffer;
  buffer.reserve(n * 35);
  auto put = [&](const void* data, size_t size) {
    const char* c = static_cast<const char*>(data);
    buffer.insert(buffer.end(), c, c + size);
  };
  for (const Surfel& s : map.surfels()) {
    if (!map.Stable(s)) continue;
    put(s.position.data(), 12);
    put(s.normal.data(), 12);
    put(s.color.data(), 3);
    put(&s.radius_m, 4);
    put(&s.confidence, 4);
  }
  out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  file.Commit();
}

// The stable surfels' normals (camera frame) seen from world_from_camera, each
// surfel covering its projected disc (up to 3 pixels); black where there is none.
void WriteNormalMapPng(const std::string& path,
                       const SurfelMap& map,
                       const SE3& world_from_camera,
                       const PinholeIntrinsics& intrinsics) {
  std::vector<uint32_t> index_map;
  map.RenderIndexMap(
      world_from_camera, intrinsics, map.options().output_min_confidence, 3, &index_map);
  const Eigen::Matrix3f camera_from_world =
      world_from_camera.RotationMatrix().transpose().cast<float>();
  cv::Mat image(intrinsics.height, intrinsics.width, CV_8UC3, cv::Scalar(0, 0, 0));
  for (int v = 0; v < intrinsics.height; ++v) {
    for (int u = 0; u < intrinsics.width; ++u) {
      const uint32_t s = index_map[static_cast<size_t>(v) * intrinsics.width + u];
      if (s == SurfelMap::kNoSurfel) continue;
      const Eigen::Vector3f n = camera_from_world * map.surfels()[s].normal;
      auto to_byte = [](float x) {
        return static_cast<uint8_t>(std::clamp(std::lround(127.5f * (x + 1.f)), 0L, 255L));
      };
      image.at<cv::Vec3b>(v, u) = cv::Vec3b(to_byte(n.z()), to_byte(n.y()), to_byte(n.x()));  // BGR
    }
  }
  if (!WritePngFile(path, image)) throw InputError(path, "", "cannot write the PNG image");
}

// The stable surfels' normals (sensor frame) seen from world_from_sensor in a
// spherical image with square pixels (the layout's azimuth step, its elevation
// range), each surfel covering its projected disc (up to 3 pixels); black where
// there is none.
void WriteSphericalNormalMapPng(const std::string& path,
                                const SurfelMap& map,
                                const SE3& world_from_sensor,
                                const SphericalProjection& layout) {
  const double step = layout.azimuth_step_rad();
  const double top = layout.elevation_top_rad() + 0.5 * layout.elevation_step_rad();
  const double bottom = top - layout.height() * layout.elevation_step_rad();
  const int rows = std::max(1, static_cast<int>(std::lround((top - bottom) / step)));
  const SphericalProjection image_projection(layout.width(), rows, top - 0.5 * step, step);
  std::vector<uint32_t> index_map;
  map.RenderIndexMap(
      world_from_sensor, image_projection, map.options().output_min_confidence, 3, &index_map);
  const Eigen::Matrix3f sensor_from_world =
      world_from_sensor.RotationMatrix().transpose().cast<float>();
  cv::Mat image(rows, layout.width(), CV_8UC3, cv::Scalar(0, 0, 0));
  for (int v = 0; v < rows; ++v) {
    for (int u = 0; u < layout.width(); ++u) {
      const uint32_t s = index_map[static_cast<size_t>(v) * layout.width() + u];
      if (s == SurfelMap::kNoSurfel) continue;
      const Eigen::Vector3f n = sensor_from_world * map.surfels()[s].normal;
      auto to_byte = [](float x) {
        return static_cast<uint8_t>(std::clamp(std::lround(127.5f * (x + 1.f)), 0L, 255L));
      };
      image.at<cv::Vec3b>(v, u) = cv::Vec3b(to_byte(n.z()), to_byte(n.y()), to_byte(n.x()));  // BGR
    }
  }
  if (!WritePngFile(path, image)) throw InputError(path, "", "cannot write the PNG image");
}

// Writes the outputs both modes share: trajectory.txt, surfels.ply, the two
// normal-map PNGs (write_normal_maps, given the output folder), and
// fusion_summary.json = `summary` plus the map's counts (stable surfels written,
// surfels in the map, bytes) and the observation totals; then config.yaml and
// commits the folder.
void WriteFusionOutputs(const Trajectory& trajectory,
                        const SurfelMap& map,
                        const FuseStats& totals,
                        const std::function<void(OutputFolder*)>& write_normal_maps,
                        const OptionManager& options,
                        nlohmann::json summary,
                        OutputFolder* output) {
  const size_t stable = map.NumStable();
  WriteTum(output->File("trajectory.txt"), trajectory);
  WriteSurfelsPly(output->File("surfels.ply"), map);
  write_normal_maps(output);
  summary["surfels"] = stable;
  summary["surfels_in_map"] = map.size();
  summary["output_min_confidence"] = map.options().output_min_confidence;
  summary["bytes_per_surfel"] = SurfelMap::BytesPerSurfel();
  summary["map_bytes"] = map.size() * SurfelMap::BytesPerSurfel();
  summary["observations"] = {{"merged", totals.merged},
                             {"added", totals.added},
                             {"skipped", totals.skipped},
                             {"surfels_removed", totals.removed}};
  WriteFileAtomically(output->File("fusion_summary.json"), summary.dump(2) + "\n");
  options.WriteConfig(output->File("config.yaml"));
  output->Commit();
}

struct LidarFusionRun {
  std::string input_path, output_path, lio_path, pose_source, trajectory_path;
  int max_frames = 0;
  bool overwrite = false;
  LidarFusionOptions lidar;
  SurfelFusionOptions fusion;
};

// `lisfm fusion --mode lidar`: lio's de-skewed keyframes (IMU frame) fused with
// world_from_imu poses from lio's keyframes.csv, a TUM trajectory (a pose within
// 1 ms of each keyframe stamp) or the sequence's groundtruth.txt (interpolated,
// gaps up to 0.1 s); the sensor is the rig's lidar0.
int RunLidarFusion(const LidarFusionRun& run, const OptionManager& options) {
  OutputFolder output(run.output_path, run.overwrite);
  const auto t_start = std::chrono::steady_clock::now();
  LogStage("Reading the lio keyframes");
  if (!DirExists(run.lio_path)) {
    throw InputError(
        run.lio_path, "", "--lio_path: not found: expected a `lisfm lio` output folder");
  }
  const Rig rig = ReadRigYaml(JoinPaths(run.input_path, "rig.yaml"));
  const RigLidar* lidar = rig.FindLidar("lidar0");
  if (lidar == nullptr || lidar->type != LidarType::kSpinning) {
    throw InputError(JoinPaths(run.input_path, "rig.yaml"),
                     "lidars",
                     "--mode lidar: expected a spinning LiDAR lidar0 (its scans become range "
                     "images), found none");
  }
  const SE3 imu_from_lidar = lidar->imu_from_lidar;
  const SE3 lidar_from_imu = imu_from_lidar.Inverse();
  const LioOutput lio = ReadLioOutput(run.lio_path);
  const size_t num_frames =
      run.max_frames > 0 ? std::min(lio.keyframes.size(), static_cast<size_t>(run.max_frames))
                         : lio.keyframes.size();
  // world_from_imu of each keyframe.
  std::vector<SE3> poses(num_frames);
  if (run.pose_source == "lio") {
    for (size_t i = 0; i < num_frames; ++i) poses[i] = lio.keyframes[i].world_from_imu;
  } else {
    const bool groundtruth = run.pose_source == "groundtruth";
    const std::string path =
        groundtruth ? JoinPaths(run.input_path, "groundtruth.txt") : run.trajectory_path;
    const Trajectory trajectory = ReadTum(path);
    if (trajectory.empty()) throw InputError(path, "", "expected poses, found none");
    for (size_t i = 0; i < num_frames; ++i) {
      const TimestampNs t = lio.keyframes[i].t_ns;
      std::optional<SE3> pose;
      if (groundtruth) {
        pose = trajectory.Interpolate(t, 100000000);
      } else {
        const int k = trajectory.Nearest(t, 1000000);
        if (k >= 0) pose = trajectory[k].pose;
      }
      if (!pose) {
        throw InputError(
            path,
            "",
            fmt::format("expected a pose at keyframe {} (stamp {} ns, {:.6f} s; {}), "
                        "found none (the trajectory covers {:.6f} to {:.6f} s)",
                        i,
                        t,
                        NsToSeconds(t),
                        groundtruth ? "interpolated across gaps up to 0.1 s" : "within 1 ms",
                        NsToSeconds(trajectory.start_ns()),
                        NsToSeconds(trajectory.end_ns())));
      }
      poses[i] = *pose;
    }
  }
  // A keyframe in the sensor frame: lidar0's points (sensor_id 0) moved by lidar_from_imu.
  auto load = [&](size_t i) {
    PointCloud cloud = ReadPcd(lio.keyframes[i].cloud_path);
    const Eigen::Matrix3f R = lidar_from_imu.RotationMatrix().cast<float>();
    const Eigen::Vector3f t = lidar_from_imu.translation().cast<float>();
    size_t kept = 0;
    for (const LidarPoint& p : cloud.points) {
      if (p.sensor_id != 0 || !std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        continue;
      LidarPoint q = p;
      const Eigen::Vector3f x = R * p.xyz() + t;
      q.x = x.x();
      q.y = x.y();
      q.z = x.z();
      cloud.points[kept++] = q;
    }
    cloud.points.resize(kept);
    return cloud;
  };
  PointCloud current = load(0);
  const LidarImageLayout layout =
      FitLidarImageLayout(current, run.lidar, lio.keyframes[0].cloud_path);
  LogInfo("{}: {} of {} keyframes, range image {}x{} ({:.3f} x {:.3f} deg, rows {}), poses: {}",
          run.lio_path,
          num_frames,
          lio.keyframes.size(),
          layout.projection.width(),
          layout.projection.height(),
          layout.projection.azimuth_step_rad() * 180 / M_PI,
          layout.projection.elevation_step_rad() * 180 / M_PI,
          layout.row_of_ring.empty() ? "by elevation" : "one per ring",
          run.pose_source == "trajectory" ? run.trajectory_path : run.pose_source);
  LidarFusion system(layout, run.lidar, run.fusion);

  LogStage("Fusion");
  ProgressReporter progress("fusion", static_cast<int64_t>(num_frames));
  Trajectory trajectory;
  double load_ms = 0, preprocess_ms = 0, fuse_ms = 0;
  FuseStats totals;
  const auto t_loop = std::chrono::steady_clock::now();
  for (size_t i = 0; i < num_frames; ++i) {
    // Load keyframe i + 1 while keyframe i is fused; a loading error is rethrown
    // after both tasks (thrown inside parallel_invoke it would cancel the fusion).
    PointCloud next;
    double next_load_ms = 0;
    std::exception_ptr load_error;
    LidarFrameResult r;
    tbb::parallel_invoke(
        [&] {
          if (i + 1 >= num_frames) return;
          const auto t0 = std::chrono::steady_clock::now();
          try {
            next = load(i + 1);
          } catch (...) {
            load_error = std::current_exception();
          }
          next_load_ms = 1e3 * Seconds(t0);
        },
        [&] { r = system.AddScan(current, poses[i] * imu_from_lidar); });
    if (load_error) std::rethrow_exception(load_error);
    load_ms += next_load_ms;
    preprocess_ms += r.preprocess_ms;
    fuse_ms += r.fuse_ms;
    totals.merged += r.fuse.merged;
    totals.added += r.fuse.added;
    totals.skipped += r.fuse.skipped;
    totals.removed += r.fuse.removed;
    trajectory.PushBack({lio.keyframes[i].t_ns, poses[i]});
    current = std::move(next);
    progress.Add();
  }
  progress.Finish();
  const double loop_s = Seconds(t_loop);

  LogStage("Writing outputs");
  const auto t_write = std::chrono::steady_clock::now();
  const SurfelMap& map = system.map();
  const double compute_ms = preprocess_ms + fuse_ms;
  const size_t scan_points = system.num_scan_points();
  const size_t stable = map.NumStable();
  nlohmann::json summary;
  summary["mode"] = "lidar";
  summary["input_path"] = run.input_path;
  summary["lio_path"] = run.lio_path;
  summary["pose_source"] = run.pose_source;
  summary["keyframes"] = num_frames;
  summary["frames"] = num_frames;
  summary["range_image"] = {
      {"width", layout.projection.width()},
      {"height", layout.projection.height()},
      {"azimuth_step_deg", layout.projection.azimuth_step_rad() * 180 / M_PI},
      {"elevation_step_deg", layout.projection.elevation_step_rad() * 180 / M_PI},
      {"elevation_top_deg", layout.projection.elevation_top_rad() * 180 / M_PI},
      {"rows_from_rings", !layout.row_of_ring.empty()}};
  summary["scan_points"] = scan_points;
  summary["input_points"] = system.num_input_points();
  // Surfels written / scan points within the range limits over all keyframes.
  summary["compression_ratio"] = scan_points > 0 ? static_cast<double>(stable) / scan_points : 0.0;
  summary["stage_ms"] = {{"load", load_ms},
                         {"preprocess", preprocess_ms},
                         {"fusion", fuse_ms},
                         {"loop_wall", 1e3 * loop_s}};
  summary["stage_ms_per_keyframe"] = {{"load", load_ms / num_frames},
                                      {"preprocess", preprocess_ms / num_frames},
                                      {"fusion", fuse_ms / num_frames},
                                      {"loop_wall", 1e3 * loop_s / num_frames}};
  summary["fusion_keyframes_per_s"] = compute_ms > 0 ? 1e3 * num_frames / compute_ms : 0.0;
  summary["wall_keyframes_per_s"] = loop_s > 0 ? num_frames / loop_s : 0.0;
  WriteFusionOutputs(
      trajectory,
      map,
      totals,
      [&](OutputFolder* out) {
        WriteSphericalNormalMapPng(out->File("normals_first_keyframe.png"),
                                   map,
                                   poses.front() * imu_from_lidar,
                                   layout.projection);
        WriteSphericalNormalMapPng(out->File("normals_last_keyframe.png"),
                                   map,
                                   poses.back() * imu_from_lidar,
                                   layout.projection);
      },
      options,
      std::move(summary),
      &output);
  LogInfo(
      "fusion: {} keyframes (range image {}x{}), {} surfels written (confidence >= {}; {} in the "
      "map, {} bytes each; {:.2f} % of {} scan points), fusion {:.1f} keyframes/s ({:.1f} "
      "ms/keyframe: preprocess {:.1f}, fusion {:.1f}), wall {:.1f} keyframes/s with loading; "
      "writing {:.2f} s, total {:.1f} s; wrote {}/{{trajectory.txt, surfels.ply, "
      "fusion_summary.json, normals_first_keyframe.png, normals_last_keyframe.png}}",
      num_frames,
      layout.projection.width(),
      layout.projection.height(),
      stable,
      run.fusion.output_min_confidence,
      map.size(),
      SurfelMap::BytesPerSurfel(),
      scan_points > 0 ? 100.0 * stable / scan_points : 0.0,
      scan_points,
      compute_ms > 0 ? 1e3 * num_frames / compute_ms : 0.0,
      compute_ms / num_frames,
      preprocess_ms / num_frames,
      fuse_ms / num_frames,
      loop_s > 0 ? num_frames / loop_s : 0.0,
      Seconds(t_write),
      Seconds(t_start),
      output.final_path());
  return 0;
}

}  // namespace

int RunFusion(int argc, char** argv) {
  OptionManager options("lisfm fusion",
                        "dense RGB-D SLAM: projective ICP (frame to model) and surfel fusion; "
                        "--mode lidar: surfel fusion of lio keyframes with given poses");
  std::string input_path, output_path, mode = "rgbd", lio_path, pose_source = "icp",
                                       trajectory_path, layout = "auto", intrinsics_path;
  double depth_units_per_m = 0;
  int max_frames = 0;
  bool overwrite = false;
  RgbdFusionOptions rgbd;
  ProjectiveIcpOptions icp;
  SurfelFusionOptions fusion;
  options.AddRequiredString("input_path",
                            &input_path,
                            "RGB-D sequence: lisfm sequence folder (rgbd0/), TUM RGB-D or "
                            "7-Scenes folder; --mode lidar: the sequence folder (rig.yaml)");
  options.AddRequiredString("output_path",
                            &output_path,
                            "output folder: trajectory.txt, surfels.ply, fusion_summary.json, "
                            "normals_{first,last}_camera.png, config.yaml");
  options.AddChoice("mode",
                    &mode,
                    {"rgbd", "lidar"},
                    "input kind: RGB-D frames, or (lidar) lio's de-skewed keyframes with given "
                    "poses");
  options.AddString("lio_path", &lio_path, "--mode lidar: the lisfm lio output folder");
  options.AddChoice("pose_source",
                    &pose_source,
                    {"icp", "groundtruth", "trajectory", "lio"},
                    "poses: frame-to-model ICP (rgbd), the data set's poses, a TUM file, or lio's "
                    "keyframe poses (lidar; its default)");
  options.AddString("trajectory_path",
                    &trajectory_path,
                    "--pose_source trajectory: TUM file of world_from_camera (rgbd) or "
                    "world_from_imu (lidar: pose_slam's trajectory.txt) with a pose at every "
                    "frame time");
  options.AddChoice("layout",
                    &layout,
                    {"auto", "lisfm", "tum", "7scenes"},
                    "folder layout of --input_path (auto: detect)");
  options.AddString("intrinsics_path",
                    &intrinsics_path,
                    "intrinsics overriding the layout's (camera.yaml or 3x3 K text file)");
  options.AddDouble("depth_units_per_m",
                    &depth_units_per_m,
                    "depth image units per metre, overriding the layout's (0 = the layout's)",
                    OptionRange::AtLeast(0));
  options.AddInt(
      "max_frames", &max_frames, "fuse only the first N frames (0 = all)", OptionRange::AtLeast(0));
  AddRgbdFusionOptions(&options, &rgbd);
  AddSurfelFusionOptions(&options, &fusion);
  AddProjectiveIcpOptions(&options, &icp);
  LidarFusionOptions lidar;
  AddLidarFusionOptions(&options, &lidar);
  options.AddBool("overwrite", &overwrite, "replace an earlier lisfm output at --output_path");
  if (!options.Parse(argc, argv)) return 0;
  if (mode == "lidar") {
    if (lio_path.empty()) throw UsageError("--mode lidar needs --lio_path (a lisfm lio output)");
    if (pose_source == "icp") {
      if (options.IsSet("pose_source")) {
        throw UsageError(
            "--mode lidar takes --pose_source lio, trajectory or groundtruth (not icp: the "
            "keyframes are fused with given poses)");
      }
      pose_source = "lio";
      options.Set("pose_source", "lio");
    }
    if (pose_source == "trajectory" && trajectory_path.empty()) {
      throw UsageError("--pose_source trajectory needs --trajectory_path");
    }
    if (pose_source != "trajectory" && !trajectory_path.empty()) {
      throw UsageError("--trajectory_path is only used with --pose_source trajectory");
    }
    for (const char* name : {"layout", "intrinsics_path", "depth_units_per_m"}) {
      if (options.IsSet(name)) {
        throw UsageError(fmt::format("--{} is only used with --mode rgbd", name));
      }
    }
    LidarFusionRun run;
    run.input_path = input_path;
    run.output_path = output_path;
    run.lio_path = lio_path;
    run.pose_source = pose_source;
    run.trajectory_path = trajectory_path;
    run.max_frames = max_frames;
    run.overwrite = overwrite;
    run.lidar = lidar;
    run.fusion = fusion;
    return RunLidarFusion(run, options);
  }
  if (pose_source == "lio") throw UsageError("--pose_source lio is only used with --mode lidar");
  if (pose_source == "trajectory" && trajectory_path.empty()) {
    throw UsageError("--pose_source trajectory needs --trajectory_path");
  }
  if (pose_source != "trajectory" && !trajectory_path.empty()) {
    throw UsageError("--trajectory_path is only used with --pose_source trajectory");
  }
  if (!lio_path.empty()) throw UsageError("--lio_path is only used with --mode lidar");
  OutputFolder output(output_path, overwrite);

  const auto t_start = std::chrono::steady_clock::now();
  LogStage("Reading the RGB-D sequence");
  RgbdReadOptions read;
  read.layout = ParseRgbdLayout(layout);
  read.intrinsics_path = intrinsics_path;
  read.depth_units_per_m = depth_units_per_m;
  const RgbdSequence sequence = ReadRgbdSequence(input_path, read);
  const size_t num_frames = max_frames > 0
                                ? std::min(sequence.frames.size(), static_cast<size_t>(max_frames))
                                : sequence.frames.size();
  std::vector<SE3> poses;
  if (pose_source == "groundtruth") poses = GivenPoses(sequence, num_frames);
  if (pose_source == "trajectory")
    poses = PosesFromTrajectory(trajectory_path, sequence, num_frames);
  const int factor = rgbd.downsample_factor;
  const RgbdIntrinsics di = DownsampleIntrinsics(sequence.intrinsics, factor);
  const PinholeIntrinsics intrinsics{di.fx, di.fy, di.cx, di.cy, di.width, di.height};
  LogInfo(
      "{} ({} layout): {} of {} frames, {}x{} -> {}x{} (downsample factor {}), depth scale "
      "{} m/unit, poses: {}",
      input_path,
      RgbdLayoutName(sequence.layout),
      num_frames,
      sequence.frames.size(),
      sequence.intrinsics.width,
      sequence.intrinsics.height,
      intrinsics.width,
      intrinsics.height,
      factor,
      sequence.depth_m_per_unit,
      pose_source == "icp" ? "projective ICP" : pose_source);

  // The reader samples every factor-th pixel; the fusion takes the frames as they are.
  RgbdFusionOptions fusion_rgbd = rgbd;
  fusion_rgbd.downsample_factor = 1;
  RgbdFusion system(intrinsics, fusion_rgbd, icp, fusion);

  LogStage("Fusion");
  ProgressReporter progress("fusion", static_cast<int64_t>(num_frames));
  Trajectory trajectory;
  double load_ms = 0, preprocess_ms = 0, track_ms = 0, fuse_ms = 0;
  size_t untracked = 0, not_converged = 0;
  FuseStats totals;
  RgbdImage current = LoadRgbdFrame(sequence, 0, factor);
  SE3 first_pose, last_pose;
  const auto t_loop = std::chrono::steady_clock::now();
  for (size_t i = 0; i < num_frames; ++i) {
    // Load frame i + 1 while frame i is fused (image decoding is the slow part of I/O).
    // A loading error is kept and rethrown after both tasks: thrown inside
    // parallel_invoke it would cancel the fusion's parallel loops half-way.
    RgbdImage next;
    double next_load_ms = 0;
    std::exception_ptr load_error;
    RgbdFrameResult r;
    tbb::parallel_invoke(
        [&] {
          if (i + 1 >= num_frames) return;
          const auto t0 = std::chrono::steady_clock::now();
          try {
            next = LoadRgbdFrame(sequence, i + 1, factor);
          } catch (...) {
            load_error = std::current_exception();
          }
          next_load_ms = 1e3 * Seconds(t0);
        },
        [&] {
          std::optional<SE3> given;
          if (!poses.empty()) given = poses[i];
          if (pose_source == "icp" && i == 0 && sequence.frames[0].world_from_camera) {
            given = sequence.frames[0].world_from_camera;  // the data set's frame, if any
          }
          r = system.AddFrame(current.depth_m, current.rgb, given);
        });
    if (load_error) std::rethrow_exception(load_error);
    load_ms += next_load_ms;
    preprocess_ms += r.preprocess_ms;
    track_ms += r.track_ms;
    fuse_ms += r.fuse_ms;
    totals.merged += r.fuse.merged;
    totals.added += r.fuse.added;
    totals.skipped += r.fuse.skipped;
    totals.removed += r.fuse.removed;
    if (pose_source == "icp" && i > 0) {
      untracked += r.tracked ? 0 : 1;
      not_converged += r.icp.converged ? 0 : 1;
    }
    trajectory.PushBack({sequence.frames[i].t_ns, r.world_from_camera});
    if (i == 0) first_pose = r.world_from_camera;
    last_pose = r.world_from_camera;
    current = std::move(next);
    progress.Add();
  }
  progress.Finish();
  const double loop_s = Seconds(t_loop);

  LogStage("Writing outputs");
  const auto t_write = std::chrono::steady_clock::now();
  const SurfelMap& map = system.map();
  const size_t stable = map.NumStable();
  const double compute_ms = preprocess_ms + track_ms + fuse_ms;
  const double pixels = static_cast<double>(num_frames) * intrinsics.width * intrinsics.height;
  nlohmann::json summary;
  summary["input_path"] = input_path;
  summary["layout"] = RgbdLayoutName(sequence.layout);
  summary["pose_source"] = pose_source;
  summary["frames"] = num_frames;
  summary["width"] = intrinsics.width;
  summary["height"] = intrinsics.height;
  summary["downsample_factor"] = factor;
  summary["input_pixels"] = static_cast<uint64_t>(pixels);
  summary["input_points"] = system.num_input_points();
  // The write-up's compression ratio: surfels / (frames x downsampled pixels).
  summary["compression_ratio"] = pixels > 0 ? stable / pixels : 0.0;
  summary["frames_not_tracked"] = untracked;
  summary["frames_icp_not_converged"] = not_converged;
  summary["stage_ms"] = {{"load", load_ms},
                         {"preprocess", preprocess_ms},
                         {"tracking", track_ms},
                         {"fusion", fuse_ms},
                         {"loop_wall", 1e3 * loop_s}};
  summary["stage_ms_per_frame"] = {{"load", load_ms / num_frames},
                                   {"preprocess", preprocess_ms / num_frames},
                                   {"tracking", track_ms / num_frames},
                                   {"fusion", fuse_ms / num_frames},
                                   {"loop_wall", 1e3 * loop_s / num_frames}};
  summary["tracking_fusion_frames_per_s"] = compute_ms > 0 ? 1e3 * num_frames / compute_ms : 0.0;
  summary["wall_frames_per_s"] = loop_s > 0 ? num_frames / loop_s : 0.0;
  WriteFusionOutputs(
      trajectory,
      map,
      totals,
      [&](OutputFolder* out) {
        WriteNormalMapPng(out->File("normals_first_camera.png"), map, first_pose, intrinsics);
        WriteNormalMapPng(out->File("normals_last_camera.png"), map, last_pose, intrinsics);
      },
      options,
      std::move(summary),
      &output);
  if (pose_source == "icp" && untracked > 0) {
    LogWarning(
        "fusion: {} of {} frames kept the initial guess of tracking (too few ICP "
        "matches)",
        untracked,
        num_frames - 1);
  }
  LogInfo(
      "fusion: {} frames ({}x{}), {} surfels written (confidence >= {}; {} in the map, {} "
      "bytes each, compression {:.2f} %), tracking + fusion {:.1f} frames/s ({:.1f} ms/frame: "
      "preprocess {:.1f}, tracking {:.1f}, fusion {:.1f}), wall {:.1f} frames/s with "
      "loading; writing {:.2f} s, total {:.1f} s; wrote {}/{{trajectory.txt, surfels.ply, "
      "fusion_summary.json, normals_first_camera.png, normals_last_camera.png}}",
      num_frames,
      intrinsics.width,
      intrinsics.height,
      stable,
      fusion.output_min_confidence,
      map.size(),
      SurfelMap::BytesPerSurfel(),
      pixels > 0 ? 100.0 * stable / pixels : 0.0,
      compute_ms > 0 ? 1e3 * num_frames / compute_ms : 0.0,
      compute_ms / num_frames,
      preprocess_ms / num_frames,
      track_ms / num_frames,
      fuse_ms / num_frames,
      loop_s > 0 ? num_frames / loop_s : 0.0,
      Seconds(t_write),
      Seconds(t_start),
      output.final_path());
  return 0;
}

}  // namespace lisfm
