#include "sim/texture.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <tbb/parallel_for.h>

#include "core/option_check.h"

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
inline float ToUnit(uint32_t h) { return static_cast<float>(h >> 8) * (1.0f / 16777216.0f); }
inline float Smooth(float t) { return t * t * (3.0f - 2.0f * t); }
// floor() for |x| < 2^31 without a libm call.
inline int32_t FastFloor(float x) {
  const int32_t i = static_cast<int32_t>(x);
  return i - (x < static_cast<float>(i) ? 1 : 0);
}

constexpr uint32_t kPrimeU = 0x8da6b343U;
constexpr uint32_t kPrimeV = 0xd8163841U;

// Bilinear value noise in [0, 1] on the integer lattice of (x, y).
inline float ValueNoise(float x, float y, uint32_t seed) {
  const int32_t ix = FastFloor(x), iy = FastFloor(y);
  const float ux = Smooth(x - static_cast<float>(ix)), uy = Smooth(y - static_cast<float>(iy));
  const uint32_t x0 = static_cast<uint32_t>(ix) * kPrimeU;
  const uint32_t a0 = x0 ^ seed, a1 = (x0 + kPrimeU) ^ seed;
  const uint32_t b0 = static_cast<uint32_t>(iy) * kPrimeV, b1 = b0 + kPrimeV;
  const float c00 = ToUnit(Hash(a0 ^ b0)), c10 = ToUnit(Hash(a1 ^ b0));
  const float c01 = ToUnit(Hash(a0 ^ b1)), c11 = ToUnit(Hash(a1 ^ b1));
  const float y0 = c00 + (c10 - c00) * ux, y1 = c01 + (c11 - c01) * ux;
  return y0 + (y1 - y0) * uy;
}

constexpr int kOctaves = 7;
constexpr float kCell = 0.25f;  // marking cell edge, m
constexpr int kMarksPerCell = 6;

// Squared distance from p to segment ab (2D).
inline float SegmentDistance2(float px, float py, float ax, float ay, float bx, float by) {
  const float abx = bx - ax, aby = by - ay, apx = px - ax, apy = py - ay;
  const float len2 = abx * abx + aby * aby;
  float s = len2 > 0 ? (apx * abx + apy * aby) / len2 : 0.f;
  s = s < 0.f ? 0.f : (s > 1.f ? 1.f : s);
  const float dx = apx - s * abx, dy = apy - s * aby;
  return dx * dx + dy * dy;
}

// Tile geometry: 2048 texels of 1/256 m (8 m); patches of 1 m = 256 texels.
constexpr int kTileSize = 2048;
constexpr float kTexelsPerMetre = 256.0f;
constexpr int kPatchTexels = 256;
// Patch origins (texel) in [1, 1 + kOffsetRange): the bilinear footprint of a
// patch, texels [origin - 1, origin + kPatchTexels], stays inside the tile.
constexpr uint32_t kOffsetRange = kTileSize - kPatchTexels - 2;

