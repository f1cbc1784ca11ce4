#include "core/io/g2o_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

constexpr char kEdge2Info[] = "100 0 0 100 0 1000";
const std::string kEdge3Info = "100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400";

MatX RandomInformation(int n) {
  std::normal_distribution<double> normal(0.0, 1.0);
  MatX a(n, n);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) a(r, c) = normal(test::Rng());
  }
  return a * a.transpose() + MatX::Identity(n, n);
}

SE3 RandomPlanarPose() {
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  return SE3(Quat(Eigen::AngleAxisd(u(test::Rng()), Vec3::UnitZ())),
             Vec3(u(test::Rng()), u(test::Rng()), 0.0));
}

G2oGraph RandomGraph(int dimension, int num_vertices) {
  G2oGraph graph;
  graph.dimension = dimension;
  for (int k = 0; k < num_vertices; ++k) {
    // Ids need not be contiguous or sorted in the file.
    graph.vertices.push_back(
        {3 * (num_vertices - k), dimension == 2 ? RandomPlanarPose() : test::RandomPose(), 0});
  }
  for (int k = 0; k + 1 < num_vertices; ++k) {
    G2oEdge edge;
    edge.id_i = graph.vertices[k].id;
    edge.id_j = graph.vertices[k + 1].id;
    edge.i_from_j = dimension == 2 ? RandomPlanarPose() : test::RandomPose();
    edge.information = RandomInformation(dimension == 2 ? 3 : 6);
    graph.edges.push_back(edge);
  }
  return graph;
}

void ExpectSameGraph(const G2oGraph& expected, const G2oGraph& actual) {
  ASSERT_EQ(expected.dimension, actual.dimension);
  // Vertices come back sorted by id.
  std::vector<G2oVertex> sorted = expected.vertices;
  std::sort(sorted.begin(), sorted.end(), [](const G2oVertex& a, const G2oVertex& b) {
    return a.id < b.id;
  });
  ASSERT_EQ(sorted.size(), actual.vertices.size());
  for (size_t k = 0; k < sorted.size(); ++k) {
    EXPECT_EQ(sorted[k].id, actual.vertices[k].id);
    // 17 significant digits; 2D goes through theta = atan2 and back (~1e-15).
    EXPECT_TRUE(test::PosesNear(
        sorted[k].world_from_vertex, actual.vertices[k].world_from_vertex, 1e-13, 1e-13));
  }
  ASSERT_EQ(expected.edges.size(), actual.edges.size());
  for (size_t k = 0; k < expected.edges.size(); ++k) {
    EXPECT_EQ(expected.edges[k].id_i, actual.edges[k].id_i);
    EXPECT_EQ(expected.edges[k].id_j, actual.edges[k].id_j);
    EXPECT_TRUE(
        test::PosesNear(expected.edges[k].i_from_j, actual.edges[k].i_from_j, 1e-13, 1e-13));
    EXPECT_EQ(expected.edges[k].information, actual.edges[k].information);
  }
}

TEST(G2oIo, RoundTrip2dAnd3d) {
  test::TempDir dir;
  for (const int dimension : {2, 3}) {
    const G2oGraph graph = RandomGraph(dimension, 6);
    const std::string path = dir.File("graph" + std::to_string(dimension) + ".g2o");
    WriteG2o(graph, path);
    ExpectSameGraph(graph, ReadG2o(path));
  }
}

// The record layouts, with the meaning of each field.
TEST(G2oIo, ReadsFieldsInG2oOrder) {
  test::TempDir dir;
  const std::string path2 = dir.File("a.g2o");
  test::WriteText(path2,
                  "VERTEX_SE2 0 0 0 0\n"
                  "VERTEX_SE2 1 1.5 -2 0.5\n"
                  "\n"
                  "EDGE_SE2 0 1 1 2 0.25 10 1 2 20 3 30\n");
  const G2oGraph g2 = ReadG2o(path2);
  ASSERT_EQ(g2.dimension, 2);
  ASSERT_EQ(g2.vertices.size(), 2u);
  EXPECT_EQ(g2.vertices[1].line, 2);
  EXPECT_TRUE(test::PosesNear(g2.vertices[1].world_from_vertex,
                              SE3(Quat(Eigen::AngleAxisd(0.5, Vec3::UnitZ())), Vec3(1.5, -2, 0)),
                              1e-15,
                              1e-15));
  ASSERT_EQ(g2.edges.size(), 1u);
  EXPECT_EQ(g2.edges[0].line, 4);
  EXPECT_TRUE(test::PosesNear(g2.edges[0].i_from_j,
                              SE3(Quat(Eigen::AngleAxisd(0.25, Vec3::UnitZ())), Vec3(1, 2, 0)),
                              1e-15,
                              1e-15));
  Eigen::Matrix3d info2;
  info2 << 10, 1, 2, 1, 20, 3, 2, 3, 30;
  EXPECT_EQ(g2.edges[0].information, MatX(info2));

  const std::string path3 = dir.File("b.g2o");
  test::WriteText(path3, "EDGE_SE3:QUAT 4 7 1 2 3 0 0 0.6 0.8 " + kEdge3Info + "\n");
  const G2oGraph g3 = ReadG2o(path3);
  ASSERT_EQ(g3.dimension, 3);
  EXPECT_TRUE(g3.vertices.empty());  // files without vertices are allowed
  ASSERT_EQ(g3.edges.size(), 1u);
  EXPECT_EQ(g3.edges[0].id_i, 4);
  EXPECT_EQ(g3.edges[0].id_j, 7);
  EXPECT_TRUE(test::PosesNear(
      g3.edges[0].i_from_j, SE3(Quat(0.8, 0, 0, 0.6), Vec3(1, 2, 3)), 1e-15, 1e-15));
  EXPECT_EQ(g3.edges[0].information(0, 0), 100);
  EXPECT_EQ(g3.edges[0].information(3, 3), 400);  // rotation block after translation

  // Only the translation and rotation blocks must be positive definite (cubicle.g2o).
  test::WriteText(path3,
                  "EDGE_SE3:QUAT 0 1 0 0 0 0 0 0 1 10 0 0 0 0 0 10 0 0 0 0 10 80000 0 0 10 0 0 "
                  "10 0 90000\n");
  EXPECT_EQ(ReadG2o(path3).edges[0].information(2, 3), 80000);
}

