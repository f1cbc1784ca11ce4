#include "lio/pose_slam/pose_slam.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/normal_prior.h>
#include <ceres/sphere_manifold.h>
#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numeric>
#include <set>
#include <utility>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/trajectory_io.h"
#include "core/option_check.h"
#include "core/work_list.h"
#include "icp/icp.h"
#include "icp/nearest_neighbors.h"

namespace lisfm {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void Stage(const PoseSlamCallbacks& callbacks, const std::string& name) {
  if (callbacks.on_stage) callbacks.on_stage(name);
}

// The registration clouds of one keyframe, in the LiDAR frame.
struct KeyframeClouds {
  PointSet source;  // source_voxel_size
  PointSet target;  // target_voxel_size
};

// One registered candidate pair.
struct PairResult {
  enum class Outcome { kKept, kFailed, kUnconverged, kDegenerate, kLioDifference };
  Outcome outcome = Outcome::kFailed;
  SE3 i_from_j;                    // IMU frames
  Mat6 covariance = Mat6::Zero();  // right perturbation of i_from_j (IMU frames)
};

// A pair's result as bytes (core/work_list.h), bit for bit.
std::string EncodePairResult(const PairResult& r) {
  ByteWriter writer;
  writer.Put<int32_t>(static_cast<int32_t>(r.outcome));
  writer.PutSe3(r.i_from_j);
  writer.PutMatrix(r.covariance);
  return writer.Take();
}

PairResult DecodePairResult(const std::string& bytes) {
  ByteReader reader(bytes);
  PairResult r;
  r.outcome = static_cast<PairResult::Outcome>(reader.Get<int32_t>());
  r.i_from_j = reader.GetSe3();
  r.covariance = reader.GetMatrix<Mat6>();
  THROW_CHECK(reader.AtEnd());
  return r;
}

// lio's velocity at trajectory sample k by central differences (m/s).
Vec3 LioVelocity(const Trajectory& trajectory, int k) {
  const int n = static_cast<int>(trajectory.size());
  const int a = std::max(0, k - 1), b = std::min(n - 1, k + 1);
  if (a == b) return Vec3::Zero();
  return (trajectory[b].pose.translation() - trajectory[a].pose.translation()) /
         NsToSeconds(trajectory[b].t_ns - trajectory[a].t_ns);
}

PairResult RegisterPair(const KeyframeClouds& source,
                        const KdTreeTarget& target,
                        const SE3& lio_i_from_j,
                        const SE3& imu_from_lidar,
                        const PoseSlamOptions& options,
                        uint64_t seed) {
  PairResult out;
  const SE3 lidar_from_imu = imu_from_lidar.Inverse();
  const SE3 initial = lidar_from_imu * lio_i_from_j * imu_from_lidar;
  BayesianIcpOptions bayes = options.bayesian;
  bayes.sgld.seed = seed;
  BayesianIcpResult result;
  try {
    result = RegisterBayesian(source.source, target, initial, bayes);
  } catch (const InputError&) {
    return out;  // too few matches: kFailed
  }
  if (result.icp.degenerate) {
    out.outcome = PairResult::Outcome::kDegenerate;
    return out;
  }
  if (!result.icp.converged) {
    out.outcome = PairResult::Outcome::kUnconverged;
    return out;
  }
  // T_imu = E T_lidar E^-1 with E = imu_from_lidar; on the right perturbation
  // T_lidar = T^ Exp(xi) gives T_imu = T^_imu Exp(Ad(E) xi).
  out.i_from_j = imu_from_lidar * result.posterior.mean * lidar_from_imu;
  const Mat6 adjoint = imu_from_lidar.Adjoint();
  out.covariance = adjoint * result.posterior.covariance * adjoint.transpose();
  out.covariance = 0.5 * (out.covariance + out.covariance.transpose());
  const Eigen::LLT<Mat6> llt(out.covariance);
  if (llt.info() != Eigen::Success || !out.covariance.allFinite()) return out;  // kFailed
  const SE3 difference = lio_i_from_j.Inverse() * out.i_from_j;
  if (difference.translation().norm() > options.max_translation_difference ||
      so3::Log(difference.rotation()).norm() > options.max_rotation_difference_deg * kDegToRad) {
    out.outcome = PairResult::Outcome::kLioDifference;
    return out;
  }
  out.outcome = PairResult::Outcome::kKept;
  return out;
}

// Covariance (9x9, [e_R; e_v; e_p]) of the IMU errors the noise model leaves
// out over [t_i, t_j] (dt), per axis (PoseSlamOptions::imu_*_error and
// bias_instability_*): sigma_R^2 = (imu_gyro_error integral |gyro| dt)^2 +
// (bias_instability_gyro dt)^2, sigma_v^2 = (imu_accel_error integral |accel| dt)^2
// + (bias_instability_accel dt)^2, sigma_p = sigma_v dt / 2 (rectangle rule over
// the samples inside the interval).
Mat9 UnmodelledImuCovariance(const std::vector<ImuSample>& imu,
                             TimestampNs t_i_ns,
                             TimestampNs t_j_ns,
                             const PoseSlamOptions& options) {
  auto it = std::lower_bound(
      imu.begin(), imu.end(), t_i_ns, [](const ImuSample& s, TimestampNs t) { return s.t_ns < t; });
  double angle = 0.0, velocity = 0.0;
  for (; it != imu.end() && it + 1 != imu.end() && it->t_ns < t_j_ns; ++it) {
    const double h = NsToSeconds(std::min((it + 1)->t_ns, t_j_ns) - it->t_ns);
    angle += it->gyro.norm() * h;
    velocity += it->accel.norm() * h;
  }
  const double dt = NsToSeconds(t_j_ns - t_i_ns);
  const double sigma_r =
      std::hypot(options.imu_gyro_error * angle, options.bias_instability_gyro * dt);
  const double sigma_v =
      std::hypot(options.imu_accel_error * velocity, options.bias_instability_accel * dt);
  const double sigma_p = sigma_v * dt / 2.0;
  Mat9 covariance = Mat9::Zero();
  covariance.diagonal() << Vec3::Constant(sigma_r * sigma_r), Vec3::Constant(sigma_v * sigma_v),
      Vec3::Constant(sigma_p * sigma_p);
  return covariance;
}

}  // namespace

