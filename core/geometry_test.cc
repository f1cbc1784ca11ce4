#include "core/geometry.h"

#include <gtest/gtest.h>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using test::NumericJacobian;
using test::PosesNear;
using test::RandomPose;

Vec3 RandomVec3(double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  return Vec3(u(test::Rng()), u(test::Rng()), u(test::Rng()));
}

TEST(So3, HatVeeCross) {
  const Vec3 a(1, -2, 3), b(0.5, 4, -1);
  EXPECT_TRUE((Hat(a) * b).isApprox(a.cross(b)));
  EXPECT_TRUE(Vee(Hat(a)).isApprox(a));
}

TEST(So3, ExpLogRoundTrip) {
  for (int i = 0; i < 200; ++i) {
    // Angles up to just below pi, and tiny ones for the Taylor branches.
    const double scale = (i % 4 == 0) ? 1e-9 : 1.8;
    const Vec3 w = RandomVec3(scale);
    EXPECT_TRUE(so3::Log(so3::Exp(w)).isApprox(w, 1e-9) || w.norm() < 1e-12) << w.transpose();
  }
  // Exp agrees with Eigen's AngleAxis.
  const Vec3 w(0.3, -0.2, 1.1);
  const Quat ref(Eigen::AngleAxisd(w.norm(), w.normalized()));
  EXPECT_NEAR(so3::AngularDistance(so3::Exp(w), ref), 0.0, 1e-12);
}

TEST(So3, LogNearPi) {
  const Vec3 axis = Vec3(1, 2, -1).normalized();
  const Vec3 w = (M_PI - 1e-7) * axis;
  EXPECT_TRUE(so3::Log(so3::Exp(w)).isApprox(w, 1e-6));
}

TEST(So3, RightJacobianMatchesNumeric) {
  // Exp(w + d) ~= Exp(w) Exp(J_r(w) d): J_r = d/dd Log(Exp(w)^-1 Exp(w + d)).
  for (int i = 0; i < 20; ++i) {
    const Vec3 w = RandomVec3(i == 0 ? 1e-6 : 1.5);
    const auto f = [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
      return so3::Log(so3::Exp(w).conjugate() * so3::Exp(w + Vec3(d)));
    };
    const Eigen::MatrixXd J = NumericJacobian(f, Eigen::VectorXd::Zero(3));
    EXPECT_TRUE(J.isApprox(so3::RightJacobian(w), 1e-6)) << J << "\n" << so3::RightJacobian(w);
    EXPECT_TRUE((so3::RightJacobian(w) * so3::RightJacobianInverse(w)).isIdentity(1e-9));
    // Left Jacobian: Exp(w + d) ~= Exp(J_l d) Exp(w).
    const auto g = [&](const Eigen::VectorXd& d) -> Eigen::VectorXd {
      return so3::Log(so3::Exp(w + Vec3(d)) * so3::Exp(w).conjugate());
    };
    EXPECT_TRUE(NumericJacobian(g, Eigen::VectorXd::Zero(3)).isApprox(so3::LeftJacobian(w), 1e-6));
    EXPECT_TRUE((so3::LeftJacobian(w) * so3::LeftJacobianInverse(w)).isIdentity(1e-9));
  }
}

TEST(So3, AverageOfSymmetricSpreadIsCentre) {
  const Quat centre = so3::Exp(Vec3(0.2, -0.5, 0.9));
  std::vector<Quat> qs;
  for (const Vec3& d : {Vec3(0.1, 0, 0), Vec3(-0.1, 0, 0), Vec3(0, 0.2, 0), Vec3(0, -0.2, 0)}) {
    qs.push_back(centre * so3::Exp(d));
  }
  // Flip signs of some quaternions: the average must not care.
  qs[1].coeffs() *= -1;
  EXPECT_LT(so3::AngularDistance(so3::Average(qs), centre), 1e-3);
  EXPECT_THROW(so3::Average({}), InternalError);
}

TEST(Se3, ExpLogRoundTripAndComposition) {
  for (int i = 0; i < 100; ++i) {
    Vec6 xi;
    xi << RandomVec3(1.5), RandomVec3(3.0);
    EXPECT_TRUE(SE3::Exp(xi).Log().isApprox(xi, 1e-9));
    const SE3 a = RandomPose(), b = RandomPose();
    EXPECT_TRUE((a * b).Matrix().isApprox(a.Matrix() * b.Matrix(), 1e-12));
    EXPECT_TRUE(PosesNear(a * a.Inverse(), SE3::Identity(), 1e-12, 1e-12));
    const Vec3 x = RandomVec3(10.0);
    EXPECT_TRUE((a * x).isApprox((a.Matrix() * x.homogeneous()).head<3>(), 1e-12));
  }
}

