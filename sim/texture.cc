#include "sim/texture.h"

#include <cmath>

namespace lisfm {
namespace sim {
namespace {

inline uint32_t Hash(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}
inline uint32_t Hash3(int32_t x, int32_t y, int32_t z, uint32_t seed) {
  return Hash(static_cast<uint32_t>(x) * 0x8da6b343U ^ static_cast<uint32_t>(y) * 0xd8163841U ^
              static_cast<uint32_t>(z) * 0xcb1ab31fU ^ seed);
}
inline float ToUnit(uint32_t h) { return static_cast<float>(h >> 8) * (1.0f / 16777216.0f); }
inline float Smooth(float t) { return t * t * (3.0f - 2.0f * t); }

// Trilinear value noise in [0, 1].
float ValueNoise(float x, float y, float z, uint32_t seed) {
  const float fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const int32_t ix = static_cast<int32_t>(fx), iy = static_cast<int32_t>(fy),
                iz = static_cast<int32_t>(fz);
  const float ux = Smooth(x - fx), uy = Smooth(y - fy), uz = Smooth(z - fz);
  float c[8];
  for (int i = 0; i < 8; ++i) {
    c[i] = ToUnit(Hash3(ix + (i & 1), iy + ((i >> 1) & 1), iz + (i >> 2), seed));
  }
  const float x00 = c[0] + (c[1] - c[0]) * ux, x10 = c[2] + (c[3] - c[2]) * ux;
  const float x01 = c[4] + (c[5] - c[4]) * ux, x11 = c[6] + (c[7] - c[6]) * ux;
  const float y0 = x00 + (x10 - x00) * uy, y1 = x01 + (x11 - x01) * uy;
  return y0 + (y1 - y0) * uz;
}

constexpr float kCell = 0.25f;  // marking cell edge, m
constexpr int kMarksPerCell = 6;

// Distance from p to segment ab.
inline float SegmentDistance(const Eigen::Vector3f& p, const Eigen::Vector3f& a,
                             const Eigen::Vector3f& b) {
  const Eigen::Vector3f ab = b - a;
  const float s = std::fmin(1.0f, std::fmax(0.0f, (p - a).dot(ab) / ab.squaredNorm()));
  return (p - a - s * ab).norm();
}

}  // namespace

float Albedo(const TextureOptions& options, uint32_t surface_id, const Eigen::Vector3f& p_in) {
  const uint32_t seed = Hash(options.seed * 0x9e3779b9U + surface_id * 0x85ebca6bU + 1U);
  const Eigen::Vector3f p = p_in * options.frequency_scale;
  // fBm over 6 octaves, wavelengths 1.6 m .. 5 cm, contrast boosted.
  float noise = 0.f, amplitude = 0.5f, total = 0.f;
  float f = 1.0f / 1.6f;
  for (int octave = 0; octave < 7; ++octave) {
    noise += amplitude * ValueNoise(p.x() * f, p.y() * f, p.z() * f, seed + octave * 101U);
    total += amplitude;
    amplitude *= 0.9f;
    f *= 2.0f;
  }
  noise /= total;
  float albedo = 0.5f + 3.0f * (noise - 0.5f);
  // Markings: each cell holds a few shapes fully inside it (so only the own
  // cell needs testing): discs/blobs, strokes (letter-like segments), rings.
  const float cx = std::floor(p.x() / kCell), cy = std::floor(p.y() / kCell),
              cz = std::floor(p.z() / kCell);
  const Eigen::Vector3f cell_origin(cx * kCell, cy * kCell, cz * kCell);
  uint32_t h = Hash3(static_cast<int32_t>(cx), static_cast<int32_t>(cy),
                     static_cast<int32_t>(cz), seed ^ 0xa5a5a5a5U);
  for (int m = 0; m < kMarksPerCell; ++m) {
    h = Hash(h + 0x68e31da4U);
    const uint32_t type = h % 4;
    const float shade = (h >> 4) & 1 ? 0.95f : 0.04f;
    const uint32_t h1 = Hash(h ^ 0x1b873593U), h2 = Hash(h1), h3 = Hash(h2);
    const float size = 0.02f + 0.06f * ToUnit(h3);
    const float margin = size + 0.01f;
    const float span = kCell - 2 * margin;
    if (span <= 0) continue;
    const Eigen::Vector3f centre =
        cell_origin + Eigen::Vector3f(margin + span * ToUnit(h1), margin + span * ToUnit(h2),
                                      margin + span * ToUnit(Hash(h3)));
    const float dist = (p - centre).norm();
    if (dist > size + 0.005f) continue;  // outside this mark's bounding sphere
    if (type == 0) {  // blob
      if (dist < size * 0.8f) albedo = shade;
    } else if (type == 1) {  // ring
      if (std::fabs(dist - 0.7f * size) < 0.012f) albedo = shade;
    } else {  // strokes: two or three segments through the mark's sphere
      uint32_t hs = Hash(h3 ^ 0x2545f491U);
      Eigen::Vector3f prev = centre + size * Eigen::Vector3f(ToUnit(hs) - 0.5f,
                                                             ToUnit(Hash(hs + 1)) - 0.5f,
                                                             ToUnit(Hash(hs + 2)) - 0.5f);
      for (int k = 0; k < static_cast<int>(type); ++k) {
        hs = Hash(hs + 7U);
        const Eigen::Vector3f next =
            centre + size * Eigen::Vector3f(ToUnit(hs) - 0.5f, ToUnit(Hash(hs + 1)) - 0.5f,
                                            ToUnit(Hash(hs + 2)) - 0.5f) * 1.6f;
        if (SegmentDistance(p, prev, next) < 0.008f + 0.01f * ToUnit(hs >> 3)) {
          albedo = shade;
        }
        prev = next;
      }
    }
  }
  return std::fmin(0.97f, std::fmax(0.03f, albedo));
}

Eigen::Vector3f SurfaceTint(const TextureOptions& options, uint32_t surface_id) {
  const uint32_t h = Hash(options.seed * 0x27d4eb2dU + surface_id * 0x165667b1U);
  return Eigen::Vector3f(0.5f + 0.5f * ToUnit(h), 0.5f + 0.5f * ToUnit(Hash(h)),
                         0.5f + 0.5f * ToUnit(Hash(h + 1)));
}

}  // namespace sim
}  // namespace lisfm
