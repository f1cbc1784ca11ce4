// `lisfm global_mapper`: global SfM on a COLMAP database.
//
// Stages (each in its own header, all acting on one MapperState):
//   LoadMapperState (cameras, images, keypoints, priors, rig frames)
//   → LiDAR constraints attached to frames (optional)
//   → BuildViewGraph (robust relative poses from the database's inlier matches)
//   → per connected component of frames:
//       AverageRotations → AverageTranslations → BuildTracks → TriangulateTracks
//       → rounds of { RunBundleAdjustment → FilterTracks → RetriangulateTracks
//                     → CompleteAndMergeTracks }
//       → final RunBundleAdjustment + FilterTracks
//       → frames left with too few observations are dropped
//   → one COLMAP Reconstruction per component (largest first).
// GlobalMapperOptions::skip_<stage> leaves out rotation averaging, translation
// averaging (the pose priors stand in), bundle adjustment or retriangulation;
// the summary records each skipped stage.
//
// Gauge and scale: with pose priors or LiDAR constraints the result is metric
// and in the priors' world frame (constraints alone fix the scale only);
// without either it is up to a similarity (like COLMAP's mapper).
//
// Failures: InputError for unusable inputs (database without two-view
// geometries, cameras without usable intrinsics, a rig that does not match the
// image names); a view graph with no component of at least
// `min_component_frames` frames gives an empty result (reported, no model).
#pragma once

#include <string>
#include <vector>

#include "colmap_ext/io/database.h"
#include "colmap_ext/io/reconstruction.h"
#include "colmap_ext/sfm/bundle_adjustment.h"
#include "colmap_ext/sfm/lidar_constraints.h"
#include "colmap_ext/sfm/mapper_state.h"
#include "colmap_ext/sfm/rotation_averaging.h"
#include "colmap_ext/sfm/tracks.h"
#include "colmap_ext/sfm/translation_averaging.h"
#include "colmap_ext/sfm/triangulation.h"
#include "colmap_ext/sfm/view_graph.h"
#include "core/work_list.h"