TEST(Se3, ExpMatchesMatrixExponentialSeries) {
  Vec6 xi;
  xi << 0.3, -0.4, 0.2, 1.0, 2.0, -0.5;
  Mat4 X = Mat4::Zero();
  X.block<3, 3>(0, 0) = Hat(xi.head<3>());
  X.block<3, 1>(0, 3) = xi.tail<3>();
  Mat4 sum = Mat4::Identity(), term = Mat4::Identity();
  for (int k = 1; k < 30; ++k) {
    term = term * X / k;
    sum += term;
  }
  EXPECT_TRUE(SE3::Exp(xi).Matrix().isApprox(sum, 1e-12));
}

TEST(Se3, AdjointMovesPerturbations) {
  for (int i = 0; i < 20; ++i) {
    const SE3 T = RandomPose();
    Vec6 xi;
    xi << RandomVec3(0.5), RandomVec3(1.0);
    const SE3 lhs = SE3::Exp(T.Adjoint() * xi);
    const SE3 rhs = T * SE3::Exp(xi) * T.Inverse();
    EXPECT_TRUE(PosesNear(lhs, rhs, 1e-9, 1e-9));
  }
}

TEST(Se3, InterpolateEndpointsAndMidpoint) {
  const SE3 a = RandomPose(), b = RandomPose();
  EXPECT_TRUE(PosesNear(Interpolate(a, b, 0.0), a, 1e-9, 1e-12));
  EXPECT_TRUE(PosesNear(Interpolate(a, b, 1.0), b, 1e-9, 1e-12));
  const SE3 mid = Interpolate(a, b, 0.5);
  EXPECT_NEAR(so3::AngularDistance(a.rotation(), mid.rotation()),
              so3::AngularDistance(mid.rotation(), b.rotation()), 1e-9);
  EXPECT_TRUE(mid.translation().isApprox(0.5 * (a.translation() + b.translation())));
}

TEST(Se3, AverageOfIdenticalPosesIsThatPose) {
  const SE3 p = RandomPose();
  EXPECT_TRUE(PosesNear(Average({p, p, p}, {1, 2, 3}), p, 1e-9, 1e-12));
}

TEST(Alignment, RecoversKnownSim3AndSe3) {
  Eigen::Matrix3Xd src(3, 50);
  for (int i = 0; i < src.cols(); ++i) src.col(i) = RandomVec3(10.0);
  const SE3 T = RandomPose();
  const double scale = 1.7;
  Eigen::Matrix3Xd dst(3, src.cols());
  for (int i = 0; i < src.cols(); ++i) dst.col(i) = scale * (T.rotation() * src.col(i)) + T.translation();
  const Sim3 sim = AlignUmeyama(src, dst, true);
  EXPECT_NEAR(sim.scale, scale, 1e-9);
  EXPECT_TRUE(PosesNear(sim.pose, T, 1e-9, 1e-9));
  for (int i = 0; i < src.cols(); ++i) dst.col(i) = T * Vec3(src.col(i));
  const Sim3 se3 = AlignUmeyama(src, dst, false);
  EXPECT_DOUBLE_EQ(se3.scale, 1.0);
  EXPECT_TRUE(PosesNear(se3.pose, T, 1e-9, 1e-9));
}

TEST(Alignment, RejectsDegenerateInput) {
  Eigen::Matrix3Xd two(3, 2);
  two.setRandom();
  EXPECT_THROW(AlignUmeyama(two, two, false), InputError);
  Eigen::Matrix3Xd line(3, 10);
  for (int i = 0; i < 10; ++i) line.col(i) = Vec3(i, 2 * i, 0);
  EXPECT_THROW(AlignUmeyama(line, line, false), InputError);
  Eigen::Matrix3Xd a(3, 5), b(3, 6);
  a.setRandom();
  b.setRandom();
  EXPECT_THROW(AlignUmeyama(a, b, false), InputError);
}

}  // namespace
}  // namespace lisfm
