// `lisfm global_mapper`: global SfM on a COLMAP database.
//
// Stages (each in its own header, all acting on one MapperState):
//   LoadMapperState (cameras, images, keypoints, priors, rig frames)
//   → LiDAR constraints attached to frames (optional)
//   → BuildViewGraph (robust relative poses from the database's inlier matches)
//   → per connected component of frames:
//       AverageRotations → AverageTranslations → BuildTracks → TriangulateTracks
//       → rounds of { RunBundleAdjustment → FilterTracks → RetriangulateTracks }
//       → final RunBundleAdjustment + FilterTracks
//       → frames left with too few observations are dropped
//   → one COLMAP Reconstruction per component (largest first).
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

#include <nlohmann/json.hpp>

#include "colmap_ext/sfm/bundle_adjustment.h"
#include "colmap_ext/io/database.h"
#include "colmap_ext/sfm/lidar_constraints.h"
#include "colmap_ext/sfm/mapper_state.h"
#include "colmap_ext/io/reconstruction.h"
#include "colmap_ext/sfm/rotation_averaging.h"
#include "colmap_ext/sfm/tracks.h"
#include "colmap_ext/sfm/translation_averaging.h"
#include "colmap_ext/sfm/triangulation.h"
#include "colmap_ext/sfm/view_graph.h"

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
};

struct GlobalMapperResult {
  std::vector<Reconstruction> models;  // largest component first
  nlohmann::json summary;              // counts and timings of every stage
};

// `rig` and `lidar_constraints` may be null / empty. `image_path` is only
// used for point colours.
GlobalMapperResult RunGlobalMapper(const Database& database, const Rig* rig,
                                   const std::vector<LidarConstraintRecord>& lidar_constraints,
                                   const std::string& image_path,
                                   const GlobalMapperOptions& options);

}  // namespace colmap
}  // namespace lisfm
