#include "sim/spline_trajectory.h"

#include <gtest/gtest.h>

#include "sim/motion.h"
#include "sim/scene.h"
#include "tests/common/sim_walks.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

SplineTrajectory RandomSpline() {
  std::vector<Quat> rotations;
  std::vector<Vec3> positions;
  for (int i = 0; i < 20; ++i) {
    rotations.push_back(test::RandomPose(3.0, 1.0).rotation());
    positions.push_back(test::RandomPose(0.1, 2.0).translation());
  }
  return SplineTrajectory(1000000000LL, 0.2, rotations, positions);
}

// Analytic derivatives against central differences of the pose. Tolerance:
// central differences with h = 1e-5 s have truncation error ~h^2 * |jerk| and
// round-off ~1e-16 / h^2 for the second derivative; 1e-4 relative covers both.
TEST(SplineTrajectory, DerivativesMatchFiniteDifferences) {
  const SplineTrajectory spline = RandomSpline();
  const int64_t h = 10000;  // 10 us
  for (TimestampNs t = spline.start_ns() + 2 * h; t < spline.end_ns() - 2 * h;
       t += 123456789) {
    const TrajectorySample s = spline.Evaluate(t);
    const SE3 a = spline.Pose(t - h), b = spline.Pose(t + h);
    const Vec3 v_num = (b.translation() - a.translation()) / 2e-5;
    EXPECT_LT((v_num - s.velocity_world).norm(), 1e-4 * (1 + v_num.norm()));
    const Vec3 acc_num =
        (b.translation() - 2 * s.world_from_imu.translation() + a.translation()) / 1e-10;
    EXPECT_LT((acc_num - s.acceleration_world).norm(), 1e-3 * (1 + acc_num.norm()));
    const Vec3 omega_num = so3::Log(a.rotation().conjugate() * b.rotation()) / 2e-5;
    EXPECT_LT((omega_num - s.angular_velocity_body).norm(), 1e-4 * (1 + omega_num.norm()));
  }
}

TEST(SplineTrajectory, FitFollowsSmoothSamples) {
  Trajectory samples;
  for (int i = 0; i <= 300; ++i) {  // 30 s at 10 Hz
    const double t = 0.1 * i;
    const Vec3 p(2 * std::sin(0.3 * t), 1.5 * std::cos(0.2 * t), 0.1 * t);
    const Quat q = so3::Exp(Vec3(0.2 * std::sin(0.5 * t), 0.1 * t, 0.3 * std::cos(0.4 * t)));
    samples.PushBack({SecondsToNs(100.0 + t), SE3(q, p)});
  }
  const SplineTrajectory spline = SplineTrajectory::Fit(samples, 0.1);
  // Smooth motion (|a| <= 0.2 m/s^2): the fitted cubic B-spline stays within
  // 5 mm / 0.3 deg of the samples away from the ends.
  for (size_t i = 5; i + 5 < samples.size(); ++i) {
    EXPECT_TRUE(test::PosesNear(spline.Pose(samples[i].t_ns), samples[i].pose,
                                0.3 * M_PI / 180, 0.005))
        << "sample " << i;
  }
}

TEST(GenerateWalking, RestsAreExactAndSpeedIsWalking) {
  const auto scene = Scene::Generate(DefaultSceneOptions("office"));
  std::vector<StationaryPeriod> rests;
  const SplineTrajectory walk =
      GenerateWalking(scene->route(), 40.0, 0, 3, ThreeStopWalk(), &rests);
  ASSERT_EQ(rests.size(), 3u);
  for (const StationaryPeriod& r : rests) {
    const TrajectorySample s0 = walk.Evaluate(r.start_ns);
    for (TimestampNs t = r.start_ns; t <= r.end_ns; t += 50000000) {
      const TrajectorySample s = walk.Evaluate(t);
      EXPECT_EQ(s.velocity_world.norm(), 0.0);
      EXPECT_EQ(s.angular_velocity_body.norm(), 0.0);
      EXPECT_TRUE(test::PosesNear(s.world_from_imu, s0.world_from_imu, 1e-12, 1e-12));
    }
  }
  // Mid-walk: about 1 m/s, IMU z pointing down (HILTI mounting), x forward.
  const TrajectorySample s = walk.Evaluate(SecondsToNs(10.0));
  EXPECT_NEAR(s.velocity_world.norm(), 1.0, 0.25);
  const Vec3 up_in_imu = s.world_from_imu.rotation().conjugate() * Vec3::UnitZ();
  EXPECT_LT(up_in_imu.z(), -0.95);
  const Vec3 v_in_imu = s.world_from_imu.rotation().conjugate() * s.velocity_world;
  EXPECT_GT(v_in_imu.x(), 0.8 * v_in_imu.norm());
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
