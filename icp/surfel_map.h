// Point-based fusion (Keller et al. 2013, "Real-time 3D Reconstruction in
// Dynamic Scenes using Point-based Fusion"): a map of surfels that organised
// frames are merged into.
//
// Frames: surfel positions and normals are in the world frame (m); a frame's
// vertex/normal map is in its camera frame, placed by world_from_camera.
//
// One fusion step (Fuse) with the frame's pose (R, t) and frame index k:
//  1. Index map: every surfel is projected into the camera and kept, per pixel,
//     when it is the nearest (z-buffer); one pixel per surfel.
//  2. Association: a valid pixel with vertex q and normal n_q is matched to the
//     surfel of its own pixel or, failing that, of the (2r+1)^2 window around it
//     (r = association_radius_px), the compatible one closest to R q + t. With
//     d = p - (R q + t), compatible means: |n_p . d| < max_merge_distance_m (along
//     the surfel normal), |d - n_p (n_p . d)| < r_p + r_q (the discs overlap
//     sideways) and angle(n_p, R n_q) < max_merge_angle_deg.
//  3. Merge (confidence-weighted averaging, observation weight 1):
//       p <- (w p + (R q + t)) / (w + 1),   n <- normalise(w n + R n_q),
//       colour and radius likewise,  w <- w + 1,  last_seen <- k.
//     A surfel takes at most one observation per frame; further pixels matched to
//     it are neither merged nor added.
//  4. Addition: the other valid pixels become surfels with w = 1,
//     first_seen = last_seen = k.
//  5. Removal of unstable surfels: k - first_seen > unstable_age_frames and
//     w < unstable_min_confidence (seen long ago, rarely confirmed).
// Output: surfels with w >= output_min_confidence (Stable()).
//
// Radius of an observation (m): the pixel footprint sqrt(2) z / (f |cos a|)
// / 2 with a the angle between the normal and the viewing ray (|cos a| >= 0.2),
// f the mean focal length.
//
// Spinning LiDAR frames (range images, icp/spherical_projection.h) fuse by the
// same steps with the spherical projection in place of the pinhole: the index map
// keeps the nearest range per pixel, the association window wraps around in
// azimuth, and an observation's radius is the pixel footprint
// r sqrt(da^2 + de^2) / (2 |cos a|) with r the range and da, de the angular steps.
//
// Threads: rendering runs in parallel (TBB, atomic z-buffer whose ties are broken
// by the lower surfel index); association, merge and addition visit pixels in row
// order. Results do not depend on the thread count. Not thread-safe itself.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/geometry.h"
#include "icp/icp.h"
#include "icp/projective_icp.h"
#include "icp/spherical_projection.h"

namespace lisfm {

struct Surfel {
  Eigen::Vector3f position;        // world frame (m)
  Eigen::Vector3f normal;          // world frame, unit
  float radius_m = 0;              // disc radius (m)
  float confidence = 0;            // w: number of merged observations
  int32_t first_seen = 0;          // frame index of the first observation
  int32_t last_seen = 0;           // frame index of the last merged observation
  std::array<uint8_t, 3> color{};  // RGB
};

struct SurfelFusionOptions {
  double max_merge_distance_m = 0.02;  // distance along the surfel normal below this to merge (m)
  // Surfel and observed normals closer than this (deg). Normals from central
  // differences of raw Kinect depth at 320x240 scatter by tens of degrees at 3 m;
  // at 20 deg most real observations were added as new surfels instead of merged.
  double max_merge_angle_deg = 45.0;
  int association_radius_px = 1;       // window radius r of the association search (pixels, 0..3)
  int unstable_age_frames = 30;        // N: remove surfels first seen more than N frames ago ...
  double unstable_min_confidence = 3;  // M: ... whose confidence is below M (0 = never remove)
  double output_min_confidence = 2;    // Stable(): surfels with at least this confidence
  bool Check() const;
};

// One organised frame ready to fuse: vertices/normals in the camera frame and
// the colour of each pixel (RGB; empty = grey).
struct FusionFrame {
  PinholeIntrinsics intrinsics;
  VertexNormalMap map;
  std::vector<std::array<uint8_t, 3>> colors;
};

struct FuseStats {
  size_t valid_pixels = 0;  // pixels with a vertex and a normal
  size_t merged = 0;        // observations merged into surfels
  size_t added = 0;         // new surfels
  size_t skipped = 0;       // pixels whose surfel already took an observation this frame
  size_t removed = 0;       // unstable surfels removed
};

class SurfelMap {
 public:
  static constexpr uint32_t kNoSurfel = 0xffffffffu;

