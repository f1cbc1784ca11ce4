// Track establishment for `lisfm global_mapper` (stage 4a): joins the
// inlier matches of the view graph into multi-view tracks (feature tracks,
// one per hypothesised 3D point) by union-find over keypoints.
//
// Input: MapperState::view_graph edges with `valid == true` whose two images
// are both registered (MapperState::IsRegistered); their `inliers` are
// (point2D_idx in image_id1, point2D_idx in image_id2) pairs. Edges between two
// images of the same rig frame are used as well (they link keypoints even
// though they carry no information on the frame poses).
//
// Inconsistent tracks: a connected set of keypoints that holds two or more
// keypoints of one image cannot be one 3D point. Rule (documented and
// deterministic, in the spirit of COLMAP's / GLOMAP's "keep the most
// consistent observation"): in every such image the keypoint with the most
// inlier matches (its degree in the match graph; all its matches lie inside
// the same component) is kept, ties going to the smallest point2D_idx; the
// other keypoints of that image are dropped from the track (their track_ids
// stay -1). The rest of the track is kept as one track.
//
// Output: state->tracks is replaced (every track untriangulated, `rejected`
// empty, elements sorted by image id); tracks are ordered by the smallest
// (image_id, point2D_idx) of their connected component, so the result does not
// depend on the order of the edges or of their matches.
// Every SfmImage::track_ids is resized to its keypoints and set to the index
// of the keypoint's track in state->tracks, or -1.
//
// Failures: matches whose keypoint index is out of range for the image are
// skipped and counted (a warning is logged); a non-null state is required
// (InternalError otherwise). Single-threaded; O(matches * alpha) time and
// O(keypoints of registered images) memory.
#pragma once

#include <cstddef>

#include "colmap_ext/sfm/mapper_state.h"

namespace lisfm {
namespace colmap {

struct TrackOptions {
  // Tracks with fewer observations (images) than this are dropped (>= 2).
  int min_track_length = 2;
  // Cap on the observations of one track (0 = no cap). Longer tracks keep the
  // observations with the most inlier matches (ties: smaller image id).
  int max_track_length = 0;

  bool Check() const;
};

struct TrackStats {
  size_t num_edges_used = 0;      // valid edges between registered images
  size_t num_matches_used = 0;    // inlier matches of those edges
  size_t num_matches_invalid = 0; // skipped: keypoint index out of range
  size_t num_components = 0;      // connected keypoint sets with >= 2 keypoints
  size_t num_tracks_inconsistent = 0;           // components with 2+ keypoints in one image
  size_t num_observations_dropped_inconsistent = 0;  // keypoints dropped by that rule
  size_t num_tracks_dropped_short = 0;          // fewer than min_track_length images
  size_t num_tracks_capped = 0;                 // shortened to max_track_length
  size_t num_observations_dropped_cap = 0;      // observations removed by the cap
  size_t num_tracks = 0;                        // tracks in state->tracks
  size_t num_observations = 0;                  // elements over all tracks
  double mean_track_length = 0.0;               // num_observations / num_tracks (0 if none)
  double seconds = 0.0;                         // wall time
};

// Builds state->tracks and every image's track_ids as described above.
// Throws InternalError when options.Check() fails.
TrackStats BuildTracks(const TrackOptions& options, MapperState* state);

}  // namespace colmap
}  // namespace lisfm
