#include "lio/pose_slam/chordal_initialization.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

SE3 RandomPlanarPose() {
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  return SE3(Quat(Eigen::AngleAxisd(u(test::Rng()), Vec3::UnitZ())),
             Vec3(u(test::Rng()), u(test::Rng()), 0.0));
}

// Random poses (pose 0 at the origin, the gauge) with a chain plus random
// extra edges, noise-free measurements and random weights.
std::vector<ChordalMeasurement> ConsistentGraph(int dimension,
                                                int num_poses,
                                                std::vector<SE3>* truth) {
  truth->clear();
  for (int k = 0; k < num_poses; ++k) {
    truth->push_back(k == 0 ? SE3() : dimension == 2 ? RandomPlanarPose() : test::RandomPose());
  }
  std::uniform_real_distribution<double> weight(0.1, 100.0);
  std::uniform_int_distribution<int> pick(0, num_poses - 1);
  std::vector<ChordalMeasurement> measurements;
  const auto add = [&](int i, int j) {
    measurements.push_back(
        {i, j, (*truth)[i].Inverse() * (*truth)[j], weight(test::Rng()), weight(test::Rng())});
  };
  for (int k = 0; k + 1 < num_poses; ++k) add(k + 1, k);  // either direction
  for (int e = 0; e < num_poses; ++e) {
    const int i = pick(test::Rng()), j = pick(test::Rng());
    if (i != j) add(i, j);
  }
  return measurements;
}

// Noise-free measurements: the relaxation's minimiser is the truth itself
// (F = 0 there), so the projection changes nothing and the translations follow.
TEST(ChordalInitialization, ExactOnNoiseFreeGraphs) {
  for (const int dimension : {2, 3}) {
    std::vector<SE3> truth;
    const std::vector<ChordalMeasurement> measurements = ConsistentGraph(dimension, 40, &truth);
    const std::vector<SE3> poses = ChordalInitialization(dimension, 40, measurements);
    ASSERT_EQ(poses.size(), truth.size());
    // Sparse LDL^T on a well-conditioned system: ~1e-12 of rounding.
    for (size_t k = 0; k < poses.size(); ++k) {
      EXPECT_TRUE(test::PosesNear(poses[k], truth[k], 1e-9, 1e-9)) << dimension << "D pose " << k;
    }
    EXPECT_LT(ChordalObjective(measurements, poses), 1e-16);
  }
}

// With noisy measurements the initialisation is no longer exact, but close:
// its objective is of the order of the noise (not of a wrong basin).
TEST(ChordalInitialization, CloseUnderNoise) {
  std::vector<SE3> truth;
  std::vector<ChordalMeasurement> measurements = ConsistentGraph(3, 30, &truth);
  std::normal_distribution<double> noise(0.0, 0.01);
  for (ChordalMeasurement& m : measurements) {
    Vec6 xi;
    for (int k = 0; k < 6; ++k) xi(k) = noise(test::Rng());
    m.i_from_j = m.i_from_j * SE3::Exp(xi);
  }
  const std::vector<SE3> poses = ChordalInitialization(3, 30, measurements);
  for (size_t k = 0; k < poses.size(); ++k) {
    // 0.01 rad / 0.01 m per measurement over a few hops of a well-connected graph.
    EXPECT_TRUE(test::PosesNear(poses[k], truth[k], 0.1, 0.2)) << "pose " << k;
  }
  EXPECT_LT(ChordalObjective(measurements, poses), ChordalObjective(measurements, [&] {
              std::vector<SE3> moved = truth;
              for (SE3& pose : moved) pose = pose * SE3::Exp(Vec6::Constant(0.1));
              return moved;
            }()));
}

TEST(ChordalInitialization, RejectsDisconnectedGraphs) {
  const std::vector<ChordalMeasurement> measurements = {{0, 1, SE3(), 1.0, 1.0},
                                                        {2, 3, SE3(), 1.0, 1.0}};
  EXPECT_THROW(ChordalInitialization(3, 4, measurements), InternalError);
  EXPECT_THROW(ChordalInitialization(3, 2, {{0, 2, SE3(), 1.0, 1.0}}), InternalError);
}

}  // namespace
}  // namespace lisfm
