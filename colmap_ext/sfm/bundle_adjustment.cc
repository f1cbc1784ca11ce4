#include "colmap_ext/sfm/bundle_adjustment.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <set>
#include <thread>
#include <unordered_map>
#include <vector>

#include "colmap_ext/sfm/camera_model_functors.h"
#include "colmap_ext/sfm/schur_bundle_adjuster.h"
#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"

namespace lisfm {
namespace colmap {
namespace {

// A pose as Ceres parameter blocks: Eigen quaternion coefficients (x, y, z, w)
// and a translation.
struct PoseBlock {
  std::array<double, 4> q;
  std::array<double, 3> t;
  explicit PoseBlock(const SE3& pose) {
    const Quat r = pose.rotation().normalized();
    for (int i = 0; i < 4; ++i) q[i] = r.coeffs()[i];
    for (int i = 0; i < 3; ++i) t[i] = pose.translation()[i];
  }
  SE3 ToSE3() const {
    return SE3(Quat(q[3], q[0], q[1], q[2]).normalized(),
               Vec3(t[0], t[1], t[2]));
  }
};

// A pose block inside a shared buffer, laid out as PoseBlock (q = x, y, z, w).
struct PoseSlot {
  struct Span {
    double* p;
    double* data() const { return p; }
  };
  Span q, t;
  SE3 ToSE3() const {
    return SE3(Quat(q.p[3], q.p[0], q.p[1], q.p[2]).normalized(), Vec3(t.p[0], t.p[1], t.p[2]));
  }
};

// One observation of a track in a registered image.
struct Observation {
  size_t track_idx;
  image_t image_id;
  point2D_t point2D_idx;
};

SE3 CamFromRig(const MapperState& state, camera_t camera_id) {
  const auto it = state.cam_from_rig.find(camera_id);
  if (it != state.cam_from_rig.end()) return it->second;
  THROW_CHECK_MSG(!state.has_rig,
                  "camera " << camera_id << " has no cam_from_rig");
  return SE3::Identity();
}

bool ImageIsRegistered(const MapperState& state,
                       image_t image_id,
                       const SfmImage** image) {
  const auto it = state.images.find(image_id);
  if (it == state.images.end()) return false;
  const auto frame = state.frames.find(it->second.frame_id);
  if (frame == state.frames.end() || !frame->second.registered) return false;
  *image = &it->second;
  return true;
}

// Reprojection error (px) of one observation with the state's current values;
// +inf for a point behind the camera.
double ObservationError(const MapperState& state,
                        const Track& track,
                        const TrackElement& el) {
  const SfmImage& image = state.images.at(el.image_id);
  const SE3 cam_from_world = CamFromRig(state, image.camera_id) *
                             state.frames.at(image.frame_id).rig_from_world;
  Vec2 pixel;
  if (!state.cameras.at(image.camera_id)
           .Project(cam_from_world * track.xyz, &pixel)) {
    return std::numeric_limits<double>::infinity();
  }
  return (pixel - image.keypoints.at(el.point2D_idx)).norm();
}

double MeanError(const MapperState& state,
                 const std::vector<Observation>& observations) {
  if (observations.empty()) return 0.0;
  double sum = 0.0;
  for (const Observation& obs : observations) {
    sum += ObservationError(state,
                            state.tracks[obs.track_idx],
                            TrackElement{obs.image_id, obs.point2D_idx});
  }
  return sum / static_cast<double>(observations.size());
}

ceres::LossFunction* MakeLoss(const BundleAdjustmentOptions& options) {
  if (options.loss_type == "huber")
    return new ceres::HuberLoss(options.loss_scale);
  if (options.loss_type == "cauchy")
    return new ceres::CauchyLoss(options.loss_scale);
  return nullptr;  // trivial
}

ceres::CostFunction* MakeReprojectionCost(int model_id,
                                          const Vec2& observed,
                                          const SE3& cam_from_rig,
                                          bool refine_cam_from_rig) {
  return VisitCameraModel(model_id, [&](auto model) -> ceres::CostFunction* {
    using Model = decltype(model);
    if (refine_cam_from_rig)
      return RigReprojectionErrorFunctor<Model>::Create(observed);
    return new AnalyticReprojectionCost<Model>(
        observed, cam_from_rig.rotation(), cam_from_rig.translation());
  });
}

// sqrt_information S with S^T S = covariance^-1, or false when the covariance
// is not symmetric positive definite.
template <int N>
bool SqrtInformation(const Eigen::Matrix<double, N, N>& covariance,
                     Eigen::Matrix<double, N, N>* sqrt_information) {
  if (!covariance.allFinite()) return false;
  const double asymmetry =
      (covariance - covariance.transpose()).cwiseAbs().maxCoeff();
  if (asymmetry > 1e-9 * std::max(1.0, covariance.cwiseAbs().maxCoeff()))
    return false;
  Eigen::LLT<Eigen::Matrix<double, N, N>> cov_llt(covariance);
  if (cov_llt.info() != Eigen::Success) return false;
  const Eigen::Matrix<double, N, N> information =
      cov_llt.solve(Eigen::Matrix<double, N, N>::Identity());
  Eigen::LLT<Eigen::Matrix<double, N, N>> info_llt(
      0.5 * (information + information.transpose()));
  if (info_llt.info() != Eigen::Success) return false;
  // information = L L^T  =>  (L^T)^T (L^T) = information.
  *sqrt_information = info_llt.matrixL().transpose();
  return sqrt_information->allFinite();
}

// Point subsampling: with max_tracks_per_image > 0, every registered image
// contributes its best max_tracks_per_image triangulated tracks (longest
// first, then smallest error, then lowest index: deterministic) and the
// problem holds their union; otherwise every track. Returns a mask over
// state.tracks.
std::vector<char> SelectTracks(const MapperState& state, int max_tracks_per_image) {
  std::vector<char> selected(state.tracks.size(), max_tracks_per_image > 0 ? 0 : 1);
  if (max_tracks_per_image <= 0) return selected;
  std::map<image_t, std::vector<size_t>> tracks_of_image;
  for (size_t k = 0; k < state.tracks.size(); ++k) {
    const Track& track = state.tracks[k];
    if (!track.triangulated) continue;
    for (const TrackElement& el : track.elements) tracks_of_image[el.image_id].push_back(k);
  }
  auto better = [&](size_t a, size_t b) {
    const Track& ta = state.tracks[a];
    const Track& tb = state.tracks[b];
    if (ta.elements.size() != tb.elements.size()) return ta.elements.size() > tb.elements.size();
    if (ta.error != tb.error) return ta.error < tb.error;
    return a < b;
  };
  for (auto& [image_id, ids] : tracks_of_image) {
    const size_t keep = std::min(ids.size(), static_cast<size_t>(max_tracks_per_image));
    std::partial_sort(ids.begin(), ids.begin() + keep, ids.end(), better);
    for (size_t i = 0; i < keep; ++i) selected[ids[i]] = 1;
  }
  return selected;
}

struct PositionPrior {
  frame_t frame_id;
  Vec3 position;
  Mat3 sqrt_information;
};
struct RotationPrior {
  frame_t frame_id;
  Quat rig_from_world;
  double sigma;
};
struct LidarTerm {
  frame_t frame_id1;
  frame_t frame_id2;
  SE3 rig1_from_rig2;
  Mat6 sqrt_information;
};

// Everything both solvers need: the residuals (validated) and the gauge.
struct BaSpec {
  const std::vector<Observation>* observations = nullptr;  // grouped by track
  const std::set<size_t>* track_set = nullptr;
  const std::set<frame_t>* frame_set = nullptr;
  const std::set<camera_t>* camera_set = nullptr;
  std::map<camera_t, std::vector<int>> constant_params;  // sorted indices
  std::vector<PositionPrior> position_priors;
  std::vector<RotationPrior> rotation_priors;
  std::vector<LidarTerm> lidar_terms;
  // X = rig_from_prior (refine_prior_frame): the prior and LiDAR terms go
  // through X; its rotation / translation are refined where *_free.
  // X's translation is refined along the first prior_frame_translation_free_axes
  // columns of prior_frame_translation_axes (orthonormal) and held along the rest.
  bool prior_frame = false;
  bool prior_frame_rotation_free = false;
  Mat3 prior_frame_translation_axes = Mat3::Identity();
  int prior_frame_translation_free_axes = 0;
  bool first_frame_fixed = false;  // gauge: first frame held
  frame_t scale_frame = 0;         // gauge: this frame's translation
  int scale_coordinate = -1;       //   coordinate held (-1: none)
};

// The guard of X (bundle_adjustment.h): the marginal covariance of X's tangent
// [dtheta (EigenQuaternionManifold, rad); dt (m)] in a linear model of the pose
// terms (LiDAR terms and priors, whitened by their own covariances) at the
// current values, whose unknowns are X and the similarity that the images
// leave free: world_from_rig -> S * world_from_rig with S = (1 + s) Exp(omega)
// x + w. J = d r / d [dtheta, dt, s, omega, w] by central differences (steps
// 1e-6 rad / m / unitless); H = J^T J; X's marginal information is the Schur
// complement H_xx - H_xg H_gg^+ H_gx (pseudo-inverse: a similarity direction
// no term sees is a gauge that does not touch X). False when that is not
// finite.
bool PriorFrameCovariance(const BaSpec& spec, const MapperState& state, Mat6* covariance) {
  constexpr int kNumUnknowns = 13;
  using VecZ = Eigen::Matrix<double, kNumUnknowns, 1>;
  using MatZ = Eigen::Matrix<double, kNumUnknowns, kNumUnknowns>;
  // Every pose term's whitened residual at the perturbation z.
  const auto residuals = [&](const VecZ& z) {
    const SE3 x(so3::Exp(Vec3(z.segment<3>(0))) * state.rig_from_prior.rotation(),
                state.rig_from_prior.translation() + z.segment<3>(3));
    const Quat world_rotation = so3::Exp(Vec3(z.segment<3>(7)));
    const auto pose = [&](frame_t frame_id) {
      const SE3 world_from_rig = state.frames.at(frame_id).rig_from_world.Inverse();
      return PoseBlock(SE3(world_rotation * world_from_rig.rotation(),
                           (1.0 + z(6)) * (world_rotation * world_from_rig.translation()) +
                               z.segment<3>(10))
                           .Inverse());
    };
    const PoseBlock xb(x);
    std::vector<double> r;
    const auto evaluate = [&](const ceres::CostFunction& cost, const double* const* params) {
      std::vector<double> out(cost.num_residuals());
      if (cost.Evaluate(params, out.data(), nullptr)) r.insert(r.end(), out.begin(), out.end());
    };
    for (const PositionPrior& prior : spec.position_priors) {
      const PoseBlock b = pose(prior.frame_id);
      const std::unique_ptr<ceres::CostFunction> cost(
          PriorFramePositionPriorFunctor::Create(prior.position, prior.sqrt_information));
      const double* params[] = {b.q.data(), b.t.data(), xb.t.data()};
      evaluate(*cost, params);
    }
    for (const RotationPrior& prior : spec.rotation_priors) {
      const PoseBlock b = pose(prior.frame_id);
      const std::unique_ptr<ceres::CostFunction> cost(
          PriorFrameRotationPriorFunctor::Create(prior.rig_from_world, prior.sigma));
      const double* params[] = {b.q.data(), xb.q.data()};
      evaluate(*cost, params);
    }
    for (const LidarTerm& term : spec.lidar_terms) {
      const PoseBlock b1 = pose(term.frame_id1);
      const PoseBlock b2 = pose(term.frame_id2);
      const std::unique_ptr<ceres::CostFunction> cost(
          PriorFrameRelativePoseFunctor::Create(term.rig1_from_rig2, term.sqrt_information));
      const double* params[] = {
          b1.q.data(), b1.t.data(), b2.q.data(), b2.t.data(), xb.q.data(), xb.t.data()};
      evaluate(*cost, params);
    }
    return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(r.data(), r.size()));
  };
  const size_t num_residuals = static_cast<size_t>(residuals(VecZ::Zero()).size());
  constexpr double kStep = 1e-6;
  Eigen::MatrixXd J(num_residuals, kNumUnknowns);
  for (int k = 0; k < kNumUnknowns; ++k) {
    const VecZ step = VecZ::Unit(k) * kStep;
    const Eigen::VectorXd plus = residuals(step);
    const Eigen::VectorXd minus = residuals(-step);
    if (static_cast<size_t>(plus.size()) != num_residuals ||
        static_cast<size_t>(minus.size()) != num_residuals) {
      return false;
    }
    J.col(k) = (plus - minus) / (2.0 * kStep);
  }
  const MatZ H = J.transpose() * J;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 7, 7>> gauge(
      H.bottomRightCorner<7, 7>());
  const Eigen::Matrix<double, 7, 1> values = gauge.eigenvalues();
  Eigen::Matrix<double, 7, 1> inverse_values = Eigen::Matrix<double, 7, 1>::Zero();
  for (int i = 0; i < 7; ++i) {
    if (values(i) > 1e-12 * std::max(1.0, values(6))) inverse_values(i) = 1.0 / values(i);
  }
  const Eigen::Matrix<double, 7, 7> gauge_pinv =
      gauge.eigenvectors() * inverse_values.asDiagonal() * gauge.eigenvectors().transpose();
  const Eigen::Matrix<double, 6, 7> H_xg = H.topRightCorner<6, 7>();
  Mat6 information = H.topLeftCorner<6, 6>() - H_xg * gauge_pinv * H_xg.transpose();
  // Plus a weak prior of 1 rad / 1 m per axis, so that a direction no term
  // sees (t_X along the only turn axis) gets sigma ~1, far above any limit,
  // while the seen ones (information >> 1) keep theirs.
  information = 0.5 * (information + information.transpose()).eval() + Mat6::Identity();
  const Eigen::SelfAdjointEigenSolver<Mat6> eigen(information);
  const Vec6 x_values = eigen.eigenvalues();
  if (!(x_values(0) > 0.0) || !x_values.allFinite()) return false;
  *covariance = eigen.eigenvectors() * x_values.cwiseInverse().asDiagonal() *
                eigen.eigenvectors().transpose();
  return true;
}

// Tangent of X's translation along the columns of `axes` (orthonormal 3 x k):
// t = t0 + axes * delta, so that only those directions move.
class TranslationSubspaceManifold : public ceres::Manifold {
 public:
  explicit TranslationSubspaceManifold(const Eigen::Matrix<double, 3, Eigen::Dynamic>& axes)
      : axes_(axes) {}
  int AmbientSize() const override { return 3; }
  int TangentSize() const override { return static_cast<int>(axes_.cols()); }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    Vec3::Map(x_plus_delta) =
        Eigen::Map<const Vec3>(x) + axes_ * Eigen::Map<const Eigen::VectorXd>(delta, axes_.cols());
    return true;
  }
  bool PlusJacobian(const double* /*x*/, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::RowMajor>>(
        jacobian, 3, axes_.cols()) = axes_;
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    Eigen::Map<Eigen::VectorXd>(y_minus_x, axes_.cols()) =
        axes_.transpose() * (Eigen::Map<const Vec3>(y) - Eigen::Map<const Vec3>(x));
    return true;
  }
  bool MinusJacobian(const double* /*x*/, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
        jacobian, axes_.cols(), 3) = axes_.transpose();
    return true;
  }

