// Procedural surface texture, view-consistent: the albedo of a surface point
// depends only on the surface and the point, never on the view (needed for SfM
// and for checking projections).
//
// Content: a fixed 8 m x 8 m texture tile (2048 x 2048 texels of 3.9 mm,
// generated once per process in under 1 s of CPU) holding 7-octave value
// noise (wavelengths 1.6 m .. 2.5 cm, contrast boosted) and random markings
// (discs, rings, letter-like strokes, 6 per 0.25 m cell): dense,
// high-contrast detail. A surface is textured in its own 2D coordinates (u, v):
// the two scene-frame coordinates other than the dominant axis of its normal
// (exact plane coordinates for the axis-aligned faces of the procedural
// scenes; at most a sqrt(3) stretch on oblique triangles). The (u, v) plane is
// cut into 1 m cells and each cell shows a 1 m patch of the tile at an offset
// and in one of 8 orientations drawn from a hash of (seed, surface id, cell),
// so the texture does not repeat in practice (two given cells show the same
// tile content, over more than half of their area and in the same orientation,
// with probability 0.16 %) while a lookup is one hash and one bilinear texel
// fetch (a few tens of ns, cheap enough for one call per camera pixel and
// LiDAR point; the per-pixel 7-octave solid noise it replaces cost ~ 250 ns).
// Patch borders are visible as texture seams (view-consistent).
//
// Thread safety: all functions are thread-safe; Texture is immutable.
#pragma once

#include <cstdint>

#include <Eigen/Core>

namespace lisfm {
namespace sim {

struct TextureOptions {
  uint32_t seed = 1;        // scene seed (combined with the surface id)
  float frequency_scale = 1.0f;  // multiplies all spatial frequencies
  bool Check() const;
};

// Index (0, 1, 2) of the largest |component| of `normal` (ties: lowest index);
// the texture's 2D coordinates are the other two. Depends only on the
// surface, not on the sign of the normal (RayHit normals face the viewer).
inline int TextureAxis(const Eigen::Vector3f& normal) {
  const float ax = normal.x() < 0 ? -normal.x() : normal.x();
  const float ay = normal.y() < 0 ? -normal.y() : normal.y();
  const float az = normal.z() < 0 ? -normal.z() : normal.z();
  if (ax >= ay && ax >= az) return 0;
  return ay >= az ? 1 : 2;
}

class Texture {
 public:
  // Cheap: the tile is shared by all Texture objects of the process (built by
  // the first one).
  explicit Texture(const TextureOptions& options);

  // Albedo in [0.03, 0.97] at `p` (scene frame, m) on surface `surface_id`
  // whose normal's dominant axis is `axis` (TextureAxis).
  float Albedo(uint32_t surface_id, const Eigen::Vector3f& p, int axis) const;
  // The albedo averaged over about 1.6 cm x 1.6 cm (4x4 texels; a LiDAR beam
  // footprint at 5-10 m): from a 256 KB mip level, so random lookups are cheap.
  float FootprintAlbedo(uint32_t surface_id, const Eigen::Vector3f& p, int axis) const;
  // A per-surface tint (multiplies the albedo in colour renders), components in [0.5, 1].
  Eigen::Vector3f Tint(uint32_t surface_id) const;

  const TextureOptions& options() const { return options_; }

 private:
  // Bilinear lookup at level-0 tile coordinates.
  float Fetch(float x, float y) const;
  // Level-0 tile coordinates (texels, centres at +0.5) of `p`.
  void PatchCoordinates(uint32_t surface_id, const Eigen::Vector3f& p, int axis, float* x,
                        float* y) const;

  TextureOptions options_;
  uint32_t seed_mix_;
  const uint8_t* tile_;  // process-lifetime tile, 8x8-texel blocks
  const uint8_t* mip_;   // process-lifetime 4x4-averaged tile, row-major
};

}  // namespace sim
}  // namespace lisfm
