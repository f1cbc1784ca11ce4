#include "sim/texture.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

namespace lisfm {
namespace sim {
namespace {

double Correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = a.size();
  double ma = 0, mb = 0;
  for (size_t i = 0; i < n; ++i) {
    ma += a[i] / n;
    mb += b[i] / n;
  }
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < n; ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

// The albedo is a function of the surface point only: the same for both
// normal signs and any normal length, in range, and it depends on the
// in-plane coordinates only (the coordinate along the normal is ignored).
TEST(Texture, ViewConsistentAndInRange) {
  const Texture texture{TextureOptions()};
  double sum = 0, sum2 = 0;
  int n = 0;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3f p(0.37f * i, 2.0f + 0.011f * i, 1.3f);
    const float a = texture.Albedo(7, p, 2);
    EXPECT_GE(a, 0.03f - 1e-6f);
    EXPECT_LE(a, 0.97f + 1e-6f);
    EXPECT_EQ(a, texture.Albedo(7, p, TextureAxis(Eigen::Vector3f(0, 0, -3))));
    EXPECT_EQ(a, texture.Albedo(7, p, TextureAxis(Eigen::Vector3f(0.1f, -0.2f, 1))));
    EXPECT_EQ(a, texture.Albedo(7, p + Eigen::Vector3f(0, 0, 0.5f), 2));
    sum += a;
    sum2 += a * a;
    ++n;
  }
  // High contrast: standard deviation of at least 0.2 (a flat texture fails).
  EXPECT_GT(std::sqrt(sum2 / n - (sum / n) * (sum / n)), 0.2);
}

// No repetition: the texture of neighbouring 1 m cells, of the same cell on
// another surface and of another scene seed are uncorrelated (|r| < 0.2 over
// 2500 samples; the same cell twice gives r = 1, checked as a control).
TEST(Texture, CellsSurfacesAndSeedsDiffer) {
  const Texture texture{TextureOptions()};
  TextureOptions other_seed;
  other_seed.seed = 2;
  const Texture texture2(other_seed);
  auto sample = [](const Texture& t, uint32_t surface, float u0, float v0) {
    std::vector<double> out;
    for (int i = 0; i < 50; ++i) {
      for (int j = 0; j < 50; ++j) {
        out.push_back(t.Albedo(surface, Eigen::Vector3f(u0 + 0.02f * i, v0 + 0.02f * j, 0), 2));
      }
    }
    return out;
  };
  const auto base = sample(texture, 3, 4.0f, 6.0f);
  EXPECT_NEAR(Correlation(base, sample(texture, 3, 4.0f, 6.0f)), 1.0, 1e-12);
  for (int du = -1; du <= 1; ++du) {
    for (int dv = -1; dv <= 1; ++dv) {
      if (du == 0 && dv == 0) continue;
      EXPECT_LT(std::abs(Correlation(base, sample(texture, 3, 4.0f + du, 6.0f + dv))), 0.2)
          << du << " " << dv;
    }
  }
  EXPECT_LT(std::abs(Correlation(base, sample(texture, 4, 4.0f, 6.0f))), 0.2);
  EXPECT_LT(std::abs(Correlation(base, sample(texture2, 3, 4.0f, 6.0f))), 0.2);
}

// FootprintAlbedo is the albedo averaged over ~1.6 cm: it follows the mean of
// Albedo over a 1.4 cm square (mean absolute difference < 0.05 and r > 0.9;
// not exact, as the mip texels are not aligned with the square and are
// sampled bilinearly), while a 5 cm shifted average does not.
TEST(Texture, FootprintAlbedoIsTheLocalAverage) {
  const Texture texture{TextureOptions()};
  std::vector<double> footprint, mean, shifted;
  double abs_diff = 0;
  for (int i = 0; i < 400; ++i) {
    // Centres of 1/64 m mip texels inside one 1 m cell.
    const float u = 10.0f + (8 + 2 * (i % 20)) / 64.0f + 0.5f / 64.0f;
    const float v = 20.0f + (8 + 2 * (i / 20)) / 64.0f + 0.5f / 64.0f;
    footprint.push_back(texture.FootprintAlbedo(5, Eigen::Vector3f(u, 0, v), 1));
    auto average = [&](float cu, float cv) {
      double s = 0;
      for (int a = 0; a < 8; ++a) {
        for (int b = 0; b < 8; ++b) {
          const Eigen::Vector3f p(cu + (a - 3.5f) / 512.0f, 0, cv + (b - 3.5f) / 512.0f);
          s += texture.Albedo(5, p, 1);
        }
      }
      return s / 64;
    };
    mean.push_back(average(u, v));
    shifted.push_back(average(u + 0.05f, v));
    abs_diff += std::abs(footprint.back() - mean.back()) / 400;
  }
  EXPECT_LT(abs_diff, 0.05);
  const double r = Correlation(footprint, mean);
  EXPECT_GT(r, 0.9);
  EXPECT_LT(Correlation(footprint, shifted), r - 0.3);
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