 private:
  Eigen::Matrix<double, 3, Eigen::Dynamic> axes_;
};

int NumThreads(const BundleAdjustmentOptions& options) {
  return options.num_threads > 0
             ? options.num_threads
             : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

void SolveWithCeres(const BundleAdjustmentOptions& options,
                    const BaSpec& spec,
                    std::chrono::steady_clock::time_point start,
                    MapperState* state,
                    BundleAdjustmentStats* stats) {
  // Ceres orders the parameter blocks of a ParameterBlockOrdering group by
  // address: every block other than the points (frame poses, cam_from_rig,
  // rig_from_prior, intrinsics) lives in one buffer, in creation order, so
  // that the elimination order does not depend on where the heap put
  // separately allocated blocks (which other threads' allocations change).
  // The points are the elements of state->tracks (ascending addresses).
  size_t buffer_size = 7 * (spec.frame_set->size() + spec.camera_set->size() + 1);
  for (camera_t camera_id : *spec.camera_set) {
    buffer_size += state->cameras.at(camera_id).params.size();
  }
  std::vector<double> buffer(buffer_size);
  size_t buffer_used = 0;
  const auto take = [&](size_t n) {
    THROW_CHECK_LE(buffer_used + n, buffer.size());
    double* p = buffer.data() + buffer_used;
    buffer_used += n;
    return p;
  };
  const auto make_pose = [&](const SE3& pose) {
    const PoseBlock block(pose);
    PoseSlot slot{{take(4)}, {take(3)}};
    std::copy(block.q.begin(), block.q.end(), slot.q.data());
    std::copy(block.t.begin(), block.t.end(), slot.t.data());
    return slot;
  };
  std::map<frame_t, PoseSlot> frame_blocks;
  for (frame_t frame_id : *spec.frame_set) {
    frame_blocks.emplace(frame_id, make_pose(state->frames.at(frame_id).rig_from_world));
  }
  const bool refine_rig = state->has_rig && options.refine_cam_from_rig;
  const camera_t reference_camera = *spec.camera_set->begin();
  PoseSlot prior_frame_block = make_pose(state->rig_from_prior);
  std::map<camera_t, PoseSlot> rig_blocks;
  if (refine_rig) {
    for (camera_t camera_id : *spec.camera_set) {
      if (camera_id == reference_camera)
        continue;  // stays constant (functor member)
      rig_blocks.emplace(camera_id, make_pose(CamFromRig(*state, camera_id)));
    }
  }
  std::map<camera_t, double*> camera_params;
  for (camera_t camera_id : *spec.camera_set) {
    const std::vector<double>& params = state->cameras.at(camera_id).params;
    double* p = take(params.size());
    std::copy(params.begin(), params.end(), p);
    camera_params.emplace(camera_id, p);
  }

  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  std::unique_ptr<ceres::LossFunction> loss(MakeLoss(options));
  ceres::EigenQuaternionManifold quaternion_manifold;
  std::vector<std::unique_ptr<ceres::Manifold>> owned_manifolds;

  for (const Observation& obs : *spec.observations) {
    const SfmImage& image = state->images.at(obs.image_id);
    double* intrinsics = camera_params.at(image.camera_id);
    const Camera& camera = state->cameras.at(image.camera_id);
    PoseSlot& frame = frame_blocks.at(image.frame_id);
    Track& track = state->tracks[obs.track_idx];
    const Vec2& observed = image.keypoints[obs.point2D_idx];
    const bool refine_this_rig = refine_rig && image.camera_id != reference_camera;
    ceres::CostFunction* cost = MakeReprojectionCost(
        camera.model_id, observed, CamFromRig(*state, image.camera_id), refine_this_rig);
    if (refine_this_rig) {
      PoseSlot& rig = rig_blocks.at(image.camera_id);
      problem.AddResidualBlock(cost,
                               loss.get(),
                               rig.q.data(),
                               rig.t.data(),
                               frame.q.data(),
                               frame.t.data(),
                               track.xyz.data(),
                               intrinsics);
    } else {
      problem.AddResidualBlock(
          cost, loss.get(), frame.q.data(), frame.t.data(), track.xyz.data(), intrinsics);
    }
  }
  for (auto& [frame_id, block] : frame_blocks) {
    problem.SetManifold(block.q.data(), &quaternion_manifold);
  }
  for (auto& [camera_id, block] : rig_blocks) {
    problem.SetManifold(block.q.data(), &quaternion_manifold);
  }
  // Intrinsics: hold the groups that are not refined.
  for (camera_t camera_id : *spec.camera_set) {
    double* intrinsics = camera_params.at(camera_id);
    const std::vector<int>& constant = spec.constant_params.at(camera_id);
    const int num_params = static_cast<int>(state->cameras.at(camera_id).params.size());
    if (static_cast<int>(constant.size()) == num_params) {
      problem.SetParameterBlockConstant(intrinsics);
    } else if (!constant.empty()) {
      owned_manifolds.push_back(std::make_unique<ceres::SubsetManifold>(num_params, constant));
      problem.SetManifold(intrinsics, owned_manifolds.back().get());
    }
  }
  double* x_q = prior_frame_block.q.data();
  double* x_t = prior_frame_block.t.data();
  for (const PositionPrior& prior : spec.position_priors) {
    PoseSlot& block = frame_blocks.at(prior.frame_id);
    if (spec.prior_frame) {
      problem.AddResidualBlock(
          PriorFramePositionPriorFunctor::Create(prior.position, prior.sqrt_information),
          nullptr,
          block.q.data(),
          block.t.data(),
          x_t);
    } else {
      problem.AddResidualBlock(PositionPriorFunctor::Create(prior.position, prior.sqrt_information),
                               nullptr,
                               block.q.data(),
                               block.t.data());
    }
  }
  for (const RotationPrior& prior : spec.rotation_priors) {
    PoseSlot& block = frame_blocks.at(prior.frame_id);
    if (spec.prior_frame) {
      problem.AddResidualBlock(
          PriorFrameRotationPriorFunctor::Create(prior.rig_from_world, prior.sigma),
          nullptr,
          block.q.data(),
          x_q);
    } else {
      problem.AddResidualBlock(
          RotationPriorFunctor::Create(prior.rig_from_world, prior.sigma), nullptr, block.q.data());
    }
  }
  for (const LidarTerm& term : spec.lidar_terms) {
    PoseSlot& b1 = frame_blocks.at(term.frame_id1);
    PoseSlot& b2 = frame_blocks.at(term.frame_id2);
    if (spec.prior_frame) {
      problem.AddResidualBlock(
          PriorFrameRelativePoseFunctor::Create(term.rig1_from_rig2, term.sqrt_information),
          nullptr,
          b1.q.data(),
          b1.t.data(),
          b2.q.data(),
          b2.t.data(),
          x_q,
          x_t);
    } else {
      problem.AddResidualBlock(
          RelativePoseFunctor::Create(term.rig1_from_rig2, term.sqrt_information),
          nullptr,
          b1.q.data(),
          b1.t.data(),
          b2.q.data(),
          b2.t.data());
    }
  }
  if (problem.HasParameterBlock(x_q)) {
    problem.SetManifold(x_q, &quaternion_manifold);
    if (!spec.prior_frame_rotation_free) problem.SetParameterBlockConstant(x_q);
  }
  if (problem.HasParameterBlock(x_t)) {
    const int free_axes = spec.prior_frame_translation_free_axes;
    if (free_axes == 0) {
      problem.SetParameterBlockConstant(x_t);
    } else if (free_axes < 3) {
      owned_manifolds.push_back(std::make_unique<TranslationSubspaceManifold>(
          spec.prior_frame_translation_axes.leftCols(free_axes)));
      problem.SetManifold(x_t, owned_manifolds.back().get());
    }
  }
  // Gauge.
  if (!options.refine_frame_poses) {
    for (auto& [frame_id, block] : frame_blocks) {
      problem.SetParameterBlockConstant(block.q.data());
      problem.SetParameterBlockConstant(block.t.data());
    }
  } else {
    if (spec.first_frame_fixed) {
      PoseSlot& first = frame_blocks.begin()->second;
      problem.SetParameterBlockConstant(first.q.data());
      problem.SetParameterBlockConstant(first.t.data());
    }
    if (spec.scale_coordinate >= 0) {
      PoseSlot& far = frame_blocks.at(spec.scale_frame);
      owned_manifolds.push_back(std::make_unique<ceres::SubsetManifold>(
          3, std::vector<int>{spec.scale_coordinate}));
      problem.SetManifold(far.t.data(), owned_manifolds.back().get());
    }
  }
  // Solver.
  ceres::Solver::Options solver_options;
  const bool dense = static_cast<int>(frame_blocks.size()) <= options.dense_schur_max_frames;
  if (dense) {
    solver_options.linear_solver_type = ceres::DENSE_SCHUR;
  } else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
    solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
    solver_options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  } else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE)) {
    solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
    solver_options.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
  } else {
    solver_options.linear_solver_type = ceres::ITERATIVE_SCHUR;
    solver_options.preconditioner_type = ceres::SCHUR_JACOBI;
  }
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (size_t k : *spec.track_set) ordering->AddElementToGroup(state->tracks[k].xyz.data(), 0);
  std::vector<double*> blocks;
  problem.GetParameterBlocks(&blocks);
  for (double* block : blocks) {
    if (!ordering->IsMember(block)) ordering->AddElementToGroup(block, 1);
  }
  solver_options.linear_solver_ordering = ordering;
  solver_options.max_num_iterations = options.max_num_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  // One thread by default: Ceres 2.1's multi-threaded Schur elimination and
  // cost sum add the contributions of the points in thread-timing order, so
  // their last bits (and with them the model) would differ from run to run.
  solver_options.num_threads = options.ceres_num_threads;
  solver_options.minimizer_progress_to_stdout = options.verbose;
  solver_options.logging_type = options.verbose ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;

  ceres::Solver::Summary summary;
  const auto solve_start = std::chrono::steady_clock::now();
  stats->setup_seconds = std::chrono::duration<double>(solve_start - start).count();
  ceres::Solve(solver_options, &problem, &summary);
  stats->ceres_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - solve_start).count();
  stats->linear_solver_seconds = summary.linear_solver_time_in_seconds;
  stats->evaluation_seconds =
      summary.residual_evaluation_time_in_seconds + summary.jacobian_evaluation_time_in_seconds;
  stats->initial_cost = summary.initial_cost;
  stats->final_cost = summary.final_cost;
  stats->num_iterations = static_cast<int>(summary.iterations.size());
  stats->converged = summary.termination_type == ceres::CONVERGENCE;
  stats->usable = summary.IsSolutionUsable();
  stats->termination = ceres::TerminationTypeToString(summary.termination_type) +
                       std::string(": ") + summary.message;
  stats->linear_solver = ceres::LinearSolverTypeToString(summary.linear_solver_type_used);

  // Write back (the points were optimised in place).
  for (const auto& [camera_id, p] : camera_params) {
    std::vector<double>& params = state->cameras.at(camera_id).params;
    std::copy(p, p + params.size(), params.begin());
  }
  for (const auto& [frame_id, block] : frame_blocks) {
    state->frames.at(frame_id).rig_from_world = block.ToSE3();
  }
  for (const auto& [camera_id, block] : rig_blocks) {
    state->cam_from_rig[camera_id] = block.ToSE3();
  }
  if (spec.prior_frame) state->rig_from_prior = prior_frame_block.ToSE3();
}

