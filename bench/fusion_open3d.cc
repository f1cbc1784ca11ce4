// The Open3D peer of `lisfm fusion` on the same RGB-D frames (scripts/bench_fusion.sh):
// frames read with core/io/rgbd_io.h (same downsample factor, same metric depth, same
// intrinsics), then
//  - tracking: Open3D's `pipelines::odometry::ComputeRGBDOdometry` with the hybrid
//    (photometric + geometric) term, frame to frame: T_{i-1,i} = target_from_source with
//    source frame i and target frame i-1, world_from_camera_i = world_from_camera_{i-1} T_{i-1,i},
//    started at the data set's pose of frame 0 (identity without one) -> trajectory.txt;
//  - integration: `pipelines::integration::ScalableTSDFVolume` with the given poses
//    (extrinsic = camera_from_world; or the odometry poses with --integration_poses
//    odometry), colour RGB8, then ExtractTriangleMesh -> mesh.ply.
// Each stage is timed per frame (ms; the Open3D image conversions of a stage count in it);
// loading (PNG/JPEG decoding and downsampling, shared with lisfm) is timed apart.
//
// Outputs in OUTPUT_DIR: trajectory.txt (TUM, world_from_camera, frame stamps),
// groundtruth.txt (the data set's poses, TUM, when it has any), mesh.ply (binary, vertex
// colours and normals), open3d_summary.json.
//
// Usage: lisfm_fusion_open3d --input_path SEQ --output_path OUT [--downsample 2]
//          [--max_frames 0] [--layout auto] [--intrinsics_path K] [--depth_max 4.0]
//          [--depth_diff_max 0.03] [--voxel_length 0.0078125] [--sdf_trunc 0.04]
//          [--integration_poses given|odometry] [--skip_odometry 0|1] [--skip_integration 0|1]
// Defaults are Open3D's: OdometryOption() (iterations {20, 10, 5}, depth_diff_max 0.03 m,
// depth_max 4 m) and the voxel size / truncation of its RGB-D integration tutorial
// (4 m / 512, 0.04 m).
#include <fmt/format.h>
#include <open3d/camera/PinholeCameraIntrinsic.h>
#include <open3d/geometry/Image.h>
#include <open3d/geometry/RGBDImage.h>
#include <open3d/geometry/TriangleMesh.h>
#include <open3d/io/TriangleMeshIO.h>
#include <open3d/pipelines/integration/ScalableTSDFVolume.h>
#include <open3d/pipelines/odometry/Odometry.h>
#include <open3d/utility/Logging.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/rgbd_io.h"
#include "core/io/trajectory_io.h"

namespace lisfm {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point a) {
  return std::chrono::duration<double, std::milli>(Clock::now() - a).count();
}

struct Args {
  std::string input_path, output_path, intrinsics_path;
  std::string layout = "auto";
  std::string integration_poses = "given";
  int downsample = 2;
  int max_frames = 0;  // 0 = all
  double depth_max = 4.0;
  double depth_diff_max = 0.03;
  double voxel_length = 4.0 / 512.0;
  double sdf_trunc = 0.04;
  bool skip_odometry = false, skip_integration = false;
};

constexpr const char* kUsage =
    "usage: lisfm_fusion_open3d --input_path SEQ --output_path OUT [--downsample 2] "
    "[--max_frames 0] [--layout auto|lisfm|tum|7scenes] [--intrinsics_path K] "
    "[--depth_max 4.0] [--depth_diff_max 0.03] [--voxel_length 0.0078125] [--sdf_trunc 0.04] "
    "[--integration_poses given|odometry] [--skip_odometry 0|1] [--skip_integration 0|1]";

double ParseNumber(const std::string& name, const std::string& value) {
  double v = 0;
  if (!ParseDouble(value, &v)) throw UsageError("--" + name + " " + value + ": not a number");
  return v;
}

