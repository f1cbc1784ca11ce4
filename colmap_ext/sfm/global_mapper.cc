#include "colmap_ext/sfm/global_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"
#include "core/rig.h"

namespace lisfm {
namespace colmap {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(const Clock::time_point& start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

size_t CountObservations(const MapperState& state) {
  size_t n = 0;
  for (const Track& track : state.tracks) {
    if (track.triangulated) n += track.elements.size();
  }
  return n;
}

size_t CountTriangulated(const MapperState& state) {
  size_t n = 0;
  for (const Track& track : state.tracks) n += track.triangulated ? 1 : 0;
  return n;
}

double MeanTrackError(const MapperState& state) {
  double sum = 0.0;
  size_t n = 0;
  for (const Track& track : state.tracks) {
    if (track.triangulated && track.error >= 0) {
      sum += track.error;
      ++n;
    }
  }
  return n > 0 ? sum / n : 0.0;
}

// Removes the observations of unregistered images from the tracks; a track
// left with fewer than two observations is no longer triangulated.
void DropUnregisteredObservations(MapperState* state) {
  for (size_t t = 0; t < state->tracks.size(); ++t) {
    Track& track = state->tracks[t];
    auto keep = [&](const TrackElement& e) { return state->IsRegistered(e.image_id); };
    std::vector<TrackElement> kept;
    for (const TrackElement& e : track.elements) {
      if (keep(e)) {
        kept.push_back(e);
      } else {
        state->images.at(e.image_id).track_ids[e.point2D_idx] = -1;
      }
    }
    track.elements.swap(kept);
    std::vector<TrackElement> kept_rejected;
    for (const TrackElement& e : track.rejected) {
      if (keep(e)) {
        kept_rejected.push_back(e);
      } else {
        state->images.at(e.image_id).track_ids[e.point2D_idx] = -1;
      }
    }
    track.rejected.swap(kept_rejected);
    if (track.elements.size() < 2) track.triangulated = false;
  }
}

// "a.jpg, b.jpg, ... (+N more)": the first image name of up to `max_listed` frames.
std::string FrameNames(const MapperState& state, const std::vector<frame_t>& frame_ids,
                       size_t max_listed = 5) {
  std::string text;
  for (size_t i = 0; i < frame_ids.size() && i < max_listed; ++i) {
    const SfmFrame& frame = state.frames.at(frame_ids[i]);
    text += (i > 0 ? ", " : "") +
            (frame.image_ids.empty() ? "frame " + std::to_string(frame.frame_id)
                                     : state.images.at(frame.image_ids.front()).name);
  }
  if (frame_ids.size() > max_listed) {
    text += fmt::format(" (+{} more)", frame_ids.size() - max_listed);
  }
  return text;
}

// The frames of `frame_ids` that `state` does not register.
std::vector<frame_t> UnregisteredFrames(const std::vector<frame_t>& frame_ids,
                                        const MapperState& state) {
  std::vector<frame_t> lost;
  for (const frame_t id : frame_ids) {
    if (!state.frames.at(id).registered) lost.push_back(id);
  }
  return lost;
}

// Relative focal-length difference above which a dropped frame's warning
// suspects its camera's prior (EXIF) focal length.
constexpr double kSuspectFocalDifference = 0.2;

// Why the focal length of `camera_id` (used by a frame being dropped) looks
// wrong, or "": compared with the median focal length that bundle adjustment
// gave the cameras of the same image size in `registered` (other cameras), or
// when there are none, with its own prior in `prior_cameras`.
std::string SuspectFocalLength(const MapperState& state,
                               const std::map<camera_t, Camera>& prior_cameras,
                               const std::set<camera_t>& registered, camera_t camera_id) {
  const Camera& camera = state.cameras.at(camera_id);
  const double focal = camera.MeanFocalLength();
  std::vector<double> peers;
  for (const camera_t other : registered) {
    const Camera& c = state.cameras.at(other);
    if (other != camera_id && c.width == camera.width && c.height == camera.height) {
      peers.push_back(c.MeanFocalLength());
    }
  }
  if (!peers.empty()) {
    std::nth_element(peers.begin(), peers.begin() + peers.size() / 2, peers.end());
    const double peer = peers[peers.size() / 2];
    if (std::abs(focal / peer - 1.0) <= kSuspectFocalDifference) return "";
    return fmt::format("; its camera {} has focal length {:.1f} px, {:.2f}x the {:.1f} px that "
                       "bundle adjustment gave the registered cameras of this image size (a "
                       "wrong EXIF/prior focal length?)",
                       camera_id, focal, focal / peer, peer);
  }
  const double prior = prior_cameras.at(camera_id).MeanFocalLength();
  if (std::abs(focal / prior - 1.0) <= kSuspectFocalDifference) return "";
  return fmt::format("; its camera {} went from the prior focal length {:.1f} px to {:.1f} px "
                     "in bundle adjustment (a wrong EXIF/prior focal length?)",
                     camera_id, prior, focal);
}

// Frames whose images see fewer than `min_observations` triangulated points
// are unregistered, each with a warning that says why: the count and, when a
// camera of the frame has a suspect focal length (SuspectFocalLength), that
// too. Returns how many.
size_t DropWeakFrames(int min_observations, const std::map<camera_t, Camera>& prior_cameras,
                      MapperState* state) {
  std::map<frame_t, int> observations;
  for (const Track& track : state->tracks) {
    if (!track.triangulated) continue;
    for (const TrackElement& e : track.elements) {
      ++observations[state->images.at(e.image_id).frame_id];
    }
  }
  std::vector<frame_t> weak;
  std::set<camera_t> kept_cameras;
  for (const auto& [frame_id, frame] : state->frames) {
    if (!frame.registered) continue;
    if (observations[frame_id] < min_observations) {
      weak.push_back(frame_id);
    } else {
      for (const image_t id : frame.image_ids) kept_cameras.insert(state->images.at(id).camera_id);
    }
  }
  for (const frame_t frame_id : weak) {
    std::string focal;
    for (const image_t image_id : state->frames.at(frame_id).image_ids) {
      focal = SuspectFocalLength(*state, prior_cameras, kept_cameras,
                                 state->images.at(image_id).camera_id);
      if (!focal.empty()) break;
    }
    LogWarning("global_mapper: dropped frame {}: it sees {} triangulated points, fewer than "
               "Mapper.min_frame_observations = {}{}",
               FrameNames(*state, {frame_id}), observations[frame_id], min_observations, focal);
  }
  for (const frame_t frame_id : weak) state->frames.at(frame_id).registered = false;
  if (!weak.empty()) DropUnregisteredObservations(state);
  return weak.size();
}

// Cameras of registered frames whose parameters are bogus after bundle
// adjustment (GlobalMapperOptions::min/max_focal_length_ratio,
// max_extra_param) are reset to their prior parameters (`prior_cameras`) and
// held constant in later adjustments (MapperState::constant_intrinsics), each
// with a warning naming the camera, the parameter and the frames that use it.
// Returns how many.
size_t ResetBogusCameras(const GlobalMapperOptions& options,
                         const std::map<camera_t, Camera>& prior_cameras,
                         MapperState* state) {
  std::map<camera_t, std::vector<frame_t>> users;
  for (const auto& [frame_id, frame] : state->frames) {
    if (!frame.registered) continue;
    for (const image_t id : frame.image_ids) {
      users[state->images.at(id).camera_id].push_back(frame_id);
    }
  }
  size_t num_reset = 0;
  for (auto& [camera_id, frames] : users) {
    if (state->constant_intrinsics.count(camera_id) > 0) continue;
    std::string why;
    if (!state->cameras.at(camera_id).HasBogusParams(options.min_focal_length_ratio,
                                                     options.max_focal_length_ratio,
                                                     options.max_extra_param, &why)) {
      continue;
    }
    frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
    LogWarning("global_mapper: bundle adjustment gave camera {} bogus parameters ({}; "
               "Mapper.min_focal_length_ratio / max_focal_length_ratio / max_extra_param): "
               "reset to its prior parameters and held from now on; used by {}",
               camera_id, why, FrameNames(*state, frames));
    state->cameras.at(camera_id).params = prior_cameras.at(camera_id).params;
    state->constant_intrinsics.insert(camera_id);
    ++num_reset;
  }
  return num_reset;
}

MapperModelCounts ModelCounts(const MapperState& state) {
  MapperModelCounts counts;
  counts.registered_frames = state.NumRegisteredFrames();
  counts.registered_images = state.NumRegisteredImages();
  counts.points = CountTriangulated(state);
  counts.observations = CountObservations(state);
  counts.mean_reprojection_error_px = MeanTrackError(state);
  return counts;
}

// skip_rotation_averaging: the frames of `frame_ids` with a rotation prior
// take it (registered), the others are unregistered. Fills the counts of
// `stats` that apply.
void RotationsFromPriors(const std::vector<frame_t>& frame_ids,
                         MapperState* state,
                         RotationAveragingStats* stats) {
  stats->num_input_frames = frame_ids.size();
  for (const frame_t id : frame_ids) {
    SfmFrame& frame = state->frames.at(id);
    frame.registered = frame.has_prior_rotation;
    if (!frame.has_prior_rotation) continue;
    frame.rig_from_world =
        SE3(frame.prior_rig_from_world_rotation, frame.rig_from_world.translation());
    ++stats->num_prior_frames;
    ++stats->num_registered_frames;
  }
  stats->initialization = "priors";
}

// skip_translation_averaging: each registered frame of `frame_ids` with a
// position prior takes it (rig origin c in world: rig_from_world translation
// t = -R c); the others are unregistered.
void PositionsFromPriors(const std::vector<frame_t>& frame_ids, MapperState* state) {
  for (const frame_t id : frame_ids) {
    SfmFrame& frame = state->frames.at(id);
    if (!frame.registered) continue;
    if (!frame.has_prior_position) {
      frame.registered = false;
      continue;
    }
    const Quat& rotation = frame.rig_from_world.rotation();
    frame.rig_from_world = SE3(rotation, -(rotation * frame.prior_position));
  }
}

// The inlier matches of the database's usable two-view geometries (configs
// as BuildViewGraph) between images of `state`, as correspondence carriers
// for CompleteAndMergeTracks; empty when completion and merging are off or
// track_completion_database_matches is false.
std::vector<ViewGraphEdge> DatabaseMatches(const Database& database,
                                           const GlobalMapperOptions& options,
                                           const MapperState& state) {
  std::vector<ViewGraphEdge> matches;
  if (!options.track_completion_database_matches || options.num_refinement_rounds == 0 ||
      (!options.track_completion.complete && !options.track_completion.merge)) {
    return matches;
  }
  for (auto& [pair_id, geometry] : database.ReadAllTwoViewGeometries()) {
    const TwoViewConfig config = static_cast<TwoViewConfig>(geometry.config);
    if (config == TwoViewConfig::kUndefined || config == TwoViewConfig::kDegenerate ||
        config == TwoViewConfig::kWatermark || config == TwoViewConfig::kMultiple ||
        geometry.inlier_matches.rows() == 0) {
      continue;
    }
    image_t image_id1 = kInvalidImageId, image_id2 = kInvalidImageId;
    PairIdToImagePair(pair_id, &image_id1, &image_id2);
    if (!state.images.count(image_id1) || !state.images.count(image_id2)) continue;
    ViewGraphEdge edge;
    edge.image_id1 = image_id1;
    edge.image_id2 = image_id2;
    edge.inliers.reserve(geometry.inlier_matches.rows());
    for (Eigen::Index k = 0; k < geometry.inlier_matches.rows(); ++k) {
      edge.inliers.emplace_back(geometry.inlier_matches(k, 0), geometry.inlier_matches(k, 1));
    }
    matches.push_back(std::move(edge));
  }
  return matches;
}

// ---- Stages of RunGlobalMapper, in call order ----

// Loads cameras, images, keypoints, priors and rig frames and attaches the
// LiDAR constraints to frames; fills the load counts of `summary`.
MapperState LoadStage(const Database& database, const Rig* rig,
                      const std::vector<LidarConstraintRecord>& lidar_constraints,
                      const GlobalMapperOptions& options, GlobalMapperSummary* summary) {
  const auto t0 = Clock::now();
  MapperState base = LoadMapperState(database, rig, options.load);
  size_t num_keypoints = 0;
  for (const auto& [id, image] : base.images) num_keypoints += image.keypoints.size();
  summary->num_cameras = base.cameras.size();
  summary->num_images = base.images.size();
  summary->num_frames = base.frames.size();
  summary->num_keypoints = num_keypoints;
  summary->has_rig = rig != nullptr;
  summary->load_seconds = SecondsSince(t0);
  LogInfo("global_mapper: {} cameras, {} images in {} frames, {} keypoints", base.cameras.size(),
          base.images.size(), base.frames.size(), num_keypoints);

  if (!lidar_constraints.empty()) {
    const size_t attached = AttachLidarConstraints(
        lidar_constraints,
        static_cast<int64_t>(options.lidar_constraint_tolerance_ms * 1e6), &base);
    summary->has_lidar_constraints = true;
    summary->num_lidar_constraints_read = lidar_constraints.size();
    summary->num_lidar_constraints_attached = attached;
    LogInfo("global_mapper: {} of {} LiDAR constraints attached to frames", attached,
            lidar_constraints.size());
  }
  return base;
}

// Builds the view graph of `base` and returns its connected components of
// frames (largest first, FrameComponents); counts and warns about the
// components below min_component_frames. `pair_runner` splits the per-pair
// estimation (BuildViewGraph); on a process that only computed its share
// (summary->view_graph.share_only) it returns no component.
std::vector<std::vector<frame_t>> ViewGraphStage(const Database& database,
                                                 const GlobalMapperOptions& options,
                                                 const WorkListRunner& pair_runner,
                                                 MapperState* base,
                                                 GlobalMapperSummary* summary) {
  const auto t0 = Clock::now();
  summary->view_graph = BuildViewGraph(database, options.view_graph, base, pair_runner);
  if (summary->view_graph.share_only) return {};
  summary->view_graph_seconds = SecondsSince(t0);
  LogInfo("global_mapper: view graph with {} edges from {} pairs ({:.2f} s)",
          summary->view_graph.num_edges, summary->view_graph.num_pairs_in_database,
          summary->view_graph_seconds);

  std::vector<std::vector<frame_t>> components = FrameComponents(*base);
  std::vector<frame_t> small;
  for (const auto& c : components) {
    if (static_cast<int>(c.size()) < options.min_component_frames) {
      summary->num_frames_in_small_components += c.size();
      small.insert(small.end(), c.begin(), c.end());
    } else {
      ++summary->num_components;
    }
  }
  if (!small.empty()) {
    LogWarning("global_mapper: {} frame(s) not reconstructed: their view-graph components have "
               "fewer than Mapper.min_component_frames = {} frames (too few matched pairs "
               "link them to the rest): {}",
               small.size(), options.min_component_frames, FrameNames(*base, small));
  }
  if (components.empty() ||
      static_cast<int>(components.front().size()) < options.min_component_frames) {
    LogWarning("global_mapper: no connected component with at least {} frames; no model",
               options.min_component_frames);
  }
  return components;
}

// Frame rotations of component `c` (`frame_ids`): rotation averaging, or the
// rotation priors when skip_rotation_averaging; warns about dropped frames.
void RotationStage(const GlobalMapperOptions& options, size_t c,
                   const std::vector<frame_t>& frame_ids, MapperState* state,
                   MapperComponentSummary* comp) {
  const auto t0 = Clock::now();
  if (options.skip_rotation_averaging) {
    comp->rotation_averaging_skipped = true;
    RotationsFromPriors(frame_ids, state, &comp->rotation_averaging);
  } else {
    comp->rotation_averaging = AverageRotations(options.rotation_averaging, frame_ids, state);
  }
  comp->rotation_averaging_seconds = SecondsSince(t0);

  const std::vector<frame_t> lost = UnregisteredFrames(frame_ids, *state);
  if (!lost.empty()) {
    LogWarning("global_mapper: component {}: rotation averaging dropped {} of {} frame(s): {}: {}",
               c, lost.size(), frame_ids.size(),
               options.skip_rotation_averaging
                   ? "they have no pose prior (Mapper.skip_rotation_averaging = 1)"
                   : "their relative rotations to the rest were rejected as inconsistent "
                     "(RotationAveraging.max_rotation_error_deg)",
               FrameNames(*state, lost));
  }
}

// Frame positions of the frames of `frame_ids` that rotation averaging
// registered: translation averaging, or the position priors when
// skip_translation_averaging; warns about dropped frames.
void TranslationStage(const GlobalMapperOptions& options, size_t c,
                      const std::vector<frame_t>& frame_ids, MapperState* state,
                      MapperComponentSummary* comp) {
  const auto t0 = Clock::now();
  std::vector<frame_t> registered;
  for (const frame_t id : frame_ids) {
    if (state->frames.at(id).registered) registered.push_back(id);
  }
  if (options.skip_translation_averaging) {
    comp->translation_averaging_skipped = true;
    PositionsFromPriors(registered, state);
  } else {
    comp->translation_averaging =
        AverageTranslations(options.translation_averaging, registered, state);
  }
  comp->translation_averaging_registered_frames = state->NumRegisteredFrames();
  comp->translation_averaging_seconds = SecondsSince(t0);
  const std::vector<frame_t> lost = UnregisteredFrames(registered, *state);
  if (!lost.empty()) {
    LogWarning("global_mapper: component {}: translation averaging dropped {} frame(s): {}: {}",
               c, lost.size(),
               options.skip_translation_averaging
                   ? "they have no position prior (Mapper.skip_translation_averaging = 1)"
                   : "no position is determined for them once outlier directions are removed",
               FrameNames(*state, lost));
  }
}

// Tracks from the matches of registered images, then their first triangulation.
void TrackStage(const GlobalMapperOptions& options, MapperState* state,
                MapperComponentSummary* comp) {
  const auto t0 = Clock::now();
  comp->tracks = BuildTracks(options.tracks, state);
  TriangulationOptions initial = options.triangulation;
  initial.max_reprojection_error_px *= options.initial_reprojection_error_factor;
  comp->triangulation = TriangulateTracks(initial, state);
  comp->tracks_seconds = SecondsSince(t0);
}

// The bundle adjustment options of refinement round `round` (the last one,
// round == num_refinement_rounds, is the final adjustment).
BundleAdjustmentOptions RoundBundleAdjustmentOptions(const GlobalMapperOptions& options,
                                                     bool final_round) {
  BundleAdjustmentOptions ba_options = options.bundle_adjustment;
  if (!final_round) ba_options.function_tolerance = options.refinement_function_tolerance;
  if (final_round && options.final_full_bundle_adjustment &&
      ba_options.max_tracks_per_image > 0) {
    // From the converged subsampled solution a few iterations reach the
    // full optimum's accuracy; the long tail of tiny cost decreases is
    // where the time went (Lund door: 34 iterations, 12 s, for the same
    // camera errors as after 5).
    ba_options.max_tracks_per_image = 0;
    ba_options.max_num_iterations =
        std::min(ba_options.max_num_iterations, options.final_max_num_iterations);
  }
  return ba_options;
}

// One refinement round of component `c`: bundle adjustment (repeated with
// the cameras it made bogus reset and held), then (points
// left out of a subsampled adjustment re-triangulated) filtering and, except
// in the final round, retriangulation.
MapperRoundSummary RefinementRound(const GlobalMapperOptions& options,
                                   size_t c,
                                   int round,
                                   const std::vector<ViewGraphEdge>& database_matches,
                                   const std::map<camera_t, Camera>& prior_cameras,
                                   MapperState* state) {
  MapperRoundSummary r;
  r.final_round = round == options.num_refinement_rounds;
  auto t0 = Clock::now();
  const BundleAdjustmentOptions ba_options = RoundBundleAdjustmentOptions(options, r.final_round);
  r.bundle_adjustment_skipped = options.skip_bundle_adjustment;
  if (!r.bundle_adjustment_skipped) {
    r.bundle_adjustment = RunBundleAdjustment(ba_options, state);
    r.reset_bogus_cameras = ResetBogusCameras(options, prior_cameras, state);
    if (r.reset_bogus_cameras > 0) {
      // The poses and points followed the bogus intrinsics: adjust again
      // with the reset cameras held.
      r.bundle_adjustment = RunBundleAdjustment(ba_options, state);
    }
  }
  r.bundle_adjustment_seconds = SecondsSince(t0);
  t0 = Clock::now();
  if (!r.bundle_adjustment_skipped && ba_options.max_tracks_per_image > 0) {
    // The points left out of the adjustment follow the new poses.
    TriangulateTracks(options.triangulation, state);
  }
  const FilterStats filtered = FilterTracks(options.triangulation, state);
  r.filtered_observations =
      filtered.num_observations_rejected_depth + filtered.num_observations_rejected_reprojection;
  r.retriangulation_skipped = !r.final_round && options.skip_retriangulation;
  if (!r.final_round && !r.retriangulation_skipped) {
    r.retriangulated_observations = RetriangulateTracks(options.triangulation, state);
  }
  r.track_completion_run =
      !r.final_round && (options.track_completion.complete || options.track_completion.merge);
  if (r.track_completion_run) {
    std::vector<ViewGraphEdge> correspondences = state->view_graph.edges;
    correspondences.insert(correspondences.end(), database_matches.begin(), database_matches.end());
    r.track_completion = CompleteAndMergeTracks(
        options.track_completion, options.triangulation, correspondences, state);
  }
  r.filter_retriangulate_seconds = SecondsSince(t0);
  r.model = ModelCounts(*state);
  LogInfo("global_mapper: component {} round {}: {} frames, {} points, {} observations, "
          "{:.3f} px",
          c, round, r.model.registered_frames, r.model.points, r.model.observations,
          r.model.mean_reprojection_error_px);
  return r;
}

// Logs rig_from_prior after the last adjustment of component `c` when it used
// the prior frame.
void LogRigFromPrior(size_t c, const MapperState& state, const MapperComponentSummary& comp) {
  if (comp.refinement.empty() || !comp.refinement.back().bundle_adjustment.prior_frame_used) {
    return;
  }
  const BundleAdjustmentStats& ba = comp.refinement.back().bundle_adjustment;
  const Vec3 omega_deg = so3::Log(state.rig_from_prior.rotation()) * 180.0 / M_PI;
  const Vec3 t_mm = state.rig_from_prior.translation() * 1e3;
  LogInfo(
      "global_mapper: component {}: rig_from_prior (the priors' / LiDAR constraints' "
      "frame in the rig frame): rotation {:.4f} deg [{:.4f}, {:.4f}, {:.4f}] (rig axes), "
      "translation [{:.2f}, {:.2f}, {:.2f}] mm; rotation {}, translation refined along {} "
      "of 3 directions",
      c,
      omega_deg.norm(),
      omega_deg.x(),
      omega_deg.y(),
      omega_deg.z(),
      t_mm.x(),
      t_mm.y(),
      t_mm.z(),
      ba.prior_frame_rotation_refined ? "refined" : "held",
      ba.prior_frame_translation_directions_refined);
}

// One line with the wall time (s) of each stage of component `c`.
void LogStageTimes(size_t c, const MapperComponentSummary& comp) {
  double ba_seconds = 0.0;
  double filter_seconds = 0.0;
  for (const MapperRoundSummary& r : comp.refinement) {
    ba_seconds += r.bundle_adjustment_seconds;
    filter_seconds += r.filter_retriangulate_seconds;
  }
  LogInfo("global_mapper: component {} stage times (s): rotation averaging {:.3f}, translation "
          "averaging {:.3f}, tracks + triangulation {:.3f}, bundle adjustment {:.3f} ({} "
          "round(s)), filter + retriangulation {:.3f}, model {:.3f}",
          c, comp.rotation_averaging_seconds, comp.translation_averaging_seconds,
          comp.tracks_seconds, ba_seconds, comp.refinement.size(), filter_seconds,
          comp.to_model_seconds);
}

// Reconstructs component `c` (`frame_ids`) from a copy of `base`: averaging,
// tracks, refinement rounds, weak frames dropped. Appends its summary to
// `summary->components`; returns false when it lost its frames in averaging
// (no model). `*model` is the component's model otherwise.
bool ReconstructComponent(const MapperState& base,
                          const std::string& image_path,
                          const std::vector<ViewGraphEdge>& database_matches,
                          const GlobalMapperOptions& options,
                          size_t c,
                          const std::vector<frame_t>& frame_ids,
                          GlobalMapperSummary* summary,
                          Reconstruction* model) {
  MapperComponentSummary& comp = summary->components.emplace_back();
  comp.frames = frame_ids.size();
  MapperState state = base;  // the stages register only this component's frames

  RotationStage(options, c, frame_ids, &state, &comp);
  TranslationStage(options, c, frame_ids, &state, &comp);
  if (static_cast<int>(state.NumRegisteredFrames()) < options.min_component_frames) {
    LogWarning("global_mapper: component {} lost its frames in averaging", c);
    comp.lost_frames_in_averaging = true;
    return false;
  }
  TrackStage(options, &state, &comp);
  for (int round = 0; round <= options.num_refinement_rounds; ++round) {
    comp.refinement.push_back(RefinementRound(options, c, round, database_matches, base.cameras, &state));
  }
  LogRigFromPrior(c, state, comp);
  comp.dropped_weak_frames = DropWeakFrames(options.min_frame_observations, base.cameras, &state);
  comp.model = ModelCounts(state);

  const auto t0 = Clock::now();
  *model = ToReconstruction(state, options.read_colors ? image_path : std::string());
  comp.to_model_seconds = SecondsSince(t0);
  LogStageTimes(c, comp);
  return true;
}

}  // namespace

bool GlobalMapperOptions::Check() const {
  CHECK_OPTION_NESTED(load);
  CHECK_OPTION_NESTED(view_graph);
  CHECK_OPTION_NESTED(rotation_averaging);
  CHECK_OPTION_NESTED(translation_averaging);
  CHECK_OPTION_NESTED(tracks);
  CHECK_OPTION_NESTED(triangulation);
  CHECK_OPTION_GE(initial_reprojection_error_factor, 1.0);
  CHECK_OPTION_MSG(min_focal_length_ratio,
                   min_focal_length_ratio > 0.0 && min_focal_length_ratio <= 1.0, "in (0, 1]");
  CHECK_OPTION_GE(max_focal_length_ratio, 1.0);
  CHECK_OPTION_GT(max_extra_param, 0.0);
  CHECK_OPTION_NESTED(track_completion);
  CHECK_OPTION_NESTED(bundle_adjustment);
  CHECK_OPTION_GE(num_refinement_rounds, 0);
  CHECK_OPTION_GE(refinement_function_tolerance, 0.0);
  CHECK_OPTION_GE(final_max_num_iterations, 0);
  CHECK_OPTION_GE(min_component_frames, 1);
  CHECK_OPTION_GE(min_frame_observations, 0);
  CHECK_OPTION_GE(lidar_constraint_tolerance_ms, 0.0);
  return true;
}

GlobalMapperResult RunGlobalMapper(const Database& database,
                                   const Rig* rig,
                                   const std::vector<LidarConstraintRecord>& lidar_constraints,
                                   const std::string& image_path,
                                   const GlobalMapperOptions& options,
                                   const WorkListRunner& pair_runner) {
  THROW_CHECK_OPTIONS(options);
  GlobalMapperResult result;
  GlobalMapperSummary& summary = result.summary;
  const auto start = Clock::now();

  MapperState base = LoadStage(database, rig, lidar_constraints, options, &summary);
  const std::vector<std::vector<frame_t>> components =
      ViewGraphStage(database, options, pair_runner, &base, &summary);
  if (summary.view_graph.share_only) {
    result = GlobalMapperResult();
    result.share_only = true;
    return result;
  }

  const std::vector<ViewGraphEdge> database_matches = DatabaseMatches(database, options, base);
  for (size_t c = 0; c < components.size(); ++c) {
    if (static_cast<int>(components[c].size()) < options.min_component_frames) continue;
    if (!options.reconstruct_all_components && !result.models.empty()) {
      std::vector<frame_t> skipped;
      for (size_t k = c; k < components.size(); ++k) {
        if (static_cast<int>(components[k].size()) < options.min_component_frames) continue;
        skipped.insert(skipped.end(), components[k].begin(), components[k].end());
      }
      LogWarning("global_mapper: {} frame(s) of smaller components not reconstructed "
                 "(Mapper.reconstruct_all_components = 0): {}",
                 skipped.size(), FrameNames(base, skipped));
      break;
    }
    Reconstruction model;
    if (ReconstructComponent(
            base, image_path, database_matches, options, c, components[c], &summary, &model) &&
        model.NumImages() >= static_cast<size_t>(std::max(2, options.min_component_frames))) {
      result.models.push_back(std::move(model));
    }
  }
  std::stable_sort(result.models.begin(), result.models.end(),
                   [](const Reconstruction& a, const Reconstruction& b) {
                     return a.NumImages() > b.NumImages();
                   });
  summary.num_models = result.models.size();
  summary.total_seconds = SecondsSince(start);
  return result;
}

}  // namespace colmap
}  // namespace lisfm
