#include "colmap_ext/sfm/global_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/logging.h"
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

nlohmann::json ModelCounts(const MapperState& state) {
  return {{"registered_frames", state.NumRegisteredFrames()},
          {"registered_images", state.NumRegisteredImages()},
          {"points", CountTriangulated(state)},
          {"observations", CountObservations(state)},
          {"mean_reprojection_error_px", MeanTrackError(state)}};
}

}  // namespace

GlobalMapperResult RunGlobalMapper(const Database& database, const Rig* rig,
                                   const std::vector<LidarConstraintRecord>& lidar_constraints,
                                   const std::string& image_path,
                                   const GlobalMapperOptions& options) {
  GlobalMapperResult result;
  nlohmann::json& summary = result.summary;
  const auto start = Clock::now();

  // ---- load ----
  auto t0 = Clock::now();
  MapperState base = LoadMapperState(database, rig, options.load);
  size_t num_keypoints = 0;
  for (const auto& [id, image] : base.images) num_keypoints += image.keypoints.size();
  summary["load"] = {{"cameras", base.cameras.size()},
                     {"images", base.images.size()},
                     {"frames", base.frames.size()},
                     {"keypoints", num_keypoints},
                     {"rig", rig != nullptr},
                     {"seconds", SecondsSince(t0)}};
  LogInfo("global_mapper: {} cameras, {} images in {} frames, {} keypoints", base.cameras.size(),
          base.images.size(), base.frames.size(), num_keypoints);

  if (!lidar_constraints.empty()) {
    const size_t attached = AttachLidarConstraints(
        lidar_constraints,
        static_cast<int64_t>(options.lidar_constraint_tolerance_ms * 1e6), &base);
    summary["lidar_constraints"] = {{"read", lidar_constraints.size()}, {"attached", attached}};
    LogInfo("global_mapper: {} of {} LiDAR constraints attached to frames", attached,
            lidar_constraints.size());
  }

  // ---- view graph ----
  t0 = Clock::now();
  const ViewGraphStats vg = BuildViewGraph(database, options.view_graph, &base);
  summary["view_graph"] = {{"pairs_in_database", vg.num_pairs_in_database},
                           {"edges", vg.num_edges},
                           {"intra_frame_edges", vg.num_intra_frame_edges},
                           {"skipped_config", vg.num_skipped_config},
                           {"rejected_few_inliers", vg.num_rejected_few_inliers},
                           {"rejected_reestimation", vg.num_rejected_reestimation},
                           {"inlier_matches", vg.num_inlier_matches},
                           {"seconds", SecondsSince(t0)}};
  LogInfo("global_mapper: view graph with {} edges from {} pairs ({:.2f} s)", vg.num_edges,
          vg.num_pairs_in_database, SecondsSince(t0));

  std::vector<std::vector<frame_t>> components = FrameComponents(base);
  summary["components"] = nlohmann::json::array();
  size_t num_small = 0;
  for (const auto& c : components) {
    if (static_cast<int>(c.size()) < options.min_component_frames) ++num_small;
  }
  summary["num_components"] = components.size() - num_small;
  summary["num_frames_in_small_components"] = 0;
  for (const auto& c : components) {
    if (static_cast<int>(c.size()) < options.min_component_frames) {
      summary["num_frames_in_small_components"] =
          summary["num_frames_in_small_components"].get<size_t>() + c.size();
    }
  }
  {
    std::vector<frame_t> small;
    for (const auto& c : components) {
      if (static_cast<int>(c.size()) < options.min_component_frames) {
        small.insert(small.end(), c.begin(), c.end());
      }
    }
    if (!small.empty()) {
      LogWarning("global_mapper: {} frame(s) not reconstructed: their view-graph components have "
                 "fewer than Mapper.min_component_frames = {} frames (too few matched pairs "
                 "link them to the rest): {}",
                 small.size(), options.min_component_frames, FrameNames(base, small));
    }
  }
  if (components.empty() ||
      static_cast<int>(components.front().size()) < options.min_component_frames) {
    LogWarning("global_mapper: no connected component with at least {} frames; no model",
               options.min_component_frames);
  }

  for (size_t c = 0; c < components.size(); ++c) {
    const std::vector<frame_t>& frame_ids = components[c];
    if (static_cast<int>(frame_ids.size()) < options.min_component_frames) continue;
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
    nlohmann::json comp;
    comp["frames"] = frame_ids.size();
    MapperState state = base;  // the stages register only this component's frames

    t0 = Clock::now();
    const RotationAveragingStats ra =
        AverageRotations(options.rotation_averaging, frame_ids, &state);
    comp["rotation_averaging"] = {{"registered_frames", ra.num_registered_frames},
                                  {"edges", ra.num_edge_measurements},
                                  {"lidar_constraints", ra.num_lidar_measurements},
                                  {"prior_frames", ra.num_prior_frames},
                                  {"rejected_edges", ra.num_rejected_edges},
                                  {"iterations", ra.num_iterations},
                                  {"initialization", ra.initialization},
                                  {"mean_residual_deg", ra.mean_residual_deg},
                                  {"seconds", SecondsSince(t0)}};

    const std::vector<frame_t> lost_rotation = UnregisteredFrames(frame_ids, state);
    if (!lost_rotation.empty()) {
      LogWarning("global_mapper: component {}: rotation averaging dropped {} of {} frame(s): "
                 "their relative rotations to the rest were rejected as inconsistent "
                 "(RotationAveraging.max_rotation_error_deg): {}",
                 c, lost_rotation.size(), frame_ids.size(), FrameNames(state, lost_rotation));
    }

    t0 = Clock::now();
    std::vector<frame_t> registered;
    for (const frame_t id : frame_ids) {
      if (state.frames.at(id).registered) registered.push_back(id);
    }
    const TranslationAveragingStats ta =
        AverageTranslations(options.translation_averaging, registered, &state);
    comp["translation_averaging"] = {{"registered_frames", state.NumRegisteredFrames()},
                                     {"edges", ta.num_edges_input},
                                     {"rejected_1dsfm", ta.num_rejected_1dsfm},
                                     {"rejected_residual", ta.num_rejected_residual},
                                     {"prior_residuals", ta.num_prior_residuals},
                                     {"lidar_residuals", ta.num_lidar_residuals},
                                     {"metric", ta.metric},
                                     {"gauge", ta.gauge},
                                     {"seconds_1dsfm", ta.seconds_1dsfm},
                                     {"seconds", SecondsSince(t0)}};
    const std::vector<frame_t> lost_translation = UnregisteredFrames(registered, state);
    if (!lost_translation.empty()) {
      LogWarning("global_mapper: component {}: translation averaging dropped {} frame(s): no "
                 "position is determined for them once outlier directions are removed: {}",
                 c, lost_translation.size(), FrameNames(state, lost_translation));
    }
    if (static_cast<int>(state.NumRegisteredFrames()) < options.min_component_frames) {
      LogWarning("global_mapper: component {} lost its frames in averaging", c);
      summary["components"].push_back(comp);
      continue;
    }

    t0 = Clock::now();
    const TrackStats tracks = BuildTracks(options.tracks, &state);
    const TriangulationStats tri = TriangulateTracks(options.triangulation, &state);
    comp["tracks"] = {{"tracks", tracks.num_tracks},
                      {"inconsistent", tracks.num_tracks_inconsistent},
                      {"mean_track_length", tracks.mean_track_length},
                      {"triangulated", tri.num_tracks_triangulated},
                      {"failed_angle", tri.num_tracks_failed_angle},
                      {"failed_reprojection", tri.num_tracks_failed_reprojection},
                      {"failed_depth", tri.num_tracks_failed_depth},
                      {"observations", tri.num_observations},
                      {"mean_reprojection_error_px", tri.mean_reprojection_error_px},
                      {"seconds", SecondsSince(t0)}};

    nlohmann::json rounds = nlohmann::json::array();
    for (int round = 0; round <= options.num_refinement_rounds; ++round) {
      const bool final_round = round == options.num_refinement_rounds;
      nlohmann::json r;
      t0 = Clock::now();
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
      const BundleAdjustmentStats ba = RunBundleAdjustment(ba_options, &state);
      r["bundle_adjustment"] = {{"residuals", ba.num_reprojection_residuals},
                                {"prior_residuals",
                                 ba.num_position_prior_residuals + ba.num_rotation_prior_residuals},
                                {"lidar_residuals", ba.num_lidar_residuals},
                                {"gauge", ba.gauge},
                                {"iterations", ba.num_iterations},
                                {"initial_error_px", ba.initial_mean_reprojection_error_px},
                                {"final_error_px", ba.final_mean_reprojection_error_px},
                                {"termination", ba.termination},
                                {"usable", ba.usable},
                                {"solver", ba.linear_solver},
                                {"initial_cost", ba.initial_cost},
                                {"final_cost", ba.final_cost},
                                {"setup_seconds", ba.setup_seconds},
                                {"ceres_seconds", ba.ceres_seconds},
                                {"linear_solver_seconds", ba.linear_solver_seconds},
                                {"evaluation_seconds", ba.evaluation_seconds},
                                {"seconds", SecondsSince(t0)}};
      t0 = Clock::now();
      if (ba_options.max_tracks_per_image > 0) {
        // The points left out of the adjustment follow the new poses.
        TriangulateTracks(options.triangulation, &state);
      }
      const FilterStats filtered = FilterTracks(options.triangulation, &state);
      r["filtered_observations"] = filtered.num_observations_rejected_depth +
                                   filtered.num_observations_rejected_reprojection;
      if (!final_round) {
        r["retriangulated_observations"] = RetriangulateTracks(options.triangulation, &state);
      }
      r["filter_retriangulate_seconds"] = SecondsSince(t0);
      r["model"] = ModelCounts(state);
      rounds.push_back(r);
      LogInfo("global_mapper: component {} round {}: {} frames, {} points, {} observations, "
              "{:.3f} px",
              c, round, state.NumRegisteredFrames(), CountTriangulated(state),
              CountObservations(state), MeanTrackError(state));
    }
    comp["refinement"] = rounds;
    comp["dropped_weak_frames"] =
        DropWeakFrames(options.min_frame_observations, base.cameras, &state);
    comp["model"] = ModelCounts(state);

    t0 = Clock::now();
    Reconstruction model =
        ToReconstruction(state, options.read_colors ? image_path : std::string());
    comp["to_model_seconds"] = SecondsSince(t0);
    summary["components"].push_back(comp);
    if (model.NumImages() >= static_cast<size_t>(std::max(2, options.min_component_frames))) {
      result.models.push_back(std::move(model));
    }
  }
  std::stable_sort(result.models.begin(), result.models.end(),
                   [](const Reconstruction& a, const Reconstruction& b) {
                     return a.NumImages() > b.NumImages();
                   });
  summary["num_models"] = result.models.size();
  summary["total_seconds"] = SecondsSince(start);
  return result;
}

}  // namespace colmap
}  // namespace lisfm
