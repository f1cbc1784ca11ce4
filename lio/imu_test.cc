#include "lio/imu.h"

#include <gtest/gtest.h>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

std::vector<ImuSample> StaticSamples(const Quat& world_from_imu,
                                     const Vec3& gyro_bias,
                                     double accel_unit,
                                     double noise,
                                     double duration_s) {
  std::normal_distribution<double> n(0.0, noise);
  std::vector<ImuSample> s;
  const Vec3 f_world(0, 0, 9.81);  // specific force of a static IMU points up
  for (int i = 0; i * 0.0025 <= duration_s; ++i) {
    ImuSample x;
    x.t_ns = 1000000000LL + i * 2500000LL;
    x.gyro = gyro_bias + Vec3(n(test::Rng()), n(test::Rng()), n(test::Rng()));
    x.accel = (world_from_imu.conjugate() * f_world + Vec3(n(test::Rng()), n(test::Rng()), n(test::Rng()))) /
              accel_unit;
    s.push_back(x);
  }
  return s;
}

TEST(ImuInit, RecoversTiltAndGyroBias) {
  const Quat R = so3::Exp(Vec3(0.3, -1.2, 0.7));  // any mounting
  const Vec3 bias(0.01, -0.02, 0.005);
  const auto samples = StaticSamples(R, bias, 1.0, 1e-3, 1.0);
  ImuInitializerOptions options;
  const ImuInitialization init = InitializeFromStaticImu(samples, options);
  ASSERT_TRUE(init.success) << init.message;
  EXPECT_DOUBLE_EQ(init.accel_scale, 1.0);
  // 1e-3 noise averaged over 200 samples: bias within 3 sigma/sqrt(n) ~ 2e-4.
  EXPECT_LT((init.gyro_bias - bias).norm(), 3e-4);
  // Tilt: the world z axis seen from the IMU agrees (yaw is free by definition).
  const Vec3 up_true = R.conjugate() * Vec3::UnitZ();
  const Vec3 up_est = init.world_from_imu.conjugate() * Vec3::UnitZ();
  EXPECT_LT(std::acos(std::min(1.0, up_true.dot(up_est))), 1e-3);
}

TEST(ImuInit, DetectsAccelerometerInG) {
  const auto samples = StaticSamples(Quat::Identity(), Vec3::Zero(), 9.81, 1e-4, 1.0);
  const ImuInitialization init = InitializeFromStaticImu(samples, ImuInitializerOptions());
  ASSERT_TRUE(init.success);
  EXPECT_DOUBLE_EQ(init.accel_scale, 9.81);
}

TEST(ImuInit, RejectsMotionAndShortData) {
  auto samples = StaticSamples(Quat::Identity(), Vec3::Zero(), 1.0, 1e-3, 1.0);
  for (size_t i = 0; i < samples.size(); ++i) samples[i].gyro.x() += std::sin(i * 0.1);  // shaking
  EXPECT_FALSE(InitializeFromStaticImu(samples, ImuInitializerOptions()).success);
  const auto short_samples = StaticSamples(Quat::Identity(), Vec3::Zero(), 1.0, 1e-3, 0.1);
  const auto r = InitializeFromStaticImu(short_samples, ImuInitializerOptions());
  EXPECT_FALSE(r.success);
  EXPECT_FALSE(r.message.empty());
  EXPECT_FALSE(InitializeFromStaticImu({}, ImuInitializerOptions()).success);
}

}  // namespace
}  // namespace lisfm
