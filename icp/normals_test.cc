#include "icp/normals.h"

#include <cmath>

#include <gtest/gtest.h>

#include "icp/icp.h"
#include "icp/testing/scenes.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// A tilted noise-free plane: every normal equals the plane normal (up to float
// rounding, 1e-4) oriented towards the viewpoint; l0 = 0, so planarity = l1/l2 > 0
// everywhere (10 random neighbours can be elongated, so only > 0 per point),
// and on average well above a line's (~0): mean > 0.4.
TEST(EstimateNormals, TiltedPlane) {
  PointSet flat;
  test::SamplePlane(2, 0.0, Eigen::Vector3d(-2, -2, 0), Eigen::Vector3d(2, 2, 0), 2000, 0.0,
                    test::Rng(), &flat);
  const SE3 pose(so3::Exp(Vec3(0.3, -0.2, 0.1)), Vec3(0.5, 0.2, 3.0));
  const PointSet pts = test::Transformed(flat, pose);
  const Eigen::Vector3f expected = (pose.rotation() * Vec3::UnitZ()).cast<float>();
  const KdTree tree(pts);
  const Normals normals = EstimateNormals(tree, NormalOptions(), Eigen::Vector3f::Zero());
  ASSERT_EQ(normals.size(), pts.size());
  float mean_planarity = 0.f;
  for (size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector3f n = normals.normals[i];
    EXPECT_NEAR(std::abs(n.dot(expected)), 1.0f, 1e-4f);
    EXPECT_GT(n.dot(-pts[i]), 0.f) << "normal must face the viewpoint";
    EXPECT_GT(normals.planarity[i], 0.f);
    mean_planarity += normals.planarity[i] / pts.size();
  }
  EXPECT_GT(mean_planarity, 0.4f);
}

// Points on a line have planarity ~0 ((l1 - l0)/l2 with l0 ~ l1 ~ 0).
TEST(EstimateNormals, LineHasLowPlanarity) {
  PointSet pts;
  for (int i = 0; i < 200; ++i) pts.emplace_back(0.01f * i, 0.f, 0.f);
  const KdTree tree(pts);
  const Normals normals = EstimateNormals(tree, NormalOptions());
  for (float p : normals.planarity) EXPECT_LT(p, 0.01f);
}

// A camera facing a wall at z = 2: organised normals are (0, 0, -1) inside, zero on the border.
TEST(EstimateOrganizedNormals, Wall) {
  PinholeIntrinsics K{100, 100, 20, 15, 40, 30};
  PointSet map(K.width * K.height);
  for (int v = 0; v < K.height; ++v) {
    for (int u = 0; u < K.width; ++u) {
      map[v * K.width + u] = Eigen::Vector3f(2.f * (u - 20) / 100.f, 2.f * (v - 15) / 100.f, 2.f);
    }
  }
  const Normals n = EstimateOrganizedNormals(map, K.width, K.height);
  EXPECT_TRUE(n.normals[15 * K.width + 20].isApprox(Eigen::Vector3f(0, 0, -1), 1e-6f));
  EXPECT_TRUE(n.normals[0].isZero());
  EXPECT_EQ(n.planarity[0], 0.f);
}

}  // namespace
}  // namespace lisfm
