// The formulation of Ceres' own 3D pose-graph example
// (ceres-solver examples/slam/pose_graph_3d: pose_graph_3d.cc and
// pose_graph_3d_error_term.h), written here as a bench variant because Debian's
// libceres-dev ships no examples (scripts/bench_pose_graph.sh). Not the same
// objective as `lisfm pose_graph`, so it does not reach SE-Sync's F*: it is the
// timing reference.
//
// The example's formulation: per pose a position block (3) and a quaternion
// block (4, ceres::EigenQuaternionManifold); per edge the 6 residuals
//   L [ R_a^T (p_b - p_a) - p~_ab ; 2 vec(q~_ab (q_a^-1 q_b)^-1) ]
// with L the lower Cholesky factor of the edge's full 6x6 information matrix;
// the first pose (smallest id) held constant; SPARSE_NORMAL_CHOLESKY, at most
// 200 iterations, Ceres' default tolerances; started from the file's vertices.
// Edges whose full information matrix is not positive definite (cubicle.g2o)
// get the block-diagonal part of it (the example would take a garbage factor).
//
// Prints `key: value` lines: poses, edges, edges_block_diagonal, iterations,
// termination, solve_s, cost (Ceres' 1/2 sum ||r||^2), F_final (SE-Sync's
// objective at the example's solution), jacobian_s and linear_solver_s
// (Ceres' time in Jacobian evaluation and in the linear solver).
// Usage: lisfm_pose_graph_ceres_example GRAPH.g2o [--init chordal] [--threads N]
#include <ceres/autodiff_cost_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <Eigen/Cholesky>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "core/io/g2o_io.h"
#include "lio/pose_slam/chordal_initialization.h"
#include "lio/pose_slam/g2o_pose_graph.h"

namespace lisfm {
namespace {

struct PoseBlocks {
  Eigen::Vector3d p;
  Eigen::Quaterniond q;
};

// The example's error term: the estimate of i_from_j from the two poses, the
// position error in frame i and twice the vector part of the rotation error
// quaternion Z_q * (estimate_q)^-1, weighted by L.
struct ExampleErrorTerm {
  ExampleErrorTerm(const SE3& i_from_j, const Mat6& sqrt_information)
      : measured_t(i_from_j.translation()), measured_q(i_from_j.rotation()), L(sqrt_information) {}

  template <typename T>
  bool operator()(const T* const position_i,
                  const T* const rotation_i,
                  const T* const position_j,
                  const T* const rotation_j,
                  T* out) const {
    using Vec3T = Eigen::Matrix<T, 3, 1>;
    using QuatT = Eigen::Quaternion<T>;
    const QuatT world_q_i = Eigen::Map<const QuatT>(rotation_i);
    const QuatT world_q_j = Eigen::Map<const QuatT>(rotation_j);
    const Vec3T world_t_i = Eigen::Map<const Vec3T>(position_i);
    const Vec3T world_t_j = Eigen::Map<const Vec3T>(position_j);
    const QuatT i_q_world = world_q_i.conjugate();
    const Vec3T estimated_t = i_q_world * (world_t_j - world_t_i);
    const QuatT estimated_q = i_q_world * world_q_j;
    const QuatT rotation_error = measured_q.cast<T>() * estimated_q.conjugate();
    Eigen::Matrix<T, 6, 1> error;
    error << estimated_t - measured_t.cast<T>(), T(2.0) * rotation_error.vec();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> residuals(out);
    residuals = L.cast<T>() * error;
    return true;
  }

  static ceres::CostFunction* Create(const SE3& i_from_j, const Mat6& sqrt_information) {
    return new ceres::AutoDiffCostFunction<ExampleErrorTerm, 6, 3, 4, 3, 4>(
        new ExampleErrorTerm(i_from_j, sqrt_information));
  }

