// `lisfm pose_slam`: the batch back end on lio's output (lio/pose_slam/pose_slam.h):
// Bayesian ICP pairs, IMU preintegration with piecewise-constant bias, zero
// velocity at rests, one pose graph; writes the corrected trajectory, the
// optimised keyframes, the kept ICP constraints, the keyframe covariances, the
// map rebuilt from the optimised keyframes and a JSON summary.
// Under `mpirun -np N` the ICP pairs are split across the ranks (core/mpi);
// rank 0 gets every pair's result, solves and writes; the outputs are those of
// one process, byte for byte.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/keyframe_covariances_io.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/trajectory_io.h"
#include "core/logging.h"
#include "core/mpi/mpi_world.h"
#include "core/options.h"
#include "core/point_cloud.h"
#include "core/progress.h"
#include "importers/sequence.h"
#include "lio/pose_slam/pose_slam.h"

namespace lisfm {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

nlohmann::json SolveJson(const PoseGraphSolveSummary& s) {
  return {{"converged", s.converged},
          {"iterations", s.iterations},
          {"initial_cost", s.initial_cost},
          {"final_cost", s.final_cost},
          {"seconds", s.seconds},
          {"linear_solver", s.linear_solver},
          {"message", s.message}};
}

nlohmann::json SummaryJson(const PoseSlamResult& r, double map_s, double total_s) {
  nlohmann::json j;
  j["keyframes"] = r.keyframe_times.size();
  j["nodes"] = r.num_nodes;
  j["rest_nodes"] = r.num_rest_nodes;
  j["biases"] = r.num_biases;
  j["factors"] = {{"odometry", r.num_odometry_factors},
                  {"icp", r.num_icp_factors},
                  {"imu", r.num_imu_factors},
                  {"bias_random_walk", r.num_bias_random_walk_factors},
                  {"zero_velocity", r.num_zero_velocity_factors},
                  {"stationary_pose", r.num_stationary_pose_factors}};
  const PoseSlamPairCounts& p = r.pairs;
  j["pairs"] = {{"candidates", p.candidates},
                {"inside_stationary", p.inside_stationary},
                {"registered", p.registered},
                {"rejected_failed", p.failed},
                {"rejected_unconverged", p.unconverged},
                {"rejected_degenerate", p.degenerate},
                {"rejected_lio_difference", p.lio_difference},
                {"rejected_residual", p.residual_outliers},
                {"kept", p.kept}};
  nlohmann::json periods = nlohmann::json::array();
  for (const StationaryPeriod& s : r.stationary_periods) {
    periods.push_back({{"start_ns", s.start_ns}, {"end_ns", s.end_ns}});
  }
  j["stationary_periods"] = periods;
  j["solve"] = SolveJson(r.solve);
  if (r.second_pass) j["second_solve"] = SolveJson(r.second_solve);
  j["final_cost"] = r.second_pass ? r.second_solve.final_cost : r.solve.final_cost;
  nlohmann::json biases = nlohmann::json::array();
  for (const Vec6& b : r.biases) {
    biases.push_back({{"gyro", {b(0), b(1), b(2)}}, {"accel", {b(3), b(4), b(5)}}});
  }
  j["biases"] = biases;
  j["gravity_direction"] = {
      r.gravity_direction.x(), r.gravity_direction.y(), r.gravity_direction.z()};
  const PoseSlamTimings& t = r.timings;
  j["seconds"] = {{"load_clouds", t.load_clouds},
                  {"candidates", t.candidates},
                  {"icp", t.icp},
                  {"build", t.build},
                  {"solve", t.solve},
                  {"second_solve", t.second_solve},
                  {"covariances", t.covariances},
                  {"map", map_s},
                  {"total", total_s}};
  return j;
}

}  // namespace

