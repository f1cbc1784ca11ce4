#include "importers/testing/pose_slam_standin.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdlib>
#include <mutex>
#include <set>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/keyframe_covariances_io.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/trajectory_io.h"
#include "icp/bayesian_icp.h"
#include "icp/icp.h"
#include "icp/nearest_neighbors.h"
#include "icp/normals.h"

namespace lisfm {
namespace test {

size_t WritePoseSlamStandIn(const std::string& lio_path,
                            const std::string& output_dir,
                            const PoseSlamStandInOptions& options) {
  CreateDirs(output_dir);
  const Trajectory trajectory = ReadTum(JoinPaths(lio_path, "trajectory.txt"));
  WriteTum(JoinPaths(output_dir, "trajectory.txt"), trajectory);
  // keyframes.csv: t_ns,tx,ty,tz,qx,qy,qz,qw.
  const std::string csv = JoinPaths(lio_path, "keyframes/keyframes.csv");
  LineReader reader(csv);
  std::string line;
  Trajectory keyframes;
  while (reader.Next(&line)) {
    const std::string t = Trim(line);
    if (t.empty() || t[0] == '#') continue;
    const auto cols = SplitString(t, ",");
    if (cols.size() != 8) throw InputError(csv, reader.Where(), "expected 8 columns");
    StampedPose p;
    double v[7];
    if (!ParseInt64(cols[0], &p.t_ns)) throw InputError(csv, reader.Where(), "bad stamp");
    for (int i = 0; i < 7; ++i) {
      if (!ParseDouble(cols[i + 1], &v[i])) throw InputError(csv, reader.Where(), "bad number");
    }
    p.pose = SE3(Quat(v[6], v[3], v[4], v[5]).normalized(), Vec3(v[0], v[1], v[2]));
    keyframes.PushBack(p);
  }
  WriteTum(JoinPaths(output_dir, "keyframes.txt"), keyframes);

  std::vector<KeyframeCovariance> covariances;
  for (const StampedPose& k : keyframes.poses()) {
    KeyframeCovariance c;
    c.t_ns = k.t_ns;
    const double r = options.keyframe_sigma_rotation_rad, t = options.keyframe_sigma_translation_m;
    c.covariance.diagonal() << r * r, r * r, r * r, t * t, t * t, t * t;
    covariances.push_back(c);
  }
  WriteKeyframeCovariances(covariances, JoinPaths(output_dir, "keyframe_covariances.txt"));

  // Candidate pairs: index steps below min_index_step, and each keyframe's
  // nearest partners with a step in [min_index_step, max_index_step].
  const int n = static_cast<int>(keyframes.size());
  std::set<std::pair<int, int>> pairs;
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n && j - i < options.min_index_step; ++j) pairs.insert({i, j});
  }
  for (int i = 0; i < n; ++i) {
    std::vector<std::pair<double, int>> near;
    for (int j = 0; j < n; ++j) {
      const int step = std::abs(j - i);
      if (step < options.min_index_step || step > options.max_index_step) continue;
      const double d = (keyframes[i].pose.translation() - keyframes[j].pose.translation()).norm();
      if (d <= options.max_pair_distance_m) near.push_back({d, j});
    }
    std::sort(near.begin(), near.end());
    for (size_t u = 0; u < near.size() && u < static_cast<size_t>(options.max_pairs_per_keyframe);
         ++u) {
      pairs.insert({std::min(i, near[u].second), std::max(i, near[u].second)});
    }
  }
  std::vector<PointSet> clouds(n);
  for (int i = 0; i < n; ++i) {
    clouds[i] = FinitePointsOf(
        ReadPointCloud(JoinPaths(lio_path, fmt::format("keyframes/{}.pcd", keyframes[i].t_ns))));
  }
  const std::vector<std::pair<int, int>> list(pairs.begin(), pairs.end());
  std::vector<LidarConstraintRecord> records(list.size());
  std::vector<char> ok(list.size(), 0);
  tbb::parallel_for(size_t(0), list.size(), [&](size_t q) {
    const auto [i, j] = list[q];
    const SE3 initial = keyframes[i].pose.Inverse() * keyframes[j].pose;  // i_from_j
    BayesianIcpOptions bayes;
    bayes.icp.field_of_view_gate = false;  // the clouds are in the IMU frame
    bayes.icp.visibility_gate_m = 0.0;
    bayes.sgld.num_iterations = options.sgld_iterations;
    bayes.sgld.burn_in = std::min(bayes.sgld.burn_in, options.sgld_iterations / 3);
    NormalOptions normals;
    normals.num_neighbors = bayes.normal_neighbors;
    try {
      const KdTreeTarget target(VoxelDownsamplePoints(clouds[i], options.target_voxel_m), normals);
      const PointSet source = VoxelDownsamplePoints(clouds[j], options.source_voxel_m);
      LidarConstraintRecord& r = records[q];
      r.t_i_ns = keyframes[i].t_ns;
      r.t_j_ns = keyframes[j].t_ns;
      if (options.point_to_plane_only) {
        const IcpResult icp = RegisterPointToPlane(source, target, initial, bayes.icp);
        if (!icp.converged) return;
        r.i_from_j = icp.target_from_source;
        r.covariance = Mat6::Zero();
        r.covariance.diagonal() << 1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4;
      } else {
        const BayesianIcpResult result = RegisterBayesian(source, target, initial, bayes);
        if (!result.icp.converged) return;
        r.i_from_j = result.posterior.mean;
        r.covariance =
            0.5 * (result.posterior.covariance + result.posterior.covariance.transpose());
      }
      // A registration far from lio's relative pose is a failure, not a constraint.
      const Vec6 d = (initial.Inverse() * r.i_from_j).Log();
      if (d.head<3>().norm() > 0.05 || d.tail<3>().norm() > 0.3) return;
      ok[q] = 1;
    } catch (const InputError&) {
      // Too few points / matches: no constraint.
    }
  });
  std::vector<LidarConstraintRecord> kept;
  for (size_t q = 0; q < list.size(); ++q) {
    if (ok[q]) kept.push_back(records[q]);
  }
  WriteLidarConstraints(kept, JoinPaths(output_dir, "constraints.txt"));
  return kept.size();
}

}  // namespace test
}  // namespace lisfm
