#include "colmap_ext/sfm/tracks.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <limits>
#include <numeric>
#include <unordered_map>
#include <vector>

#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"

namespace lisfm {
namespace colmap {

namespace {

// Union-find over dense node ids with path halving and union by size.
class UnionFind {
 public:
  explicit UnionFind(size_t n) : parent_(n), size_(n, 1) {
    std::iota(parent_.begin(), parent_.end(), uint32_t{0});
  }
  uint32_t Find(uint32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  void Union(uint32_t a, uint32_t b) {
    a = Find(a);
    b = Find(b);
    if (a == b) return;
    if (size_[a] < size_[b]) std::swap(a, b);
    parent_[b] = a;
    size_[a] += size_[b];
  }

 private:
  std::vector<uint32_t> parent_;
  std::vector<uint32_t> size_;
};

}  // namespace

bool TrackOptions::Check() const {
  CHECK_OPTION_GE(min_track_length, 2);
  CHECK_OPTION_MSG(max_track_length, max_track_length == 0 || max_track_length >= min_track_length,
                   "0 or >= min_track_length (" + std::to_string(min_track_length) + ")");
  return true;
}

TrackStats BuildTracks(const TrackOptions& options, MapperState* state) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  TrackStats stats;

  // Dense node ids: the keypoints of registered images, in (image_id,
  // point2D_idx) order. Unregistered images get no nodes.
  std::vector<image_t> node_image;         // node -> image id
  std::unordered_map<image_t, uint32_t> image_offset;
  size_t num_nodes = 0;
  for (auto& [image_id, image] : state->images) {
    image.track_ids.assign(image.keypoints.size(), -1);
    if (!state->IsRegistered(image_id)) continue;
    THROW_CHECK_LT(num_nodes + image.keypoints.size(),
                   static_cast<size_t>(std::numeric_limits<uint32_t>::max()));
    image_offset[image_id] = static_cast<uint32_t>(num_nodes);
    num_nodes += image.keypoints.size();
  }
  node_image.resize(num_nodes);
  for (const auto& [image_id, offset] : image_offset) {
    const size_t n = state->images.at(image_id).keypoints.size();
    std::fill(node_image.begin() + offset, node_image.begin() + offset + n, image_id);
  }

  UnionFind union_find(num_nodes);
  std::vector<uint32_t> degree(num_nodes, 0);
  for (const ViewGraphEdge& edge : state->view_graph.edges) {
    if (!edge.valid) continue;
    const auto it1 = image_offset.find(edge.image_id1);
    const auto it2 = image_offset.find(edge.image_id2);
    if (it1 == image_offset.end() || it2 == image_offset.end()) continue;
    ++stats.num_edges_used;
    const size_t n1 = state->images.at(edge.image_id1).keypoints.size();
    const size_t n2 = state->images.at(edge.image_id2).keypoints.size();
    for (const auto& [idx1, idx2] : edge.inliers) {
      if (idx1 >= n1 || idx2 >= n2) {
        ++stats.num_matches_invalid;
        continue;
      }
      const uint32_t a = it1->second + idx1;
      const uint32_t b = it2->second + idx2;
      ++degree[a];
      ++degree[b];
      union_find.Union(a, b);
      ++stats.num_matches_used;
    }
  }
  if (stats.num_matches_invalid > 0) {
    LogWarning("tracks: skipped {} inlier matches with a keypoint index out of range",
               stats.num_matches_invalid);
  }

  // Components in the order of their smallest node (counting sort by root).
  std::vector<int64_t> component_of_root(num_nodes, -1);
  std::vector<uint32_t> component_size;
  std::vector<uint32_t> node_component(num_nodes, 0);
  for (uint32_t node = 0; node < num_nodes; ++node) {
    if (degree[node] == 0) continue;
    const uint32_t root = union_find.Find(node);
    if (component_of_root[root] < 0) {
      component_of_root[root] = static_cast<int64_t>(component_size.size());
      component_size.push_back(0);
    }
    node_component[node] = static_cast<uint32_t>(component_of_root[root]);
    ++component_size[node_component[node]];
  }
  stats.num_components = component_size.size();
  std::vector<size_t> component_begin(component_size.size() + 1, 0);
  for (size_t c = 0; c < component_size.size(); ++c) {
    component_begin[c + 1] = component_begin[c] + component_size[c];
  }
  std::vector<uint32_t> members(component_begin.back());
  {
    std::vector<size_t> fill = component_begin;
    for (uint32_t node = 0; node < num_nodes; ++node) {
      if (degree[node] > 0) members[fill[node_component[node]]++] = node;
    }
  }

  state->tracks.clear();
  std::vector<uint32_t> kept;
  for (size_t c = 0; c < component_size.size(); ++c) {
    // Members are sorted by node id, i.e. by (image_id, point2D_idx): one
    // pass keeps the best keypoint of each image.
    kept.clear();
    bool inconsistent = false;
    for (size_t m = component_begin[c]; m < component_begin[c + 1]; ++m) {
      const uint32_t node = members[m];
      if (!kept.empty() && node_image[kept.back()] == node_image[node]) {
        inconsistent = true;
        ++stats.num_observations_dropped_inconsistent;
        if (degree[node] > degree[kept.back()]) kept.back() = node;  // ties: keep smaller idx
      } else {
        kept.push_back(node);
      }
    }
    if (inconsistent) ++stats.num_tracks_inconsistent;
    if (kept.size() < static_cast<size_t>(options.min_track_length)) {
      ++stats.num_tracks_dropped_short;
      continue;
    }
    if (options.max_track_length > 0 &&
        kept.size() > static_cast<size_t>(options.max_track_length)) {
      // Most matched first, ties by image id (node order); then back to image order.
      std::stable_sort(kept.begin(), kept.end(), [&](uint32_t a, uint32_t b) {
        return degree[a] > degree[b];
      });
      stats.num_observations_dropped_cap += kept.size() - options.max_track_length;
      kept.resize(options.max_track_length);
      std::sort(kept.begin(), kept.end());
      ++stats.num_tracks_capped;
    }
    const int track_id = static_cast<int>(state->tracks.size());
    Track track;
    track.elements.reserve(kept.size());
    for (const uint32_t node : kept) {
      const image_t image_id = node_image[node];
      const point2D_t idx = node - image_offset.at(image_id);
      track.elements.push_back(TrackElement{image_id, idx});
      state->images.at(image_id).track_ids[idx] = track_id;
    }
    stats.num_observations += track.elements.size();
    state->tracks.push_back(std::move(track));
  }
  stats.num_tracks = state->tracks.size();
  stats.mean_track_length =
      stats.num_tracks > 0 ? static_cast<double>(stats.num_observations) / stats.num_tracks : 0.0;
  stats.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  LogInfo(
      "tracks: {} tracks ({} observations, mean length {:.2f}) from {} matches of {} edges; "
      "{} inconsistent ({} observations dropped), {} too short, {} capped; {:.3f} s",
      stats.num_tracks, stats.num_observations, stats.mean_track_length,
      stats.num_matches_used, stats.num_edges_used, stats.num_tracks_inconsistent,
      stats.num_observations_dropped_inconsistent, stats.num_tracks_dropped_short,
      stats.num_tracks_capped, stats.seconds);
  return stats;
}

}  // namespace colmap
}  // namespace lisfm