Args ParseArgs(int argc, char** argv) {
  Args a;
  std::map<std::string, std::string> kv;
  for (int i = 1; i < argc; ++i) {
    const std::string key = argv[i];
    if (key == "-h" || key == "--help") throw UsageError(kUsage);
    if (key.rfind("--", 0) != 0 || i + 1 >= argc) {
      throw UsageError("expected --option value, found '" + key + "'\n" + kUsage);
    }
    kv[key.substr(2)] = argv[++i];
  }
  for (const auto& [k, v] : kv) {
    if (k == "input_path")
      a.input_path = v;
    else if (k == "output_path")
      a.output_path = v;
    else if (k == "intrinsics_path")
      a.intrinsics_path = v;
    else if (k == "layout")
      a.layout = v;
    else if (k == "integration_poses")
      a.integration_poses = v;
    else if (k == "downsample")
      a.downsample = static_cast<int>(ParseNumber(k, v));
    else if (k == "max_frames")
      a.max_frames = static_cast<int>(ParseNumber(k, v));
    else if (k == "depth_max")
      a.depth_max = ParseNumber(k, v);
    else if (k == "depth_diff_max")
      a.depth_diff_max = ParseNumber(k, v);
    else if (k == "voxel_length")
      a.voxel_length = ParseNumber(k, v);
    else if (k == "sdf_trunc")
      a.sdf_trunc = ParseNumber(k, v);
    else if (k == "skip_odometry")
      a.skip_odometry = ParseNumber(k, v) != 0;
    else if (k == "skip_integration")
      a.skip_integration = ParseNumber(k, v) != 0;
    else
      throw UsageError("unknown option --" + k + "\n" + kUsage);
  }
  if (a.input_path.empty() || a.output_path.empty()) {
    throw UsageError("--input_path and --output_path are required\n" + std::string(kUsage));
  }
  if (a.downsample < 1 || a.downsample > 16) throw UsageError("--downsample must be in [1, 16]");
  if (a.max_frames < 0) throw UsageError("--max_frames must be >= 0");
  if (!(a.depth_max > 0) || !(a.depth_diff_max > 0) || !(a.voxel_length > 0) ||
      !(a.sdf_trunc > 0)) {
    throw UsageError("--depth_max, --depth_diff_max, --voxel_length, --sdf_trunc must be > 0");
  }
  if (a.integration_poses != "given" && a.integration_poses != "odometry") {
    throw UsageError("--integration_poses must be given or odometry");
  }
  return a;
}

// Open3D images holding one loaded frame: depth float metres (1 channel, 4 bytes), colour
// RGB8.
void ToOpen3d(const RgbdImage& frame,
              open3d::geometry::Image* depth,
              open3d::geometry::Image* color) {
  depth->Prepare(frame.width, frame.height, 1, 4);
  std::memcpy(depth->data_.data(), frame.depth_m.data(), frame.depth_m.size() * sizeof(float));
  color->Prepare(frame.width, frame.height, 3, 1);
  std::memcpy(color->data_.data(), frame.rgb.data(), frame.rgb.size());
}

struct Stats {
  double total = 0;
  size_t count = 0;
  std::vector<double> values;
  void Add(double ms) {
    total += ms;
    ++count;
    values.push_back(ms);
  }
  double Mean() const { return count ? total / count : 0.0; }
  double Median() const {
    if (values.empty()) return 0.0;
    std::vector<double> v = values;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  }
};

