#include "icp/lidar_fusion.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/errors.h"
#include "icp/spherical_projection.h"

namespace lisfm {
namespace {

constexpr double kDeg = M_PI / 180.0;

// An XT-32-like image: 2000 columns, 32 rows from +15 to -16 deg.
SphericalProjection Xt32() { return SphericalProjection(2000, 32, 15 * kDeg, 1 * kDeg); }

TEST(SphericalProjection, FastAtan2IsWithin1e5Rad) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> c(-50.f, 50.f);
  double worst = 0;
  for (int k = 0; k < 200000; ++k) {
    const float y = c(rng), x = c(rng);
    worst = std::max(worst, std::abs(double{FastAtan2(y, x)} - std::atan2(double{y}, double{x})));
  }
  for (float a = -3.14f; a < 3.14f; a += 1e-3f) {
    const float y = std::sin(a), x = std::cos(a);
    worst = std::max(worst, std::abs(double{FastAtan2(y, x)} - std::atan2(double{y}, double{x})));
  }
  EXPECT_LT(worst, 1e-5);
  EXPECT_EQ(FastAtan2(0.f, 0.f), 0.f);
  EXPECT_NEAR(FastAtan2(0.f, -1.f), M_PI, 1e-6);
  EXPECT_NEAR(FastAtan2(-1.f, 0.f), -M_PI / 2, 1e-6);
}

// Every pixel's ray scaled to a range projects back to the pixel and the range.
TEST(SphericalProjection, PixelRayRoundTrip) {
  const SphericalProjection p = Xt32();
  for (int v = 0; v < p.height(); ++v) {
    for (int u = 0; u < p.width(); u += 7) {
      const Eigen::Vector3f ray = p.Ray(u, v);
      ASSERT_NEAR(ray.norm(), 1.f, 1e-6f);
      for (float range : {0.7f, 5.f, 43.f}) {
        int pu = -1, pv = -1;
        float r = 0;
        ASSERT_TRUE(p.Project(range * ray, &pu, &pv, &r)) << u << " " << v;
        EXPECT_EQ(pu, u);
        EXPECT_EQ(pv, v);
        EXPECT_NEAR(r, range, 1e-5f * range);
      }
    }
  }
}

// A point projects to the pixel whose ray is within half a step of its direction,
// columns wrap at azimuth +-pi, and elevations beyond the rows do not project.
TEST(SphericalProjection, PointsLandInTheirPixel) {
  const SphericalProjection p = Xt32();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> az(-M_PI, M_PI), el(-16.4 * kDeg, 15.4 * kDeg),
      range(0.5, 50);
  for (int k = 0; k < 20000; ++k) {
    const double a = az(rng), e = el(rng), r = range(rng);
    const Eigen::Vector3f x =
        (r * Eigen::Vector3d(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)))
            .cast<float>();
    int u, v;
    float rr;
    ASSERT_TRUE(p.Project(x, &u, &v, &rr));
    const Eigen::Vector3f ray = p.Ray(u, v);
    const double pixel_az = std::atan2(ray.y(), ray.x());
    const double pixel_el = std::asin(ray.z());
    double d_az = std::remainder(a - pixel_az, 2 * M_PI);
    EXPECT_LE(std::abs(d_az), 0.5 * p.azimuth_step_rad() + 1e-5) << a;
    EXPECT_LE(std::abs(e - pixel_el), 0.5 * p.elevation_step_rad() + 1e-5) << e;
    EXPECT_NEAR(rr, r, 1e-5 * r);
  }
  int u, v;
  float r;
  ASSERT_TRUE(p.Project(Eigen::Vector3f(-5.f, 1e-4f, 0.f), &u, &v, &r));
  EXPECT_EQ(u, 0);
  ASSERT_TRUE(p.Project(Eigen::Vector3f(-5.f, -1e-4f, 0.f), &u, &v, &r));
  EXPECT_EQ(u, p.width() - 1);
  EXPECT_EQ(p.WrapColumn(-1), p.width() - 1);
  EXPECT_EQ(p.WrapColumn(p.width()), 0);
  EXPECT_FALSE(p.Project(Eigen::Vector3f(5.f, 0.f, 5.f * std::tan(15.6f * kDeg)), &u, &v, &r));
  EXPECT_FALSE(p.Project(Eigen::Vector3f(5.f, 0.f, -5.f * std::tan(16.6f * kDeg)), &u, &v, &r));
  EXPECT_FALSE(p.Project(Eigen::Vector3f::Zero(), &u, &v, &r));
}

