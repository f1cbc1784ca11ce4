#include "colmap_ext/bundle_adjustment.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <thread>
#include <vector>

#include "colmap_ext/camera_model_functors.h"
#include "core/errors.h"
#include "core/logging.h"

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

}  // namespace

bool BundleAdjustmentOptions::Check() const {
  return (loss_type == "trivial" || loss_type == "huber" ||
          loss_type == "cauchy") &&
         loss_scale > 0.0 && max_num_iterations >= 0 &&
         function_tolerance >= 0.0 && gradient_tolerance >= 0.0 &&
         parameter_tolerance >= 0.0 && dense_schur_max_frames >= 0 &&
         max_tracks_per_image >= 0 &&
         (num_threads == -1 || num_threads >= 1);
}

BundleAdjustmentStats RunBundleAdjustment(
    const BundleAdjustmentOptions& options, MapperState* state) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_MSG(options.Check(), "invalid BundleAdjustmentOptions");
  const auto start = std::chrono::steady_clock::now();
  BundleAdjustmentStats stats;

  // Observations of triangulated tracks in registered images; tracks with
  // fewer than two such observations leave the point undetermined (skipped).
  std::vector<Observation> observations;
  std::set<size_t> track_set;
  std::set<frame_t> frame_set;
  std::set<image_t> image_set;
  std::set<camera_t> camera_set;
  const std::vector<char> selected = SelectTracks(*state, options.max_tracks_per_image);
  for (size_t k = 0; k < state->tracks.size(); ++k) {
    const Track& track = state->tracks[k];
    if (!track.triangulated || !selected[k]) continue;
    std::vector<Observation> track_obs;
    for (const TrackElement& el : track.elements) {
      const SfmImage* image = nullptr;
      if (!ImageIsRegistered(*state, el.image_id, &image)) continue;
      THROW_CHECK_LT(el.point2D_idx, image->keypoints.size());
      track_obs.push_back({k, el.image_id, el.point2D_idx});
    }
    if (track_obs.size() < 2) continue;
    track_set.insert(k);
    for (const Observation& obs : track_obs) {
      const SfmImage& image = state->images.at(obs.image_id);
      frame_set.insert(image.frame_id);
      image_set.insert(obs.image_id);
      camera_set.insert(image.camera_id);
      observations.push_back(obs);
    }
  }
  stats.num_points = track_set.size();
  stats.num_frames = frame_set.size();
  stats.num_images = image_set.size();
  stats.num_cameras = camera_set.size();
  if (observations.empty()) {
    stats.termination = "no observations";
    LogWarning(
        "bundle adjustment: no triangulated track with two registered "
        "observations");
    return stats;
  }
  stats.initial_mean_reprojection_error_px = MeanError(*state, observations);

  // Parameter blocks.
  std::map<frame_t, PoseBlock> frame_blocks;
  for (frame_t frame_id : frame_set) {
    frame_blocks.emplace(frame_id,
                         PoseBlock(state->frames.at(frame_id).rig_from_world));
  }
  const bool refine_rig = state->has_rig && options.refine_cam_from_rig;
  const camera_t reference_camera = *camera_set.begin();
  std::map<camera_t, PoseBlock> rig_blocks;
  if (refine_rig) {
    for (camera_t camera_id : camera_set) {
      if (camera_id == reference_camera)
        continue;  // stays constant (functor member)
      rig_blocks.emplace(camera_id, PoseBlock(CamFromRig(*state, camera_id)));
    }
  }

  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  std::unique_ptr<ceres::LossFunction> loss(MakeLoss(options));
  ceres::EigenQuaternionManifold quaternion_manifold;
  std::vector<std::unique_ptr<ceres::Manifold>> owned_manifolds;

  for (const Observation& obs : observations) {
    const SfmImage& image = state->images.at(obs.image_id);
    Camera& camera = state->cameras.at(image.camera_id);
    THROW_CHECK_MSG(camera.VerifyParams(),
                    "camera " << camera.camera_id << " is invalid");
    PoseBlock& frame = frame_blocks.at(image.frame_id);
    Track& track = state->tracks[obs.track_idx];
    const Vec2& observed = image.keypoints[obs.point2D_idx];
    const bool refine_this_rig =
        refine_rig && image.camera_id != reference_camera;
    ceres::CostFunction* cost =
        MakeReprojectionCost(camera.model_id,
                             observed,
                             CamFromRig(*state, image.camera_id),
                             refine_this_rig);
    if (refine_this_rig) {
      PoseBlock& rig = rig_blocks.at(image.camera_id);
      problem.AddResidualBlock(cost,
                               loss.get(),
                               rig.q.data(),
                               rig.t.data(),
                               frame.q.data(),
                               frame.t.data(),
                               track.xyz.data(),
                               camera.params.data());
    } else {
      problem.AddResidualBlock(cost,
                               loss.get(),
                               frame.q.data(),
                               frame.t.data(),
                               track.xyz.data(),
                               camera.params.data());
    }
  }
  stats.num_reprojection_residuals = observations.size();
  for (auto& [frame_id, block] : frame_blocks) {
    problem.SetManifold(block.q.data(), &quaternion_manifold);
  }
  for (auto& [camera_id, block] : rig_blocks) {
    problem.SetManifold(block.q.data(), &quaternion_manifold);
  }

  // Intrinsics: hold the groups that are not refined.
  for (camera_t camera_id : camera_set) {
    Camera& camera = state->cameras.at(camera_id);
    const CameraParamGroups groups = CameraModelParamGroups(camera.model_id);
    std::vector<int> constant;
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
    const int num_params = static_cast<int>(camera.params.size());
    if (static_cast<int>(constant.size()) == num_params) {
      problem.SetParameterBlockConstant(camera.params.data());
    } else {
      ++stats.num_cameras_refined;
      if (!constant.empty()) {
        owned_manifolds.push_back(
            std::make_unique<ceres::SubsetManifold>(num_params, constant));
        problem.SetManifold(camera.params.data(), owned_manifolds.back().get());
      }
    }
  }

  // Pose priors.
  size_t num_frames_with_position_prior = 0;
  size_t num_frames_with_rotation_prior = 0;
  if (options.use_priors) {
    for (auto& [frame_id, block] : frame_blocks) {
      const SfmFrame& frame = state->frames.at(frame_id);
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
        problem.AddResidualBlock(PositionPriorFunctor::Create(
                                     frame.prior_position, sqrt_information),
                                 nullptr,
                                 block.q.data(),
                                 block.t.data());
        ++num_frames_with_position_prior;
      }
      if (frame.has_prior_rotation) {
        if (!(frame.prior_rotation_sigma > 0.0) ||
            !std::isfinite(frame.prior_rotation_sigma)) {
          throw InputError("pose prior of frame " + std::to_string(frame_id),
                           "field prior_rotation_sigma",
                           "expected a positive finite sigma (rad), found " +
                               std::to_string(frame.prior_rotation_sigma));
        }
        problem.AddResidualBlock(
            RotationPriorFunctor::Create(
                frame.prior_rig_from_world_rotation.normalized(),
                frame.prior_rotation_sigma),
            nullptr,
            block.q.data());
        ++num_frames_with_rotation_prior;
      }
    }
  }
  stats.num_position_prior_residuals = num_frames_with_position_prior;
  stats.num_rotation_prior_residuals = num_frames_with_rotation_prior;

  // LiDAR relative pose constraints between frames in the problem.
  if (options.use_lidar_constraints) {
    for (size_t c = 0; c < state->lidar_constraints.size(); ++c) {
      const LidarConstraint& constraint = state->lidar_constraints[c];
      const auto it1 = frame_blocks.find(constraint.frame_id1);
      const auto it2 = frame_blocks.find(constraint.frame_id2);
      if (it1 == frame_blocks.end() || it2 == frame_blocks.end() ||
          constraint.frame_id1 == constraint.frame_id2) {
        ++stats.num_lidar_constraints_skipped;
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
      problem.AddResidualBlock(RelativePoseFunctor::Create(
                                   constraint.rig1_from_rig2, sqrt_information),
                               nullptr,
                               it1->second.q.data(),
                               it1->second.t.data(),
                               it2->second.q.data(),
                               it2->second.t.data());
      ++stats.num_lidar_residuals;
    }
  } else {
    stats.num_lidar_constraints_skipped = state->lidar_constraints.size();
  }

  // Gauge.
  if (!options.refine_frame_poses) {
    for (auto& [frame_id, block] : frame_blocks) {
      problem.SetParameterBlockConstant(block.q.data());
      problem.SetParameterBlockConstant(block.t.data());
    }
    stats.gauge = "frame poses constant";
  } else {
    const bool pose_from_priors = num_frames_with_position_prior >= 3 ||
                                  (num_frames_with_position_prior >= 1 &&
                                   num_frames_with_rotation_prior >= 1);
    const bool scale_fixed =
        num_frames_with_position_prior >= 2 || stats.num_lidar_residuals > 0;
    const frame_t first_frame = frame_blocks.begin()->first;
    PoseBlock& first = frame_blocks.begin()->second;
    std::vector<std::string> parts;
    if (pose_from_priors) {
      parts.push_back("pose from priors");
    } else {
      problem.SetParameterBlockConstant(first.q.data());
      problem.SetParameterBlockConstant(first.t.data());
      parts.push_back("frame " + std::to_string(first_frame) + " fixed");
    }
    if (scale_fixed) {
      parts.push_back(stats.num_lidar_residuals > 0
                          ? "metric scale from LiDAR constraints"
                          : "metric scale from priors");
    } else if (frame_blocks.size() >= 2) {
      // The frame farthest from the first one; its largest translation
      // coordinate is held (COLMAP's scale gauge).
      const Vec3 first_center = first.ToSE3().Inverse().translation();
      frame_t far_frame = first_frame;
      double far_distance = -1.0;
      for (auto& [frame_id, block] : frame_blocks) {
        if (frame_id == first_frame) continue;
        const double distance =
            (block.ToSE3().Inverse().translation() - first_center).norm();
        if (distance > far_distance) {
          far_distance = distance;
          far_frame = frame_id;
        }
      }
      PoseBlock& far = frame_blocks.at(far_frame);
      int coordinate = 0;
      for (int i = 1; i < 3; ++i) {
        if (std::abs(far.t[i]) > std::abs(far.t[coordinate])) coordinate = i;
      }
      owned_manifolds.push_back(std::make_unique<ceres::SubsetManifold>(
          3, std::vector<int>{coordinate}));
      problem.SetManifold(far.t.data(), owned_manifolds.back().get());
      parts.push_back("scale: frame " + std::to_string(far_frame) + " t[" +
                      std::to_string(coordinate) + "] fixed");
    }
    for (size_t i = 0; i < parts.size(); ++i) {
      stats.gauge += (i ? "; " : "") + parts[i];
    }
  }
  // Solver.
  ceres::Solver::Options solver_options;
  const bool dense =
      static_cast<int>(frame_blocks.size()) <= options.dense_schur_max_frames;
  if (dense) {
    solver_options.linear_solver_type = ceres::DENSE_SCHUR;
  } else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(
                 ceres::SUITE_SPARSE)) {
    solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
    solver_options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  } else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(
                 ceres::EIGEN_SPARSE)) {
    solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
    solver_options.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
  } else {
    solver_options.linear_solver_type = ceres::ITERATIVE_SCHUR;
    solver_options.preconditioner_type = ceres::SCHUR_JACOBI;
  }
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (size_t k : track_set)
    ordering->AddElementToGroup(state->tracks[k].xyz.data(), 0);
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
  solver_options.num_threads =
      options.num_threads > 0
          ? options.num_threads
          : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  solver_options.minimizer_progress_to_stdout = options.verbose;
  solver_options.logging_type =
      options.verbose ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;

  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);

  stats.initial_cost = summary.initial_cost;
  stats.final_cost = summary.final_cost;
  stats.num_iterations = static_cast<int>(summary.iterations.size());
  stats.converged = summary.termination_type == ceres::CONVERGENCE;
  stats.usable = summary.IsSolutionUsable();
  stats.termination = ceres::TerminationTypeToString(summary.termination_type) +
                      std::string(": ") + summary.message;
  stats.linear_solver =
      ceres::LinearSolverTypeToString(summary.linear_solver_type_used);

  // Write back (camera params and points were optimised in place).
  for (const auto& [frame_id, block] : frame_blocks) {
    state->frames.at(frame_id).rig_from_world = block.ToSE3();
  }
  for (const auto& [camera_id, block] : rig_blocks) {
    state->cam_from_rig[camera_id] = block.ToSE3();
  }
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
  }
  stats.final_mean_reprojection_error_px = MeanError(*state, observations);
  stats.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  LogInfo(
      "bundle adjustment: {} frames, {} images, {} points, {} observations, {} "
      "prior + {} "
      "LiDAR residuals; gauge: {}; cost {:.6g} -> {:.6g}, mean error {:.3f} -> "
      "{:.3f} px, {} "
      "iterations ({}), {:.2f} s",
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
      stats.seconds);
  return stats;
}

}  // namespace colmap
}  // namespace lisfm