BayesianIcpOptions PoseSlamBayesianIcpOptions() {
  BayesianIcpOptions options;
  options.icp.min_planarity = 0.0;  // why: see pose_slam.h
  options.icp.min_normal_contrast = 0.5;
  options.icp.visibility_follows_surface = true;
  options.noise_sigma_scale = 1.168;
  return options;
}

bool PoseSlamOptions::Check() const {
  CHECK_OPTION_GE(knn, 1);
  CHECK_OPTION_GE(min_index_step, 1);
  CHECK_OPTION_GE(max_index_step, min_index_step);
  CHECK_OPTION_GT(source_voxel_size, 0.0);
  CHECK_OPTION_GT(target_voxel_size, 0.0);
  CHECK_OPTION_GT(max_translation_difference, 0.0);
  CHECK_OPTION_GT(max_rotation_difference_deg, 0.0);
  CHECK_OPTION_GT(outlier_chi2, 0.0);
  CHECK_OPTION_GT(odometry_sigma_rotation_deg, 0.0);
  CHECK_OPTION_GE(odometry_sigma_rotation_deg_per_m, 0.0);
  CHECK_OPTION_GT(odometry_sigma_translation, 0.0);
  CHECK_OPTION_GE(odometry_sigma_translation_per_m, 0.0);
  CHECK_OPTION_GE(imu_gyro_error, 0.0);
  CHECK_OPTION_GE(imu_accel_error, 0.0);
  CHECK_OPTION_GE(bias_instability_gyro, 0.0);
  CHECK_OPTION_GE(bias_instability_accel, 0.0);
  CHECK_OPTION_GT(bias_prior_gyro, 0.0);
  CHECK_OPTION_GT(bias_prior_accel, 0.0);
  CHECK_OPTION_GT(gravity, 0.0);
  CHECK_OPTION_MSG(num_threads, num_threads == -1 || num_threads >= 1, "-1 or >= 1");
  return icp_loss.Check() && bayesian.Check() && stationary.Check() && zero_velocity.Check() &&
         preintegration.Check() && solver.Check();
}

