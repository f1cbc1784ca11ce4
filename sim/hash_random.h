// Counter-based random numbers for the simulator: every draw is a pure
// function of a 64-bit key built from (seed, sensor, index, ...), so results
// do not depend on the thread count or the order of the work.
#pragma once

#include <cmath>
#include <cstdint>

namespace lisfm {
namespace sim {

// The splitmix64 finaliser: a bijective 64-bit mix with full avalanche.
inline uint64_t Mix64(uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  x ^= x >> 31;
  return x;
}

// Uniform in [0, 1) from the top 53 bits of a hash.
inline double HashUniform(uint64_t h) { return static_cast<double>(h >> 11) * 0x1.0p-53; }

// Standard normal from a hash (Box-Muller on its two 32-bit halves).
inline double HashNormal(uint64_t h) {
  const double u1 = (static_cast<double>(h >> 32) + 0.5) * 0x1.0p-32;
  const double u2 = (static_cast<double>(h & 0xffffffffULL) + 0.5) * 0x1.0p-32;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

// Approximately standard normal from a hash: the sum of its four 16-bit
// uniforms (Irwin-Hall, variance 4/12) centred and scaled to unit variance.
inline float HashGaussian(uint64_t h) {
  const float sum =
      static_cast<float>((h & 0xffff) + ((h >> 16) & 0xffff) + ((h >> 32) & 0xffff) + (h >> 48));
  return (sum * (1.0f / 65536.0f) - 2.0f) * 1.7320508f;
}

}  // namespace sim
}  // namespace lisfm