// The tile's albedo at (u, v) in metres: fBm over 7 octaves (wavelengths
// 1.6 m .. 2.5 cm, slowly decaying amplitudes for dense fine detail) with the
// contrast boosted, then markings: each 0.25 m cell holds 6 shapes fully
// inside it (so only the own cell needs testing): discs, rings and strokes.
float TileAlbedo(float u, float v) {
  constexpr uint32_t kSeed = 0x51ed270bU;
  float noise = 0.f, amplitude = 0.5f, total = 0.f;
  float f = 1.0f / 1.6f;
  for (int octave = 0; octave < kOctaves; ++octave) {
    // A per-octave offset keeps the lattices of different octaves unaligned.
    const float offset = 0.37f * static_cast<float>(octave);
    noise += amplitude * ValueNoise(u * f + offset, v * f - offset, kSeed + octave * 0x9e3779b9U);
    total += amplitude;
    amplitude *= 0.9f;
    f *= 2.0f;
  }
  noise /= total;
  float albedo = 0.5f + 3.0f * (noise - 0.5f);
  const int32_t cu = FastFloor(u * (1.0f / kCell)), cv = FastFloor(v * (1.0f / kCell));
  const float lu = u - static_cast<float>(cu) * kCell, lv = v - static_cast<float>(cv) * kCell;
  uint32_t h = Hash((static_cast<uint32_t>(cu) * kPrimeU) ^ (static_cast<uint32_t>(cv) * kPrimeV) ^
                    kSeed ^ 0xa5a5a5a5U);
  for (int m = 0; m < kMarksPerCell; ++m) {
    // One hash per mark decides its size, centre, type and shade.
    h = Hash(h + 0x68e31da4U);
    const float size = 0.02f + 0.06f * static_cast<float>(h & 255u) * (1.0f / 255.0f);
    // Every shape lies within size + 0.02 m of its centre (stroke ends within
    // 0.78 * size, plus at most 0.018 m of stroke width).
    const float reach = size + 0.02f;
    const float span = kCell - 2 * reach;  // >= 0.05 m
    const float mu = reach + span * static_cast<float>((h >> 8) & 1023u) * (1.0f / 1023.0f);
    const float mv = reach + span * static_cast<float>((h >> 18) & 1023u) * (1.0f / 1023.0f);
    const float du = lu - mu, dv = lv - mv;
    const float d2 = du * du + dv * dv;
    if (d2 > reach * reach) continue;  // outside this mark's bounding circle
    const uint32_t type = (h >> 28) & 3u;
    const float shade = (h >> 30) & 1u ? 0.95f : 0.04f;
    if (type == 0) {  // disc
      if (d2 < 0.64f * size * size) albedo = shade;
    } else if (type == 1) {  // ring
      if (std::fabs(std::sqrt(d2) - 0.7f * size) < 0.012f) albedo = shade;
    } else {  // strokes: two or three segments through the mark's circle
      uint32_t hs = Hash(h ^ 0x2545f491U);
      float pu = mu + size * (ToUnit(hs) - 0.5f), pv = mv + size * (ToUnit(Hash(hs + 1)) - 0.5f);
      for (uint32_t k = 0; k < type; ++k) {
        hs = Hash(hs + 7U);
        const float nu = mu + 1.1f * size * (ToUnit(hs) - 0.5f);
        const float nv = mv + 1.1f * size * (ToUnit(Hash(hs + 1)) - 0.5f);
        const float width = 0.008f + 0.01f * ToUnit(hs >> 3);
        if (SegmentDistance2(lu, lv, pu, pv, nu, nv) < width * width) albedo = shade;
        pu = nu;
        pv = nv;
      }
    }
  }
  return std::fmin(0.97f, std::fmax(0.03f, albedo));
}

// Texels are stored in 8x8 blocks of 64 bytes (one cache line each), blocks
// row-major: a bilinear fetch and the fetches of neighbouring pixels mostly
// share a cache line.
constexpr int kBlocksPerRow = kTileSize / 8;
inline size_t TexelIndex(uint32_t x, uint32_t y) {
  return (static_cast<size_t>(y >> 3) * kBlocksPerRow + (x >> 3)) * 64 + (y & 7u) * 8 + (x & 7u);
}

const uint8_t* Tile() {
  static const std::vector<uint8_t> tile = [] {
    // 64 spare bytes so that the texels can start on a cache-line boundary.
    std::vector<uint8_t> t(static_cast<size_t>(kTileSize) * kTileSize + 64);
    const size_t shift = (64 - reinterpret_cast<uintptr_t>(t.data()) % 64) % 64;
    uint8_t* texels = t.data() + shift;
    tbb::parallel_for(0, kTileSize, [&](int y) {
      for (int x = 0; x < kTileSize; ++x) {
        const float a = TileAlbedo((x + 0.5f) / kTexelsPerMetre, (y + 0.5f) / kTexelsPerMetre);
        texels[TexelIndex(x, y)] = static_cast<uint8_t>(a * 255.f + 0.5f);
      }
    });
    return t;
  }();
  const size_t shift = (64 - reinterpret_cast<uintptr_t>(tile.data()) % 64) % 64;
  return tile.data() + shift;
}

// The tile averaged over 4x4 texels (1.56 cm texels, 512 x 512, row-major):
// 256 KB, so that random lookups (LiDAR points) stay in cache.
constexpr int kMipFactor = 4;
constexpr int kMipSize = kTileSize / kMipFactor;
const uint8_t* MipTile() {
  static const std::vector<uint8_t> mip = [] {
    const uint8_t* tile = Tile();
    std::vector<uint8_t> m(static_cast<size_t>(kMipSize) * kMipSize);
    for (int y = 0; y < kMipSize; ++y) {
      for (int x = 0; x < kMipSize; ++x) {
        int sum = 0;
        for (int dy = 0; dy < kMipFactor; ++dy) {
          for (int dx = 0; dx < kMipFactor; ++dx) {
            sum += tile[TexelIndex(x * kMipFactor + dx, y * kMipFactor + dy)];
          }
        }
        m[static_cast<size_t>(y) * kMipSize + x] =
            static_cast<uint8_t>((sum + kMipFactor * kMipFactor / 2) / (kMipFactor * kMipFactor));
      }
    }
    return m;
  }();
  return mip.data();
}

}  // namespace

bool TextureOptions::Check() const {
  CHECK_OPTION_GT(frequency_scale, 0.0f);
  return true;
}

