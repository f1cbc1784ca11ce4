// Trajectory: ordering invariant, slerp interpolation, nearest-sample lookup
// and path length on hand-made samples with known answers.
#include "core/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

constexpr int64_t kMs = 1000000;
// A realistic absolute stamp (HILTI 2022 clock), to exercise int64 arithmetic.
constexpr TimestampNs kT0 = 1646304541627162000LL;

SE3 YawPose(double yaw_rad, const Vec3& t) {
  return SE3(Quat(Eigen::AngleAxisd(yaw_rad, Vec3::UnitZ())), t);
}

Trajectory ThreeSamples() {
  return Trajectory({{kT0, YawPose(0.0, Vec3(0, 0, 0))},
                     {kT0 + 100 * kMs, YawPose(1.0, Vec3(1, 2, 0))},
                     {kT0 + 300 * kMs, YawPose(1.0, Vec3(4, 6, 0))}});
}

TEST(Trajectory, RejectsNonIncreasingStamps) {
  auto two = [](TimestampNs a, TimestampNs b) {
    return Trajectory({{a, SE3()}, {b, SE3()}});
  };
  EXPECT_THROW(two(kT0, kT0), InternalError);
  EXPECT_THROW(two(kT0, kT0 - 1), InternalError);
  EXPECT_EQ(two(kT0, kT0 + 1).size(), 2u);
  Trajectory t;
  EXPECT_TRUE(t.empty());
  t.PushBack({kT0, SE3()});
  EXPECT_THROW(t.PushBack({kT0, SE3()}), InternalError);
  t.PushBack({kT0 + 1, SE3()});
  EXPECT_EQ(t.size(), 2u);
  EXPECT_EQ(t.start_ns(), kT0);
  EXPECT_EQ(t.end_ns(), kT0 + 1);
  EXPECT_THROW(Trajectory().start_ns(), InternalError);
}

TEST(Trajectory, InterpolatesWithSlerpAndLinearTranslation) {
  const Trajectory traj = ThreeSamples();
  // Exactly at a sample: that sample.
  const auto at = traj.Interpolate(kT0 + 100 * kMs);
  ASSERT_TRUE(at.has_value());
  EXPECT_TRUE(test::PosesNear(*at, traj[1].pose, 1e-15, 1e-15));
  // A quarter of the way between samples 0 and 1: yaw 0.25 rad (slerp about a
  // fixed axis is linear in the angle), translation a quarter of the way.
  const auto q = traj.Interpolate(kT0 + 25 * kMs);
  ASSERT_TRUE(q.has_value());
  EXPECT_TRUE(
      test::PosesNear(*q, YawPose(0.25, Vec3(0.25, 0.5, 0)), 1e-12, 1e-12));
  // Half way between samples 1 and 2 (200 ms apart).
  const auto h = traj.Interpolate(kT0 + 200 * kMs);
  ASSERT_TRUE(h.has_value());
  EXPECT_TRUE(test::PosesNear(*h, YawPose(1.0, Vec3(2.5, 4, 0)), 1e-12, 1e-12));
  // End points are inside; outside is nullopt.
  EXPECT_TRUE(traj.Interpolate(kT0).has_value());
  EXPECT_TRUE(traj.Interpolate(kT0 + 300 * kMs).has_value());
  EXPECT_FALSE(traj.Interpolate(kT0 - 1).has_value());
  EXPECT_FALSE(traj.Interpolate(kT0 + 300 * kMs + 1).has_value());
  EXPECT_FALSE(Trajectory().Interpolate(kT0).has_value());
}

TEST(Trajectory, InterpolationRespectsMaxGap) {
  const Trajectory traj = ThreeSamples();
  // Samples 0-1 are 100 ms apart, 1-2 are 200 ms apart.
  EXPECT_TRUE(traj.Interpolate(kT0 + 50 * kMs, 150 * kMs).has_value());
  EXPECT_FALSE(traj.Interpolate(kT0 + 150 * kMs, 150 * kMs).has_value());
  EXPECT_TRUE(traj.Interpolate(kT0 + 150 * kMs, 200 * kMs).has_value());
  // A stamp that hits a sample needs no bracketing gap.
  EXPECT_TRUE(traj.Interpolate(kT0 + 300 * kMs, 1).has_value());
}

TEST(Trajectory, NearestUsesBinarySearchAndTolerance) {
  const Trajectory traj = ThreeSamples();
  EXPECT_EQ(traj.Nearest(kT0, 0), 0);
  EXPECT_EQ(traj.Nearest(kT0 + 40 * kMs, 50 * kMs), 0);
  EXPECT_EQ(traj.Nearest(kT0 + 60 * kMs, 50 * kMs), 1);
  EXPECT_EQ(traj.Nearest(kT0 + 60 * kMs, 39 * kMs), -1);
  // Tie half way between 0 and 1: the earlier sample.
  EXPECT_EQ(traj.Nearest(kT0 + 50 * kMs, 50 * kMs), 0);
  // Before the start and after the end.
  EXPECT_EQ(traj.Nearest(kT0 - 10 * kMs, 10 * kMs), 0);
  EXPECT_EQ(traj.Nearest(kT0 - 10 * kMs, 9 * kMs), -1);
  EXPECT_EQ(traj.Nearest(kT0 + 310 * kMs, 10 * kMs), 2);
  EXPECT_EQ(traj.Nearest(kT0 + 310 * kMs, 9 * kMs), -1);
  EXPECT_EQ(Trajectory().Nearest(kT0, kMs), -1);
}

TEST(Trajectory, PathLengthSumsSegments) {
  // Segments (1,2,0) and (3,4,0): sqrt(5) + 5.
  EXPECT_NEAR(ThreeSamples().PathLength(), std::sqrt(5.0) + 5.0, 1e-12);
  EXPECT_EQ(Trajectory().PathLength(), 0.0);
  const Trajectory single({{kT0, SE3()}});
  EXPECT_EQ(single.PathLength(), 0.0);
}

}  // namespace
}  // namespace lisfm
