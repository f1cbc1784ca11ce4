// A pose graph on Ceres: poses, relative-pose factors, gauge, Levenberg-
// Marquardt with a sparse Cholesky solver, and marginal covariances. The same
// machinery serves `lisfm pose_graph` (SE-Sync's chordal objective on g2o
// graphs) and pose_slam (information-weighted ICP / odometry factors, plus
// factors of its own on the pose blocks and on parameter blocks it adds to
// problem()).
//
// Poses are world_from_body. 3D pose blocks are 7 doubles [qx qy qz qw tx ty tz]
// on PoseManifold (tangent xi = [omega; v], right perturbation, DESIGN.md);
// 2D pose blocks are 3 doubles [x y theta] (m, rad), Euclidean. The blocks
// live as long as the graph and never move (pointers stay valid).
//
// Gauge: poses marked with SetPoseConstant() are held fixed; when none is
// marked, Solve() holds pose 0 fixed. Every other pose must be joined to a
// fixed pose through factors, else its estimate (and covariance) is undefined.
// Not thread-safe; Solve() itself uses options.num_threads threads.
#pragma once

#include <ceres/problem.h>

#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "lio/pose_slam/pose_manifold.h"

namespace lisfm {

// Ceres' default tolerances: on the SE-Sync benchmark graphs they stop within
// 4e-5 of the optimal objective (docs/BENCHMARKS.md, "Pose graph").
struct PoseGraphSolverOptions {
  int max_num_iterations = 500;       // Levenberg-Marquardt iterations at most
  double function_tolerance = 1e-6;   // stop when |cost change| / cost is below this
  double gradient_tolerance = 1e-10;  // stop when max |projected gradient| is below this
  double parameter_tolerance = 1e-8;  // stop when |step| / (|x| + tol) is below this
  int num_threads = -1;               // Jacobian evaluation threads (-1 = all cores)
  bool verbose = false;               // Ceres' glog logging; its full report in the debug log
  bool Check() const;
};

// A robust loss on a factor's squared residual s = ||r||^2 (Ceres rho(s)).
struct RobustLossOptions {
  std::string kernel = "none";  // none | huber | cauchy
  double scale = 1.0;           // residual norm (in sigmas) where the kernel bends, > 0
  bool Check() const;
};

// The outcome of Solve() (values, STYLE.md): costs are Ceres' (1/2) sum rho(||r||^2).
struct PoseGraphSolveSummary {
  bool converged = false;  // Ceres CONVERGENCE (a tolerance was met)
  bool usable = false;     // Ceres IsSolutionUsable(): CONVERGENCE or NO_CONVERGENCE
  int iterations = 0;      // Levenberg-Marquardt iterations (accepted and rejected)
  double initial_cost = 0.0;
  double final_cost = 0.0;
  double seconds = 0.0;       // wall time of ceres::Solve
  std::string linear_solver;  // e.g. "SPARSE_NORMAL_CHOLESKY (SUITE_SPARSE)"
  std::string message;        // Ceres' termination type and message
};

class PoseGraph {
 public:
  using FactorId = ceres::ResidualBlockId;

  // `dimension`: 3 (default) or 2; throws InternalError otherwise.
  explicit PoseGraph(int dimension = 3);
  ~PoseGraph();
  PoseGraph(const PoseGraph&) = delete;
  PoseGraph& operator=(const PoseGraph&) = delete;

  int dimension() const { return dimension_; }
  int num_poses() const { return static_cast<int>(poses_.size()); }
  int num_factors() const { return problem_->NumResidualBlocks(); }

  // Adds a pose (2D: x, y and the yaw of `world_from_body`; its roll and pitch
  // must be zero) and returns its index 0, 1, ...
  int AddPose(const SE3& world_from_body);
  SE3 Pose(int index) const;  // 2D: rotation about z, z = 0
  void SetPose(int index, const SE3& world_from_body);
  // The parameter block of a pose, to add other factors on it through problem().
  double* PoseBlock(int index);
  void SetPoseConstant(int index);
  bool IsPoseConstant(int index) const;

