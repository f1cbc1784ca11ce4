#include "lio/point_to_plane.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

struct Case {
  CalibratedPose state;
  BodyRates rates;
  Vec3 x_lidar;
  Vec4 plane;
};

// A random state, handheld-like rates (up to ~1.7 rad/s, 2 m/s), a point 1-20 m
// away and a plane through a point near it.
Case RandomCase() {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&](double scale) -> Vec3 {
    return Vec3(u(test::Rng()), u(test::Rng()), u(test::Rng())) * scale;
  };
  Case c;
  const SE3 pose = test::RandomPose(3.0, 10.0);
  const SE3 extrinsic = test::RandomPose(3.0, 0.2);
  c.state.world_R_imu = pose.RotationMatrix();
  c.state.world_p_imu = pose.translation();
  c.state.imu_R_lidar = extrinsic.RotationMatrix();
  c.state.imu_p_lidar = extrinsic.translation();
  c.state.time_offset_change_s = 0.01 * u(test::Rng());
  c.rates.angular_velocity = vec(1.0);
  c.rates.velocity = vec(1.2);
  c.x_lidar = vec(1.0).normalized() * (1.0 + 19.0 * 0.5 * (1.0 + u(test::Rng())));
  const Vec3 n = vec(1.0).normalized();
  const Vec3 on_plane = CalibratedPointInWorld(c.state, c.rates, c.x_lidar) + vec(0.05);
  c.plane << n, -n.dot(on_plane);
  return c;
}

// The state moved by the 13-vector e = [dθ, dp, dθ_e, dt_e, dt_d] (right
// perturbations for the rotations, as lio/point_to_plane.h defines them).
CalibratedPose Perturbed(const CalibratedPose& s, const Eigen::VectorXd& e) {
  CalibratedPose out = s;
  out.world_R_imu = s.world_R_imu * so3::ExpMatrix(e.segment<3>(0));
  out.world_p_imu = s.world_p_imu + e.segment<3>(3);
  out.imu_R_lidar = s.imu_R_lidar * so3::ExpMatrix(e.segment<3>(6));
  out.imu_p_lidar = s.imu_p_lidar + e.segment<3>(9);
  out.time_offset_change_s = s.time_offset_change_s + e(12);
  return out;
}

TEST(CalibratedPointToPlane, JacobianMatchesCentralDifferences) {
  for (int trial = 0; trial < 200; ++trial) {
    const Case c = RandomCase();
    CalibratedPointJacobian analytic;
    Vec3 q;
    const double r =
        CalibratedPointToPlaneResidual(c.state, c.rates, c.x_lidar, c.plane, &analytic, &q);
    EXPECT_NEAR(
        r,
        c.plane.head<3>().dot(CalibratedPointInWorld(c.state, c.rates, c.x_lidar)) + c.plane(3),
        1e-12);
    EXPECT_LT((q - (c.state.imu_R_lidar * c.x_lidar + c.state.imu_p_lidar)).norm(), 1e-12);
    const Eigen::MatrixXd numeric = test::NumericJacobian(
        [&](const Eigen::VectorXd& e) {
          Eigen::VectorXd out(1);
          out(0) =
              CalibratedPointToPlaneResidual(Perturbed(c.state, e), c.rates, c.x_lidar, c.plane);
          return out;
        },
        Eigen::VectorXd::Zero(13),
        1e-6);
    // Central differences with step 1e-6 on residuals of up to ~30 m: truncation
    // O(h^2 |r'''|) and rounding O(eps |r| / h) ~ 1e-8 each; a wrong sign or frame
    // in any column is off by O(1) (the entries are m per rad, m/m, m/s).
    for (int j = 0; j < 13; ++j) {
      EXPECT_NEAR(analytic(j), numeric(0, j), 1e-6 * std::max(1.0, std::abs(numeric(0, j))))
          << "trial " << trial << " column " << j;
    }
  }
}

// With no time-offset change the first six columns are FAST-LIO2's
// point-to-plane Jacobian on the IMU-frame point (the uncalibrated update in
// lio/lio_odometry.cc).
TEST(CalibratedPointToPlane, ReducesToTheUncalibratedJacobian) {
  for (int trial = 0; trial < 50; ++trial) {
    Case c = RandomCase();
    c.state.time_offset_change_s = 0;
    CalibratedPointJacobian h;
    const double r = CalibratedPointToPlaneResidual(c.state, c.rates, c.x_lidar, c.plane, &h);
    const Mat3& R = c.state.world_R_imu;
    const Vec3 pb = c.state.imu_R_lidar * c.x_lidar + c.state.imu_p_lidar;
    const Vec3 n = c.plane.head<3>();
    EXPECT_NEAR(r, n.dot(R * pb + c.state.world_p_imu) + c.plane(3), 1e-12);
    EXPECT_LT((h.head<3>() - (-(R * Hat(pb)).transpose() * n)).norm(), 1e-12);
    EXPECT_LT((h.segment<3>(3) - n).norm(), 1e-15);
  }
}

// The time-offset term moves the point to where the body carried it: with
// constant body rate ω and world velocity v, the exact world point of a
// return captured δ later is R·Exp(ωδ)·q + p + vδ; the model agrees to second
// order in δ (|ω|² δ² |q| / 2 ≈ 2e-6 m for δ = 2 ms), while ignoring the
// offset is wrong by ~ |v + ω×q| δ (mm).
TEST(CalibratedPointToPlane, TimeOffsetMovesThePointWithTheBody) {
  for (int trial = 0; trial < 50; ++trial) {
    Case c = RandomCase();
    for (const double delta : {0.002, -0.002}) {
      c.state.time_offset_change_s = delta;
      const Vec3 q = c.state.imu_R_lidar * c.x_lidar + c.state.imu_p_lidar;
      const Vec3 exact =
          c.state.world_R_imu * so3::ExpMatrix(c.rates.angular_velocity * delta) * q +
          c.state.world_p_imu + c.rates.velocity * delta;
      const Vec3 model = CalibratedPointInWorld(c.state, c.rates, c.x_lidar);
      const Vec3 ignored = c.state.world_R_imu * q + c.state.world_p_imu;
      const double bound = c.rates.angular_velocity.squaredNorm() * delta * delta * q.norm();
      EXPECT_LT((model - exact).norm(), bound + 1e-12);
      EXPECT_GT((ignored - exact).norm(), 10 * bound);
    }
  }
}

}  // namespace
}  // namespace lisfm