  Vec3 measured_t;
  Quat measured_q;
  Mat6 L;

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

int Main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: lisfm_pose_graph_ceres_example GRAPH.g2o [--init chordal] "
                 "[--threads N]\n");
    return 2;
  }
  const std::string path = argv[1];
  bool chordal = false;
  int threads = 1;
  for (int k = 2; k + 1 < argc; k += 2) {
    const std::string flag = argv[k], value = argv[k + 1];
    if (flag == "--init") chordal = value == "chordal";
    if (flag == "--threads") threads = std::atoi(value.c_str());
  }
  const G2oGraph graph = ReadG2o(path);
  if (graph.dimension != 3 || graph.vertices.empty()) {
    std::fprintf(
        stderr, "%s: the example formulation needs a 3D graph with vertices\n", path.c_str());
    return 1;
  }
  std::map<int64_t, PoseBlocks> poses;  // ordered by id: begin() is the gauge
  for (const G2oVertex& vertex : graph.vertices) {
    poses[vertex.id] = {vertex.world_from_vertex.translation(),
                        vertex.world_from_vertex.rotation()};
  }
  std::map<int64_t, int> index;
  for (const auto& [id, pose] : poses) index.emplace(id, static_cast<int>(index.size()));
  std::vector<ChordalMeasurement> measurements;
  for (const G2oEdge& edge : graph.edges) {
    const SeSyncWeights w = SeSyncEdgeWeights(edge, 3);
    measurements.push_back(
        {index.at(edge.id_i), index.at(edge.id_j), edge.i_from_j, w.kappa, w.tau});
  }
  double init_s = 0.0;
  if (chordal) {
    const auto start = std::chrono::steady_clock::now();
    const std::vector<SE3> initial =
        ChordalInitialization(3, static_cast<int>(poses.size()), measurements);
    init_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    SE3 anchor;  // the gauge vertex keeps its pose from the file
    for (const G2oVertex& vertex : graph.vertices) {
      if (vertex.id == poses.begin()->first) anchor = vertex.world_from_vertex;
    }
    for (auto& [id, pose] : poses) {
      const SE3 p = anchor * initial[index.at(id)];
      pose = {p.translation(), p.rotation()};
    }
  }

  const auto setup_start = std::chrono::steady_clock::now();
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ceres::EigenQuaternionManifold quaternion_manifold;
  int block_diagonal = 0;
  for (const G2oEdge& edge : graph.edges) {
    Mat6 information = edge.information;
    Eigen::LLT<Mat6> llt(information);
    if (llt.info() != Eigen::Success) {
      information.topRightCorner<3, 3>().setZero();
      information.bottomLeftCorner<3, 3>().setZero();
      llt.compute(information);
      ++block_diagonal;
    }
    const Mat6 L = llt.matrixL();
    PoseBlocks& a = poses.at(edge.id_i);
    PoseBlocks& b = poses.at(edge.id_j);
    problem.AddResidualBlock(ExampleErrorTerm::Create(edge.i_from_j, L),
                             nullptr,
                             a.p.data(),
                             a.q.coeffs().data(),
                             b.p.data(),
                             b.q.coeffs().data());
    problem.SetManifold(a.q.coeffs().data(), &quaternion_manifold);
    problem.SetManifold(b.q.coeffs().data(), &quaternion_manifold);
  }
  problem.SetParameterBlockConstant(poses.begin()->second.p.data());
  problem.SetParameterBlockConstant(poses.begin()->second.q.coeffs().data());
  ceres::Solver::Options options;
  options.max_num_iterations = 200;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.num_threads = threads;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  const auto solve_start = std::chrono::steady_clock::now();
  ceres::Solve(options, &problem, &summary);
  const auto end = std::chrono::steady_clock::now();

  std::vector<SE3> solution(poses.size());
  for (const auto& [id, pose] : poses) solution[index.at(id)] = SE3(pose.q, pose.p);
  std::printf(
      "poses: %zu\nedges: %zu\nedges_block_diagonal: %d\ninitialization: %s\n"
      "iterations: %d\ntermination: %s\ninit_s: %.3f\nsetup_s: %.3f\nsolve_s: %.3f\n"
      "cost: %.9g\nF_final: %.9g\njacobian_s: %.3f\nlinear_solver_s: %.3f\n",
      poses.size(),
      graph.edges.size(),
      block_diagonal,
      chordal ? "chordal" : "vertices",
      static_cast<int>(summary.iterations.size()) - 1,
      ceres::TerminationTypeToString(summary.termination_type),
      init_s,
      std::chrono::duration<double>(solve_start - setup_start).count(),
      std::chrono::duration<double>(end - solve_start).count(),
      summary.final_cost,
      ChordalObjective(measurements, solution),
      summary.jacobian_evaluation_time_in_seconds,
      summary.linear_solver_time_in_seconds);
  return 0;
}

}  // namespace
}  // namespace lisfm

int main(int argc, char** argv) { return lisfm::Main(argc, argv); }