  explicit SurfelMap(const SurfelFusionOptions& options = SurfelFusionOptions());

  // Steps 1-5 above for `frame` at world_from_camera, frame index `frame_index`
  // (non-decreasing across calls). Throws InputError when the frame's arrays do
  // not match its intrinsics.
  FuseStats Fuse(const FusionFrame& frame, const SE3& world_from_camera, int frame_index);

  // The nearest surfel per pixel (kNoSurfel where none) of `intrinsics`'s image
  // seen from world_from_camera; surfels with confidence below min_confidence are
  // ignored. `splat` > 0 also covers the pixels within the surfel's projected
  // radius (at most splat pixels away) that no surfel centre falls into, at the
  // depth where their rays meet the surfel's plane; 0 = one pixel per surfel.
  void RenderIndexMap(const SE3& world_from_camera,
                      const PinholeIntrinsics& intrinsics,
                      double min_confidence,
                      int splat,
                      std::vector<uint32_t>* index_map) const;

  // The model's vertex and normal maps in the camera frame at world_from_camera
  // (the target of RegisterProjective), from RenderIndexMap with `splat`. A pixel's
  // vertex is where its ray meets the plane of its surfel (within 4 radii of the
  // centre; else the centre): like a measured vertex it lies on the pixel's ray.
  // index_map: where the index map is rendered (it stays there, e.g. for the
  // model's colour); null = a temporary.
  void RenderVertexNormalMap(const SE3& world_from_camera,
                             const PinholeIntrinsics& intrinsics,
                             double min_confidence,
                             int splat,
                             VertexNormalMap* out,
                             std::vector<uint32_t>* index_map = nullptr) const;

  // Steps 1-5 for a range image of a spinning LiDAR at world_from_sensor: `map` has
  // projection's size, vertices and normals in the sensor frame; colors is empty or
  // one per pixel. Throws InputError when the sizes do not match.
  FuseStats Fuse(const VertexNormalMap& map,
                 const std::vector<std::array<uint8_t, 3>>& colors,
                 const SphericalProjection& projection,
                 const SE3& world_from_sensor,
                 int frame_index);

  // RenderIndexMap for a spherical image: nearest range per pixel; `splat` > 0 also
  // covers the pixels within the surfel's projected disc (an ellipse: the angular
  // steps differ; at most splat pixels away in each direction) at the range where
  // their rays meet the surfel's plane.
  void RenderIndexMap(const SE3& world_from_sensor,
                      const SphericalProjection& projection,
                      double min_confidence,
                      int splat,
                      std::vector<uint32_t>* index_map) const;

  // Step 5 alone, at frame index `frame_index`; returns how many were removed.
  size_t RemoveUnstable(int frame_index);

  // Appends a surfel (tests, other front ends).
  void Add(const Surfel& surfel) { surfels_.push_back(surfel); }
  const std::vector<Surfel>& surfels() const { return surfels_; }
  size_t size() const { return surfels_.size(); }
  bool Stable(const Surfel& s) const { return s.confidence >= options_.output_min_confidence; }
  size_t NumStable() const;
  const SurfelFusionOptions& options() const { return options_; }
  // Memory of one surfel in the map (bytes).
  static constexpr size_t BytesPerSurfel() { return sizeof(Surfel); }

 private:
  template <class Camera>
  FuseStats FuseImpl(const VertexNormalMap& map,
                     const std::vector<std::array<uint8_t, 3>>& colors,
                     const Camera& camera,
                     const SE3& world_from_camera,
                     int frame_index);
  // Clears the z-buffer for num_pixels pixels and returns it.
  std::atomic<uint64_t>* ClearedZBuffer(size_t num_pixels) const;

  SurfelFusionOptions options_;
  std::vector<Surfel> surfels_;
  // Per-frame workspaces (kept to avoid allocations per frame).
  mutable std::unique_ptr<std::atomic<uint64_t>[]> zbuffer_;
  mutable size_t zbuffer_size_ = 0;
  struct RenderedSurfel {
    Eigen::Vector3f position, normal;
    float radius_m = 0;
    uint32_t index = kNoSurfel;
  };
  std::vector<uint32_t> index_map_;
  std::vector<RenderedSurfel> rendered_;
  std::vector<uint32_t> match_;
};

}  // namespace lisfm
