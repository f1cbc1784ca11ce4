// The LiDAR error sources (LidarErrorOptions) against their definitions in
// sim/lidar_simulator.h, on plane scenes seen by a static spinning LiDAR at the
// origin (spin axis z; no motion, so every point's ray is known exactly).
#include <cmath>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "sim/lidar_simulator.h"
#include "sim/materials.h"
#include "sim/scene.h"

namespace lisfm {
namespace sim {
namespace {

// The rectangle x = x0, y in [y0, y1], z in [z0, z1] (two triangles, id `id`).
void AddWallX(double x0, double y0, double y1, double z0, double z1, uint32_t id,
              std::vector<Triangle>* tris) {
  const Eigen::Vector3f a(x0, y0, z0), b(x0, y1, z0), c(x0, y1, z1), d(x0, y0, z1);
  tris->push_back({a, b, c, id});
  tris->push_back({a, c, d, id});
}

// Surfaces 0..n-1 get the named materials.
std::unique_ptr<Scene> PlaneScene(std::vector<Triangle> tris,
                                  const std::vector<std::string>& materials) {
  auto scene = Scene::FromTriangles(std::move(tris));
  std::vector<MaterialId> ids;
  for (const std::string& m : materials) ids.push_back(*FindMaterial(m));
  scene->SetMaterials(ids);
  return scene;
}

SplineTrajectory Still() {
  return SplineTrajectory(0, 0.1, std::vector<Quat>(4, Quat::Identity()),
                          std::vector<Vec3>(4, Vec3::Zero()));
}

RigLidar Spinning() {
  RigLidar l;
  l.type = LidarType::kSpinning;
  l.rings = 32;
  l.min_range = 0.05;
  l.max_range = 120.0;
  l.scan_rate = 10.0;
  return l;
}

// Error sources on, every one off: each test switches on what it checks.
LidarSimOptions AllOff() {
  LidarSimOptions o;
  o.noise_scale = 0;
  o.errors_enabled = true;
  o.errors.incidence_noise_gain = 0;
  o.errors.beam_divergence_mrad = 0;
  o.errors.range_at_10_percent_m = 0;
  o.errors.dropout_reflectivity = 0;
  return o;
}

PointCloud Scan(const Scene& scene, const LidarSimOptions& options, int64_t index = 0) {
  const SplineTrajectory still = Still();
  const LidarSimulator sim(scene, still, Spinning(), TextureOptions(), options);
  return sim.SimulateScan(0, index);
}

// Intensity = 100 (rho_d m cos(theta) + rho_s cos(theta)^20): on a plaster
// wall (texture modulation m within 2.5 % of 1) intensity / (100 rho_d cos)
// stays within 3.5 % of 1 from normal to 84 deg incidence; a concrete wall
// seen by the same beams is darker by rho ratio 0.35 / 0.8 (within 10 %: its
// modulation is within 10.5 % and follows the same texture); a metal wall (rho_d 0.05, rho_s 0.6) is bright only near normal
// incidence, as the specular lobe says.
TEST(LidarErrors, IntensityFollowsReflectivityAndIncidence) {
  LidarSimOptions options = AllOff();
  auto wall = [](const std::string& material) {
    std::vector<Triangle> tris;
    AddWallX(4.0, -40, 40, -5, 5, 0, &tris);
    return PlaneScene(tris, {material});
  };
  const PointCloud plaster = Scan(*wall("painted_plaster"), options);
  const PointCloud concrete = Scan(*wall("bare_concrete"), options);
  const PointCloud metal = Scan(*wall("metal"), options);
  ASSERT_GT(plaster.size(), 10000u);
  ASSERT_EQ(plaster.size(), concrete.size());  // nothing dropped: same beams
  ASSERT_EQ(plaster.size(), metal.size());
  int checked_grazing = 0;
  for (size_t i = 0; i < plaster.size(); ++i) {
    const LidarPoint& p = plaster.points[i];
    const double cos_incidence = p.x / p.xyzd().norm();  // wall normal = x
    const double expected = 100.0 * 0.8 * cos_incidence;
    EXPECT_NEAR(p.intensity / expected, 1.0, 0.035) << "cos " << cos_incidence;
    EXPECT_NEAR(concrete.points[i].intensity / p.intensity, 0.35 / 0.8, 0.1 * 0.35 / 0.8);
    const double c = cos_incidence;
    const double metal_expected = 100.0 * (0.05 * c + 0.6 * std::pow(c, 20));
    // Metal's texture modulation spans a wider band (contrast 0.3 around
    // albedo 0.55): only the specular part is checked tightly.
    EXPECT_NEAR(metal.points[i].intensity, metal_expected, 100.0 * 0.05 * c * 0.3);
    if (c < 0.2) ++checked_grazing;
  }
  EXPECT_GT(checked_grazing, 100);
}

// sigma(theta) = range_sigma (1 + g (1/cos(theta) - 1)): with g = 1 the range
// residuals, normalised by the model's sigma, have unit variance in every
// incidence band (chi-square mean within 10 %, > 1000 points per band), and
// the raw spread at 60-75 deg incidence is 2-4x that near normal incidence.
// With g = 0 the spread is the same in all bands.
TEST(LidarErrors, RangeNoiseGrowsWithIncidence) {
  std::vector<Triangle> tris;
  AddWallX(3.0, -40, 40, -5, 5, 0, &tris);
  const auto scene = PlaneScene(tris, {"painted_plaster"});
  for (const double gain : {1.0, 0.0}) {
    LidarSimOptions options = AllOff();
    options.noise_scale = 1.0;
    options.range_sigma = 0.01;
    options.errors.incidence_noise_gain = gain;
    const double bands[3][2] = {{0.9, 1.0}, {0.5, 0.6}, {0.25, 0.5}};
    double chi2[3] = {0, 0, 0}, sq[3] = {0, 0, 0};
    int count[3] = {0, 0, 0};
    for (int64_t scan = 0; scan < 3; ++scan) {
      const PointCloud cloud = Scan(*scene, options, scan);
      for (const LidarPoint& p : cloud.points) {
        const Vec3 x = p.xyzd();
        const double cos_incidence = x.x() / x.norm();
        const double residual = x.norm() - 3.0 / cos_incidence;
        const double sigma = 0.01 * (1.0 + gain * (1.0 / std::max(cos_incidence, 0.1) - 1.0));
        for (int b = 0; b < 3; ++b) {
          if (cos_incidence < bands[b][0] || cos_incidence >= bands[b][1]) continue;
          chi2[b] += residual * residual / (sigma * sigma);
          sq[b] += residual * residual;
          ++count[b];
        }
      }
    }
    for (int b = 0; b < 3; ++b) {
      ASSERT_GT(count[b], 1000) << "band " << b;
      EXPECT_NEAR(chi2[b] / count[b], 1.0, 0.1) << "gain " << gain << " band " << b;
    }
    const double spread_ratio = std::sqrt((sq[1] / count[1]) / (sq[0] / count[0]));
    if (gain == 1.0) {
      EXPECT_GT(spread_ratio, 1.5);  // 1/cos over [0.5, 0.6] vs ~1: about 1.8
      EXPECT_LT(spread_ratio, 2.2);
    } else {
      EXPECT_NEAR(spread_ratio, 1.0, 0.1);
    }
  }
}

// A 1 m wide board 0.5 m in front of a wall: with 3 mrad divergence some
// beams near the board's vertical edges return a point between board and wall
// (expected 2 edges x 32 rings x 2 beams x P(straddle) 0.48 = 61), every such
// point lies between the two surfaces along its own ray and within a column
// gap + half a divergence of an edge; no point off the surfaces elsewhere.
// With the board 3 m in front (beyond the 1 m merge separation) no point lies
// between: the strongest echo wins (the board's, also for a wall beam that
// grazes the board: it lands on the board's plane beside the board).
TEST(LidarErrors, MixedPixelsOnlyAtDepthEdgesAndBetweenSurfaces) {
  for (const double board_x : {5.5, 3.0}) {
    std::vector<Triangle> tris;
    AddWallX(6.0, -20, 20, -5, 5, 0, &tris);
    AddWallX(board_x, -0.5, 0.5, -5, 5, 1, &tris);
    const auto scene = PlaneScene(tris, {"painted_plaster", "wood"});
    LidarSimOptions options = AllOff();
    options.errors.beam_divergence_mrad = 3.0;
    const PointCloud cloud = Scan(*scene, options);
    ASSERT_GT(cloud.size(), 5000u);
    const double column_gap = 2 * M_PI / 2000;
    int mixed = 0;
    for (const LidarPoint& p : cloud.points) {
      const Vec3 x = p.xyzd();
      const Vec3 ray = x.normalized();
      const double r = x.norm();
      const double r_board = board_x / ray.x(), r_wall = 6.0 / ray.x();
      const bool on_wall = std::abs(r - r_wall) < 1e-4;
      const bool on_board_plane = std::abs(r - r_board) < 1e-4;
      // The ray meets the board where |y| <= 0.5 at x = board_x.
      const bool inside_board = std::abs(ray.y() * r_board) <= 0.5 + 1e-4;
      if (on_wall || (on_board_plane && inside_board)) continue;
      // Off the surfaces: merged echoes between them, or the board's stronger
      // echo returned by a beam just beside it.
      const bool between = r > r_board + 1e-4 && r < r_wall - 1e-4;
      EXPECT_TRUE(between || on_board_plane) << "range " << r;
      if (between) ++mixed;
      const double az = std::atan2(ray.y(), ray.x());
      const double edge = std::atan2(0.5, board_x);
      EXPECT_LT(std::abs(std::abs(az) - edge), column_gap + 1.5e-3 + 1e-5)
          << "point off the surfaces away from the board's edges, azimuth " << az;
    }
    if (board_x == 5.5) {
      EXPECT_GT(mixed, 25);
      EXPECT_LT(mixed, 110);
    } else {
      EXPECT_EQ(mixed, 0);
    }
  }
}

// Dropouts: each returned point of a reference scan (dropouts off) has the
// apparent reflectivity rho = intensity / 100; with rho_half = 0.02 a pulse
// is lost with p = 1 - (1 - p_m) (1 - 1 / (1 + (rho / rho_half)^2)). On black
// rubber (p_m = 0) and glass (p_m = 0.5) the number of lost points over 4
// scans matches sum(p) within 4 binomial standard deviations, and is large.
TEST(LidarErrors, DropoutRateOnDarkAndGlassyMaterialsMatchesItsProbability) {
  for (const std::string material : {"black_rubber", "glass"}) {
    std::vector<Triangle> tris;
    AddWallX(3.0, -3, 3, -3, 3, 0, &tris);
    const auto scene = PlaneScene(tris, {material});
    const double p_material = Materials()[*FindMaterial(material)].dropout;
    double expected = 0, variance = 0;
    size_t reference_points = 0, kept = 0;
    for (int64_t scan = 0; scan < 4; ++scan) {
      LidarSimOptions options = AllOff();
      const PointCloud reference = Scan(*scene, options, scan);
      options.errors.dropout_reflectivity = 0.02;
      const PointCloud cloud = Scan(*scene, options, scan);
      reference_points += reference.size();
      kept += cloud.size();
      for (const LidarPoint& p : reference.points) {
        const double q = p.intensity / 100.0 / 0.02;
        const double drop = 1.0 - (1.0 - p_material) * (1.0 - 1.0 / (1.0 + q * q));
        expected += drop;
        variance += drop * (1.0 - drop);
      }
    }
    ASSERT_GT(reference_points, 2000u);
    const double lost = static_cast<double>(reference_points - kept);
    EXPECT_NEAR(lost, expected, 4.0 * std::sqrt(variance)) << material;
    EXPECT_GT(lost, 0.1 * reference_points) << material;
  }
}

// Maximum range R10 sqrt(rho / 0.1): a black-rubber wall at 60 m loses most
// beams and every kept point satisfies the bound (noise off); a plaster wall
// at the same distance (rho 0.8: R_max beyond the sensor's 120 m) loses none.
TEST(LidarErrors, MaximumRangeFollowsTheMaterial) {
  for (const std::string material : {"black_rubber", "painted_plaster"}) {
    std::vector<Triangle> tris;
    AddWallX(60.0, -20, 20, -20, 20, 0, &tris);
    const auto scene = PlaneScene(tris, {material});
    LidarSimOptions options = AllOff();
    const PointCloud reference = Scan(*scene, options);
    options.errors.range_at_10_percent_m = 80.0;
    const PointCloud cloud = Scan(*scene, options);
    ASSERT_GT(reference.size(), 500u);
    for (const LidarPoint& p : cloud.points) {
      EXPECT_LE(p.xyzd().norm(), 80.0 * std::sqrt(p.intensity / 100.0 / 0.1) + 1e-3);
    }
    if (material == "painted_plaster") {
      EXPECT_EQ(cloud.size(), reference.size());
    } else {
      EXPECT_LT(cloud.size(), reference.size() / 2);
    }
  }
}

// The error path is deterministic per (seed, scan) and the draws differ
// between scans.
TEST(LidarErrors, DeterministicPerScan) {
  std::vector<Triangle> tris;
  AddWallX(3.0, -3, 3, -3, 3, 0, &tris);
  const auto scene = PlaneScene(tris, {"black_rubber"});
  LidarSimOptions options;
  options.errors_enabled = true;
  const PointCloud a = Scan(*scene, options, 5), b = Scan(*scene, options, 5);
  const PointCloud c = Scan(*scene, options, 6);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a.points[i].x, b.points[i].x);
  EXPECT_NE(a.size(), c.size());
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
