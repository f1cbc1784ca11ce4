// `lisfm pose_graph`: optimises a g2o pose graph (2D or 3D) on SE-Sync's
// objective: chordal initialisation, then Levenberg-Marquardt (Ceres, sparse
// Cholesky); prints the objective before and after, iterations and times, and
// writes the optimised graph.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <string>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/g2o_io.h"
#include "core/logging.h"
#include "core/options.h"
#include "core/progress.h"
#include "lio/pose_slam/g2o_pose_graph.h"

namespace lisfm {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string FormatObjective(double value) {
  return std::isnan(value) ? "nan" : fmt::format("{:.9g}", value);
}

}  // namespace

int RunPoseGraph(int argc, char** argv) {
  OptionManager options("lisfm pose_graph",
                        "optimise a g2o pose graph (VERTEX_SE2/EDGE_SE2 or "
                        "VERTEX_SE3:QUAT/EDGE_SE3:QUAT) on SE-Sync's objective");
  std::string input_path, output_path;
  G2oOptimizationOptions pose_graph;
  options.AddRequiredString("input_path", &input_path, "g2o pose graph to optimise");
  options.AddString("output_path",
                    &output_path,
                    "g2o file for the optimised graph (vertices = optimised poses, edges as read; "
                    "optional)");
  AddPoseGraphOptions(&options, &pose_graph);
  if (!options.Parse(argc, argv)) return 0;
  pose_graph.solver.verbose = GetLogLevel() <= LogLevel::kDebug;
  if (!output_path.empty()) CheckOutputFileWritable(output_path, "--output_path");

  const auto start = std::chrono::steady_clock::now();
  LogStage("pose_graph: " + input_path);
  const G2oGraph graph = ReadG2o(input_path);
  CheckG2oConnected(graph, input_path);
  if (pose_graph.initialization == "vertices" && graph.vertices.empty()) {
    throw InputError(
        input_path, "", "--PoseGraph.initialization vertices needs VERTEX records, found none");
  }
  const double read_s = SecondsSince(start);

  G2oOptimizationResult result;
  {
    ProgressReporter progress("pose_graph: Levenberg-Marquardt iterations",
                              pose_graph.solver.max_num_iterations);
    result = OptimizeG2oGraph(graph, pose_graph, [&](int, double) { progress.Add(); });
  }
  if (!result.solve.usable) {
    throw std::runtime_error(
        fmt::format("pose_graph: {}: the solver failed: {}", input_path, result.solve.message));
  }
  const G2oGraph optimized = WithOptimizedVertices(graph, result);
  double write_s = 0.0;
  if (!output_path.empty()) {
    const auto write_start = std::chrono::steady_clock::now();
    WriteG2o(optimized, output_path);
    write_s = SecondsSince(write_start);
  }
  const double total_s = SecondsSince(start);

  // Machine-readable lines (stdout); F is SE-Sync's objective (IJRR 2019, eq. (12)).
  std::cout << fmt::format(
      "dimension: {}\nposes: {}\nedges: {}\nF_vertices: {}\nF_initial: {}\nF_final: {}\n"
      "initialization: {}\niterations: {}\nconverged: {}\ntermination: {}\nlinear_solver: {}\n"
      "time_s: read {:.3f} initialization {:.3f} solve {:.3f} write {:.3f} total {:.3f}\n",
      graph.dimension,
      result.ids.size(),
      graph.edges.size(),
      FormatObjective(result.objective_vertices),
      FormatObjective(result.objective_initial),
      FormatObjective(result.objective_final),
      pose_graph.initialization,
      result.solve.iterations,
      result.solve.converged,
      result.solve.message,
      result.solve.linear_solver,
      read_s,
      result.initialization_seconds,
      result.solve.seconds,
      write_s,
      total_s);
  if (!result.solve.converged) {
    std::cout << "WARNING: not converged: " << result.solve.message << "\n";
  }
  std::cout.flush();
  LogInfo(
      "pose_graph: {}D graph, {} poses, {} edges; F = {} at the {} start, {} after {} "
      "Levenberg-Marquardt iterations ({}); {:.3f} s in total{}",
      graph.dimension,
      result.ids.size(),
      graph.edges.size(),
      FormatObjective(result.objective_initial),
      pose_graph.initialization,
      FormatObjective(result.objective_final),
      result.solve.iterations,
      result.solve.converged ? "converged" : "NOT converged",
      total_s,
      output_path.empty() ? "" : "; wrote " + output_path);
  return 0;
}

}  // namespace lisfm