namespace lisfm {

struct Rig;

namespace colmap {

struct GlobalMapperOptions {
  // The refinement rounds adjust each image's best 500 tracks (the rest are
  // re-triangulated), the final adjustment all of them: on Lund door this
  // gives the same camera errors as full adjustments in a quarter of the time.
  GlobalMapperOptions() { bundle_adjustment.max_tracks_per_image = 500; }
  LoadMapperStateOptions load;
  ViewGraphOptions view_graph;
  RotationAveragingOptions rotation_averaging;
  TranslationAveragingOptions translation_averaging;
  TrackOptions tracks;
  TriangulationOptions triangulation;
  // The first triangulation, on the poses of rotation and translation
  // averaging, keeps observations within this factor (>= 1) times
  // triangulation.max_reprojection_error_px (which every later triangulation
  // and filter uses). Averaged poses are off by a few tenths of a degree
  // (several pixels at the image border): a tight first threshold rejects
  // correct observations, and the first bundle adjustment then settles where
  // they do not fit.
  double initial_reprojection_error_factor = 3.0;
  // Completion and merging of the tracks at the end of each refinement round
  // (after its retriangulation, before the next adjustment).
  TrackCompletionOptions track_completion;
  // Completion and merging follow, besides the view graph's edges (valid or
  // not), the inlier matches of the database's two-view geometries (those of
  // pairs the view graph rejected or whose matches it re-estimated away).
  bool track_completion_database_matches = true;
  BundleAdjustmentOptions bundle_adjustment;
  // Rounds of bundle adjustment → filter → retriangulate before the final BA.
  // One is enough: on the five real data sets of scripts/compare_colmap.sh a
  // second subsampled round changed no camera error in the 3rd digit but took up to
  // 30 more iterations (docs/BENCHMARKS.md, "global_mapper vs stock colmap mapper").
  int num_refinement_rounds = 1;
  // Relative cost change at which the (subsampled) refinement rounds stop;
  // the final full adjustment starts from there. 1e-4 gave the same camera
  // errors as 1e-6 on all five real data sets with half the iterations.
  double refinement_function_tolerance = 1e-4;
  // The final bundle adjustment uses every point even when the refinement
  // rounds subsample them (BundleAdjustmentOptions::max_tracks_per_image).
  bool final_full_bundle_adjustment = true;
  // Iteration cap of that final full adjustment (it starts from the
  // subsampled optimum).
  int final_max_num_iterations = 5;
  // After each bundle adjustment, a camera whose parameters are bogus
  // (Camera::HasBogusParams: focal length / max(width, height) outside
  // [min_focal_length_ratio in (0, 1], max_focal_length_ratio >= 1], or a
  // distortion parameter above max_extra_param; COLMAP's mapper defaults) is
  // reset to its prior parameters and held constant, and the adjustment runs
  // again: a wrong prior focal length lets the adjustment fit a degenerate
  // far-away camera to its observations, and distortion terms that few points
  // constrain can run off. Its frames then stand or fall by their
  // observations (min_frame_observations).
  double min_focal_length_ratio = 0.1;
  double max_focal_length_ratio = 10.0;
  double max_extra_param = 1.0;
  // Components with fewer frames are not reconstructed.
  int min_component_frames = 2;
  // Reconstruct every component (COLMAP writes one model per component);
  // false = only the largest.
  bool reconstruct_all_components = true;
  // A frame (image without a rig) whose images see fewer triangulated points
  // in total is dropped from the final model.
  int min_frame_observations = 15;
  // Constraint stamps attach to frames within this tolerance.
  double lidar_constraint_tolerance_ms = 1.0;
  // Read point colours from the images (needs --image_path).
  bool read_colors = true;
  // Stages to leave out (COLMAP's skip_<stage>); all run by default.
  // Rotation averaging: each frame of a component takes its prior rotation
  // (SfmFrame::prior_rig_from_world_rotation); frames without one are not
  // registered. Needs rotation priors in the database.
  bool skip_rotation_averaging = false;
  // Translation averaging: each registered frame takes its prior position;
  // frames without one are unregistered. Needs position priors.
  bool skip_translation_averaging = false;
  // Every bundle adjustment (refinement rounds and final): the poses stay
  // those of averaging (or the priors); tracks are still filtered.
  bool skip_bundle_adjustment = false;
  // The retriangulation at the end of each refinement round.
  bool skip_retriangulation = false;
  bool Check() const;
};

// Counts of the current model of a component.
struct MapperModelCounts {
  size_t registered_frames = 0;
  size_t registered_images = 0;
  size_t points = 0;        // triangulated tracks
  size_t observations = 0;  // observations of triangulated tracks
  double mean_reprojection_error_px = 0.0;
};

// One refinement round (or the final adjustment): bundle adjustment, then
// filtering and, except in the final round, retriangulation.
struct MapperRoundSummary {
  bool bundle_adjustment_skipped = false;
  BundleAdjustmentStats bundle_adjustment;  // default when skipped
  double bundle_adjustment_seconds = 0.0;
  size_t reset_bogus_cameras = 0;  // reset to their prior after the adjustment
  size_t filtered_observations = 0;  // rejected for depth or reprojection error
  bool final_round = false;          // no retriangulation in the final round
  bool retriangulation_skipped = false;
  size_t retriangulated_observations = 0;
  bool track_completion_run = false;  // completion or merging ran in this round
  TrackCompletionStats track_completion;
  double filter_retriangulate_seconds = 0.0;
  MapperModelCounts model;  // after the round
};

struct MapperComponentSummary {
  size_t frames = 0;  // frames of the view-graph component
  bool rotation_averaging_skipped = false;
  RotationAveragingStats rotation_averaging;  // when skipped: counts of the prior frames
  double rotation_averaging_seconds = 0.0;
  bool translation_averaging_skipped = false;
  TranslationAveragingStats translation_averaging;  // default when skipped
  size_t translation_averaging_registered_frames = 0;
  double translation_averaging_seconds = 0.0;
  // Fewer than min_component_frames frames were left after averaging: the
  // component stops here (the fields below keep their defaults).
  bool lost_frames_in_averaging = false;
  TrackStats tracks;
  TriangulationStats triangulation;
  double tracks_seconds = 0.0;  // BuildTracks + TriangulateTracks
  std::vector<MapperRoundSummary> refinement;  // the rounds, then the final adjustment
  size_t dropped_weak_frames = 0;
  MapperModelCounts model;  // the final model of the component
  double to_model_seconds = 0.0;
};

// Counts and timings (s) of every stage of RunGlobalMapper.
struct GlobalMapperSummary {
  size_t num_cameras = 0;
  size_t num_images = 0;
  size_t num_frames = 0;
  size_t num_keypoints = 0;
  bool has_rig = false;
  double load_seconds = 0.0;
  bool has_lidar_constraints = false;  // constraints were given
  size_t num_lidar_constraints_read = 0;
  size_t num_lidar_constraints_attached = 0;
  ViewGraphStats view_graph;
  double view_graph_seconds = 0.0;
  size_t num_components = 0;  // with at least min_component_frames frames
  size_t num_frames_in_small_components = 0;
  std::vector<MapperComponentSummary> components;  // reconstructed ones, in order
  size_t num_models = 0;
  double total_seconds = 0.0;
};

struct GlobalMapperResult {
  std::vector<Reconstruction> models;  // largest component first
  GlobalMapperSummary summary;
  // `pair_runner` sent this process's view-graph pairs to another process,
  // which continues alone: models and summary are empty here.
  bool share_only = false;
};

// `rig` and `lidar_constraints` may be null / empty. `image_path` is only
// used for point colours. `pair_runner` runs the view graph's per-pair
// estimation (BuildViewGraph; empty: all pairs in this process).
GlobalMapperResult RunGlobalMapper(const Database& database,
                                   const Rig* rig,
                                   const std::vector<LidarConstraintRecord>& lidar_constraints,
                                   const std::string& image_path,
                                   const GlobalMapperOptions& options,
                                   const WorkListRunner& pair_runner = {});

}  // namespace colmap
}  // namespace lisfm