// The same problem through SolveSchurBundleAdjustment (schur_bundle_adjuster.h).
void SolveWithSchur(const BundleAdjustmentOptions& options,
                    const BaSpec& spec,
                    std::chrono::steady_clock::time_point start,
                    MapperState* state,
                    BundleAdjustmentStats* stats) {
  SchurBaProblem problem;
  std::map<frame_t, int> frame_index;
  for (frame_t frame_id : *spec.frame_set) {
    frame_index[frame_id] = static_cast<int>(problem.frames.size());
    const SE3& pose = state->frames.at(frame_id).rig_from_world;
    SchurBaFrame frame;
    frame.rig_from_world_rotation = pose.rotation();
    frame.rig_from_world_translation = pose.translation();
    const bool all_fixed = !options.refine_frame_poses ||
                           (spec.first_frame_fixed && frame_id == *spec.frame_set->begin());
    frame.fixed.fill(all_fixed);
    if (options.refine_frame_poses && spec.scale_coordinate >= 0 && frame_id == spec.scale_frame) {
      frame.fixed[3 + spec.scale_coordinate] = true;
    }
    problem.frames.push_back(frame);
  }
  std::map<camera_t, int> camera_index;
  for (camera_t camera_id : *spec.camera_set) {
    camera_index[camera_id] = static_cast<int>(problem.cameras.size());
    const Camera& camera = state->cameras.at(camera_id);
    SchurBaCamera c;
    c.model_id = camera.model_id;
    c.params = camera.params;
    const std::vector<int>& constant = spec.constant_params.at(camera_id);
    for (int i = 0; i < static_cast<int>(camera.params.size()); ++i) {
      if (!std::binary_search(constant.begin(), constant.end(), i)) c.free_indices.push_back(i);
    }
    problem.cameras.push_back(std::move(c));
  }
  for (const auto& [camera_id, c] : camera_index) {
    const SE3 cam_from_rig = CamFromRig(*state, camera_id);
    problem.cameras[c].cam_from_rig_rotation =
        cam_from_rig.rotation().normalized().toRotationMatrix();
    problem.cameras[c].cam_from_rig_translation = cam_from_rig.translation();
  }
  // Frame and camera index of every image in the problem.
  struct ImageIndex {
    int frame;
    int camera;
    const std::vector<Vec2>* keypoints;
  };
  std::unordered_map<image_t, ImageIndex> image_index;
  for (const auto& [image_id, image] : state->images) {
    const auto f = frame_index.find(image.frame_id);
    const auto c = camera_index.find(image.camera_id);
    if (f != frame_index.end() && c != camera_index.end()) {
      image_index.emplace(image_id, ImageIndex{f->second, c->second, &image.keypoints});
    }
  }
  std::vector<size_t> track_of_point;
  problem.observations.reserve(spec.observations->size());
  for (const Observation& obs : *spec.observations) {
    if (track_of_point.empty() || track_of_point.back() != obs.track_idx) {
      track_of_point.push_back(obs.track_idx);
      problem.points.push_back(state->tracks[obs.track_idx].xyz);
    }
    const ImageIndex& index = image_index.at(obs.image_id);
    SchurBaObservation o;
    o.frame = index.frame;
    o.camera = index.camera;
    o.point = static_cast<int>(problem.points.size()) - 1;
    o.observed = (*index.keypoints)[obs.point2D_idx];
    problem.observations.push_back(o);
  }
  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  const bool x = spec.prior_frame;
  for (const PositionPrior& prior : spec.position_priors) {
    costs.emplace_back(
        x ? PriorFramePositionPriorFunctor::Create(prior.position, prior.sqrt_information)
          : PositionPriorFunctor::Create(prior.position, prior.sqrt_information));
    problem.pose_terms.push_back(
        {SchurBaPoseTerm::kPose, costs.back().get(), frame_index.at(prior.frame_id), -1, x});
  }
  for (const RotationPrior& prior : spec.rotation_priors) {
    costs.emplace_back(x ? PriorFrameRotationPriorFunctor::Create(prior.rig_from_world, prior.sigma)
                         : RotationPriorFunctor::Create(prior.rig_from_world, prior.sigma));
    problem.pose_terms.push_back(
        {SchurBaPoseTerm::kRotation, costs.back().get(), frame_index.at(prior.frame_id), -1, x});
  }
  for (const LidarTerm& term : spec.lidar_terms) {
    costs.emplace_back(
        x ? PriorFrameRelativePoseFunctor::Create(term.rig1_from_rig2, term.sqrt_information)
          : RelativePoseFunctor::Create(term.rig1_from_rig2, term.sqrt_information));
    problem.pose_terms.push_back({SchurBaPoseTerm::kRelative,
                                  costs.back().get(),
                                  frame_index.at(term.frame_id1),
                                  frame_index.at(term.frame_id2),
                                  x});
  }
  if (x) {
    problem.has_rig_from_prior = true;
    problem.rig_from_prior_rotation = state->rig_from_prior.rotation();
    problem.rig_from_prior_translation = state->rig_from_prior.translation();
    problem.rig_from_prior_translation_axes = spec.prior_frame_translation_axes;
    for (int k = 0; k < 3; ++k) {
      problem.rig_from_prior_fixed[k] = !spec.prior_frame_rotation_free;
      problem.rig_from_prior_fixed[3 + k] = k >= spec.prior_frame_translation_free_axes;
    }
  }
  SchurBaOptions schur_options;
  schur_options.loss_type = options.loss_type;
  schur_options.loss_scale = options.loss_scale;
  schur_options.max_num_iterations = options.max_num_iterations;
  schur_options.function_tolerance = options.function_tolerance;
  schur_options.gradient_tolerance = options.gradient_tolerance;
  schur_options.parameter_tolerance = options.parameter_tolerance;
  schur_options.num_threads = NumThreads(options);
  const auto solve_start = std::chrono::steady_clock::now();
  stats->setup_seconds = std::chrono::duration<double>(solve_start - start).count();
  const SchurBaSummary summary = SolveSchurBundleAdjustment(schur_options, &problem);
  stats->ceres_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - solve_start).count();
  stats->linear_solver_seconds = summary.linear_solver_seconds;
  stats->evaluation_seconds = summary.evaluation_seconds;
  stats->initial_cost = summary.initial_cost;
  stats->final_cost = summary.final_cost;
  stats->num_iterations = summary.num_iterations;
  stats->converged = summary.converged;
  stats->usable = std::isfinite(summary.final_cost);
  stats->termination = summary.termination;
  stats->linear_solver = "lisfm dense Schur LM";

  for (const auto& [frame_id, f] : frame_index) {
    state->frames.at(frame_id).rig_from_world =
        SE3(problem.frames[f].rig_from_world_rotation.normalized(),
            problem.frames[f].rig_from_world_translation);
  }
  for (const auto& [camera_id, c] : camera_index) {
    state->cameras.at(camera_id).params = problem.cameras[c].params;
  }
  for (size_t p = 0; p < track_of_point.size(); ++p) {
    state->tracks[track_of_point[p]].xyz = problem.points[p];
  }
  if (x) {
    state->rig_from_prior =
        SE3(problem.rig_from_prior_rotation.normalized(), problem.rig_from_prior_translation);
  }
}

