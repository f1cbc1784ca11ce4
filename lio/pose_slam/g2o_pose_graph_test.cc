#include "lio/pose_slam/g2o_pose_graph.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

#include "core/io/g2o_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// SE-Sync's published optimal objective values F* (Rosen et al., IJRR 2019,
// Tables 1 and 2; ../shared/data/pose_graphs/OPTIMA.md). They have 4
// significant digits, so the tolerance is the rounding: |F - F*| <= 5e-4 F*.
constexpr double kPublishedRelativeTolerance = 5e-4;

void ExpectReachesOptimum(const std::string& name, double published_optimum) {
  const std::string path = test::SharedData("pose_graphs/" + name);
  const G2oGraph graph = ReadG2o(path);
  CheckG2oConnected(graph, path);
  const G2oOptimizationResult result = OptimizeG2oGraph(graph, G2oOptimizationOptions());
  EXPECT_TRUE(result.solve.usable) << name << ": " << result.solve.message;
  EXPECT_LE(result.objective_final, result.objective_initial) << name;
  EXPECT_NEAR(
      result.objective_final, published_optimum, kPublishedRelativeTolerance * published_optimum)
      << name << ": chordal F = " << result.objective_initial << ", " << result.solve.iterations
      << " iterations, " << result.solve.message;
}

TEST(SeSyncEdgeWeights, FromInformation) {
  G2oEdge edge3;
  edge3.information = MatX::Zero(6, 6);
  edge3.information.diagonal() << 1, 2, 4, 10, 20, 40;  // translation, then rotation
  const SeSyncWeights w3 = SeSyncEdgeWeights(edge3, 3);
  EXPECT_DOUBLE_EQ(w3.tau, 3.0 / (1.0 + 0.5 + 0.25));
  EXPECT_DOUBLE_EQ(w3.kappa, 3.0 / (2.0 * (0.1 + 0.05 + 0.025)));
  G2oEdge edge2;
  edge2.information = MatX::Zero(3, 3);
  edge2.information << 4, 1, 0, 1, 4, 0, 0, 0, 7;
  const SeSyncWeights w2 = SeSyncEdgeWeights(edge2, 2);
  // trace([[4 1][1 4]]^-1) = 8 / 15.
  EXPECT_DOUBLE_EQ(w2.tau, 2.0 / (8.0 / 15.0));
  EXPECT_DOUBLE_EQ(w2.kappa, 7.0);
}

// smallGrid3D has no published optimum: with its measurements replaced by the
// exact relative poses of its vertices the optimum is F = 0 at those vertices
// (up to the gauge), whichever initialisation.
TEST(G2oPoseGraph, ConsistentGraphWithRealTopology) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/smallGrid3D.g2o");
  G2oGraph graph = ReadG2o(test::SharedData("pose_graphs/smallGrid3D.g2o"));
  std::map<int64_t, SE3> truth;
  for (const G2oVertex& vertex : graph.vertices) truth[vertex.id] = vertex.world_from_vertex;
  for (G2oEdge& edge : graph.edges) {
    edge.i_from_j = truth.at(edge.id_i).Inverse() * truth.at(edge.id_j);
  }
  const G2oOptimizationResult result = OptimizeG2oGraph(graph, G2oOptimizationOptions());
  // The chordal initialisation is exact here (ChordalInitialization tests),
  // anchored at the first vertex.
  EXPECT_LT(result.objective_initial, 1e-12);
  EXPECT_LT(result.objective_final, 1e-12);
  for (size_t k = 0; k < result.ids.size(); ++k) {
    EXPECT_TRUE(test::PosesNear(result.poses[k], truth.at(result.ids[k]), 1e-8, 1e-8))
        << "vertex " << result.ids[k];
  }
}

// The real smallGrid3D from its own vertices and from the chordal
// initialisation: both reach the same minimum (its noise is small).
TEST(G2oPoseGraph, VerticesAndChordalStartsAgree) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/smallGrid3D.g2o");
  const G2oGraph graph = ReadG2o(test::SharedData("pose_graphs/smallGrid3D.g2o"));
  G2oOptimizationOptions options;
  const G2oOptimizationResult chordal = OptimizeG2oGraph(graph, options);
  options.initialization = "vertices";
  const G2oOptimizationResult vertices = OptimizeG2oGraph(graph, options);
  EXPECT_DOUBLE_EQ(vertices.objective_initial, vertices.objective_vertices);
  EXPECT_NEAR(chordal.objective_final, vertices.objective_final, 1e-6 * chordal.objective_final);
  EXPECT_LT(chordal.objective_final, chordal.objective_vertices);
}

// Real graphs that solve in about a second each.
TEST(G2oPoseGraph, ReachesPublishedOptimumOnSmallRealGraphs) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/intel.g2o");
  ExpectReachesOptimum("intel.g2o", 52.35);           // 2D, 1,728 poses
  ExpectReachesOptimum("CSAIL.g2o", 31.70);           // 2D, no vertices
  ExpectReachesOptimum("parking-garage.g2o", 1.263);  // 3D, 1,661 poses
}

}  // namespace
}  // namespace lisfm
