#include "icp/nearest_neighbors.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

PointSet RandomPoints(int n) {
  std::uniform_real_distribution<float> u(-5.f, 5.f);
  PointSet pts(n);
  for (auto& p : pts) p = Eigen::Vector3f(u(test::Rng()), u(test::Rng()), u(test::Rng()));
  return pts;
}

// kNN and radius search must equal brute force exactly (same float distances).
TEST(KdTree, MatchesBruteForce) {
  const PointSet pts = RandomPoints(3000);
  const KdTree tree(pts);
  const PointSet queries = RandomPoints(200);
  for (const auto& q : queries) {
    std::vector<float> d2(pts.size());
    for (size_t i = 0; i < pts.size(); ++i) d2[i] = (pts[i] - q).squaredNorm();
    std::vector<float> sorted = d2;
    std::sort(sorted.begin(), sorted.end());
    uint32_t idx[8];
    float dist[8];
    ASSERT_EQ(tree.Knn(q, 8, idx, dist), 8u);
    for (int k = 0; k < 8; ++k) {
      EXPECT_FLOAT_EQ(dist[k], sorted[k]);
      EXPECT_FLOAT_EQ(d2[idx[k]], sorted[k]);
    }
    uint32_t nearest;
    float nearest_d2;
    ASSERT_TRUE(tree.Nearest(q, &nearest, &nearest_d2));
    EXPECT_FLOAT_EQ(nearest_d2, sorted[0]);
    std::vector<uint32_t> in_radius;
    std::vector<float> in_radius_d2;
    tree.Radius(q, 1.0f, &in_radius, &in_radius_d2);
    const size_t expected = std::count_if(d2.begin(), d2.end(), [](float d) { return d <= 1.0f; });
    EXPECT_EQ(in_radius.size(), expected);
    // Bounded nearest: found iff the nearest is within the bound (also exactly at
    // it: the tree's own squared distance, whose float rounding may differ from
    // the brute force's in the last bit), and then the same point as Nearest().
    for (const float bound : {0.5f * nearest_d2, nearest_d2, 2.0f * nearest_d2 + 1e-3f}) {
      uint32_t within;
      float within_d2;
      const bool found = tree.NearestWithin(q, bound, &within, &within_d2);
      EXPECT_EQ(found, nearest_d2 <= bound) << bound;
      if (found) {
        EXPECT_EQ(within_d2, nearest_d2);
        EXPECT_EQ(within, nearest);
      }
    }
    // Bounded kNN: Knn()'s points up to the bound, in the same order (bounds
    // between, at and beyond the 3rd and 8th neighbours' distances).
    for (const float bound : {dist[2], 0.5f * (dist[2] + dist[3]), dist[7], 2.0f * dist[7]}) {
      uint32_t idx_within[8];
      float dist_within[8];
      const size_t n = tree.KnnWithin(q, 8, bound, idx_within, dist_within);
      const size_t expected_n = std::count_if(dist, dist + 8, [&](float d) { return d <= bound; });
      ASSERT_EQ(n, expected_n) << bound;
      for (size_t k = 0; k < n; ++k) {
        EXPECT_EQ(idx_within[k], idx[k]);
        EXPECT_EQ(dist_within[k], dist[k]);
      }
    }
  }
}

// Brute-force k nearest squared distances of q (ascending), with the tree's own
// float formula (dx^2 + dy^2) + dz^2.
std::vector<float> BruteForceSorted(const PointSet& pts, const Eigen::Vector3f& q) {
  std::vector<float> d2(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    const float dx = pts[i].x() - q.x(), dy = pts[i].y() - q.y(), dz = pts[i].z() - q.z();
    d2[i] = dx * dx + dy * dy + dz * dz;
  }
  std::sort(d2.begin(), d2.end());
  return d2;
}

