#include "lio/pose_slam/stationary_detection.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "sim/imu_errors.h"
#include "sim/imu_simulator.h"
#include "sim/motion.h"
#include "tests/common/sim_walks.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

constexpr TimestampNs kStartNs = 1'000'000'000'000LL;  // 1000 s

TimestampNs At(double t_s) { return kStartNs + SecondsToNs(t_s); }

// A closed 12 m x 8 m walk with exact rests at the start, middle and end.
sim::SplineTrajectory Walk(double duration_s,
                           uint32_t seed,
                           std::vector<sim::StationaryPeriod>* rests) {
  sim::WalkingRoute route;
  route.waypoints = {Vec3(0, 0, 1.4), Vec3(12, 0, 1.4), Vec3(12, 8, 1.4), Vec3(0, 8, 1.4)};
  route.closed = true;
  return sim::GenerateWalking(route, duration_s, kStartNs, seed, ThreeStopWalk(), rests);
}

// The simulator's realistic IMU (sim/imu_simulator.h, sim/imu_errors.h):
// BMI085 white noise, random-walk and initial biases, scale, misalignment and
// temperature drift, 400 Hz.
std::vector<ImuSample> RealisticImu(const sim::SplineTrajectory& trajectory, uint32_t seed) {
  sim::ImuSimOptions options;
  options.seed = seed;
  const sim::ImuErrors errors = sim::DrawImuErrors(
      sim::ImuErrorOptions(), 1.0, seed, trajectory.start_ns(), trajectory.end_ns());
  return sim::SimulateImu(
      trajectory, ImuNoise(), trajectory.start_ns(), trajectory.end_ns(), options, &errors);
}

// The detector finds the simulator's exact rests (start, middle, end) and
// nothing while walking, for 3 seeds of the realistic IMU. The reported rests
// are the spans where the spline is exactly constant; the walk ramps up
// smoothly around them (motion within 2 knots, 0.2 s, then a 1.2 s cosine
// ramp). Measured: the detected ends lie within 0.09 s of the reported ones
// (tolerance 0.15 s), and the true speed stays below 1 mm/s everywhere inside
// the detected periods, so zero-velocity factors there hold.
TEST(StationaryDetection, FindsTheSimulatorRests) {
  constexpr double kToleranceS = 0.15;
  for (const uint32_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::vector<sim::StationaryPeriod> rests;
    const sim::SplineTrajectory trajectory = Walk(60.0, seed, &rests);
    ASSERT_EQ(rests.size(), 3u);
    const std::vector<StationaryPeriod> found =
        DetectStationaryPeriods(RealisticImu(trajectory, seed), StationaryDetectionOptions());
    ASSERT_EQ(found.size(), rests.size());
    for (size_t r = 0; r < rests.size(); ++r) {
      SCOPED_TRACE("rest " + std::to_string(r));
      EXPECT_NEAR(NsToSeconds(found[r].start_ns - rests[r].start_ns), 0.0, kToleranceS);
      EXPECT_NEAR(NsToSeconds(found[r].end_ns - rests[r].end_ns), 0.0, kToleranceS);
      double max_speed = 0;
      for (TimestampNs t = found[r].start_ns; t <= found[r].end_ns; t += 10'000'000) {
        max_speed = std::max(max_speed, trajectory.Evaluate(t).velocity_world.norm());
      }
      EXPECT_LT(max_speed, 1e-3);
    }
  }
}

// lio's trajectory (one pose per 10 Hz scan; here the truth) stands still in
// the same rests, to within the 0.2 s of motion that the spline has inside
// the nominal rest ends and one pose step (tolerance 0.3 s).
TEST(StationaryDetection, FromPosesFindsTheRests) {
  std::vector<sim::StationaryPeriod> rests;
  const sim::SplineTrajectory trajectory = Walk(60.0, 1, &rests);
  Trajectory poses;
  for (TimestampNs t = trajectory.start_ns(); t <= trajectory.end_ns(); t += 100'000'000) {
    poses.PushBack({t, trajectory.Pose(t)});
  }
  const std::vector<StationaryPeriod> found =
      DetectStationaryPeriodsFromPoses(poses, 0.02, 0.02, 1.0);
  ASSERT_EQ(found.size(), rests.size());
  for (size_t r = 0; r < rests.size(); ++r) {
    EXPECT_NEAR(NsToSeconds(found[r].start_ns - rests[r].start_ns), 0.0, 0.3);
    EXPECT_NEAR(NsToSeconds(found[r].end_ns - rests[r].end_ns), 0.0, 0.3);
  }
}

