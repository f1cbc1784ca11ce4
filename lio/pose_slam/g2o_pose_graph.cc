#include "lio/pose_slam/g2o_pose_graph.h"

#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <limits>
#include <unordered_map>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

SeSyncWeights SeSyncEdgeWeights(const G2oEdge& edge, int dimension) {
  const MatX& information = edge.information;
  SeSyncWeights weights;
  if (dimension == 3) {
    THROW_CHECK(information.rows() == 6 && information.cols() == 6);
    weights.tau = 3.0 / Mat3(information.topLeftCorner<3, 3>()).inverse().trace();
    weights.kappa = 3.0 / (2.0 * Mat3(information.bottomRightCorner<3, 3>()).inverse().trace());
  } else {
    THROW_CHECK(dimension == 2 && information.rows() == 3 && information.cols() == 3);
    weights.tau = 2.0 / Eigen::Matrix2d(information.topLeftCorner<2, 2>()).inverse().trace();
    weights.kappa = information(2, 2);
  }
  return weights;
}

bool G2oOptimizationOptions::Check() const {
  CHECK_OPTION_MSG(initialization,
                   initialization == "chordal" || initialization == "vertices",
                   "one of chordal, vertices");
  CHECK_OPTION_NESTED(solver);
  return true;
}

G2oOptimizationResult OptimizeG2oGraph(const G2oGraph& graph,
                                       const G2oOptimizationOptions& options,
                                       const std::function<void(int, double)>& on_iteration) {
  THROW_CHECK_MSG(options.Check(), "OptimizeG2oGraph: " << LastOptionCheckFailure().ToString());
  THROW_CHECK(graph.dimension == 2 || graph.dimension == 3);
  G2oOptimizationResult result;
  // Poses: the vertices' ids, or the ids the edges name when there are no vertices.
  for (const G2oVertex& vertex : graph.vertices) result.ids.push_back(vertex.id);
  if (graph.vertices.empty()) {
    for (const G2oEdge& edge : graph.edges) {
      result.ids.push_back(edge.id_i);
      result.ids.push_back(edge.id_j);
    }
  }
  std::sort(result.ids.begin(), result.ids.end());
  result.ids.erase(std::unique(result.ids.begin(), result.ids.end()), result.ids.end());
  std::unordered_map<int64_t, int> index;
  for (size_t k = 0; k < result.ids.size(); ++k) index[result.ids[k]] = static_cast<int>(k);
  const int num_poses = static_cast<int>(result.ids.size());

  std::vector<ChordalMeasurement> measurements;
  measurements.reserve(graph.edges.size());
  for (const G2oEdge& edge : graph.edges) {
    const SeSyncWeights w = SeSyncEdgeWeights(edge, graph.dimension);
    measurements.push_back(
        {index.at(edge.id_i), index.at(edge.id_j), edge.i_from_j, w.kappa, w.tau});
  }
  std::vector<SE3> file_poses;
  if (!graph.vertices.empty()) {
    file_poses.resize(num_poses);
    for (const G2oVertex& vertex : graph.vertices) {
      file_poses[index.at(vertex.id)] = vertex.world_from_vertex;
    }
    result.objective_vertices = ChordalObjective(measurements, file_poses);
  } else {
    result.objective_vertices = std::numeric_limits<double>::quiet_NaN();
  }

  std::vector<SE3> initial;
  if (options.initialization == "vertices") {
    THROW_CHECK_MSG(!file_poses.empty(),
                    "OptimizeG2oGraph: vertices initialisation without "
                    "vertices");
    initial = file_poses;
  } else {
    const auto start = std::chrono::steady_clock::now();
    initial = ChordalInitialization(graph.dimension, num_poses, measurements);
    result.initialization_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!file_poses.empty()) {
      const SE3 anchor = file_poses[0];  // F is invariant under a global rigid transform
      for (SE3& pose : initial) pose = anchor * pose;
    }
  }
  result.objective_initial = ChordalObjective(measurements, initial);

  PoseGraph pose_graph(graph.dimension);
  for (const SE3& pose : initial) pose_graph.AddPose(pose);
  pose_graph.SetPoseConstant(0);
  for (const ChordalMeasurement& m : measurements) {
    pose_graph.AddChordalFactor(m.i, m.j, m.i_from_j, m.kappa, m.tau);
  }
  result.solve = pose_graph.Solve(options.solver, on_iteration);
  result.poses.reserve(num_poses);
  for (int k = 0; k < num_poses; ++k) result.poses.push_back(pose_graph.Pose(k));
  result.objective_final = ChordalObjective(measurements, result.poses);
  return result;
}

G2oGraph WithOptimizedVertices(const G2oGraph& graph, const G2oOptimizationResult& result) {
  THROW_CHECK_EQ(result.ids.size(), result.poses.size());
  G2oGraph out;
  out.dimension = graph.dimension;
  out.edges = graph.edges;
  for (size_t k = 0; k < result.ids.size(); ++k) {
    out.vertices.push_back({result.ids[k], result.poses[k], 0});
  }
  return out;
}

}  // namespace lisfm