// Mean reprojection error of each adjusted track over its registered images;
// returns the mean over all those observations (the adjusted ones).
double UpdateTrackErrors(const std::set<size_t>& track_set, MapperState* state) {
  double total = 0.0;
  size_t total_count = 0;
  for (size_t k : track_set) {
    Track& track = state->tracks[k];
    double sum = 0.0;
    int count = 0;
    for (const TrackElement& el : track.elements) {
      const SfmImage* image = nullptr;
      if (!ImageIsRegistered(*state, el.image_id, &image)) continue;
      sum += ObservationError(*state, track, el);
      ++count;
    }
    track.error = count > 0 ? sum / count : -1.0;
    total += sum;
    total_count += static_cast<size_t>(count);
  }
  return total_count > 0 ? total / static_cast<double>(total_count) : 0.0;
}

// ---- Steps of RunBundleAdjustment, in call order ----

// The observations of the adjustment and the sets they span.
struct BaObservations {
  std::vector<Observation> observations;  // grouped by track
  std::set<size_t> track_set;
  std::set<frame_t> frame_set;
  std::set<image_t> image_set;
  std::set<camera_t> camera_set;
};

// Observations of triangulated tracks (those SelectTracks keeps) in registered
// images; tracks with fewer than two such observations leave the point
// undetermined (skipped).
BaObservations CollectObservations(const BundleAdjustmentOptions& options,
                                   const MapperState& state) {
  BaObservations o;
  const std::vector<char> selected = SelectTracks(state, options.max_tracks_per_image);
  for (size_t k = 0; k < state.tracks.size(); ++k) {
    const Track& track = state.tracks[k];
    if (!track.triangulated || !selected[k]) continue;
    std::vector<Observation> track_obs;
    for (const TrackElement& el : track.elements) {
      const SfmImage* image = nullptr;
      if (!ImageIsRegistered(state, el.image_id, &image)) continue;
      THROW_CHECK_LT(el.point2D_idx, image->keypoints.size());
      track_obs.push_back({k, el.image_id, el.point2D_idx});
    }
    if (track_obs.size() < 2) continue;
    o.track_set.insert(k);
    for (const Observation& obs : track_obs) {
      const SfmImage& image = state.images.at(obs.image_id);
      o.frame_set.insert(image.frame_id);
      o.image_set.insert(obs.image_id);
      o.camera_set.insert(image.camera_id);
      o.observations.push_back(obs);
    }
  }
  return o;
}

