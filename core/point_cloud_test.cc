#include "core/point_cloud.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <set>
#include <tuple>

#include <gtest/gtest.h>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using VoxelIdx = std::tuple<int64_t, int64_t, int64_t>;

VoxelIdx VoxelOf(const LidarPoint& p, double voxel) {
  return {static_cast<int64_t>(std::floor(p.x / voxel)),
          static_cast<int64_t>(std::floor(p.y / voxel)),
          static_cast<int64_t>(std::floor(p.z / voxel))};
}

bool SameBits(const LidarPoint& a, const LidarPoint& b) {
  return std::memcmp(&a.x, &b.x, 4) == 0 && std::memcmp(&a.y, &b.y, 4) == 0 &&
         std::memcmp(&a.z, &b.z, 4) == 0 && std::memcmp(&a.intensity, &b.intensity, 4) == 0 &&
         std::memcmp(&a.t, &b.t, 4) == 0 && a.ring == b.ring && a.sensor_id == b.sensor_id;
}

// A dense grid: 40^3 points spaced 5 cm, at cell centres (i + 0.5) * 0.05, so
// no point lies within 2.5 cm of a 0.5 m voxel boundary; shuffled, with a
// unique intensity per point so that outputs can be traced to inputs.
PointCloud DenseGrid() {
  PointCloud cloud;
  cloud.stamp_ns = 1234567890123456789LL;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 40; ++j) {
      for (int k = 0; k < 40; ++k) {
        LidarPoint p;
        p.x = static_cast<float>((i + 0.5) * 0.05 - 1.0);  // spans negative and positive
        p.y = static_cast<float>((j + 0.5) * 0.05);
        p.z = static_cast<float>((k + 0.5) * 0.05 + 3.0);
        p.intensity = static_cast<float>(cloud.size());
        p.t = static_cast<float>(k) * 1e-3f;
        p.ring = static_cast<uint16_t>(j);
        p.sensor_id = static_cast<uint8_t>(i % 2);
        cloud.points.push_back(p);
      }
    }
  }
  std::shuffle(cloud.points.begin(), cloud.points.end(), test::Rng());
  return cloud;
}

TEST(PointCloud, PositionsOf) {
  PointCloud cloud;
  cloud.points.resize(3);
  cloud.points[1].x = 1.5f;
  cloud.points[2].z = -2.25f;
  const Eigen::Matrix3Xd positions = PositionsOf(cloud);
  ASSERT_EQ(positions.cols(), 3);
  EXPECT_EQ(positions.col(1), Vec3(1.5, 0, 0));
  EXPECT_EQ(positions.col(2), Vec3(0, 0, -2.25));
  EXPECT_EQ(PositionsOf(PointCloud()).cols(), 0);
}

TEST(VoxelDownsample, DenseGridGivesOnePointPerOccupiedVoxel) {
  const PointCloud cloud = DenseGrid();
  const double voxel = 0.5;
  std::set<VoxelIdx> occupied;
  for (const LidarPoint& p : cloud.points) occupied.insert(VoxelOf(p, voxel));
  ASSERT_EQ(occupied.size(), 64u);  // 2 m cube / 0.5 m = 4 voxels per axis

  const PointCloud down = VoxelDownsample(cloud, voxel);
  EXPECT_EQ(down.stamp_ns, cloud.stamp_ns);
  ASSERT_EQ(down.size(), occupied.size());
  std::set<VoxelIdx> covered;
  for (const LidarPoint& p : down.points) covered.insert(VoxelOf(p, voxel));
  EXPECT_EQ(covered, occupied);

  // Every output is an input point (all attributes), and the member nearest to
  // its voxel's centroid (brute force over the input).
  std::map<VoxelIdx, Vec3> sums;
  std::map<VoxelIdx, int> counts;
  for (const LidarPoint& p : cloud.points) {
    auto [it, inserted] = sums.try_emplace(VoxelOf(p, voxel), Vec3::Zero());
    it->second += p.xyzd();
    ++counts[VoxelOf(p, voxel)];
  }
  for (const LidarPoint& p : down.points) {
    const size_t index = static_cast<size_t>(p.intensity);
    ASSERT_LT(index, cloud.size());
    const auto source = std::find_if(cloud.points.begin(), cloud.points.end(), [&](const LidarPoint& q) {
      return q.intensity == p.intensity;
    });
    ASSERT_NE(source, cloud.points.end());
    EXPECT_TRUE(SameBits(*source, p));
    const VoxelIdx v = VoxelOf(p, voxel);
    const Vec3 centroid = sums[v] / counts[v];
    double best = std::numeric_limits<double>::infinity();
    for (const LidarPoint& q : cloud.points) {
      if (VoxelOf(q, voxel) == v) best = std::min(best, (q.xyzd() - centroid).squaredNorm());
    }
    EXPECT_EQ((p.xyzd() - centroid).squaredNorm(), best);
  }
}