  // SE-Sync's chordal term (pose_graph_factors.h): kappa, tau > 0.
  FactorId AddChordalFactor(int i, int j, const SE3& i_from_j, double kappa, double tau);
  // Information-weighted relative pose, 3D only: `information` (6x6, symmetric
  // positive definite) is the inverse covariance of i_from_j on the right
  // perturbation xi = [omega; v] (rad, m); throws InternalError when it is not
  // positive definite.
  FactorId AddRelativePoseFactor(int i,
                                 int j,
                                 const SE3& i_from_j,
                                 const Mat6& information,
                                 const RobustLossOptions& loss = {});
  // The Ceres problem, for factors and parameter blocks of the caller's own
  // (e.g. velocities and IMU biases); it owns their cost and loss functions.
  ceres::Problem& problem() { return *problem_; }

  // Parameter storage in creation order. Ceres orders parameter blocks by
  // their addresses (ParameterBlockOrdering's sets, Covariance's sort), so
  // blocks in separate heap allocations make the order of the floating-point
  // operations, and the last bits of Solve() and PoseCovariances(), depend on
  // the allocator's state (run to run, thread count). After
  // ReserveParameters(n), the next poses and ParameterStorage() blocks, up to n
  // doubles in all, are consecutive in one buffer: address order = creation
  // order. Beyond n (or without a reservation) each block is allocated alone.
  // Call before the first AddPose.
  void ReserveParameters(size_t num_doubles);
  // `size` doubles, zero, that live as long as the graph (stable address).
  double* ParameterStorage(int size);

  // ||r||^2 of one factor at the current estimate, without its robust loss
  // (for a factor weighted by its information: the squared Mahalanobis distance).
  double SquaredResidual(FactorId factor) const;
  void RemoveFactor(FactorId factor);
  // Sum of ||r||^2 over all factors, without robust losses. For chordal factors
  // only, this is SE-Sync's objective F (eq. (12), no factor 1/2).
  double Objective() const;

  // Levenberg-Marquardt from the current estimate (the poses are updated in
  // place). SPARSE_NORMAL_CHOLESKY with SuiteSparse (CHOLMOD) when Ceres has
  // it, else with Eigen's sparse Cholesky. options must pass Check().
  // `on_iteration`, if set, is called after every iteration with its number
  // (1, 2, ...) and the cost, on the calling thread (progress display).
  PoseGraphSolveSummary Solve(const PoseGraphSolverOptions& options,
                              const std::function<void(int, double)>& on_iteration = {});

  // Marginal covariances of poses at the current estimate, given the gauge
  // (ceres::Covariance on the Gauss-Newton Hessian of the whole problem, robust
  // losses as at the estimate): 3D 6x6 on the right perturbation xi = [omega; v]
  // (rad, m); 2D 3x3 over (x, y, theta). A constant pose has a zero covariance.
  // Throws InternalError when the Hessian is rank deficient (a pose not joined
  // to the gauge). The same bits whatever the heap's state: SuiteSparse
  // allocates aligned during the call (its allocation functions are global:
  // no other thread may use SuiteSparse meanwhile).
  std::vector<MatX> PoseCovariances(const std::vector<int>& indices);

 private:
  void CheckIndex(int index) const;

  int dimension_;
  int block_size_;
  std::unique_ptr<PoseManifold> manifold_;   // shared by the 3D pose blocks
  std::unique_ptr<ceres::Problem> problem_;  // declared after manifold_: destroyed first
  std::vector<double*> poses_;               // pose blocks
  std::vector<double> storage_;              // reserved blocks, creation order
  std::deque<std::vector<double>> overflow_;  // blocks beyond the reservation
  std::vector<bool> constant_;
};

}  // namespace lisfm