// Intrinsic parameters held constant, per camera of `camera_set`.
void HoldIntrinsics(const BundleAdjustmentOptions& options, const MapperState& state,
                    const std::set<camera_t>& camera_set, BaSpec* spec,
                    BundleAdjustmentStats* stats) {
  for (camera_t camera_id : camera_set) {
    const Camera& camera = state.cameras.at(camera_id);
    THROW_CHECK_MSG(camera.VerifyParams(), "camera " << camera.camera_id << " is invalid");
    const CameraParamGroups groups = CameraModelParamGroups(camera.model_id);
    std::vector<int>& constant = spec->constant_params[camera_id];
    if (state.constant_intrinsics.count(camera_id) > 0) {
      constant.resize(camera.params.size());
      std::iota(constant.begin(), constant.end(), 0);
      continue;
    }
    if (!options.refine_focal_length) {
      constant.insert(constant.end(), groups.focal.begin(), groups.focal.end());
    }
    if (!options.refine_principal_point) {
      constant.insert(constant.end(),
                      groups.principal_point.begin(),
                      groups.principal_point.end());
    }
    if (!options.refine_extra_params) {
      constant.insert(constant.end(), groups.extra.begin(), groups.extra.end());
    }
    std::sort(constant.begin(), constant.end());
    if (constant.size() < camera.params.size()) ++stats->num_cameras_refined;
  }
}

