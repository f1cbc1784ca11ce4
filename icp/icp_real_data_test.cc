// ICP on the real clouds of ../shared/data (skipped when missing).
#include <algorithm>
#include <cmath>
#include <fstream>

#include <gtest/gtest.h>

#include "core/io/cloud_io.h"
#include "icp/bayesian_icp.h"
#include "icp/icp.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

Mat4 ReadMatrix4(const std::string& path) {
  std::ifstream in(path);
  Mat4 m;
  for (int i = 0; i < 16; ++i) in >> m(i / 4, i % 4);
  EXPECT_TRUE(static_cast<bool>(in)) << path;
  return m;
}

SE3 FromMatrix(const Mat4& m) {
  // Orthonormalise the printed (rounded) rotation.
  const Eigen::JacobiSVD<Mat3> svd(m.topLeftCorner<3, 3>(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  return SE3(Mat3(svd.matrixU() * svd.matrixV().transpose()), Vec3(m.topRightCorner<3, 1>()));
}

// fast_gicp's acceptance: within 0.05 m and 1 deg of relative.txt (README).
TEST(IcpRealData, RegistrationLidarPair) {
  LISFM_REQUIRE_SHARED_DATA("registration_lidar_pair/relative.txt");
  const std::string dir = test::SharedData("registration_lidar_pair");
  const PointSet target_full = FinitePointsOf(ReadPointCloud(dir + "/251370668.pcd"));
  const PointSet source_full = FinitePointsOf(ReadPointCloud(dir + "/251371071.pcd"));
  const SE3 reference = FromMatrix(ReadMatrix4(dir + "/relative.txt"));
  const KdTreeTarget target(VoxelDownsamplePoints(target_full, 0.1), NormalOptions());
  const PointSet source = VoxelDownsamplePoints(source_full, 0.25);
  IcpOptions options;
  const IcpResult r = RegisterPointToPlane(source, target, SE3(), options);
  EXPECT_TRUE(r.converged) << r.message;
  EXPECT_TRUE(test::PosesNear(r.target_from_source, reference, M_PI / 180.0, 0.05));
  BayesianIcpOptions bayes;  // its own association: Cauchy kernel, normals of 20 neighbours
  const KdTreeTarget bayes_target(VoxelDownsamplePoints(target_full, 0.1),
                                  NormalOptions{bayes.normal_neighbors, NormalOptions().max_radius_m});
  const BayesianIcpResult b = RegisterBayesian(source, bayes_target, SE3(), bayes);
  EXPECT_TRUE(test::PosesNear(b.posterior.mean, reference, M_PI / 180.0, 0.05));
}

SE3 BunnyReference() {
  // pointclouds_pcl/README.md: PCL IterativeClosestPoint (point-to-POINT), source
  // bun0, target bun4, max correspondence distance 0.05 m, 50 iterations, eps 1e-8;
  // T_target_source (target <- source). Running exactly that with PCL 1.13 here
  // reproduces it to 2.2e-4 element-wise (checked while fixing this test).
  Mat4 m;
  m << 0.8806, 0.036481, -0.4724, 0.03453, -0.02354, 0.9992, 0.03326, -0.001519, 0.4732,
      -0.01817, 0.8808, 0.04116, 0, 0, 0, 1;
  return FromMatrix(m);
}

// RMS nearest-neighbour (point-to-point) distance of source points mapped by T,
// over matches within 0.05 m (the README's gate).
double PointToPointRms(const PointSet& source, const KdTree& target, const SE3& T) {
  double sum = 0;
  int count = 0;
  for (const auto& p : source) {
    const Eigen::Vector3f q = (T * p.cast<double>()).cast<float>();
    uint32_t index = 0;
    float sq = 0;
    if (target.Nearest(q, &index, &sq) && sq < 0.05f * 0.05f) {
      sum += sq;
      ++count;
    }
  }
  return std::sqrt(sum / std::max(count, 1));
}

// Why point-to-plane with 10-neighbour normals lands 2.9 deg / 2.7 mm from the README's
// reference (as do PCL IterativeClosestPointWithNormals and Open3D point-to-plane, see
// docs/BENCHMARKS.md, "ICP registration vs PCL and Open3D"): the reference is the
// optimum of a different objective. Measured (397 matches each): point-to-point RMS
// 6.35 mm at the reference vs 6.71 mm at our result; point-to-plane RMS 4.05 mm at the
// reference vs 3.53 mm at our result. Each transform is the better one for its own
// objective; this partial-overlap pair is weakly constrained in rotation, so the two
// optima differ by ~3 deg. The test asserts that ordering.
TEST(IcpRealData, BunnyReferenceIsThePointToPointOptimum) {
  LISFM_REQUIRE_SHARED_DATA("pointclouds_pcl/bun0.pcd");
  const std::string dir = test::SharedData("pointclouds_pcl");
  const PointSet source = FinitePointsOf(ReadPointCloud(dir + "/bun0.pcd"));
  const PointSet target_points = FinitePointsOf(ReadPointCloud(dir + "/bun4.pcd"));
  const KdTreeTarget target(target_points, NormalOptions{10, 0.05});
  const SE3 reference = BunnyReference();
  IcpOptions options;
  options.max_correspondence_distance_m = 0.05;
  options.kernel = "none";
  options.max_iterations = 200;
  const IcpResult ours = RegisterPointToPlane(source, target, SE3(), options);
  ASSERT_TRUE(ours.converged) << ours.message;
  options.max_iterations = 1;  // statistics at the reference (one association)
  const IcpResult at_reference = RegisterPointToPlane(source, target, reference, options);
  EXPECT_LT(ours.rmse_m, at_reference.rmse_m);
  EXPECT_LT(PointToPointRms(source, target.tree(), reference),
            PointToPointRms(source, target.tree(), ours.target_from_source));
}

// Within 5 mm / 1 deg of PCL's reference result for bun0 -> bun4 (README). The clouds
// are sparse (361/397 points, ~4 mm apart, with range noise): normals from 10
// neighbours are noisy enough to tilt the point-to-plane optimum by ~3 deg (test
// above). With normals from 20 or 30 neighbours (still a local patch: ~2 cm on a 15 cm
// bunny) both land within 0.6 / 0.9 deg and 1.6 / 1.0 mm of the reference. Only the
// 0.05 m gate rejects outliers, as in PCL's run.
TEST(IcpRealData, BunnyPair) {
  LISFM_REQUIRE_SHARED_DATA("pointclouds_pcl/bun0.pcd");
  const std::string dir = test::SharedData("pointclouds_pcl");
  const PointSet source = FinitePointsOf(ReadPointCloud(dir + "/bun0.pcd"));
  const PointSet target_points = FinitePointsOf(ReadPointCloud(dir + "/bun4.pcd"));
  const SE3 reference = BunnyReference();
  for (const int k : {20, 30}) {
    const KdTreeTarget target(target_points, NormalOptions{k, 0.05});
    IcpOptions options;
    options.max_correspondence_distance_m = 0.05;
    options.kernel = "none";
    options.max_iterations = 200;
    const IcpResult r = RegisterPointToPlane(source, target, SE3(), options);
    EXPECT_TRUE(r.converged) << "k=" << k << ": " << r.message;
    EXPECT_TRUE(test::PosesNear(r.target_from_source, reference, M_PI / 180.0, 0.005))
        << "k=" << k << "\n" << r.target_from_source.Matrix();
  }
}

}  // namespace
}  // namespace lisfm