// Checks Knn / KnnWithin / Radius of `tree` at q against brute force: the same
// distances in the same order, each returned index at its returned distance.
void ExpectExactSearch(const KdTree& tree, const Eigen::Vector3f& q, size_t k, float bound) {
  const PointSet& pts = tree.points();
  const std::vector<float> sorted = BruteForceSorted(pts, q);
  const auto distance_of = [&](uint32_t i) {
    const float dx = pts[i].x() - q.x(), dy = pts[i].y() - q.y(), dz = pts[i].z() - q.z();
    return dx * dx + dy * dy + dz * dz;
  };
  std::vector<uint32_t> idx(k);
  std::vector<float> dist(k);
  const size_t n = tree.Knn(q, k, idx.data(), dist.data());
  ASSERT_EQ(n, std::min(k, pts.size()));
  for (size_t j = 0; j < n; ++j) {
    ASSERT_EQ(dist[j], sorted[j]) << "neighbour " << j << " of " << k;
    ASSERT_EQ(distance_of(idx[j]), dist[j]);
  }
  const size_t expected_within =
      std::min<size_t>(k, std::upper_bound(sorted.begin(), sorted.end(), bound) - sorted.begin());
  const size_t m = tree.KnnWithin(q, k, bound, idx.data(), dist.data());
  ASSERT_EQ(m, expected_within) << "bound " << bound;
  for (size_t j = 0; j < m; ++j) {
    ASSERT_EQ(dist[j], sorted[j]);
    ASSERT_EQ(distance_of(idx[j]), dist[j]);
  }
  std::vector<uint32_t> in_radius;
  std::vector<float> in_radius_d2;
  tree.Radius(q, std::sqrt(bound), &in_radius, &in_radius_d2);
  const float r2 = std::sqrt(bound) * std::sqrt(bound);
  const size_t expected_radius =
      std::upper_bound(sorted.begin(), sorted.end(), r2) - sorted.begin();
  ASSERT_EQ(in_radius.size(), expected_radius);
  ASSERT_TRUE(std::is_sorted(in_radius_d2.begin(), in_radius_d2.end()));
  for (size_t j = 0; j < in_radius.size(); ++j) ASSERT_EQ(distance_of(in_radius[j]), in_radius_d2[j]);
}

// Sizes around the leaf size (24) and its multiples: one leaf, a leaf and a bit,
// two levels; every query from the cloud itself and nearby.
TEST(KdTree, ExactAroundLeafSizes) {
  for (const int n : {1, 2, 5, 23, 24, 25, 47, 48, 49, 97, 300}) {
    const PointSet pts = RandomPoints(n);
    const KdTree tree(pts);
    for (int i = 0; i < std::min(n, 40); ++i) {
      const Eigen::Vector3f q = pts[i] + Eigen::Vector3f(0.01f * i, -0.02f, 0.03f);
      for (const size_t k : {size_t{1}, size_t{2}, size_t{10}, size_t{30}}) {
        ExpectExactSearch(tree, q, k, 4.0f);
      }
    }
  }
}

// A LiDAR-like cloud large enough for the parallel build (> 8192 points): three
// planes sampled along rings (many near-equal coordinates), exact duplicates and
// a sparse far cluster; queries at tree points (as the normals make them) and
// off the surfaces (as the ICP makes them), with and without bounds.
TEST(KdTree, ExactOnStructuredCloudWithDuplicates) {
  PointSet pts;
  std::uniform_real_distribution<float> noise(-0.005f, 0.005f);
  for (int ring = 0; ring < 40; ++ring) {
    for (int a = 0; a < 300; ++a) {
      const float t = 0.02f * a, h = 0.05f * ring;
      pts.emplace_back(t, h, noise(test::Rng()));         // floor
      pts.emplace_back(t, 2.0f + noise(test::Rng()), h);  // wall
      if (a % 3 == 0) pts.emplace_back(6.0f, h, t);       // grid wall, exact coordinates
    }
  }
  for (int d = 0; d < 200; ++d) pts.push_back(pts[37]);  // 200 exact duplicates
  const PointSet far = RandomPoints(50);
  for (const auto& p : far) pts.push_back(p + Eigen::Vector3f(40.f, 0.f, 0.f));
  ASSERT_GT(pts.size(), 8192u);
  const KdTree tree(pts);
  std::uniform_int_distribution<size_t> pick(0, pts.size() - 1);
  for (int trial = 0; trial < 150; ++trial) {
    const Eigen::Vector3f at_point = pts[pick(test::Rng())];
    const Eigen::Vector3f off_surface = at_point + Eigen::Vector3f(0.03f, -0.04f, 0.05f);
    for (const size_t k : {size_t{1}, size_t{2}, size_t{10}}) {
      ExpectExactSearch(tree, at_point, k, 0.01f);
      ExpectExactSearch(tree, off_surface, k, 0.09f);
    }
  }
  // The duplicates: 201 points at distance 0 from pts[37].
  uint32_t idx[64];
  float dist[64];
  ASSERT_EQ(tree.Knn(pts[37], 64, idx, dist), 64u);
  for (int j = 0; j < 64; ++j) {
    EXPECT_EQ(dist[j], 0.f);
    EXPECT_EQ(pts[idx[j]], pts[37]);
  }
  // Far from everything: the bounded search finds nothing, the unbounded the far cluster.
  EXPECT_EQ(tree.KnnWithin(Eigen::Vector3f(100.f, 0.f, 0.f), 5, 1.f, idx, dist), 0u);
  ASSERT_EQ(tree.Knn(Eigen::Vector3f(100.f, 0.f, 0.f), 5, idx, dist), 5u);
  EXPECT_GT(pts[idx[0]].x(), 30.f);
}