TEST(G2oIo, ReadsTheBenchmarkGraphs) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/tinyGrid3D.g2o");
  const G2oGraph tiny = ReadG2o(test::SharedData("pose_graphs/tinyGrid3D.g2o"));
  EXPECT_EQ(tiny.dimension, 3);
  EXPECT_EQ(tiny.vertices.size(), 9u);
  EXPECT_EQ(tiny.edges.size(), 11u);
  // CSAIL: no vertices; kitti_05: blank lines.
  const G2oGraph csail = ReadG2o(test::SharedData("pose_graphs/CSAIL.g2o"));
  EXPECT_EQ(csail.dimension, 2);
  EXPECT_TRUE(csail.vertices.empty());
  EXPECT_EQ(csail.edges.size(), 1172u);
  CheckG2oConnected(csail, "CSAIL.g2o");
  const G2oGraph kitti = ReadG2o(test::SharedData("pose_graphs/kitti_05.g2o"));
  EXPECT_EQ(kitti.edges.size(), 2826u);
}

// Bad input: one InputError naming the file, the line and what was expected/found.
TEST(G2oIo, BadInputNamesFileAndLine) {
  test::TempDir dir;
  const std::string path = dir.File("bad.g2o");
  const std::string v0 = "VERTEX_SE2 0 0 0 0\n";
  const std::string v1 = "VERTEX_SE2 1 1 0 0\n";
  const std::string e01 = std::string("EDGE_SE2 0 1 1 0 0 ") + kEdge2Info + "\n";
  struct Case {
    std::string contents;
    std::vector<std::string> fragments;
  };
  const std::vector<Case> cases = {
      {v0 + "FIX 0\n" + e01, {"line 2", "unknown tag 'FIX'"}},
      {v0 + v1 + "EDGE_SE2 0 1 1 0 0 100 0 0 100 0\n",
       {"line 3", "expected 11 fields after the tag", "found 10"}},
      {v0 + "VERTEX_SE2 1 nan 0 0\n" + e01, {"line 2", "field 2", "finite number", "'nan'"}},
      {v0 + "VERTEX_SE2 1 1 0 inf\n" + e01, {"line 2", "field 4", "'inf'"}},
      {v0 + "VERTEX_SE2 -1 1 0 0\n", {"line 2", "non-negative integer vertex id", "'-1'"}},
      {v0 + v1 + "VERTEX_SE2 0 5 5 0\n" + e01,
       {"line 3", "vertex 0 is defined twice (first on line 1)"}},
      {v0 + v1 + "EDGE_SE2 0 2 1 0 0 " + kEdge2Info + "\n",
       {"line 3", "names vertex 2", "dangling edge"}},
      {v0 + "EDGE_SE2 0 0 1 0 0 " + std::string(kEdge2Info) + "\n",
       {"line 2", "vertex 0 to itself"}},
      {v0 + "VERTEX_SE3:QUAT 1 0 0 0 0 0 0 1\n", {"line 2", "3D record in a 2D graph (line 1"}},
      {"EDGE_SE3:QUAT 0 1 0 0 0 0 0 0 0.5 " + kEdge3Info + "\n",
       {"line 1", "unit quaternion", "|q| = 0.5"}},
      {v0 + v1 + "EDGE_SE2 0 1 1 0 0 100 0 0 -100 0 1000\n",
       {"line 3", "positive-definite translation block", "minimum eigenvalue -100"}},
      {v0 + v1 + "EDGE_SE2 0 1 1 0 0 100 0 0 100 0 0\n",
       {"line 3", "positive-definite rotation block", "minimum eigenvalue 0"}},
      {v0 + v1, {"expected at least one edge"}},
      {"", {"expected at least one edge"}},
  };
  for (const Case& c : cases) {
    test::WriteText(path, c.contents);
    std::vector<std::string> fragments = c.fragments;
    fragments.push_back(path);
    EXPECT_TRUE(test::ThrowsInputError([&] { ReadG2o(path); }, fragments)) << c.contents;
  }
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadG2o(dir.File("missing.g2o")); }, {dir.File("missing.g2o")}));
}

TEST(G2oIo, ConnectivityNamesAnUnreachedVertex) {
  test::TempDir dir;
  const std::string path = dir.File("split.g2o");
  test::WriteText(path,
                  std::string("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 2 0 0\n") +
                      "EDGE_SE2 0 1 1 0 0 " + kEdge2Info + "\n");
  const G2oGraph graph = ReadG2o(path);
  EXPECT_TRUE(test::ThrowsInputError([&] { CheckG2oConnected(graph, path); },
                                     {path, "line 3", "vertex 2", "2 connected components"}));
  // Without vertices the unreached pose is named by the edge that introduces it.
  test::WriteText(path,
                  std::string("EDGE_SE2 0 1 1 0 0 ") + kEdge2Info + "\nEDGE_SE2 2 3 1 0 0 " +
                      kEdge2Info + "\n");
  const G2oGraph edges_only = ReadG2o(path);
  EXPECT_TRUE(test::ThrowsInputError([&] { CheckG2oConnected(edges_only, path); },
                                     {path, "line 2", "vertex 2"}));
}

}  // namespace
}  // namespace lisfm
