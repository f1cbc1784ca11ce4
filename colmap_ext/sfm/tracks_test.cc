#include "colmap_ext/sfm/tracks.h"

#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

// A state with `num_images` registered images (own frames, one PINHOLE
// camera, trivial rig) of `num_keypoints` keypoints each. Keypoint positions
// do not matter to BuildTracks.
MapperState MakeState(int num_images, int num_keypoints) {
  MapperState state;
  Camera camera;
  camera.camera_id = 1;
  camera.model_id = static_cast<int>(CameraModelId::kPinhole);
  camera.width = 640;
  camera.height = 480;
  camera.params = {500, 500, 320, 240};
  state.cameras[1] = camera;
  state.cam_from_rig[1] = SE3::Identity();
  for (int i = 1; i <= num_images; ++i) {
    SfmImage image;
    image.image_id = i;
    image.camera_id = 1;
    image.frame_id = i;
    for (int k = 0; k < num_keypoints; ++k) {
      image.keypoints.emplace_back(10.0 * k, 5.0 * i);
      image.normalized.push_back(camera.CamFromImg(image.keypoints.back()));
    }
    state.images[i] = image;
    SfmFrame frame;
    frame.frame_id = i;
    frame.image_ids = {static_cast<image_t>(i)};
    frame.registered = true;
    state.frames[i] = frame;
  }
  return state;
}

void AddEdge(MapperState* state,
             image_t a,
             image_t b,
             std::vector<std::pair<point2D_t, point2D_t>> inliers,
             bool valid = true) {
  ViewGraphEdge edge;
  edge.image_id1 = a;
  edge.image_id2 = b;
  edge.inliers = std::move(inliers);
  edge.valid = valid;
  edge.weight = static_cast<double>(edge.inliers.size());
  state->view_graph.AddEdge(std::move(edge));
}

std::vector<std::pair<image_t, point2D_t>> Elements(const Track& track) {
  std::vector<std::pair<image_t, point2D_t>> out;
  for (const TrackElement& e : track.elements) out.emplace_back(e.image_id, e.point2D_idx);
  return out;
}

using Obs = std::vector<std::pair<image_t, point2D_t>>;

// Every element points back to its track and every other keypoint has -1.
void ExpectTrackIdsConsistent(const MapperState& state) {
  size_t num_linked = 0;
  for (const auto& [image_id, image] : state.images) {
    ASSERT_EQ(image.track_ids.size(), image.keypoints.size());
    for (size_t k = 0; k < image.track_ids.size(); ++k) {
      if (image.track_ids[k] < 0) continue;
      ++num_linked;
      const Track& track = state.tracks.at(image.track_ids[k]);
      EXPECT_TRUE(std::any_of(track.elements.begin(), track.elements.end(),
                              [&](const TrackElement& e) {
                                return e.image_id == image_id && e.point2D_idx == k;
                              }));
    }
  }
  size_t num_elements = 0;
  for (const Track& track : state.tracks) num_elements += track.elements.size();
  EXPECT_EQ(num_linked, num_elements);
}

TEST(BuildTracks, MergesChainsIntoOneTrack) {
  // a-b and b-c only (no a-c edge): union-find must join a, b, c.
  MapperState state = MakeState(3, 5);
  AddEdge(&state, 1, 2, {{0, 3}, {1, 4}});
  AddEdge(&state, 2, 3, {{3, 2}, {4, 0}});
  const TrackStats stats = BuildTracks(TrackOptions(), &state);
  ASSERT_EQ(state.tracks.size(), 2u);
  EXPECT_EQ(Elements(state.tracks[0]), (Obs{{1, 0}, {2, 3}, {3, 2}}));
  EXPECT_EQ(Elements(state.tracks[1]), (Obs{{1, 1}, {2, 4}, {3, 0}}));
  for (const Track& track : state.tracks) {
    EXPECT_FALSE(track.triangulated);
    EXPECT_TRUE(track.rejected.empty());
  }
  EXPECT_EQ(state.images.at(2).track_ids, (std::vector<int>{-1, -1, -1, 0, 1}));
  ExpectTrackIdsConsistent(state);
  EXPECT_EQ(stats.num_edges_used, 2u);
  EXPECT_EQ(stats.num_matches_used, 4u);
  EXPECT_EQ(stats.num_tracks, 2u);
  EXPECT_EQ(stats.num_observations, 6u);
  EXPECT_DOUBLE_EQ(stats.mean_track_length, 3.0);
  EXPECT_EQ(stats.num_tracks_inconsistent, 0u);
}

