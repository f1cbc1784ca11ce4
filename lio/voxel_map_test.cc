#include "lio/voxel_map.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

std::vector<Eigen::Vector3f> RandomPoints(int n, float extent) {
  std::uniform_real_distribution<float> u(-extent, extent);
  std::vector<Eigen::Vector3f> pts(n);
  for (auto& p : pts) p = {u(test::Rng()), u(test::Rng()), u(test::Rng())};
  return pts;
}

TEST(VoxelMap, KnnIsExactWithinTheSearchedNeighbourhood) {
  VoxelMapOptions options;
  options.voxel_size = 0.5;
  options.resolution = 0.0;  // keep every point
  options.max_points_per_voxel = 100000;
  VoxelMap map(options);
  const auto pts = RandomPoints(20000, 3.0f);
  ASSERT_EQ(map.Insert(pts), pts.size());
  ASSERT_EQ(map.NumPoints(), pts.size());
  // From a voxel centre the 18-neighbourhood covers every point closer than
  // sqrt(3)/2 voxel (the nearest corner voxel), so within 0.4 m the search is exact.
  std::uniform_int_distribution<int> cell(-5, 4);
  std::vector<Eigen::Vector3f> nbrs;
  std::vector<float> d2;
  for (int q = 0; q < 200; ++q) {
    const Eigen::Vector3f query((cell(test::Rng()) + 0.5f) * 0.5f, (cell(test::Rng()) + 0.5f) * 0.5f,
                                (cell(test::Rng()) + 0.5f) * 0.5f);
    const int k = 5;
    const int found = map.KnnSearch(query, k, 0.4, &nbrs, &d2);
    std::vector<float> brute;
    for (const auto& p : pts) {
      const float d = (p - query).squaredNorm();
      if (d <= 0.16f) brute.push_back(d);
    }
    std::sort(brute.begin(), brute.end());
    ASSERT_EQ(found, std::min<int>(k, brute.size()));
    for (int i = 0; i < found; ++i) {
      EXPECT_FLOAT_EQ(d2[i], brute[i]);
      EXPECT_FLOAT_EQ((nbrs[i] - query).squaredNorm(), d2[i]);
    }
  }
}

TEST(VoxelMap, InsertionKeepsMinimumSpacing) {
  VoxelMapOptions options;
  options.voxel_size = 0.5;
  options.resolution = 0.1;
  VoxelMap map(options);
  const auto pts = RandomPoints(50000, 1.0f);
  map.Insert(pts);
  const auto stored = map.AllPoints();
  EXPECT_LT(stored.size(), pts.size());
  EXPECT_GT(stored.size(), 500u);
  // Inside one voxel no two stored points are closer than the resolution.
  for (size_t i = 0; i < stored.size(); ++i) {
    for (size_t j = i + 1; j < stored.size(); ++j) {
      const bool same_voxel = ((stored[i] / 0.5f).array().floor() == (stored[j] / 0.5f).array().floor()).all();
      if (same_voxel) {
        EXPECT_GE((stored[i] - stored[j]).norm(), 0.1f - 1e-6f);
      }
    }
  }
}

// Each stored point keeps the intensity and sensor of the return that created
// it; ToCloud lists them in the order of AllPoints.
TEST(VoxelMap, KeepsTheAttributesOfStoredPoints) {
  VoxelMapOptions options;
  options.voxel_size = 0.5;
  options.resolution = 0.1;
  VoxelMap map(options);
  const auto pts = RandomPoints(5000, 1.0f);
  std::vector<MapPointAttributes> attributes(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    attributes[i] = {static_cast<float>(i), static_cast<uint8_t>(i % 3)};
  }
  map.Insert(pts, &attributes);
  map.Insert({Eigen::Vector3f(5.1f, 5.1f, 5.1f)});  // default attributes
  const PointCloud cloud = map.ToCloud();
  const auto stored = map.AllPoints();
  ASSERT_EQ(cloud.size(), stored.size());
  ASSERT_LT(stored.size(), pts.size());
  size_t defaults = 0;
  for (size_t k = 0; k < cloud.size(); ++k) {
    const LidarPoint& p = cloud.points[k];
    EXPECT_EQ(p.xyz(), stored[k]);
    if (p.xyz() == Eigen::Vector3f(5.1f, 5.1f, 5.1f)) {
      ++defaults;
      EXPECT_EQ(p.intensity, 0.0f);
      continue;
    }
    const size_t i = static_cast<size_t>(p.intensity);  // the index of the input point
    ASSERT_LT(i, pts.size());
    EXPECT_EQ(pts[i], p.xyz());
    EXPECT_EQ(p.sensor_id, i % 3);
    EXPECT_EQ(p.t, 0.0f);
  }
  EXPECT_EQ(defaults, 1u);
}

TEST(VoxelMap, LeastRecentlyUsedVoxelsAreEvicted) {
  VoxelMapOptions options;
  options.voxel_size = 1.0;
  options.resolution = 0.0;
  options.max_voxels = 10;
  VoxelMap map(options);
  for (int i = 0; i < 30; ++i) map.Insert({Eigen::Vector3f(i + 0.5f, 0.5f, 0.5f)});
  EXPECT_EQ(map.NumVoxels(), 10u);
  EXPECT_EQ(map.NumPoints(), 10u);
  std::vector<Eigen::Vector3f> nbrs;
  std::vector<float> d2;
  EXPECT_EQ(map.KnnSearch({0.5f, 0.5f, 0.5f}, 1, 0.5, &nbrs, &d2), 0);   // evicted
  EXPECT_EQ(map.KnnSearch({29.5f, 0.5f, 0.5f}, 1, 0.5, &nbrs, &d2), 1);  // recent
}

}  // namespace
}  // namespace lisfm