TEST(VoxelDownsample, OrderIsFirstAppearanceAndDeterministic) {
  const PointCloud cloud = DenseGrid();
  const PointCloud a = VoxelDownsample(cloud, 0.5);
  const PointCloud b = VoxelDownsample(cloud, 0.5);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(SameBits(a.points[i], b.points[i]));
  // Voxels appear in the order of their first input point.
  std::vector<VoxelIdx> first_seen;
  std::set<VoxelIdx> seen;
  for (const LidarPoint& p : cloud.points) {
    if (seen.insert(VoxelOf(p, 0.5)).second) first_seen.push_back(VoxelOf(p, 0.5));
  }
  ASSERT_EQ(first_seen.size(), a.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_EQ(VoxelOf(a.points[i], 0.5), first_seen[i]);
}

TEST(VoxelDownsample, FloorsNegativeCoordinatesAndBreaksTiesToFirst) {
  PointCloud cloud;
  LidarPoint p;
  p.x = -0.25f;  // voxel -1 (truncation would wrongly merge it into voxel 0)
  p.intensity = 1;
  cloud.points.push_back(p);
  p.x = 0.25f;  // voxel 0
  p.intensity = 2;
  cloud.points.push_back(p);
  p.x = 0.75f;  // voxel 0: 0.25 and 0.75 are exactly equidistant from their centroid 0.5
  p.intensity = 3;
  cloud.points.push_back(p);
  const PointCloud down = VoxelDownsample(cloud, 1.0);
  ASSERT_EQ(down.size(), 2u);
  EXPECT_EQ(down.points[0].intensity, 1);
  EXPECT_EQ(down.points[1].intensity, 2);
}

TEST(VoxelDownsample, ZeroOrNegativeVoxelReturnsTheInput) {
  PointCloud cloud = DenseGrid();
  cloud.points[7].x = std::numeric_limits<float>::quiet_NaN();
  for (double voxel : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN()}) {
    const PointCloud same = VoxelDownsample(cloud, voxel);
    EXPECT_EQ(same.stamp_ns, cloud.stamp_ns);
    ASSERT_EQ(same.size(), cloud.size());
    for (size_t i = 0; i < cloud.size(); ++i) EXPECT_TRUE(SameBits(same.points[i], cloud.points[i]));
  }
}

TEST(VoxelDownsample, DropsNonFinitePoints) {
  PointCloud cloud;
  LidarPoint p;
  cloud.points.push_back(p);
  p.x = std::numeric_limits<float>::quiet_NaN();
  cloud.points.push_back(p);
  p.x = 0;
  p.y = std::numeric_limits<float>::infinity();
  cloud.points.push_back(p);
  p.y = 0;
  p.z = -std::numeric_limits<float>::infinity();
  cloud.points.push_back(p);
  const PointCloud down = VoxelDownsample(cloud, 0.1);
  ASSERT_EQ(down.size(), 1u);
  EXPECT_TRUE(IsFinite(down.points[0]));
  // Huge (finite) coordinates are clamped to the outermost voxel, not UB.
  cloud.points.assign(2, LidarPoint());
  cloud.points[0].x = 3e38f;
  cloud.points[1].x = -3e38f;
  EXPECT_EQ(VoxelDownsample(cloud, 1e-9).size(), 2u);
}

TEST(RemoveNonFinite, RemovesOnlyNonFiniteAndKeepsOrder) {
  PointCloud cloud;
  for (int i = 0; i < 10; ++i) {
    LidarPoint p;
    p.intensity = static_cast<float>(i);
    if (i % 3 == 1) p.x = std::numeric_limits<float>::quiet_NaN();
    if (i == 5) p.z = std::numeric_limits<float>::infinity();
    cloud.points.push_back(p);
  }
  EXPECT_EQ(RemoveNonFinite(&cloud), 4u);  // i = 1, 4, 5, 7
  std::vector<float> kept;
  for (const LidarPoint& p : cloud.points) kept.push_back(p.intensity);
  EXPECT_EQ(kept, (std::vector<float>{0, 2, 3, 6, 8, 9}));
  EXPECT_EQ(RemoveNonFinite(&cloud), 0u);
}

TEST(TransformCloud, MatchesSe3AndKeepsAttributes) {
  const PointCloud cloud = DenseGrid();
  const SE3 target_from_source = test::RandomPose();
  const PointCloud moved = TransformCloud(cloud, target_from_source);
  EXPECT_EQ(moved.stamp_ns, cloud.stamp_ns);
  ASSERT_EQ(moved.size(), cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    const Vec3 expected = target_from_source * cloud.points[i].xyzd();
    // One float rounding of a value of magnitude <= ~10 m: <= 1 ulp ~ 1e-6 m.
    EXPECT_LT((moved.points[i].xyzd() - expected).norm(), 2e-6);
    LidarPoint attributes = moved.points[i];
    attributes.x = cloud.points[i].x;
    attributes.y = cloud.points[i].y;
    attributes.z = cloud.points[i].z;
    EXPECT_TRUE(SameBits(attributes, cloud.points[i]));
  }
  const PointCloud same = TransformCloud(cloud, SE3::Identity());
  for (size_t i = 0; i < cloud.size(); ++i) EXPECT_TRUE(SameBits(same.points[i], cloud.points[i]));
}

}  // namespace
}  // namespace lisfm