// Pose priors (validated) of the frames of `frame_set`; InputError for a
// covariance or sigma that cannot whiten.
void CollectPriors(const BundleAdjustmentOptions& options, const MapperState& state,
                   const std::set<frame_t>& frame_set, BaSpec* spec,
                   BundleAdjustmentStats* stats) {
  std::vector<PositionPrior>& position_priors = spec->position_priors;
  std::vector<RotationPrior>& rotation_priors = spec->rotation_priors;
  if (options.use_priors) {
    for (frame_t frame_id : frame_set) {
      const SfmFrame& frame = state.frames.at(frame_id);
      if (frame.has_prior_position) {
        Mat3 sqrt_information;
        if (!SqrtInformation<3>(frame.prior_position_covariance,
                                &sqrt_information)) {
          throw InputError("pose prior of frame " + std::to_string(frame_id),
                           "field prior_position_covariance",
                           "expected a symmetric positive-definite 3x3 "
                           "covariance (m^2), found "
                           "one that is not");
        }
        position_priors.push_back({frame_id, frame.prior_position, sqrt_information});
      }
      if (frame.has_prior_rotation) {
        if (!(frame.prior_rotation_sigma > 0.0) ||
            !std::isfinite(frame.prior_rotation_sigma)) {
          throw InputError("pose prior of frame " + std::to_string(frame_id),
                           "field prior_rotation_sigma",
                           "expected a positive finite sigma (rad), found " +
                               std::to_string(frame.prior_rotation_sigma));
        }
        rotation_priors.push_back({frame_id,
                                   frame.prior_rig_from_world_rotation.normalized(),
                                   frame.prior_rotation_sigma});
      }
    }
  }
  stats->num_position_prior_residuals = position_priors.size();
  stats->num_rotation_prior_residuals = rotation_priors.size();
}

