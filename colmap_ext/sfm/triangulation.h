// Multi-view triangulation of tracks, and the filter / retriangulation steps
// between bundle adjustments of `lisfm global_mapper` (stage 4b).
//
// Geometry: poses from MapperState::CamFromWorld (cam_from_world =
// cam_from_rig * rig_from_world), observations are the images' keypoints in
// COLMAP pixels, points are in the world frame (the unit of the poses).
//
// One track is triangulated as follows (Hartley & Zisserman 2004, Sec. 12.2
// and 12.4 for the two steps):
//  1. linear triangulation (DLT) on the undistorted normalised coordinates
//     (SfmImage::normalized, z = 1 plane): for every observation the two rows
//     x * P.row(2) - P.row(0) and y * P.row(2) - P.row(1) of A, P = [R | t];
//     X = the right singular vector of A for the smallest singular value;
//  2. Levenberg-Marquardt refinement of the pixel reprojection error
//     sum_i |Camera::ImgFromCam(pi(R_i X + t_i)) - x_i|^2 (the maximum
//     likelihood point under isotropic pixel noise), with the distortion
//     Jacobian by central differences;
//  3. checks on every observation: positive depth (z > 0 in the camera) and
//     reprojection error <= max_reprojection_error_px; on the kept ones:
//     at least 2 observations, and the largest pairwise triangulation angle
//     (between the rays from the camera centres to X) >= min_triangulation_angle_deg.
// When some observation fails step 3 with the all-observation estimate, the
// track is solved robustly: every pair of observations (or an evenly spread,
// deterministic subset of max_hypothesis_pairs pairs) whose rays meet at an
// angle >= min_triangulation_angle_deg is a hypothesis (step 1 on the pair,
// then step 3's per-observation checks on all); the one with the most inliers
// (then the smallest summed error) wins and steps 1-3 are repeated on its
// inliers (twice at most, while the inlier set grows).
//
// Bookkeeping on Track (mapper_state.h): `elements` are the active
// observations, `rejected` those removed by a check (kept so that
// RetriangulateTracks can re-add them); image.track_ids is not changed (it
// names the track of both). Observations in images that are not registered
// are always moved to `rejected`. A track that passes gets triangulated =
// true, xyz and error (mean pixel error over `elements`); its failing
// observations are moved to `rejected`. A track that fails keeps its
// elements, with triangulated = false and error = -1.
//
// Threads: tracks are processed in parallel with TBB (options.num_threads);
// each track is computed independently and statistics are summed in track
// order, so results do not depend on the number of threads.
// Failures: a track element naming an image or keypoint that does not exist,
// or options that fail Check(), throw InternalError (the state is built by
// BuildTracks, so these are bugs, not user input).
#pragma once

#include <cstddef>
#include <vector>

#include "colmap_ext/sfm/mapper_state.h"

namespace lisfm {
namespace colmap {

struct TriangulationOptions {
  // Largest pixel reprojection error of a kept observation (px); COLMAP's
  // mapper uses 4 px (filter_max_reproj_error).
  double max_reprojection_error_px = 4.0;
  // Smallest largest-pairwise triangulation angle of a triangulated track
  // (deg); COLMAP's mapper uses 1.5 deg (filter_min_tri_angle).
  double min_triangulation_angle_deg = 1.5;
  // Levenberg-Marquardt iterations (at most) on the pixel reprojection error.
  int num_refinement_iterations = 10;
  // Pair hypotheses tried by the robust step (all pairs when there are fewer).
  int max_hypothesis_pairs = 100;
  // TBB worker threads; -1 = all available.
  int num_threads = -1;

