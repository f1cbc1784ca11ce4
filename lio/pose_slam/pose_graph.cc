#include "lio/pose_slam/pose_graph.h"

#include <ceres/covariance.h>
#include <ceres/iteration_callback.h>
#include <ceres/loss_function.h>
#include <ceres/solver.h>
#include <fmt/format.h>
#ifdef LISFM_HAVE_SUITESPARSE_CONFIG
#include <SuiteSparse_config.h>
#include <malloc.h>
#endif

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <thread>
#include <utility>

#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"
#include "lio/pose_slam/pose_graph_factors.h"

namespace lisfm {
namespace {

// Planar pose parameters (x, y, theta) of a pose whose rotation is about z.
void ToPlanarBlock(const SE3& pose, double* block) {
  const Mat3 R = pose.RotationMatrix();
  THROW_CHECK_MSG(std::abs(R(2, 2) - 1.0) < 1e-9,
                  "PoseGraph (2D): pose rotation is not about z (R(2,2) = " << R(2, 2) << ")");
  block[0] = pose.translation().x();
  block[1] = pose.translation().y();
  block[2] = std::atan2(R(1, 0), R(0, 0));
}

SE3 FromPlanarBlock(const double* block) {
  return SE3(Quat(Eigen::AngleAxisd(block[2], Vec3::UnitZ())), Vec3(block[0], block[1], 0.0));
}

ceres::LossFunction* MakeLoss(const RobustLossOptions& loss) {
  if (loss.kernel == "huber") return new ceres::HuberLoss(loss.scale);
  if (loss.kernel == "cauchy") return new ceres::CauchyLoss(loss.scale);
  return nullptr;
}

// Forwards each iteration to a callback (the first call, iteration 0, is the start).
class IterationForwarder : public ceres::IterationCallback {
 public:
  explicit IterationForwarder(const std::function<void(int, double)>& callback)
      : callback_(callback) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    if (summary.iteration > 0) callback_(summary.iteration, summary.cost);
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<void(int, double)>& callback_;
};

int NumThreads(int requested) {
  return requested > 0 ? requested
                       : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

// While alive, SuiteSparse (CHOLMOD, SuiteSparseQR) allocates on 64-byte
// boundaries. SuiteSparseQR factors its dense fronts with the system BLAS
// (ATLAS on Debian), whose kernels order their sums by the arrays' address
// alignment; malloc only guarantees 16 bytes, so the last digits of the
// covariances followed the heap's state (mpirun's allocations, the allocator's
// caches). Memory from either allocator is released with free(), so blocks
// may cross the switch. Not thread-safe: SuiteSparse's functions are global.
class AlignedSuiteSparseAllocation {
 public:
#ifdef LISFM_HAVE_SUITESPARSE_CONFIG
  AlignedSuiteSparseAllocation() : saved_(SuiteSparse_config) {
    SuiteSparse_config.malloc_func = &Malloc;
    SuiteSparse_config.calloc_func = &Calloc;
    SuiteSparse_config.realloc_func = &Realloc;
    SuiteSparse_config.free_func = &std::free;
  }
  ~AlignedSuiteSparseAllocation() {
    SuiteSparse_config.malloc_func = saved_.malloc_func;
    SuiteSparse_config.calloc_func = saved_.calloc_func;
    SuiteSparse_config.realloc_func = saved_.realloc_func;
    SuiteSparse_config.free_func = saved_.free_func;
  }

 private:
  static constexpr size_t kAlignment = 64;  // a cache line; >= any SIMD width
  static void* Malloc(size_t size) {
    void* p = nullptr;
    return posix_memalign(&p, kAlignment, std::max<size_t>(size, 1)) == 0 ? p : nullptr;
  }
  static void* Calloc(size_t count, size_t size) {
    if (size != 0 && count > SIZE_MAX / size) return nullptr;
    void* p = Malloc(count * size);
    if (p != nullptr) std::memset(p, 0, count * size);
    return p;
  }
  // A new aligned block with the old contents (malloc_usable_size: the old
  // block may come from either allocator).
  static void* Realloc(void* old, size_t size) {
    void* p = Malloc(size);
    if (p == nullptr) return nullptr;
    if (old != nullptr) {
      std::memcpy(p, old, std::min(malloc_usable_size(old), size));
      std::free(old);
    }
    return p;
  }
  SuiteSparse_config_struct saved_;
#endif
};

}  // namespace

bool PoseGraphSolverOptions::Check() const {
  CHECK_OPTION_GE(max_num_iterations, 1);
  CHECK_OPTION_GE(function_tolerance, 0.0);
  CHECK_OPTION_GE(gradient_tolerance, 0.0);
  CHECK_OPTION_GE(parameter_tolerance, 0.0);
  CHECK_OPTION_MSG(num_threads, num_threads == -1 || num_threads >= 1, "-1 or >= 1");
  return true;
}

bool RobustLossOptions::Check() const {
  CHECK_OPTION_MSG(kernel,
                   kernel == "none" || kernel == "huber" || kernel == "cauchy",
                   "one of none, huber, cauchy");
  CHECK_OPTION_GT(scale, 0.0);
  return true;
}

PoseGraph::PoseGraph(int dimension)
    : dimension_(dimension),
      block_size_(dimension == 3 ? PoseManifold::kAmbientSize : 3),
      manifold_(std::make_unique<PoseManifold>()) {
  THROW_CHECK_MSG(dimension == 2 || dimension == 3, "PoseGraph: dimension " << dimension);
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.enable_fast_removal = true;
  problem_ = std::make_unique<ceres::Problem>(problem_options);
}

PoseGraph::~PoseGraph() = default;

void PoseGraph::CheckIndex(int index) const {
  THROW_CHECK_MSG(index >= 0 && index < num_poses(),
                  "PoseGraph: pose index " << index << " of " << num_poses());
}

void PoseGraph::ReserveParameters(size_t num_doubles) {
  THROW_CHECK_MSG(poses_.empty() && storage_.empty() && overflow_.empty(),
                  "PoseGraph::ReserveParameters after the first block");
  storage_.reserve(num_doubles);
}

double* PoseGraph::ParameterStorage(int size) {
  THROW_CHECK_GT(size, 0);
  if (storage_.size() + static_cast<size_t>(size) <= storage_.capacity()) {
    storage_.resize(storage_.size() + size, 0.0);  // within capacity: no reallocation
    return storage_.data() + storage_.size() - size;
  }
  overflow_.emplace_back(size, 0.0);
  return overflow_.back().data();
}

int PoseGraph::AddPose(const SE3& world_from_body) {
  std::vector<double> values(block_size_);
  if (dimension_ == 3) {
    PoseManifold::ToBlock(world_from_body, values.data());
  } else {
    ToPlanarBlock(world_from_body, values.data());  // throws before any change
  }
  double* block = ParameterStorage(block_size_);
  std::copy(values.begin(), values.end(), block);
  poses_.push_back(block);
  constant_.push_back(false);
  if (dimension_ == 3) {
    problem_->AddParameterBlock(block, block_size_, manifold_.get());
  } else {
    problem_->AddParameterBlock(block, block_size_);
  }
  return num_poses() - 1;
}

SE3 PoseGraph::Pose(int index) const {
  CheckIndex(index);
  const double* block = poses_[index];
  return dimension_ == 3 ? PoseManifold::FromBlock(block) : FromPlanarBlock(block);
}

void PoseGraph::SetPose(int index, const SE3& world_from_body) {
  CheckIndex(index);
  double* block = poses_[index];
  if (dimension_ == 3) {
    PoseManifold::ToBlock(world_from_body, block);
  } else {
    ToPlanarBlock(world_from_body, block);
  }
}

double* PoseGraph::PoseBlock(int index) {
  CheckIndex(index);
  return poses_[index];
}

void PoseGraph::SetPoseConstant(int index) {
  CheckIndex(index);
  constant_[index] = true;
  problem_->SetParameterBlockConstant(poses_[index]);
}

bool PoseGraph::IsPoseConstant(int index) const {
  CheckIndex(index);
  return constant_[index];
}

PoseGraph::FactorId PoseGraph::AddChordalFactor(
    int i, int j, const SE3& i_from_j, double kappa, double tau) {
  CheckIndex(i);
  CheckIndex(j);
  THROW_CHECK_MSG(kappa > 0.0 && tau > 0.0 && std::isfinite(kappa) && std::isfinite(tau),
                  "PoseGraph: chordal weights kappa " << kappa << ", tau " << tau);
  ceres::CostFunction* cost = nullptr;
  if (dimension_ == 3) {
    cost = ChordalFactor3::Create(i_from_j, kappa, tau);
  } else {
    double z[3];
    ToPlanarBlock(i_from_j, z);
    cost = ChordalFactor2::Create(z[0], z[1], z[2], kappa, tau);
  }
  return problem_->AddResidualBlock(cost, nullptr, poses_[i], poses_[j]);
}

PoseGraph::FactorId PoseGraph::AddRelativePoseFactor(
    int i, int j, const SE3& i_from_j, const Mat6& information, const RobustLossOptions& loss) {
  THROW_CHECK_MSG(dimension_ == 3, "PoseGraph: relative pose factors need a 3D graph");
  CheckIndex(i);
  CheckIndex(j);
  THROW_CHECK_MSG(loss.Check(), "PoseGraph: robust loss " << loss.kernel << " " << loss.scale);
  const Eigen::LLT<Mat6> llt(0.5 * (information + information.transpose()));
  THROW_CHECK_MSG(llt.info() == Eigen::Success && information.allFinite(),
                  "PoseGraph: information matrix is not positive definite");
  // information = L L^T (L lower) = (L^T)^T (L^T): the residual is L^T e.
  const Mat6 sqrt_information = llt.matrixL().transpose();
  return problem_->AddResidualBlock(
      RelativePoseFactor::Create(i_from_j, sqrt_information), MakeLoss(loss), poses_[i], poses_[j]);
}

double PoseGraph::SquaredResidual(FactorId factor) const {
  double cost = 0.0;
  THROW_CHECK(problem_->EvaluateResidualBlock(
      factor, /*apply_loss_function=*/false, &cost, nullptr, nullptr));
  return 2.0 * cost;
}

void PoseGraph::RemoveFactor(FactorId factor) { problem_->RemoveResidualBlock(factor); }

double PoseGraph::Objective() const {
  std::vector<FactorId> factors;
  problem_->GetResidualBlocks(&factors);
  double sum = 0.0;
  for (const FactorId factor : factors) sum += SquaredResidual(factor);
  return sum;
}

PoseGraphSolveSummary PoseGraph::Solve(const PoseGraphSolverOptions& options,
                                       const std::function<void(int, double)>& on_iteration) {
  THROW_CHECK_MSG(options.Check(), "PoseGraph::Solve: " << LastOptionCheckFailure().ToString());
  if (num_poses() > 0 &&
      std::none_of(constant_.begin(), constant_.end(), [](bool c) { return c; })) {
    SetPoseConstant(0);
  }
  ceres::Solver::Options solver_options;
  solver_options.minimizer_type = ceres::TRUST_REGION;
  solver_options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.sparse_linear_algebra_library_type =
      ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE) ? ceres::SUITE_SPARSE
                                                                            : ceres::EIGEN_SPARSE;
  solver_options.max_num_iterations = options.max_num_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.num_threads = NumThreads(options.num_threads);
  solver_options.minimizer_progress_to_stdout = false;
  solver_options.logging_type = options.verbose ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;