// LiDAR relative pose constraints between two different frames of
// `frame_set` (validated); the others are counted as skipped.
void CollectLidarTerms(const BundleAdjustmentOptions& options, const MapperState& state,
                       const std::set<frame_t>& frame_set, BaSpec* spec,
                       BundleAdjustmentStats* stats) {
  std::vector<LidarTerm>& lidar_terms = spec->lidar_terms;
  if (options.use_lidar_constraints) {
    for (size_t c = 0; c < state.lidar_constraints.size(); ++c) {
      const LidarConstraint& constraint = state.lidar_constraints[c];
      if (!frame_set.count(constraint.frame_id1) ||
          !frame_set.count(constraint.frame_id2) ||
          constraint.frame_id1 == constraint.frame_id2) {
        ++stats->num_lidar_constraints_skipped;
        continue;
      }
      Mat6 sqrt_information;
      if (!SqrtInformation<6>(constraint.covariance, &sqrt_information)) {
        throw InputError(
            "LiDAR constraint " + std::to_string(c),
            "field covariance",
            "expected a symmetric positive-definite 6x6 covariance, found one "
            "that is not");
      }
      lidar_terms.push_back({constraint.frame_id1, constraint.frame_id2,
                             constraint.rig1_from_rig2, sqrt_information});
    }
  } else {
    stats->num_lidar_constraints_skipped = state.lidar_constraints.size();
  }
  stats->num_lidar_residuals = lidar_terms.size();
}

// Gauge: which frame pose coordinates are held (first frame and/or one
// translation coordinate of the frame farthest from it), from the priors and
// LiDAR terms already in `spec`.
void ChooseGauge(const BundleAdjustmentOptions& options, const MapperState& state,
                 const std::set<frame_t>& frame_set, BaSpec* spec,
                 BundleAdjustmentStats* stats) {
  const std::vector<PositionPrior>& position_priors = spec->position_priors;
  const std::vector<RotationPrior>& rotation_priors = spec->rotation_priors;
  const std::vector<LidarTerm>& lidar_terms = spec->lidar_terms;
  const frame_t first_frame = *frame_set.begin();
  frame_t& scale_frame = spec->scale_frame;
  int& scale_coordinate = spec->scale_coordinate;
  if (!options.refine_frame_poses) {
    stats->gauge = "frame poses constant";
    return;
  }
  const bool pose_from_priors = position_priors.size() >= 3 ||
                                (!position_priors.empty() && !rotation_priors.empty());
  const bool scale_fixed = position_priors.size() >= 2 || !lidar_terms.empty();
  std::vector<std::string> parts;
  if (pose_from_priors) {
    parts.push_back("pose from priors");
  } else {
    spec->first_frame_fixed = true;
    parts.push_back("frame " + std::to_string(first_frame) + " fixed");
  }
  if (scale_fixed) {
    parts.push_back(!lidar_terms.empty() ? "metric scale from LiDAR constraints"
                                         : "metric scale from priors");
  } else if (frame_set.size() >= 2) {
    // The frame farthest from the first one; its largest translation
    // coordinate is held (COLMAP's scale gauge).
    const Vec3 first_center = state.frames.at(first_frame).rig_from_world.Inverse().translation();
    double far_distance = -1.0;
    for (frame_t frame_id : frame_set) {
      if (frame_id == first_frame) continue;
      const double distance =
          (state.frames.at(frame_id).rig_from_world.Inverse().translation() - first_center)
              .norm();
      if (distance > far_distance) {
        far_distance = distance;
        scale_frame = frame_id;
      }
    }
    const Vec3 t = state.frames.at(scale_frame).rig_from_world.translation();
    scale_coordinate = 0;
    for (int i = 1; i < 3; ++i) {
      if (std::abs(t[i]) > std::abs(t[scale_coordinate])) scale_coordinate = i;
    }
    parts.push_back("scale: frame " + std::to_string(scale_frame) + " t[" +
                    std::to_string(scale_coordinate) + "] fixed");
  }
  for (size_t i = 0; i < parts.size(); ++i) {
    stats->gauge += (i ? "; " : "") + parts[i];
  }
}

// Prior frame X (refine_prior_frame, with priors or LiDAR terms in `spec`):
// which parts the data determine (guard, header comment).
void ChoosePriorFrameFreedom(const BundleAdjustmentOptions& options, const MapperState& state,
                             BaSpec* spec, BundleAdjustmentStats* stats) {
  if (options.refine_prior_frame &&
      !(spec->position_priors.empty() && spec->rotation_priors.empty() &&
        spec->lidar_terms.empty())) {
    spec->prior_frame = true;
    stats->prior_frame_used = true;
    if (!options.refine_frame_poses) {
      stats->prior_frame_note = "held: frame poses constant";
    } else if (spec->lidar_terms.empty()) {
      stats->prior_frame_note = "held: no LiDAR terms";
    } else {
      // Rotation: refined when its weakest axis is determined. Translation:
      // refined along the eigenvectors of its marginal covariance whose sigma
      // is within the limit (uncorrelated with the held ones), held along the
      // rest (a turn about one axis leaves t_X along that axis unseen).
      Mat6 covariance;
      Vec3 translation_sigmas = Vec3::Constant(std::numeric_limits<double>::infinity());
      double rotation_sigma = std::numeric_limits<double>::infinity();
      if (PriorFrameCovariance(*spec, state, &covariance)) {
        const Eigen::SelfAdjointEigenSolver<Mat3> rotation(covariance.topLeftCorner<3, 3>());
        const Eigen::SelfAdjointEigenSolver<Mat3> translation(covariance.bottomRightCorner<3, 3>());
        rotation_sigma = std::sqrt(std::max(0.0, rotation.eigenvalues()(2)));
        translation_sigmas = translation.eigenvalues().cwiseMax(0.0).cwiseSqrt();
        spec->prior_frame_translation_axes = translation.eigenvectors();
      }
      stats->prior_frame_rotation_sigma_deg = rotation_sigma * 180.0 / M_PI;
      stats->prior_frame_translation_sigma_m = translation_sigmas(2);
      stats->prior_frame_translation_sigmas_m = translation_sigmas;
      spec->prior_frame_rotation_free =
          stats->prior_frame_rotation_sigma_deg <= options.prior_frame_max_rotation_sigma_deg;
      while (spec->prior_frame_translation_free_axes < 3 &&
             translation_sigmas(spec->prior_frame_translation_free_axes) <=
                 options.prior_frame_max_translation_sigma_m) {
        ++spec->prior_frame_translation_free_axes;
      }
      const int free_axes = spec->prior_frame_translation_free_axes;
      std::string held;
      if (free_axes > 0 && free_axes < 3) {
        held = ", held along";
        for (int k = free_axes; k < 3; ++k) {
          const Vec3 axis = spec->prior_frame_translation_axes.col(k);
          held += fmt::format("{} [{:.2f}, {:.2f}, {:.2f}]",
                              k > free_axes ? " and" : "",
                              axis.x(),
                              axis.y(),
                              axis.z());
        }
        held += " (rig axes)";
      }
      stats->prior_frame_note = fmt::format(
          "rotation {} (predicted sigma {:.4f} deg, limit {:.4f}), translation {} (predicted "
          "sigma {:.2f} / {:.2f} / {:.2f} mm per direction, limit {:.2f}){}",
          spec->prior_frame_rotation_free ? "refined" : "held",
          stats->prior_frame_rotation_sigma_deg,
          options.prior_frame_max_rotation_sigma_deg,
          free_axes == 3   ? "refined"
          : free_axes == 0 ? "held"
                           : fmt::format("refined along {} of 3 directions", free_axes),
          translation_sigmas(0) * 1e3,
          translation_sigmas(1) * 1e3,
          translation_sigmas(2) * 1e3,
          options.prior_frame_max_translation_sigma_m * 1e3,
          held);
    }
    stats->prior_frame_rotation_refined = spec->prior_frame_rotation_free;
    stats->prior_frame_translation_directions_refined = spec->prior_frame_translation_free_axes;
    stats->prior_frame_translation_refined = spec->prior_frame_translation_free_axes > 0;
  }

}

