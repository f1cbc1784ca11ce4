// Solid procedural texture: an albedo evaluated at a 3D point of a surface, so
// that every view of a surface point sees the same value (view-consistent,
// as needed for SfM and for checking projections). Multi-scale value noise
// (7 octaves, wavelengths 1.6 m .. 2.5 cm) plus random markings (blobs, strokes, rings)
// seeded per surface and per 0.25 m cell: dense, high-contrast, non-repeating.
// Pure functions; thread-safe.
#pragma once

#include <cstdint>

#include <Eigen/Core>

namespace lisfm {
namespace sim {

struct TextureOptions {
  uint32_t seed = 1;        // scene seed (combined with the surface id)
  float frequency_scale = 1.0f;  // multiplies all spatial frequencies
};

// Albedo in [0.03, 0.97] at `p` (scene frame, m) on surface `surface_id`.
float Albedo(const TextureOptions& options, uint32_t surface_id, const Eigen::Vector3f& p);
// A per-surface tint (multiplies the albedo in colour renders), components in [0.5, 1].
Eigen::Vector3f SurfaceTint(const TextureOptions& options, uint32_t surface_id);

}  // namespace sim
}  // namespace lisfm