TEST(StationaryDetection, TooFewSamplesAndOptions) {
  EXPECT_TRUE(DetectStationaryPeriods({}, StationaryDetectionOptions()).empty());
  StationaryDetectionOptions options;
  EXPECT_TRUE(options.Check());
  options.window_s = 0.0;
  EXPECT_FALSE(options.Check());
  options = StationaryDetectionOptions();
  options.max_accel_std = -1.0;
  EXPECT_FALSE(options.Check());
}

TEST(StationaryPeriods, IntersectIndexAndPairs) {
  const std::vector<StationaryPeriod> a = {{At(0), At(3)}, {At(10), At(14)}, {At(20), At(21)}};
  const std::vector<StationaryPeriod> b = {{At(1), At(2.5)}, {At(12), At(30)}};
  const std::vector<StationaryPeriod> both = IntersectStationaryPeriods(a, b, 1.0);
  ASSERT_EQ(both.size(), 3u);
  EXPECT_EQ(both[0].start_ns, At(1));
  EXPECT_EQ(both[0].end_ns, At(2.5));
  EXPECT_EQ(both[1].start_ns, At(12));
  EXPECT_EQ(both[1].end_ns, At(14));
  EXPECT_EQ(both[2].start_ns, At(20));
  EXPECT_EQ(both[2].end_ns, At(21));
  EXPECT_EQ(IntersectStationaryPeriods(a, b, 1.6).size(), 1u);

  EXPECT_EQ(StationaryPeriodIndex(a, At(-1)), -1);
  EXPECT_EQ(StationaryPeriodIndex(a, At(0)), 0);
  EXPECT_EQ(StationaryPeriodIndex(a, At(3)), 0);
  EXPECT_EQ(StationaryPeriodIndex(a, At(5)), -1);
  EXPECT_EQ(StationaryPeriodIndex(a, At(12)), 1);
  EXPECT_EQ(StationaryPeriodIndex(a, At(21)), 2);
  EXPECT_EQ(StationaryPeriodIndex(a, At(25)), -1);

  EXPECT_TRUE(PairInsideStationaryPeriod(a, At(0.5), At(2.9)));
  EXPECT_TRUE(PairInsideStationaryPeriod(a, At(13), At(10)));
  EXPECT_FALSE(PairInsideStationaryPeriod(a, At(2), At(4)));   // leaves the rest
  EXPECT_FALSE(PairInsideStationaryPeriod(a, At(2), At(11)));  // two different rests
  EXPECT_FALSE(PairInsideStationaryPeriod(a, At(5), At(6)));   // both moving
  EXPECT_FALSE(PairInsideStationaryPeriod({}, At(0), At(1)));
}

// Keyframes every second from 0 to 20 s; rests at [-1, 2] (before the first
// keyframe: no new bias), [5.5, 7], [7.2, 7.8] (no keyframe inside: still a
// new bias at the next keyframe, 8 s), and [19.5, 21] (its first keyframe, 20 s,
// is the last one: no interval left for a new bias).
TEST(PiecewiseBias, NewBiasAtTheFirstKeyframeOfEachRest) {
  std::vector<TimestampNs> keyframes;
  for (int k = 0; k <= 20; ++k) keyframes.push_back(At(k));
  const std::vector<StationaryPeriod> rests = {
      {At(-1), At(2)}, {At(5.5), At(7)}, {At(7.2), At(7.8)}, {At(19.5), At(21)}};
  const PiecewiseBias bias = AssignPiecewiseBias(keyframes, rests);
  EXPECT_EQ(bias.first_keyframe, (std::vector<int>{0, 6, 8}));
  ASSERT_EQ(bias.interval_bias.size(), 20u);
  for (int k = 0; k < 20; ++k) {
    EXPECT_EQ(bias.interval_bias[k], k < 6 ? 0 : (k < 8 ? 1 : 2)) << "interval " << k;
  }
  // Spans: bias 0 keyframes 0-6 (mid 3 s), bias 1 6-8 (7 s), bias 2 8-20 (14 s).
  EXPECT_DOUBLE_EQ(BiasRandomWalkSeconds(bias, keyframes, 0), 4.0);
  EXPECT_DOUBLE_EQ(BiasRandomWalkSeconds(bias, keyframes, 1), 7.0);

  // No rests: one bias; one keyframe: no interval.
  EXPECT_EQ(AssignPiecewiseBias(keyframes, {}).num_biases(), 1);
  const PiecewiseBias single = AssignPiecewiseBias({At(0)}, rests);
  EXPECT_EQ(single.num_biases(), 1);
  EXPECT_TRUE(single.interval_bias.empty());
}

}  // namespace
}  // namespace lisfm