TEST(KdTree, EmptyAndNonFinite) {
  const KdTree empty(PointSet{});
  uint32_t idx;
  float d2;
  EXPECT_FALSE(empty.Nearest(Eigen::Vector3f::Zero(), &idx, &d2));
  PointSet bad = RandomPoints(10);
  bad[7].y() = std::nanf("");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { KdTree tree(bad, "scan.pcd"); }, {"point 7", "scan.pcd"}));
}

// Voxel centroids: two points in one voxel average, separate voxels stay apart.
TEST(VoxelDownsamplePoints, Centroids) {
  const PointSet pts = {{0.1f, 0.1f, 0.1f}, {0.3f, 0.3f, 0.3f}, {1.5f, 0.2f, 0.2f},
                        {std::nanf(""), 0.f, 0.f}};
  const PointSet out = VoxelDownsamplePoints(pts, 1.0);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_TRUE(out[0].isApprox(Eigen::Vector3f(0.2f, 0.2f, 0.2f), 1e-6f));
  EXPECT_TRUE(out[1].isApprox(pts[2], 1e-6f));
  EXPECT_EQ(VoxelDownsamplePoints(pts, 0.0).size(), pts.size());
}

// Independent reference: std::map from voxel index to (first appearance, sum),
// in the documented order (first appearance) with the same double summation.
PointSet ReferenceVoxelGrid(const PointSet& pts, double voxel) {
  std::map<std::array<int64_t, 3>, std::pair<size_t, Eigen::Vector4d>> cells;
  for (const auto& p : pts) {
    if (!p.allFinite()) continue;
    const std::array<int64_t, 3> key = {static_cast<int64_t>(std::floor(p.x() * (1.0 / voxel))),
                                        static_cast<int64_t>(std::floor(p.y() * (1.0 / voxel))),
                                        static_cast<int64_t>(std::floor(p.z() * (1.0 / voxel)))};
    auto it = cells.try_emplace(key, cells.size(), Eigen::Vector4d::Zero()).first;
    it->second.second += Eigen::Vector4d(p.x(), p.y(), p.z(), 1.0);
  }
  PointSet out(cells.size());
  for (const auto& [key, cell] : cells) {
    out[cell.first] = (cell.second.head<3>() / cell.second.w()).cast<float>();
  }
  return out;
}

// The open-addressing fast path and the fallback for voxel indices beyond its
// 21-bit packing (a point 1e6 m away at 0.05 m voxels) both equal the reference
// exactly (same order, bit-identical centroids), including negative coordinates
// and many points per voxel.
TEST(VoxelDownsamplePoints, EqualsReferenceOnFastPathAndFallback) {
  // 0.05 m and 0.3 m voxels give ~48k / ~27k voxels, more than the fast
  // path's initial table (sized for half the points, at most half full) holds:
  // its growth is exercised too.
  PointSet pts = RandomPoints(50000);
  pts[123].y() = std::nanf("");  // skipped (no key) on both paths
  pts[40000].z() = std::numeric_limits<float>::infinity();
  for (const double voxel : {0.05, 0.3, 2.0}) {
    const PointSet out = VoxelDownsamplePoints(pts, voxel);
    const PointSet ref = ReferenceVoxelGrid(pts, voxel);
    ASSERT_EQ(out.size(), ref.size()) << voxel;
    for (size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], ref[i]) << voxel << " " << i;
  }
  pts.push_back(Eigen::Vector3f(1e6f, -2.f, 3.f));
  const PointSet out = VoxelDownsamplePoints(pts, 0.05);
  const PointSet ref = ReferenceVoxelGrid(pts, 0.05);
  ASSERT_EQ(out.size(), ref.size());
  for (size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], ref[i]) << i;
}

}  // namespace
}  // namespace lisfm