  IterationForwarder forwarder(on_iteration);
  if (on_iteration) solver_options.callbacks.push_back(&forwarder);

  ceres::Solver::Summary ceres_summary;
  const auto start = std::chrono::steady_clock::now();
  ceres::Solve(solver_options, problem_.get(), &ceres_summary);
  if (options.verbose) LogDebug("{}", ceres_summary.FullReport());
  PoseGraphSolveSummary summary;
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  summary.converged = ceres_summary.termination_type == ceres::CONVERGENCE;
  summary.usable = ceres_summary.IsSolutionUsable();
  summary.iterations = static_cast<int>(ceres_summary.iterations.size()) - 1;  // 0: the start
  summary.iterations = std::max(summary.iterations, 0);
  summary.initial_cost = ceres_summary.initial_cost;
  summary.final_cost = ceres_summary.final_cost;
  summary.linear_solver =
      fmt::format("{} ({})",
                  ceres::LinearSolverTypeToString(ceres_summary.linear_solver_type_used),
                  ceres::SparseLinearAlgebraLibraryTypeToString(
                      solver_options.sparse_linear_algebra_library_type));
  summary.message = std::string(ceres::TerminationTypeToString(ceres_summary.termination_type)) +
                    ": " + ceres_summary.message;
  return summary;
}

std::vector<MatX> PoseGraph::PoseCovariances(const std::vector<int>& indices) {
  ceres::Covariance::Options covariance_options;
  covariance_options.algorithm_type = ceres::SPARSE_QR;
  covariance_options.num_threads = NumThreads(-1);
  const AlignedSuiteSparseAllocation aligned;
  ceres::Covariance covariance(covariance_options);
  std::vector<std::pair<const double*, const double*>> blocks;
  for (const int index : indices) {
    CheckIndex(index);
    if (!constant_[index]) blocks.emplace_back(poses_[index], poses_[index]);
  }
  std::sort(blocks.begin(), blocks.end());
  blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
  if (!blocks.empty()) {
    THROW_CHECK_MSG(covariance.Compute(blocks, problem_.get()),
                    "PoseGraph: the Hessian is rank deficient (a pose not joined to the gauge?)");
  }
  const int tangent = dimension_ == 3 ? PoseManifold::kTangentSize : 3;
  std::vector<MatX> out;
  for (const int index : indices) {
    MatX block = MatX::Zero(tangent, tangent);
    if (!constant_[index]) {
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> row_major(tangent,
                                                                                       tangent);
      THROW_CHECK(covariance.GetCovarianceBlockInTangentSpace(
          poses_[index], poses_[index], row_major.data()));
      block = row_major;
    }
    out.push_back(block);
  }
  return out;
}

}  // namespace lisfm