Texture::Texture(const TextureOptions& options)
    : options_(options), seed_mix_(Hash(options.seed * 0x9e3779b9U + 1U)), tile_(Tile()),
      mip_(MipTile()) {
  THROW_CHECK_OPTIONS(options_);
}

inline void Texture::PatchCoordinates(uint32_t surface_id, const Eigen::Vector3f& p, int axis,
                                      float* x, float* y) const {
  // Seed of (scene seed, surface); seed_mix_ = Hash(scene seed) is precomputed,
  // the cell hash below mixes it further.
  const uint32_t seed = seed_mix_ + surface_id * 0x85ebca6bU;
  // Surface coordinates (u, v) in metres: the two coordinates other than `axis`.
  const float u = p[axis == 0 ? 1 : 0] * options_.frequency_scale;
  const float v = p[axis == 2 ? 1 : 2] * options_.frequency_scale;
  const int32_t cu = FastFloor(u), cv = FastFloor(v);
  float s = u - static_cast<float>(cu), t = v - static_cast<float>(cv);  // in [0, 1)
  const uint32_t h =
      Hash((static_cast<uint32_t>(cu) * kPrimeU) ^ (static_cast<uint32_t>(cv) * kPrimeV) ^ seed);
  // One of 8 orientations (transpose, mirror s, mirror t), then the offset.
  // Branch-free: the bits are random per cell.
  const float s1 = (h & 1u) ? t : s, t1 = (h & 1u) ? s : t;
  s = (h & 2u) ? 1.0f - s1 : s1;
  t = (h & 4u) ? 1.0f - t1 : t1;
  const uint32_t ox = 1 + ((((h >> 3) & 0x7ffu) * kOffsetRange) >> 11);
  const uint32_t oy = 1 + ((((h >> 14) & 0x7ffu) * kOffsetRange) >> 11);
  *x = static_cast<float>(ox) + s * kPatchTexels;
  *y = static_cast<float>(oy) + t * kPatchTexels;
}

inline float Texture::Fetch(float x, float y) const {
  // Bilinear; texel centres at +0.5.
  x -= 0.5f;
  y -= 0.5f;
  const int32_t ix = FastFloor(x), iy = FastFloor(y);
  const float fx = x - static_cast<float>(ix), fy = y - static_cast<float>(iy);
  const uint32_t x0 = static_cast<uint32_t>(ix), y0 = static_cast<uint32_t>(iy);
  const float t00 = tile_[TexelIndex(x0, y0)], t10 = tile_[TexelIndex(x0 + 1, y0)];
  const float t01 = tile_[TexelIndex(x0, y0 + 1)], t11 = tile_[TexelIndex(x0 + 1, y0 + 1)];
  const float a = t00 + (t10 - t00) * fx;
  const float b = t01 + (t11 - t01) * fx;
  return (a + (b - a) * fy) * (1.0f / 255.0f);
}

float Texture::FootprintAlbedo(uint32_t surface_id, const Eigen::Vector3f& p, int axis) const {
  float x, y;
  PatchCoordinates(surface_id, p, axis, &x, &y);
  // Level-0 texel coordinates (centres at +0.5) to mip coordinates.
  x = x * (1.0f / kMipFactor) - 0.5f;
  y = y * (1.0f / kMipFactor) - 0.5f;
  const int32_t ix = std::min(std::max(FastFloor(x), 0), kMipSize - 2);
  const int32_t iy = std::min(std::max(FastFloor(y), 0), kMipSize - 2);
  const float fx = std::min(std::max(x - static_cast<float>(ix), 0.f), 1.f);
  const float fy = std::min(std::max(y - static_cast<float>(iy), 0.f), 1.f);
  const uint8_t* row = mip_ + static_cast<size_t>(iy) * kMipSize + ix;
  const float a = row[0] + (static_cast<float>(row[1]) - row[0]) * fx;
  const float b = row[kMipSize] + (static_cast<float>(row[kMipSize + 1]) - row[kMipSize]) * fx;
  return (a + (b - a) * fy) * (1.0f / 255.0f);
}

float Texture::Albedo(uint32_t surface_id, const Eigen::Vector3f& p, int axis) const {
  float x, y;
  PatchCoordinates(surface_id, p, axis, &x, &y);
  return Fetch(x, y);
}

Eigen::Vector3f Texture::Tint(uint32_t surface_id) const {
  const uint32_t h = Hash(options_.seed * 0x27d4eb2dU + surface_id * 0x165667b1U);
  return Eigen::Vector3f(0.5f + 0.5f * ToUnit(h), 0.5f + 0.5f * ToUnit(Hash(h)),
                         0.5f + 0.5f * ToUnit(Hash(h + 1)));
}

}  // namespace sim
}  // namespace lisfm
