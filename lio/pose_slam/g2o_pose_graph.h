// SE-Sync's pose-graph problem on a g2o graph (`lisfm pose_graph`): isotropic
// weights from each edge's information matrix, the chordal initialisation, and
// Levenberg-Marquardt on SE-Sync's objective with PoseGraph.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/io/g2o_io.h"
#include "lio/pose_slam/chordal_initialization.h"
#include "lio/pose_slam/pose_graph.h"

namespace lisfm {

// SE-Sync's isotropic weights of an edge (read_g2o_file in SE-Sync's
// SESync_utils.cpp; ../shared/data/pose_graphs/OPTIMA.md), Omega the edge's
// information matrix:
//   3D: tau = 3 / trace(Omega_tt^-1), kappa = 3 / (2 trace(Omega_rr^-1))
//   2D: tau = 2 / trace(Omega_tt^-1), kappa = Omega_33 (the theta entry)
// Omega_tt, Omega_rr: the translation and rotation diagonal blocks.
struct SeSyncWeights {
  double kappa = 0.0;
  double tau = 0.0;
};
SeSyncWeights SeSyncEdgeWeights(const G2oEdge& edge, int dimension);

struct G2oOptimizationOptions {
  // Where Levenberg-Marquardt starts: "chordal" (the chordal initialisation,
  // with the first vertex at its pose in the file, or at the origin for files
  // without vertices) or "vertices" (the poses of the file's VERTEX records).
  std::string initialization = "chordal";
  PoseGraphSolverOptions solver;
  bool Check() const;
};

struct G2oOptimizationResult {
  std::vector<int64_t> ids;  // vertex ids, ascending (pose k is ids[k]); pose 0 is the gauge
  std::vector<SE3> poses;    // optimised world_from_vertex
  // SE-Sync's objective F (eq. (12)) at the file's vertices (NaN when the file
  // has none), at the initialisation and at the optimum.
  double objective_vertices = 0.0;
  double objective_initial = 0.0;
  double objective_final = 0.0;
  double initialization_seconds = 0.0;  // chordal initialisation (0 for "vertices")
  PoseGraphSolveSummary solve;
};

// Minimises SE-Sync's objective over the graph's poses. `graph` comes from
// ReadG2o and is connected (CheckG2oConnected); "vertices" initialisation needs
// vertices. Broken preconditions throw InternalError.
// `on_iteration`: PoseGraph::Solve's progress callback (iteration, Ceres cost = F / 2).
G2oOptimizationResult OptimizeG2oGraph(const G2oGraph& graph,
                                       const G2oOptimizationOptions& options,
                                       const std::function<void(int, double)>& on_iteration = {});

// `graph` with one vertex per pose of `result` (the optimised poses), edges unchanged.
G2oGraph WithOptimizedVertices(const G2oGraph& graph, const G2oOptimizationResult& result);

}  // namespace lisfm
