#include "lio/pose_slam/pose_slam.h"

#include <gtest/gtest.h>

#include <set>
#include <vector>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// Keyframes 1 m apart on a line: each pair once, i < j, step in [5, 25]. An
// interior keyframe's 25 nearest are those within 12 indices plus the earlier
// one at 13 (ties go to the lower index; so 30 pairs with 17 and, through
// 43's own list, with 43), and keyframes near the ends reach
// farther (keyframe 0's are 1..25).
TEST(KnnCandidatePairs, StepRangeAndEachPairOnce) {
  std::vector<Vec3> positions;
  for (int k = 0; k < 60; ++k) positions.push_back(Vec3(k, 0, 0));
  const auto pairs = KnnCandidatePairs(positions, 25, 5, 25);
  std::set<std::pair<int, int>> unique(pairs.begin(), pairs.end());
  EXPECT_EQ(unique.size(), pairs.size());
  std::set<int> partners_of_30;
  for (const auto& [i, j] : pairs) {
    EXPECT_LT(i, j);
    EXPECT_GE(j - i, 5);
    EXPECT_LE(j - i, 25);
    if (i == 30) partners_of_30.insert(j);
    if (j == 30) partners_of_30.insert(i);
  }
  std::set<int> expected;
  for (int k = 17; k <= 25; ++k) expected.insert(k);
  for (int k = 35; k <= 43; ++k) expected.insert(k);  // 43: 30 is its earlier one at 13
  EXPECT_EQ(partners_of_30, expected);
  EXPECT_TRUE(unique.count({0, 25}));
}

// A walk that comes back to its start after 40 keyframes: the revisit is near
// in space but 40 indices apart, beyond max_index_step, so no pair joins them.
TEST(KnnCandidatePairs, RevisitsBeyondTheIndexStepAreNotPaired) {
  std::vector<Vec3> positions;
  for (int k = 0; k < 40; ++k) {
    const double a = 2.0 * M_PI * k / 40.0;
    positions.push_back(Vec3(6.0 * std::cos(a), 6.0 * std::sin(a), 0.0));
  }
  positions.push_back(positions[0] + Vec3(0.1, 0, 0));
  for (const auto& [i, j] : KnnCandidatePairs(positions, 25, 5, 25)) {
    EXPECT_LE(j - i, 25);
    EXPECT_GE(j - i, 5);
  }
}

// A constant correction moves every pose by it; between two nodes with
// different corrections a pose halfway gets the interpolated one.
TEST(CorrectTrajectory, AppliesInterpolatedCorrections) {
  Trajectory lio;
  for (int k = 0; k <= 10; ++k) {
    lio.PushBack({k * 100'000'000LL, SE3(Quat::Identity(), Vec3(0.1 * k, 0, 0))});
  }
  const std::vector<TimestampNs> nodes = {200'000'000LL, 600'000'000LL};
  const std::vector<SE3> lio_nodes = {lio[2].pose, lio[6].pose};
  const SE3 c0(Quat::Identity(), Vec3(0, 1, 0));
  const SE3 c1(Quat::Identity(), Vec3(0, 3, 0));
  const Trajectory corrected =
      CorrectTrajectory(lio, nodes, lio_nodes, {c0 * lio_nodes[0], c1 * lio_nodes[1]});
  ASSERT_EQ(corrected.size(), lio.size());
  EXPECT_NEAR((corrected[0].pose.translation() - Vec3(0.0, 1, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR((corrected[4].pose.translation() - Vec3(0.4, 2, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR((corrected[10].pose.translation() - Vec3(1.0, 3, 0)).norm(), 0, 1e-12);
  for (size_t k = 0; k < lio.size(); ++k) EXPECT_EQ(corrected[k].t_ns, lio[k].t_ns);
}

}  // namespace
}  // namespace lisfm