LioOutput ReadLioOutput(const std::string& lio_path) {
  LioOutput lio;
  const std::string trajectory_path = JoinPaths(lio_path, "trajectory.txt");
  if (!FileExists(trajectory_path)) {
    throw InputError(lio_path, "trajectory.txt", "not found: expected a `lisfm lio` output folder");
  }
  lio.trajectory = ReadTum(trajectory_path);
  const std::string csv_path = JoinPaths(lio_path, "keyframes/keyframes.csv");
  if (!FileExists(csv_path)) {
    throw InputError(lio_path,
                     "keyframes/keyframes.csv",
                     "not found: the lio output has no keyframes (run `lisfm lio` with "
                     "--write_keyframes 1)");
  }
  std::ifstream in(csv_path);
  if (!in) throw InputError(csv_path, "", "cannot open");
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty() || line[0] == '#') continue;
    const std::string where = fmt::format("line {}", line_number);
    const std::vector<std::string> fields = SplitString(line, ",");
    if (fields.size() != 8) {
      throw InputError(
          csv_path,
          where,
          fmt::format("expected 8 fields t_ns,tx,ty,tz,qx,qy,qz,qw, found {}", fields.size()));
    }
    LioKeyframe keyframe;
    double v[7];
    try {
      size_t used = 0;
      keyframe.t_ns = std::stoll(fields[0], &used);
      if (used != fields[0].size()) throw std::invalid_argument(fields[0]);
      for (int k = 0; k < 7; ++k) {
        v[k] = std::stod(fields[k + 1], &used);
        if (used != fields[k + 1].size() || !std::isfinite(v[k])) {
          throw std::invalid_argument(fields[k + 1]);
        }
      }
    } catch (const std::exception&) {
      throw InputError(csv_path, where, "expected an integer stamp (ns) and 7 finite numbers");
    }
    const Quat q(v[6], v[3], v[4], v[5]);
    if (std::abs(q.norm() - 1.0) > 1e-6) {
      throw InputError(
          csv_path, where, fmt::format("quaternion norm {:.9f}, expected 1", q.norm()));
    }
    keyframe.world_from_imu = SE3(q.normalized(), Vec3(v[0], v[1], v[2]));
    if (!lio.keyframes.empty() && keyframe.t_ns <= lio.keyframes.back().t_ns) {
      throw InputError(csv_path,
                       where,
                       fmt::format("stamp {} does not increase (previous {})",
                                   keyframe.t_ns,
                                   lio.keyframes.back().t_ns));
    }
    const int k = lio.trajectory.Nearest(keyframe.t_ns, 0);
    if (k < 0) {
      throw InputError(csv_path,
                       where,
                       fmt::format("keyframe stamp {} ns has no pose in {}: the keyframes do not "
                                   "belong to this trajectory",
                                   keyframe.t_ns,
                                   trajectory_path));
    }
    const SE3& pose = lio.trajectory[k].pose;
    const double dt = (pose.translation() - keyframe.world_from_imu.translation()).norm();
    const double dr = so3::AngularDistance(pose.rotation(), keyframe.world_from_imu.rotation());
    if (dt > 1e-6 || dr > 1e-6) {
      throw InputError(csv_path,
                       where,
                       fmt::format("keyframe pose at {} ns differs from {} by {:.3g} m, {:.3g} "
                                   "rad: the keyframes do not belong to this trajectory",
                                   keyframe.t_ns,
                                   trajectory_path,
                                   dt,
                                   dr));
    }
    keyframe.cloud_path = JoinPaths(lio_path, fmt::format("keyframes/{}.pcd", keyframe.t_ns));
    if (!FileExists(keyframe.cloud_path)) {
      throw InputError(csv_path, where, "keyframe cloud " + keyframe.cloud_path + " not found");
    }
    lio.keyframes.push_back(std::move(keyframe));
  }
  if (lio.keyframes.size() < 2) {
    throw InputError(
        csv_path, "", fmt::format("expected at least 2 keyframes, found {}", lio.keyframes.size()));
  }
  return lio;
}