int RunPoseSlam(int argc, char** argv) {
  OptionManager options("lisfm pose_slam",
                        "batch pose graph on lio's output: Bayesian ICP pairs, IMU "
                        "preintegration with piecewise-constant bias, zero velocity at rests");
  std::string input_path, lio_path, output_path;
  bool overwrite = false;
  int lidar = 0;
  double map_voxel = 0.2;
  PoseSlamOptions pose_slam;
  options.AddRequiredString("input_path", &input_path, "sequence folder (rig.yaml, imu0/)");
  options.AddRequiredString(
      "lio_path", &lio_path, "`lisfm lio` output folder (trajectory.txt, keyframes/)");
  options.AddRequiredString("output_path", &output_path, "output folder");
  options.AddBool("overwrite", &overwrite, "replace an earlier lisfm output at --output_path");
  options.AddInt("lidar",
                 &lidar,
                 "index of the LiDAR of the keyframe clouds (its extrinsic)",
                 OptionRange::AtLeast(0));
  options.AddDouble("map_voxel_size",
                    &map_voxel,
                    "m, voxel size of the written map.pcd (0 = no downsampling)",
                    OptionRange::AtLeast(0));
  AddPoseSlamOptions(&options, &pose_slam);
  if (!options.Parse(argc, argv)) return 0;
  pose_slam.solver.verbose = GetLogLevel() <= LogLevel::kDebug;
  if (!mpi::IsRoot()) SetLogLevel(LogLevel::kError);                 // rank 0 reports
  std::optional<OutputFolder> output_folder;                         // rank 0 writes
  if (mpi::IsRoot()) output_folder.emplace(output_path, overwrite);  // checked before the work

  const auto start = std::chrono::steady_clock::now();
  LogStage("pose_slam: reading " + input_path + " and " + lio_path);
  const Sequence seq = ReadSequence(input_path);
  if (lidar >= static_cast<int>(seq.rig.lidars.size())) {
    throw InputError(
        input_path + "/rig.yaml",
        "lidars",
        fmt::format("--lidar {} but the rig has {} LiDAR(s)", lidar, seq.rig.lidars.size()));
  }
  PoseSlamInput input;
  input.lio = ReadLioOutput(lio_path);
  input.imu = seq.imu;
  input.imu_noise = seq.rig.imu;
  input.imu_from_lidar = seq.rig.lidars[lidar].imu_from_lidar;
  input.imu_path = JoinPaths(input_path, "imu0/data.csv");
  if (input.imu.empty()) throw InputError(input.imu_path, "", "no IMU samples");
  {
    // An IMU that reports in g (lio/imu.h ImuInitialization::accel_scale).
    const size_t n = std::min<size_t>(input.imu.size(), 200);
    Vec3 mean = Vec3::Zero();
    for (size_t k = 0; k < n; ++k) mean += input.imu[k].accel / static_cast<double>(n);
    if (mean.norm() < 3.0) {
      for (ImuSample& s : input.imu) s.accel *= pose_slam.gravity;
    }
  }
  LogInfo("pose_slam: {} keyframes, {} lio poses, {} IMU samples",
          input.lio.keyframes.size(),
          input.lio.trajectory.size(),
          input.imu.size());

  std::unique_ptr<ProgressReporter> progress;
  PoseSlamCallbacks callbacks;
  callbacks.on_stage = [&](const std::string& stage) {
    if (progress) progress->Finish();
    LogStage("pose_slam: " + stage);
  };
  callbacks.on_icp_start = [&](int64_t total) {
    progress = std::make_unique<ProgressReporter>("pose_slam: Bayesian ICP pairs", total);
  };
  callbacks.on_icp_pair = [&] { progress->Add(); };
  if (mpi::Active()) callbacks.pair_runner = mpi::RunWorkList;
  const PoseSlamResult result = RunPoseSlam(input, pose_slam, callbacks);
  if (progress) progress->Finish();
  if (result.share_only || !mpi::IsRoot()) return 0;  // this rank's pairs went to rank 0
  const OutputFolder& output = *output_folder;

  LogStage("pose_slam: writing " + output_path);
  const auto map_start = std::chrono::steady_clock::now();
  PointCloud map;
  for (size_t k = 0; k < input.lio.keyframes.size(); ++k) {
    const PointCloud cloud = ReadPcd(input.lio.keyframes[k].cloud_path);
    const PointCloud world = TransformCloud(cloud, result.keyframe_poses[k]);
    map.points.insert(map.points.end(), world.points.begin(), world.points.end());
    if (map_voxel > 0 && (k % 32 == 31 || k + 1 == input.lio.keyframes.size())) {
      map = VoxelDownsample(map, map_voxel);
    }
  }
  const double map_s = SecondsSince(map_start);

  WriteTum(output.File("trajectory.txt"), result.trajectory);
  Trajectory keyframes;
  for (size_t k = 0; k < result.keyframe_times.size(); ++k) {
    keyframes.PushBack({result.keyframe_times[k], result.keyframe_poses[k]});
  }
  WriteTum(output.File("keyframes.txt"), keyframes);
  WriteLidarConstraints(result.constraints, output.File("constraints.txt"));
  std::vector<KeyframeCovariance> covariances;
  for (size_t k = 0; k < result.keyframe_times.size(); ++k) {
    covariances.push_back({result.keyframe_times[k], result.keyframe_covariances[k]});
  }
  WriteKeyframeCovariances(covariances, output.File("keyframe_covariances.txt"));
  WritePcd(output.File("map.pcd"), map);
  const double total_s = SecondsSince(start);
  WriteFileAtomically(output.File("pose_slam_summary.json"),
                      SummaryJson(result, map_s, total_s).dump(2) + "\n");
  options.WriteConfig(output.File("pose_slam_config.yaml"));
  output_folder->Commit();

  const PoseSlamPairCounts& p = result.pairs;
  LogInfo(
      "pose_slam summary: {} keyframes ({} nodes, {} rests, {} bias variables); pairs {} "
      "candidates, {} inside rests, {} registered, kept {} (rejected: {} failed, {} unconverged, "
      "{} degenerate, {} off lio, {} residual outliers); factors: {} odometry, {} ICP, {} IMU, {} "
      "zero velocity; final cost {:.6g} ({}); {:.1f} s (ICP {:.1f} s, solve {:.1f} s, "
      "covariances {:.1f} s); outputs in {}",
      result.keyframe_times.size(),
      result.num_nodes,
      result.stationary_periods.size(),
      result.num_biases,
      p.candidates,
      p.inside_stationary,
      p.registered,
      p.kept,
      p.failed,
      p.unconverged,
      p.degenerate,
      p.lio_difference,
      p.residual_outliers,
      result.num_odometry_factors,
      result.num_icp_factors,
      result.num_imu_factors,
      result.num_zero_velocity_factors,
      result.second_pass ? result.second_solve.final_cost : result.solve.final_cost,
      result.second_pass ? result.second_solve.message : result.solve.message,
      total_s,
      result.timings.icp,
      result.timings.solve + result.timings.second_solve,
      result.timings.covariances,
      output_path);
  return 0;
}

}  // namespace lisfm