TEST(BuildTracks, LongChainsOfPermutedKeypointsGiveOneTrackPerPoint) {
  // 6 images see the same 40 points, each image with its own random keypoint
  // order; only consecutive images are matched. Every track must be exactly
  // one point seen in all 6 images.
  constexpr int kImages = 6, kPoints = 40;
  MapperState state = MakeState(kImages, kPoints);
  std::vector<std::vector<point2D_t>> keypoint_of_point(kImages + 1);
  for (int i = 1; i <= kImages; ++i) {
    keypoint_of_point[i].resize(kPoints);
    std::iota(keypoint_of_point[i].begin(), keypoint_of_point[i].end(), 0u);
    std::shuffle(keypoint_of_point[i].begin(), keypoint_of_point[i].end(), test::Rng());
  }
  for (int i = 1; i < kImages; ++i) {
    std::vector<std::pair<point2D_t, point2D_t>> inliers;
    for (int p = 0; p < kPoints; ++p) {
      inliers.emplace_back(keypoint_of_point[i][p], keypoint_of_point[i + 1][p]);
    }
    std::shuffle(inliers.begin(), inliers.end(), test::Rng());
    // Given as (i + 1, i); ViewGraph::AddEdge swaps the ids and the matches.
    std::vector<std::pair<point2D_t, point2D_t>> reversed;
    for (const auto& [a, b] : inliers) reversed.emplace_back(b, a);
    AddEdge(&state, i + 1, i, reversed);
  }
  BuildTracks(TrackOptions(), &state);
  ASSERT_EQ(state.tracks.size(), static_cast<size_t>(kPoints));
  std::vector<bool> seen(kPoints, false);
  for (const Track& track : state.tracks) {
    ASSERT_EQ(track.elements.size(), static_cast<size_t>(kImages));
    // The point of the first element, looked up in every image.
    const auto& first = keypoint_of_point[track.elements[0].image_id];
    const int point = static_cast<int>(
        std::find(first.begin(), first.end(), track.elements[0].point2D_idx) - first.begin());
    ASSERT_LT(point, kPoints);
    EXPECT_FALSE(seen[point]);
    seen[point] = true;
    for (const TrackElement& e : track.elements) {
      EXPECT_EQ(e.point2D_idx, keypoint_of_point[e.image_id][point]);
    }
  }
  ExpectTrackIdsConsistent(state);
}

TEST(BuildTracks, ResultDoesNotDependOnEdgeOrder) {
  MapperState a = MakeState(4, 4);
  MapperState b = MakeState(4, 4);
  AddEdge(&a, 1, 2, {{0, 1}, {2, 3}});
  AddEdge(&a, 3, 4, {{1, 1}, {0, 2}});
  AddEdge(&a, 2, 3, {{1, 0}, {3, 3}});
  AddEdge(&b, 2, 3, {{3, 3}, {1, 0}});
  AddEdge(&b, 3, 4, {{0, 2}, {1, 1}});
  AddEdge(&b, 1, 2, {{2, 3}, {0, 1}});
  BuildTracks(TrackOptions(), &a);
  BuildTracks(TrackOptions(), &b);
  ASSERT_EQ(a.tracks.size(), b.tracks.size());
  ASSERT_EQ(a.tracks.size(), 3u);
  for (size_t t = 0; t < a.tracks.size(); ++t) {
    EXPECT_EQ(Elements(a.tracks[t]), Elements(b.tracks[t]));
  }
  for (const auto& [id, image] : a.images) EXPECT_EQ(image.track_ids, b.images.at(id).track_ids);
}

TEST(BuildTracks, UsesOnlyValidEdgesBetweenRegisteredImages) {
  MapperState state = MakeState(4, 3);
  state.frames.at(4).registered = false;
  AddEdge(&state, 1, 2, {{0, 0}});
  AddEdge(&state, 2, 3, {{0, 0}, {1, 1}}, /*valid=*/false);
  AddEdge(&state, 3, 4, {{2, 2}});  // image 4 is not registered
  const TrackStats stats = BuildTracks(TrackOptions(), &state);
  ASSERT_EQ(state.tracks.size(), 1u);
  EXPECT_EQ(Elements(state.tracks[0]), (Obs{{1, 0}, {2, 0}}));
  EXPECT_EQ(stats.num_edges_used, 1u);
  EXPECT_EQ(state.images.at(4).track_ids, (std::vector<int>{-1, -1, -1}));
  EXPECT_EQ(state.images.at(3).track_ids, (std::vector<int>{-1, -1, -1}));
}