std::vector<std::pair<int, int>> KnnCandidatePairs(const std::vector<Vec3>& positions,
                                                   int knn,
                                                   int min_index_step,
                                                   int max_index_step) {
  const int n = static_cast<int>(positions.size());
  std::set<std::pair<int, int>> pairs;
  std::vector<std::pair<double, int>> distances;
  for (int i = 0; i < n; ++i) {
    distances.clear();
    for (int j = 0; j < n; ++j) {
      if (j != i) distances.emplace_back((positions[j] - positions[i]).squaredNorm(), j);
    }
    const int k = std::min<int>(knn, static_cast<int>(distances.size()));
    // Ties broken by index (pair order): deterministic.
    std::partial_sort(distances.begin(), distances.begin() + k, distances.end());
    for (int m = 0; m < k; ++m) {
      const int j = distances[m].second;
      const int step = std::abs(j - i);
      if (step >= min_index_step && step <= max_index_step) {
        pairs.emplace(std::min(i, j), std::max(i, j));
      }
    }
  }
  return {pairs.begin(), pairs.end()};
}

Trajectory CorrectTrajectory(const Trajectory& lio,
                             const std::vector<TimestampNs>& node_times,
                             const std::vector<SE3>& lio_node_poses,
                             const std::vector<SE3>& optimised_node_poses) {
  THROW_CHECK(!node_times.empty());
  THROW_CHECK_EQ(node_times.size(), lio_node_poses.size());
  THROW_CHECK_EQ(node_times.size(), optimised_node_poses.size());
  std::vector<SE3> corrections(node_times.size());
  for (size_t k = 0; k < node_times.size(); ++k) {
    corrections[k] = optimised_node_poses[k] * lio_node_poses[k].Inverse();
  }
  Trajectory out;
  for (const StampedPose& p : lio.poses()) {
    const auto it = std::upper_bound(node_times.begin(), node_times.end(), p.t_ns);
    SE3 correction;
    if (it == node_times.begin()) {
      correction = corrections.front();
    } else if (it == node_times.end()) {
      correction = corrections.back();
    } else {
      const size_t b = it - node_times.begin(), a = b - 1;
      const double s = static_cast<double>(p.t_ns - node_times[a]) /
                       static_cast<double>(node_times[b] - node_times[a]);
      correction = Interpolate(corrections[a], corrections[b], s);
    }
    out.PushBack({p.t_ns, correction * p.pose});
  }
  return out;
}