// The log lines of one adjustment (after it).
void LogAdjustment(const MapperState& state, const BundleAdjustmentStats& stats) {
  if (stats.prior_frame_used) {
    const Vec3 omega_deg = so3::Log(state.rig_from_prior.rotation()) * 180.0 / M_PI;
    const Vec3 t_mm = state.rig_from_prior.translation() * 1e3;
    LogInfo(
        "bundle adjustment: prior frame rig_from_prior: {}; now rotation [{:.4f}, {:.4f}, "
        "{:.4f}] deg (rig axes), translation [{:.2f}, {:.2f}, {:.2f}] mm",
        stats.prior_frame_note,
        omega_deg.x(),
        omega_deg.y(),
        omega_deg.z(),
        t_mm.x(),
        t_mm.y(),
        t_mm.z());
  }
  LogInfo(
      "bundle adjustment: {} frames, {} images, {} points, {} observations, {} "
      "prior + {} "
      "LiDAR residuals; gauge: {}; cost {:.6g} -> {:.6g}, mean error {:.3f} -> "
      "{:.3f} px, {} "
      "iterations ({}), {:.2f} s (setup {:.2f}, solve {:.2f}: linear {:.2f}, "
      "evaluation {:.2f})",
      stats.num_frames,
      stats.num_images,
      stats.num_points,
      stats.num_reprojection_residuals,
      stats.num_position_prior_residuals + stats.num_rotation_prior_residuals,
      stats.num_lidar_residuals,
      stats.gauge,
      stats.initial_cost,
      stats.final_cost,
      stats.initial_mean_reprojection_error_px,
      stats.final_mean_reprojection_error_px,
      stats.num_iterations,
      stats.termination,
      stats.seconds,
      stats.setup_seconds,
      stats.ceres_seconds,
      stats.linear_solver_seconds,
      stats.evaluation_seconds);
}

}  // namespace

bool BundleAdjustmentOptions::Check() const {
  CHECK_OPTION_MSG(loss_type,
                   loss_type == "trivial" || loss_type == "huber" || loss_type == "cauchy",
                   "one of trivial, huber, cauchy");
  CHECK_OPTION_GT(loss_scale, 0.0);
  CHECK_OPTION_GE(max_num_iterations, 0);
  CHECK_OPTION_GE(function_tolerance, 0.0);
  CHECK_OPTION_GE(gradient_tolerance, 0.0);
  CHECK_OPTION_GE(parameter_tolerance, 0.0);
  CHECK_OPTION_GE(max_tracks_per_image, 0);
  CHECK_OPTION_GE(prior_frame_max_rotation_sigma_deg, 0.0);
  CHECK_OPTION_GE(prior_frame_max_translation_sigma_m, 0.0);
  CHECK_OPTION_GE(dense_schur_max_frames, 0);
  CHECK_OPTION_MSG(solver, solver == "auto" || solver == "ceres" || solver == "schur",
                   "one of auto, ceres, schur");
  CHECK_OPTION_MSG(num_threads, num_threads == -1 || num_threads >= 1, "-1 or >= 1");
  CHECK_OPTION_GE(ceres_num_threads, 1);
  return true;
}

BundleAdjustmentStats RunBundleAdjustment(
    const BundleAdjustmentOptions& options, MapperState* state) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  BundleAdjustmentStats stats;

  const BaObservations problem = CollectObservations(options, *state);
  stats.num_points = problem.track_set.size();
  stats.num_frames = problem.frame_set.size();
  stats.num_images = problem.image_set.size();
  stats.num_cameras = problem.camera_set.size();
  if (problem.observations.empty()) {
    stats.termination = "no observations";
    LogWarning(
        "bundle adjustment: no triangulated track with two registered "
        "observations");
    return stats;
  }
  stats.initial_mean_reprojection_error_px = MeanError(*state, problem.observations);
  stats.num_reprojection_residuals = problem.observations.size();

  BaSpec spec;
  HoldIntrinsics(options, *state, problem.camera_set, &spec, &stats);
  CollectPriors(options, *state, problem.frame_set, &spec, &stats);
  CollectLidarTerms(options, *state, problem.frame_set, &spec, &stats);
  ChooseGauge(options, *state, problem.frame_set, &spec, &stats);
  ChoosePriorFrameFreedom(options, *state, &spec, &stats);

  const bool refine_rig = state->has_rig && options.refine_cam_from_rig;
  spec.observations = &problem.observations;
  spec.track_set = &problem.track_set;
  spec.frame_set = &problem.frame_set;
  spec.camera_set = &problem.camera_set;
  const bool use_schur =
      options.solver == "schur" ||
      (options.solver == "auto" && !refine_rig &&
       static_cast<int>(problem.frame_set.size()) <= options.dense_schur_max_frames);
  if (use_schur) {
    THROW_CHECK_MSG(!refine_rig,
                    "the Schur solver does not refine cam_from_rig; use solver ceres");
    SolveWithSchur(options, spec, start, state, &stats);
  } else {
    SolveWithCeres(options, spec, start, state, &stats);
  }
  stats.final_mean_reprojection_error_px = UpdateTrackErrors(problem.track_set, state);
  stats.rig_from_prior = state->rig_from_prior;
  stats.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  LogAdjustment(*state, stats);
  return stats;
}

}  // namespace colmap
}  // namespace lisfm
