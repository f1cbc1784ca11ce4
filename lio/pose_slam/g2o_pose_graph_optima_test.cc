// SE-Sync's published optima on the larger benchmark graphs (the small ones
// are in g2o_pose_graph_test.cc).
#include <gtest/gtest.h>

#include <string>

#include "core/io/g2o_io.h"
#include "lio/pose_slam/g2o_pose_graph.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// Rosen et al., IJRR 2019, Tables 1 and 2 (../shared/data/pose_graphs/OPTIMA.md):
// 4 significant digits, so the tolerance is their rounding, 5e-4 F*.
constexpr double kPublishedRelativeTolerance = 5e-4;

void ExpectReachesOptimum(const std::string& name, double published_optimum) {
  const std::string path = test::SharedData("pose_graphs/" + name);
  const G2oGraph graph = ReadG2o(path);
  CheckG2oConnected(graph, path);
  const G2oOptimizationResult result = OptimizeG2oGraph(graph, G2oOptimizationOptions());
  EXPECT_TRUE(result.solve.usable) << name << ": " << result.solve.message;
  EXPECT_NEAR(
      result.objective_final, published_optimum, kPublishedRelativeTolerance * published_optimum)
      << name << ": chordal F = " << result.objective_initial << ", " << result.solve.iterations
      << " iterations, " << result.solve.message;
}

TEST(G2oPoseGraphOptima, Sphere2500) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/sphere2500.g2o");
  ExpectReachesOptimum("sphere2500.g2o", 1.687e3);
}

TEST(G2oPoseGraphOptima, Cubicle) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/cubicle.g2o");
  ExpectReachesOptimum("cubicle.g2o", 7.171e2);
}

TEST(G2oPoseGraphOptima, Manhattan) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/manhattan.g2o");
  ExpectReachesOptimum("manhattan.g2o", 6.432e3);
}

TEST(G2oPoseGraphOptima, City10000) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/city10000.g2o");
  ExpectReachesOptimum("city10000.g2o", 6.386e2);
}

TEST(G2oPoseGraphOptima, Ais2klinik) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/ais2klinik.g2o");
  ExpectReachesOptimum("ais2klinik.g2o", 1.885e2);
}

}  // namespace
}  // namespace lisfm