namespace {

PoseSlamResult RunPoseSlamInArena(const PoseSlamInput& input,
                                  const PoseSlamOptions& options,
                                  const PoseSlamCallbacks& callbacks) {
  PoseSlamResult result;
  const Trajectory& lio = input.lio.trajectory;
  const std::vector<LioKeyframe>& keyframes = input.lio.keyframes;
  const int num_keyframes = static_cast<int>(keyframes.size());
  THROW_CHECK_GE(num_keyframes, 2);

  // Stationary periods (IMU) and the nodes: keyframes plus, with the zero-velocity
  // factors, lio's first and last scan inside each rest.
  result.stationary_periods = DetectStationaryPeriods(input.imu, options.stationary);
  struct Node {
    TimestampNs t_ns;
    SE3 lio_pose;
    int keyframe;  // index into keyframes, -1 for a rest node
  };
  std::vector<Node> nodes;
  for (int k = 0; k < num_keyframes; ++k) {
    nodes.push_back({keyframes[k].t_ns, keyframes[k].world_from_imu, k});
  }
  if (options.use_imu && options.use_zero_velocity) {
    std::set<TimestampNs> keyframe_stamps;
    for (const LioKeyframe& k : keyframes) keyframe_stamps.insert(k.t_ns);
    for (const StationaryPeriod& period : result.stationary_periods) {
      int first = -1, last = -1;
      for (int s = 0; s < static_cast<int>(lio.size()); ++s) {
        if (!period.Contains(lio[s].t_ns)) continue;
        if (first < 0) first = s;
        last = s;
      }
      for (const int s : {first, last}) {
        if (s < 0 || keyframe_stamps.count(lio[s].t_ns)) continue;
        keyframe_stamps.insert(lio[s].t_ns);
        nodes.push_back({lio[s].t_ns, lio[s].pose, -1});
        ++result.num_rest_nodes;
      }
    }
    std::sort(
        nodes.begin(), nodes.end(), [](const Node& a, const Node& b) { return a.t_ns < b.t_ns; });
  }
  const int num_nodes = static_cast<int>(nodes.size());
  result.num_nodes = num_nodes;
  std::vector<TimestampNs> node_times;
  for (const Node& n : nodes) node_times.push_back(n.t_ns);
  std::vector<int> node_of_keyframe(num_keyframes);
  for (int n = 0; n < num_nodes; ++n) {
    if (nodes[n].keyframe >= 0) node_of_keyframe[nodes[n].keyframe] = n;
  }

  // Candidate pairs.
  auto start = std::chrono::steady_clock::now();
  std::vector<std::pair<int, int>> pairs;
  if (options.use_icp_pairs) {
    std::vector<Vec3> positions;
    for (const LioKeyframe& k : keyframes) positions.push_back(k.world_from_imu.translation());
    for (const auto& pair : KnnCandidatePairs(
             positions, options.knn, options.min_index_step, options.max_index_step)) {
      ++result.pairs.candidates;
      if (PairInsideStationaryPeriod(
              result.stationary_periods, keyframes[pair.first].t_ns, keyframes[pair.second].t_ns)) {
        ++result.pairs.inside_stationary;
        continue;
      }
      pairs.push_back(pair);
    }
  }
  result.timings.candidates = SecondsSince(start);

  // Clouds of the keyframes that take part in a pair (of `subset`), in the
  // LiDAR frame; then the Bayesian ICP per pair, in blocks of target keyframes
  // (bounded memory: a block's KD-trees only). A pair's result depends on the
  // pair only (its seed on its keyframe indices): not on the threads, the
  // subset or the process.
  const SE3 lidar_from_imu = input.imu_from_lidar.Inverse();
  NormalOptions normal_options;
  normal_options.num_neighbors = options.bayesian.normal_neighbors;
  auto register_pairs = [&](const std::vector<size_t>& subset) {
    auto stage_start = std::chrono::steady_clock::now();
    std::vector<KeyframeClouds> clouds(num_keyframes);
    std::vector<char> needed(num_keyframes, 0);
    for (size_t p : subset) needed[pairs[p].first] = needed[pairs[p].second] = 1;
    Stage(callbacks,
          fmt::format("loading {} keyframe clouds",
                      std::count(needed.begin(), needed.end(), char(1))));
    tbb::parallel_for(0, num_keyframes, [&](int k) {
      if (!needed[k]) return;
      PointSet points = FinitePointsOf(ReadPcd(keyframes[k].cloud_path));
      for (Eigen::Vector3f& p : points) {
        p = (lidar_from_imu * p.cast<double>()).cast<float>();
      }
      clouds[k].source = VoxelDownsamplePoints(points, options.source_voxel_size);
      clouds[k].target = VoxelDownsamplePoints(points, options.target_voxel_size);
    });
    result.timings.load_clouds += SecondsSince(stage_start);

    Stage(callbacks, fmt::format("Bayesian ICP on {} pairs", subset.size()));
    stage_start = std::chrono::steady_clock::now();
    if (callbacks.on_icp_start) callbacks.on_icp_start(static_cast<int64_t>(subset.size()));
    std::vector<PairResult> subset_results(subset.size());
    constexpr int kTargetBlock = 64;
    for (size_t begin = 0; begin < subset.size();) {
      const int block_first = pairs[subset[begin]].first;
      size_t end = begin;
      while (end < subset.size() && pairs[subset[end]].first < block_first + kTargetBlock) ++end;
      std::vector<int> targets;
      for (size_t q = begin; q < end; ++q) {
        const int i = pairs[subset[q]].first;
        if (targets.empty() || targets.back() != i) targets.push_back(i);
      }
      std::vector<std::unique_ptr<KdTreeTarget>> trees(targets.size());
      tbb::parallel_for(0, static_cast<int>(targets.size()), [&](int t) {
        trees[t] = std::make_unique<KdTreeTarget>(clouds[targets[t]].target, normal_options);
      });
      tbb::parallel_for(begin, end, [&](size_t q) {
        const auto [i, j] = pairs[subset[q]];
        const int t =
            static_cast<int>(std::lower_bound(targets.begin(), targets.end(), i) - targets.begin());
        const SE3 lio_i_from_j =
            keyframes[i].world_from_imu.Inverse() * keyframes[j].world_from_imu;
        const uint64_t seed = options.bayesian.sgld.seed * 1000003ull +
                              static_cast<uint64_t>(i) * 100003ull + static_cast<uint64_t>(j);
        subset_results[q] =
            RegisterPair(clouds[j], *trees[t], lio_i_from_j, input.imu_from_lidar, options, seed);
        if (callbacks.on_icp_pair) callbacks.on_icp_pair();
      });
      begin = end;
    }
    result.timings.icp += SecondsSince(stage_start);
    return subset_results;
  };
  std::vector<PairResult> pair_results;
  if (!callbacks.pair_runner) {
    std::vector<size_t> all(pairs.size());
    std::iota(all.begin(), all.end(), size_t(0));
    pair_results = register_pairs(all);
  } else {
    // Cost of a pair: the bytes of its two keyframe clouds (points of a binary PCD).
    std::vector<double> cloud_bytes(num_keyframes, 0.0);
    for (int k = 0; k < num_keyframes; ++k) {
      std::error_code error;
      const auto bytes = std::filesystem::file_size(keyframes[k].cloud_path, error);
      cloud_bytes[k] = error ? 0.0 : static_cast<double>(bytes);
    }
    std::vector<double> costs;
    for (const auto& [i, j] : pairs) costs.push_back(cloud_bytes[i] + cloud_bytes[j]);
    // timings.icp: the wall time of the whole split (this process's share, then
    // waiting for the others' results) less this process's cloud loading.
    const auto runner_start = std::chrono::steady_clock::now();
    const auto encoded = callbacks.pair_runner(costs, [&](const std::vector<size_t>& subset) {
      std::vector<std::string> out;
      for (const PairResult& r : register_pairs(subset)) out.push_back(EncodePairResult(r));
      return out;
    });
    result.timings.icp = SecondsSince(runner_start) - result.timings.load_clouds;
    if (!encoded) {
      result.share_only = true;
      return result;
    }
    THROW_CHECK_EQ(encoded->size(), pairs.size());
    for (const std::string& bytes : *encoded) pair_results.push_back(DecodePairResult(bytes));
  }
  result.pairs.registered = static_cast<int>(pairs.size());

  // The graph.
  Stage(callbacks, "building the pose graph");
  start = std::chrono::steady_clock::now();
  PoseGraph graph;
  // Every parameter block in one buffer, in creation order (PoseGraph::
  // ReserveParameters): poses, gravity direction, velocities, biases (at most
  // one per rest plus the first).
  graph.ReserveParameters(static_cast<size_t>(num_nodes) * (PoseManifold::kAmbientSize + 3) + 3 +
                          6 * (result.stationary_periods.size() + 1));
  for (const Node& n : nodes) graph.AddPose(n.lio_pose);
  ceres::Problem& problem = graph.problem();
  // Odometry.
  for (int n = 0; n + 1 < num_nodes; ++n) {
    const SE3 i_from_j = nodes[n].lio_pose.Inverse() * nodes[n + 1].lio_pose;
    const double distance = i_from_j.translation().norm();
    const double sigma_r = (options.odometry_sigma_rotation_deg +
                            options.odometry_sigma_rotation_deg_per_m * distance) *
                           kDegToRad;
    const double sigma_t =
        options.odometry_sigma_translation + options.odometry_sigma_translation_per_m * distance;
    Vec6 information;
    information << Vec3::Constant(1.0 / (sigma_r * sigma_r)),
        Vec3::Constant(1.0 / (sigma_t * sigma_t));
    graph.AddRelativePoseFactor(n, n + 1, i_from_j, information.asDiagonal().toDenseMatrix());
    ++result.num_odometry_factors;
  }
  // ICP pairs.
  std::vector<PoseGraph::FactorId> icp_factors;
  std::vector<size_t> icp_factor_pair;
  for (size_t p = 0; p < pairs.size(); ++p) {
    const PairResult& r = pair_results[p];
    switch (r.outcome) {
      case PairResult::Outcome::kFailed:
        ++result.pairs.failed;
        continue;
      case PairResult::Outcome::kUnconverged:
        ++result.pairs.unconverged;
        continue;
      case PairResult::Outcome::kDegenerate:
        ++result.pairs.degenerate;
        continue;
      case PairResult::Outcome::kLioDifference:
        ++result.pairs.lio_difference;
        continue;
      case PairResult::Outcome::kKept:
        break;
    }
    icp_factors.push_back(graph.AddRelativePoseFactor(node_of_keyframe[pairs[p].first],
                                                      node_of_keyframe[pairs[p].second],
                                                      r.i_from_j,
                                                      r.covariance.inverse(),
                                                      options.icp_loss));
    icp_factor_pair.push_back(p);
  }
  // IMU: velocities, piecewise-constant biases, preintegration factors.
  std::vector<double*> velocities, biases;  // 3 and 6 doubles in the graph's storage
  double* gravity_direction = graph.ParameterStorage(3);
  gravity_direction[2] = -1.0;
  ceres::SphereManifold<3> sphere;
  if (options.use_imu) {
    problem.AddParameterBlock(gravity_direction, 3, &sphere);
    for (const Node& n : nodes) {
      const int s = lio.Nearest(n.t_ns, 0);
      THROW_CHECK_GE(s, 0);
      const Vec3 v = LioVelocity(lio, s);
      velocities.push_back(graph.ParameterStorage(3));
      Eigen::Map<Vec3>(velocities.back()) = v;
      problem.AddParameterBlock(velocities.back(), 3);
    }
    const PiecewiseBias piecewise = options.piecewise_bias
                                        ? AssignPiecewiseBias(node_times, result.stationary_periods)
                                        : AssignPiecewiseBias(node_times, {});
    result.num_biases = piecewise.num_biases();
    for (int b = 0; b < piecewise.num_biases(); ++b) {
      biases.push_back(graph.ParameterStorage(6));
      problem.AddParameterBlock(biases.back(), 6);
    }
    std::vector<std::unique_ptr<Preintegration>> preintegrations(num_nodes - 1);
    std::vector<std::string> errors(num_nodes - 1);
    tbb::parallel_for(0, num_nodes - 1, [&](int n) {
      try {
        preintegrations[n] =
            std::make_unique<Preintegration>(Preintegration::Integrate(input.imu,
                                                                       node_times[n],
                                                                       node_times[n + 1],
                                                                       ImuBias(),
                                                                       input.imu_noise,
                                                                       options.preintegration));
      } catch (const InputError& e) {
        errors[n] = e.what();
      }
    });
    for (int n = 0; n + 1 < num_nodes; ++n) {
      if (!errors[n].empty()) {
        throw InputError(input.imu_path,
                         fmt::format("between the keyframes at {:.3f} s and {:.3f} s",
                                     NsToSeconds(node_times[n]),
                                     NsToSeconds(node_times[n + 1])),
                         errors[n]);
      }
    }
    for (int n = 0; n + 1 < num_nodes; ++n) {
      const Mat9 extra =
          UnmodelledImuCovariance(input.imu, node_times[n], node_times[n + 1], options);
      problem.AddResidualBlock(
          ImuGravityFactor::Create(*preintegrations[n], options.gravity, extra),
          nullptr,
          graph.PoseBlock(n),
          velocities[n],
          graph.PoseBlock(n + 1),
          velocities[n + 1],
          biases[piecewise.interval_bias[n]],
          gravity_direction);
      ++result.num_imu_factors;
    }
    for (int b = 0; b + 1 < piecewise.num_biases(); ++b) {
      problem.AddResidualBlock(
          BiasRandomWalkFactor::Create(input.imu_noise,
                                       BiasRandomWalkSeconds(piecewise, node_times, b)),
          nullptr,
          biases[b],
          biases[b + 1]);
      ++result.num_bias_random_walk_factors;
    }
    // The first bias around zero (datasheet offsets): conditions a bias that a
    // short or rest-free recording barely observes.
    Vec6 prior_inverse_sigma;
    prior_inverse_sigma << Vec3::Constant(1.0 / options.bias_prior_gyro),
        Vec3::Constant(1.0 / options.bias_prior_accel);
    problem.AddResidualBlock(
        new ceres::NormalPrior(prior_inverse_sigma.asDiagonal().toDenseMatrix(), Vec6::Zero()),
        nullptr,
        biases.front());
  }
  // Rests: zero velocity at each node inside one, identity between consecutive
  // nodes of the same one.
  if (options.use_zero_velocity) {
    for (int n = 0; n < num_nodes; ++n) {
      const int period = StationaryPeriodIndex(result.stationary_periods, node_times[n]);
      if (period < 0) continue;
      if (options.use_imu) {
        problem.AddResidualBlock(
            ZeroVelocityFactor::Create(options.zero_velocity), nullptr, velocities[n]);
        ++result.num_zero_velocity_factors;
      }
      if (n + 1 < num_nodes &&
          StationaryPeriodIndex(result.stationary_periods, node_times[n + 1]) == period) {
        problem.AddResidualBlock(StationaryPoseFactor::Create(options.zero_velocity),
                                 nullptr,
                                 graph.PoseBlock(n),
                                 graph.PoseBlock(n + 1));
        ++result.num_stationary_pose_factors;
      }
    }
  }
  // Gauge: the first pose; the gravity direction is estimated in its frame.
  graph.SetPoseConstant(0);
  result.timings.build = SecondsSince(start);

  // First pass, outlier removal, second pass.
  Stage(callbacks, "optimising");
  const PoseGraphSolverOptions& solver = options.solver;
  result.solve = graph.Solve(solver);
  result.timings.solve = result.solve.seconds;
  if (!result.solve.usable) {
    throw std::runtime_error("pose_slam: the solver failed: " + result.solve.message);
  }
  std::vector<char> icp_removed(icp_factors.size(), 0);
  for (size_t f = 0; f < icp_factors.size(); ++f) {
    if (graph.SquaredResidual(icp_factors[f]) > options.outlier_chi2) {
      graph.RemoveFactor(icp_factors[f]);
      icp_removed[f] = 1;
      ++result.pairs.residual_outliers;
    }
  }
  if (result.pairs.residual_outliers > 0) {
    result.second_pass = true;
    result.second_solve = graph.Solve(solver);
    result.timings.second_solve = result.second_solve.seconds;
    if (!result.second_solve.usable) {
      throw std::runtime_error("pose_slam: the solver failed: " + result.second_solve.message);
    }
  }
  for (size_t f = 0; f < icp_factors.size(); ++f) {
    if (icp_removed[f]) continue;
    const size_t p = icp_factor_pair[f];
    LidarConstraintRecord record;
    record.t_i_ns = keyframes[pairs[p].first].t_ns;
    record.t_j_ns = keyframes[pairs[p].second].t_ns;
    record.i_from_j = pair_results[p].i_from_j;
    record.covariance = pair_results[p].covariance;
    result.constraints.push_back(record);
  }
  result.pairs.kept = static_cast<int>(result.constraints.size());
  result.num_icp_factors = result.pairs.kept;

  // Covariances of the keyframe poses.
  Stage(callbacks, "keyframe covariances");
  start = std::chrono::steady_clock::now();
  const std::vector<MatX> covariances = graph.PoseCovariances(node_of_keyframe);
  result.timings.covariances = SecondsSince(start);

  std::vector<SE3> lio_node_poses, optimised_node_poses;
  for (int n = 0; n < num_nodes; ++n) {
    lio_node_poses.push_back(nodes[n].lio_pose);
    optimised_node_poses.push_back(graph.Pose(n));
  }
  for (int k = 0; k < num_keyframes; ++k) {
    result.keyframe_times.push_back(keyframes[k].t_ns);
    result.keyframe_poses.push_back(optimised_node_poses[node_of_keyframe[k]]);
    result.keyframe_covariances.push_back(covariances[k]);
  }
  for (const double* b : biases) result.biases.push_back(Eigen::Map<const Vec6>(b));
  result.gravity_direction = Eigen::Map<const Vec3>(gravity_direction);
  result.trajectory = CorrectTrajectory(lio, node_times, lio_node_poses, optimised_node_poses);
  return result;
}

}  // namespace

PoseSlamResult RunPoseSlam(const PoseSlamInput& input,
                           const PoseSlamOptions& options,
                           const PoseSlamCallbacks& callbacks) {
  THROW_CHECK_MSG(options.Check(), "PoseSlamOptions: " << LastOptionCheckFailure().ToString());
  if (options.num_threads < 0) return RunPoseSlamInArena(input, options, callbacks);
  tbb::task_arena arena(options.num_threads);
  return arena.execute([&] { return RunPoseSlamInArena(input, options, callbacks); });
}

}  // namespace lisfm