  bool Check() const;
};

struct TriangulationStats {
  size_t num_tracks_considered = 0;    // tracks with >= 2 registered observations
  size_t num_tracks_triangulated = 0;  // passed every check
  size_t num_tracks_robust = 0;        // needed the pair-hypothesis step
  // Failures (track stays untriangulated): fewer than 2 observations with
  // positive depth / within the reprojection threshold, angle too small, or a
  // degenerate linear system (point at infinity).
  size_t num_tracks_failed_depth = 0;
  size_t num_tracks_failed_reprojection = 0;
  size_t num_tracks_failed_angle = 0;
  size_t num_tracks_failed_degenerate = 0;
  // Observations of triangulated tracks moved to `rejected`.
  size_t num_observations_rejected_depth = 0;
  size_t num_observations_rejected_reprojection = 0;
  size_t num_observations_unregistered = 0;  // any track; image not registered
  size_t num_observations = 0;               // elements of triangulated tracks
  double mean_reprojection_error_px = 0.0;   // over those observations (0 if none)
  double seconds = 0.0;
};

// Triangulates every track with >= 2 registered observations in `elements`
// from scratch (the current xyz is ignored; `rejected` stays rejected).
TriangulationStats TriangulateTracks(const TriangulationOptions& options, MapperState* state);

struct FilterStats {
  size_t num_tracks_checked = 0;  // triangulated tracks before filtering
  size_t num_observations_rejected_depth = 0;
  size_t num_observations_rejected_reprojection = 0;
  size_t num_observations_unregistered = 0;
  size_t num_tracks_untriangulated_few_observations = 0;  // < 2 left
  size_t num_tracks_untriangulated_angle = 0;             // angle too small
  size_t num_tracks_triangulated = 0;                     // after filtering
  size_t num_observations = 0;                            // after filtering
  double seconds = 0.0;
};

// After bundle adjustment: applies the checks of step 3 to the triangulated
// tracks with their current xyz and poses (nothing is re-estimated); failing
// observations move to `rejected`, tracks with < 2 observations left or too
// small an angle become untriangulated (keeping what is left in `elements`).
FilterStats FilterTracks(const TriangulationOptions& options, MapperState* state);

// After filtering (with improved poses): for triangulated tracks, moves back
// every rejected observation of a registered image that has positive depth and
// reprojects within max_reprojection_error_px at the current xyz; for
// untriangulated tracks with >= 2 registered observations in elements and
// rejected together, runs the triangulation above on all of them. Returns the
// number of observations added to triangulated tracks (re-added rejected
// observations plus all elements of newly triangulated tracks). Updates error.
size_t RetriangulateTracks(const TriangulationOptions& options, MapperState* state);

// Track completion and merging between bundle adjustments (the facts of
// COLMAP's IncrementalTriangulator::CompleteAllTracks / MergeAllTracks, on
// this module's tracks). `correspondences` are keypoint matches between two
// images, (point2D_idx in image_id1, in image_id2) as in ViewGraphEdge::inliers
// (`valid`, `cam2_from_cam1` and `weight` are not read): the view graph's
// edges, valid or not, and possibly more matches; pairs with an unregistered
// image are ignored. Both steps leave poses alone and go through the tracks in
// index order, so the result is deterministic.
//
// Completion: for every triangulated track, each keypoint linked by a
// correspondence to one of its observations (and, up to
// complete_max_transitivity links, to the observations added so far) is added
// when its image has no observation of the track yet, it is not an active
// observation of another triangulated track (merging decides those), the point
// lies in front of its camera and reprojects within
// complete_max_reprojection_error_px at the current xyz. A keypoint taken from
// another track (untriangulated, or among its `rejected`) leaves that track.
//
// Merging: two triangulated tracks t1 < t2 linked by a correspondence between
// active observations, with no image in common, become t1 when the point
// re-triangulated on all their observations (linear, then Levenberg-Marquardt on
// the pixel error, as TriangulateTracks) lies in front of every camera and
// reprojects within merge_max_reprojection_error_px in every observation;
// t2 is left empty (untriangulated) and every keypoint of t2 names t1.
// Off by default: on the real scenes of scripts/compare_colmap.sh our tracks
// (union-find over the view graph's inliers) are already closed under the
// matches, so completion adds < 0.1 % observations and merging almost never
// applies, with no effect on the cameras (docs/notes/global_mapper_vs_colmap4.md).
struct TrackCompletionOptions {
  bool complete = false;
  double complete_max_reprojection_error_px = 4.0;  // px (COLMAP: 4)
  // Correspondence links followed from the track's observations (COLMAP: 5).
  int complete_max_transitivity = 5;
  bool merge = false;
  double merge_max_reprojection_error_px = 4.0;  // px (COLMAP: 4)
  bool Check() const;
};

struct TrackCompletionStats {
  size_t num_correspondences = 0;   // distinct links between registered keypoints
  size_t num_tracks_completed = 0;  // tracks that gained observations
  size_t num_observations_completed = 0;
  size_t num_observations_taken = 0;  // of those, taken from another track
  size_t num_merge_candidates = 0;    // linked track pairs with no common image
  size_t num_merges = 0;
  size_t num_observations_merged = 0;  // observations of the tracks merged away
  double seconds = 0.0;
};

// Completion, then merging, as described above (each when enabled). Updates
// error of the changed tracks; `triangulation` gives the refinement
// iterations and the minimum triangulation angle of a merged track.
TrackCompletionStats CompleteAndMergeTracks(const TrackCompletionOptions& options,
                                            const TriangulationOptions& triangulation,
                                            const std::vector<ViewGraphEdge>& correspondences,
                                            MapperState* state);

}  // namespace colmap
}  // namespace lisfm