int Run(const Args& args) {
  open3d::utility::SetVerbosityLevel(open3d::utility::VerbosityLevel::Error);
  RgbdReadOptions read_options;
  read_options.layout = ParseRgbdLayout(args.layout);
  read_options.intrinsics_path = args.intrinsics_path;
  const RgbdSequence seq = ReadRgbdSequence(args.input_path, read_options);
  const size_t num_frames = args.max_frames > 0
                                ? std::min<size_t>(seq.frames.size(), args.max_frames)
                                : seq.frames.size();
  const bool use_given = args.integration_poses == "given";
  if (!args.skip_integration && use_given) {
    for (size_t i = 0; i < num_frames; ++i) {
      if (!seq.frames[i].world_from_camera) {
        throw InputError(seq.frames[i].depth_path,
                         "pose",
                         "integration with the given poses, but this frame has none");
      }
    }
  }
  if (!args.skip_integration && !use_given && args.skip_odometry) {
    throw UsageError("--integration_poses odometry needs the odometry (--skip_odometry 0)");
  }
  const RgbdIntrinsics k = DownsampleIntrinsics(seq.intrinsics, args.downsample);
  const open3d::camera::PinholeCameraIntrinsic intrinsic(k.width, k.height, k.fx, k.fy, k.cx, k.cy);
  std::fprintf(stderr,
               "open3d: %zu frames of %s (%s), %d x %d, intrinsics from %s\n",
               num_frames,
               args.input_path.c_str(),
               RgbdLayoutName(seq.layout).c_str(),
               k.width,
               k.height,
               seq.intrinsics_source.c_str());

  using open3d::pipelines::odometry::ComputeRGBDOdometry;
  using open3d::pipelines::odometry::OdometryOption;
  using open3d::pipelines::odometry::RGBDOdometryJacobianFromHybridTerm;
  OdometryOption odo_option;
  odo_option.depth_max_ = args.depth_max;
  odo_option.depth_diff_max_ = args.depth_diff_max;
  open3d::pipelines::integration::ScalableTSDFVolume volume(
      args.voxel_length, args.sdf_trunc, open3d::pipelines::integration::TSDFVolumeColorType::RGB8);

  Stats load, odometry, integration;
  size_t odometry_failures = 0;
  std::vector<StampedPose> trajectory;
  std::shared_ptr<open3d::geometry::RGBDImage> previous;
  SE3 world_from_camera =
      seq.frames[0].world_from_camera ? *seq.frames[0].world_from_camera : SE3::Identity();
  for (size_t i = 0; i < num_frames; ++i) {
    auto t0 = Clock::now();
    const RgbdImage frame = LoadRgbdFrame(seq, i, args.downsample);
    open3d::geometry::Image depth, color;
    ToOpen3d(frame, &depth, &color);
    load.Add(MsSince(t0));

    if (!args.skip_odometry) {
      t0 = Clock::now();
      // Intensity (float gray) + float depth, truncated at depth_max as the odometry does.
      auto current = open3d::geometry::RGBDImage::CreateFromColorAndDepth(
          color, depth, /*depth_scale=*/1.0, args.depth_max, /*convert_rgb_to_intensity=*/true);
      if (previous) {
        const auto [success, target_from_source, information] =
            ComputeRGBDOdometry(*current,
                                *previous,
                                intrinsic,
                                Eigen::Matrix4d::Identity(),
                                RGBDOdometryJacobianFromHybridTerm(),
                                odo_option);
        (void)information;
        if (success) {
          world_from_camera = world_from_camera * SE3(Mat4(target_from_source));
        } else {
          ++odometry_failures;  // constant position: the previous pose is kept
        }
      }
      previous = current;
      odometry.Add(MsSince(t0));
      trajectory.push_back({seq.frames[i].t_ns, world_from_camera});
    }

    if (!args.skip_integration) {
      t0 = Clock::now();
      auto rgbd = open3d::geometry::RGBDImage::CreateFromColorAndDepth(
          color, depth, 1.0, args.depth_max, /*convert_rgb_to_intensity=*/false);
      const SE3 pose = use_given ? *seq.frames[i].world_from_camera : world_from_camera;
      volume.Integrate(*rgbd, intrinsic, pose.Inverse().Matrix());
      integration.Add(MsSince(t0));
    }
    if ((i + 1) % 50 == 0 || i + 1 == num_frames) {
      std::fprintf(stderr, "open3d: frame %zu / %zu\n", i + 1, num_frames);
    }
  }

  CreateDirs(args.output_path);
  nlohmann::ordered_json summary;
  summary["input_path"] = args.input_path;
  summary["layout"] = RgbdLayoutName(seq.layout);
  summary["frames"] = num_frames;
  summary["width"] = k.width;
  summary["height"] = k.height;
  summary["downsample"] = args.downsample;
  summary["load_ms_per_frame"] = load.Mean();
  double extraction_ms = 0;
  if (!args.skip_odometry) {
    WriteTum(JoinPaths(args.output_path, "trajectory.txt"), Trajectory(trajectory));
    summary["odometry_ms_per_frame"] = odometry.Mean();
    summary["odometry_ms_median"] = odometry.Median();
    summary["odometry_failures"] = odometry_failures;
  }
  if (!args.skip_integration) {
    const auto t0 = Clock::now();
    const std::shared_ptr<open3d::geometry::TriangleMesh> mesh = volume.ExtractTriangleMesh();
    mesh->ComputeVertexNormals();
    extraction_ms = MsSince(t0);
    const std::string mesh_path = JoinPaths(args.output_path, "mesh.ply");
    if (!open3d::io::WriteTriangleMesh(mesh_path, *mesh, /*write_ascii=*/false)) {
      throw InputError(mesh_path, "file", "Open3D could not write the mesh");
    }
    summary["integration_ms_per_frame"] = integration.Mean();
    summary["integration_ms_median"] = integration.Median();
    summary["integration_poses"] = args.integration_poses;
    summary["extraction_ms"] = extraction_ms;
    summary["mesh_vertices"] = mesh->vertices_.size();
    summary["mesh_triangles"] = mesh->triangles_.size();
    summary["voxel_length_m"] = args.voxel_length;
    summary["sdf_trunc_m"] = args.sdf_trunc;
  }
  // Tracking + integration per frame; the one mesh extraction at the end is an output step
  // (as writing surfels.ply is for lisfm) and is reported apart.
  const double total_ms = odometry.total + integration.total;
  summary["odometry_plus_integration_ms_per_frame"] = total_ms / num_frames;
  summary["frames_per_s"] = total_ms > 0 ? 1000.0 * num_frames / total_ms : 0.0;
  if (seq.NumGivenPoses() > 0) {
    WriteTum(JoinPaths(args.output_path, "groundtruth.txt"), seq.GivenTrajectory());
  }
  WriteFileAtomically(JoinPaths(args.output_path, "open3d_summary.json"), summary.dump(2) + "\n");
  std::printf(
      "open3d: %zu frames %dx%d: load %.1f ms/frame, odometry %.1f ms/frame (%zu failures), "
      "integration %.1f ms/frame, %.1f frames/s (odometry + integration), mesh extraction "
      "%.0f ms; %s\n",
      num_frames,
      k.width,
      k.height,
      load.Mean(),
      odometry.Mean(),
      odometry_failures,
      integration.Mean(),
      total_ms > 0 ? 1000.0 * num_frames / total_ms : 0.0,
      extraction_ms,
      args.output_path.c_str());
  return 0;
}

}  // namespace
}  // namespace lisfm

int main(int argc, char** argv) {
  try {
    return lisfm::Run(lisfm::ParseArgs(argc, argv));
  } catch (const lisfm::UsageError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