// An XT-32-like scan (ring r at -16 + r deg, 2000 columns) of the inside of an axis
// aligned box [-4, 6] x [-3, 5] x [-1.5, 2.5] seen from `origin`, in the sensor frame.
PointCloud BoxScan(const Eigen::Vector3d& origin) {
  PointCloud scan;
  const Eigen::Vector3d lo(-4, -3, -1.5), hi(6, 5, 2.5);
  for (int ring = 0; ring < 32; ++ring) {
    const double e = (-16 + ring) * kDeg;
    for (int c = 0; c < 2000; ++c) {
      const double a = 2 * M_PI * (c + 0.3) / 2000;
      const Eigen::Vector3d d(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e));
      double t = 1e9;
      for (int k = 0; k < 3; ++k) {
        if (d[k] > 1e-9) t = std::min(t, (hi[k] - origin[k]) / d[k]);
        if (d[k] < -1e-9) t = std::min(t, (lo[k] - origin[k]) / d[k]);
      }
      LidarPoint p;
      const Eigen::Vector3d x = t * d;
      p.x = static_cast<float>(x.x());
      p.y = static_cast<float>(x.y());
      p.z = static_cast<float>(x.z());
      p.intensity = 50;
      p.ring = static_cast<uint16_t>(ring);
      scan.points.push_back(p);
    }
  }
  return scan;
}

// Distance of a world point to the box's surface (inside the box).
double BoxDistance(const Eigen::Vector3f& x) {
  const Eigen::Vector3d lo(-4, -3, -1.5), hi(6, 5, 2.5);
  double d = 1e9;
  for (int k = 0; k < 3; ++k) d = std::min({d, std::abs(x[k] - lo[k]), std::abs(x[k] - hi[k])});
  return d;
}

// The layout has one row per ring, the top ring first; the range image's normals
// are the walls' inward normals.
TEST(LidarFusion, LayoutAndNormalsOfABoxScan) {
  const PointCloud scan = BoxScan(Eigen::Vector3d::Zero());
  const LidarFusionOptions options;
  const LidarImageLayout layout = FitLidarImageLayout(scan, options, "box");
  EXPECT_EQ(layout.projection.width(), 2000);
  EXPECT_EQ(layout.projection.height(), 32);
  EXPECT_NEAR(layout.projection.elevation_top_rad(), 15 * kDeg, 1e-6);
  EXPECT_NEAR(layout.projection.elevation_step_rad(), 1 * kDeg, 1e-6);
  ASSERT_EQ(layout.row_of_ring.size(), 32u);
  EXPECT_EQ(layout.row_of_ring[31], 0);
  EXPECT_EQ(layout.row_of_ring[0], 31);
  LidarFusion fusion(layout, options, SurfelFusionOptions());
  VertexNormalMap image;
  std::vector<std::array<uint8_t, 3>> colors;
  EXPECT_EQ(fusion.BuildRangeImage(scan, &image, &colors), scan.size());
  size_t valid = 0, aligned = 0;
  for (size_t i = 0; i < image.vertices.size(); ++i) {
    if (!image.Valid(i)) continue;
    ++valid;
    // Away from the box's edges the normal is an axis pointing inwards.
    const Eigen::Vector3f& n = image.normals[i];
    const Eigen::Vector3f& q = image.vertices[i];
    EXPECT_LT(n.dot(q), 0.f);
    Eigen::Index axis;
    n.cwiseAbs().maxCoeff(&axis);
    aligned += std::abs(n[axis]) > 0.999f ? 1 : 0;
  }
  EXPECT_GT(valid, 50000u);
  EXPECT_GT(aligned, valid * 95 / 100);
}

// Three scans from different positions fused with their poses: the stable surfels
// lie on the box and most observations merge.
TEST(LidarFusion, FusedScansLieOnTheSurface) {
  const LidarFusionOptions options;
  const std::vector<Eigen::Vector3d> origins = {{0, 0, 0}, {0.3, 0.1, 0}, {0.6, 0.2, 0.05}};
  LidarFusion fusion(
      FitLidarImageLayout(BoxScan(origins[0]), options, "box"), options, SurfelFusionOptions());
  size_t merged = 0;
  for (const Eigen::Vector3d& o : origins) {
    const LidarFrameResult r = fusion.AddScan(BoxScan(o), SE3(Quat::Identity(), o));
    merged += r.fuse.merged;
  }
  EXPECT_GT(merged, fusion.num_input_points() / 3);
  size_t stable = 0;
  std::vector<double> d;
  for (const Surfel& s : fusion.map().surfels()) {
    if (!fusion.map().Stable(s)) continue;
    ++stable;
    d.push_back(BoxDistance(s.position));
    EXPECT_EQ(s.color[0], 255);
  }
  ASSERT_GT(stable, 20000u);
  std::sort(d.begin(), d.end());
  EXPECT_LT(d[d.size() / 2], 1e-3);
  EXPECT_LT(d[d.size() * 95 / 100], 0.01);
}

TEST(LidarFusion, ScanWithoutPointsInRangeIsAnInputError) {
  PointCloud scan;
  LidarPoint p;
  p.x = 100;
  scan.points.push_back(p);
  EXPECT_THROW(FitLidarImageLayout(scan, LidarFusionOptions(), "far.pcd"), InputError);
}

}  // namespace
}  // namespace lisfm