TEST(BuildTracks, ConflictingMatchKeepsTheMostMatchedKeypoint) {
  // Keypoints 0 and 1 of image 1 end up in one component through image 3.
  // Keypoint 0 has two matches (images 2 and 4), keypoint 1 one (image 3):
  // the documented rule keeps 1:0 and drops 1:1.
  MapperState state = MakeState(4, 2);
  AddEdge(&state, 1, 2, {{0, 0}});
  AddEdge(&state, 2, 3, {{0, 0}});
  AddEdge(&state, 1, 3, {{1, 0}});
  AddEdge(&state, 1, 4, {{0, 0}});
  const TrackStats stats = BuildTracks(TrackOptions(), &state);
  ASSERT_EQ(state.tracks.size(), 1u);
  EXPECT_EQ(Elements(state.tracks[0]), (Obs{{1, 0}, {2, 0}, {3, 0}, {4, 0}}));
  EXPECT_EQ(state.images.at(1).track_ids, (std::vector<int>{0, -1}));
  EXPECT_EQ(stats.num_tracks_inconsistent, 1u);
  EXPECT_EQ(stats.num_observations_dropped_inconsistent, 1u);
  ExpectTrackIdsConsistent(state);

  // Same degree (one match each): the smaller keypoint index wins.
  MapperState tie = MakeState(3, 2);
  AddEdge(&tie, 1, 2, {{1, 0}});
  AddEdge(&tie, 2, 3, {{0, 0}});
  AddEdge(&tie, 1, 3, {{0, 0}});
  // Component {1:0, 1:1, 2:0, 3:0}: 1:0 has degree 1, 1:1 degree 1.
  BuildTracks(TrackOptions(), &tie);
  ASSERT_EQ(tie.tracks.size(), 1u);
  EXPECT_EQ(Elements(tie.tracks[0]), (Obs{{1, 0}, {2, 0}, {3, 0}}));
  EXPECT_EQ(tie.images.at(1).track_ids, (std::vector<int>{0, -1}));
}

TEST(BuildTracks, MinAndMaxTrackLength) {
  MapperState state = MakeState(4, 2);
  AddEdge(&state, 1, 2, {{0, 0}, {1, 1}});
  AddEdge(&state, 2, 3, {{0, 0}});
  AddEdge(&state, 3, 4, {{0, 0}});
  AddEdge(&state, 2, 4, {{0, 0}});
  // Track A = {1:0, 2:0, 3:0, 4:0} with degrees 1, 3, 2, 2; track B = {1:1, 2:1}.
  TrackOptions options;
  options.min_track_length = 3;
  TrackStats stats = BuildTracks(options, &state);
  ASSERT_EQ(state.tracks.size(), 1u);
  EXPECT_EQ(stats.num_tracks_dropped_short, 1u);
  EXPECT_EQ(state.images.at(1).track_ids, (std::vector<int>{0, -1}));

  options.min_track_length = 2;
  options.max_track_length = 3;
  stats = BuildTracks(options, &state);
  ASSERT_EQ(state.tracks.size(), 2u);
  // Capped to the 3 most matched observations: 2:0 (3), then 3:0 and 4:0 (2).
  EXPECT_EQ(Elements(state.tracks[0]), (Obs{{2, 0}, {3, 0}, {4, 0}}));
  EXPECT_EQ(stats.num_tracks_capped, 1u);
  EXPECT_EQ(stats.num_observations_dropped_cap, 1u);
  EXPECT_EQ(state.images.at(1).track_ids, (std::vector<int>{-1, 1}));
  ExpectTrackIdsConsistent(state);

  options.max_track_length = 1;  // below min_track_length
  EXPECT_FALSE(options.Check());
  EXPECT_THROW(BuildTracks(options, &state), InternalError);
}

TEST(BuildTracks, SkipsMatchesOutOfRangeAndRebuildsFromScratch) {
  MapperState state = MakeState(2, 3);
  AddEdge(&state, 1, 2, {{0, 0}, {7, 1}, {1, 99}});
  TrackStats stats = BuildTracks(TrackOptions(), &state);
  EXPECT_EQ(stats.num_matches_invalid, 2u);
  ASSERT_EQ(state.tracks.size(), 1u);
  // A second call replaces the tracks (no duplicates, no stale track ids).
  state.tracks[0].triangulated = true;
  stats = BuildTracks(TrackOptions(), &state);
  ASSERT_EQ(state.tracks.size(), 1u);
  EXPECT_FALSE(state.tracks[0].triangulated);
  ExpectTrackIdsConsistent(state);
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
