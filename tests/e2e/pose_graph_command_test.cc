// `lisfm pose_graph` end to end: runs the binary like a user on real SE-Sync
// benchmark graphs (the published optimum, the written graph read back) and on
// broken g2o files (one `error: <file>:line N: ...` line, exit 1, no output
// file left behind).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "core/io/g2o_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using test::LisfmBinary;
using test::RunCommand;
using test::TempDir;

std::string Lisfm(const std::string& args, int* code) {
  std::string out;
  *code = RunCommand(LisfmBinary() + " pose_graph " + args, &out);
  return out;
}

// The `key: value` lines the command prints.
std::map<std::string, std::string> Fields(const std::string& out) {
  std::map<std::string, std::string> fields;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    const size_t colon = line.find(": ");
    if (colon != std::string::npos && line[0] != '[') {
      fields[line.substr(0, colon)] = line.substr(colon + 2);
    }
  }
  return fields;
}

double Number(const std::map<std::string, std::string>& fields, const std::string& key) {
  const auto it = fields.find(key);
  return it == fields.end() ? -1.0 : std::strtod(it->second.c_str(), nullptr);
}

size_t NumFiles(const std::string& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir)) ++n;
  return n;
}

// intel.g2o: F* = 52.35 (SE-Sync, IJRR 2019 Table 1; 4 digits: 5e-4 relative).
// The written graph carries the optimised vertices: started from them, the
// objective is already the optimum.
TEST(PoseGraphCommand, IntelReachesOptimumAndWritesTheGraph) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/intel.g2o");
  TempDir dir;
  const std::string output = dir.File("out/intel_optimized.g2o");
  int code = 0;
  std::string out = Lisfm(
      "--input_path " + test::SharedData("pose_graphs/intel.g2o") + " --output_path " + output,
      &code);
  ASSERT_EQ(code, 0) << out;
  const auto fields = Fields(out);
  EXPECT_EQ(fields.at("dimension"), "2");
  EXPECT_EQ(fields.at("poses"), "1728");
  EXPECT_EQ(fields.at("edges"), "2512");
  EXPECT_NEAR(Number(fields, "F_final"), 52.35, 5e-4 * 52.35) << out;
  EXPECT_GT(Number(fields, "F_initial"), Number(fields, "F_final"));
  EXPECT_EQ(fields.at("converged"), "true");
  const G2oGraph written = ReadG2o(output);
  EXPECT_EQ(written.vertices.size(), 1728u);
  EXPECT_EQ(written.edges.size(), 2512u);

  out = Lisfm("--input_path " + output + " --PoseGraph.initialization vertices", &code);
  ASSERT_EQ(code, 0) << out;
  const auto again = Fields(out);
  // 17-digit output: the objective at the written vertices equals the optimum.
  EXPECT_NEAR(Number(again, "F_vertices"), Number(fields, "F_final"), 1e-9 * 52.35);
  EXPECT_NEAR(Number(again, "F_final"), Number(fields, "F_final"), 1e-5 * 52.35);
}

// CSAIL.g2o has no VERTEX records (F_vertices is nan): the output gets one
// vertex per pose. F* = 31.70 (SE-Sync, IJRR 2019 Table 1).
TEST(PoseGraphCommand, GraphWithoutVerticesGetsThem) {
  LISFM_REQUIRE_SHARED_DATA("pose_graphs/CSAIL.g2o");
  TempDir dir;
  int code = 0;
  const std::string out = Lisfm("--input_path " + test::SharedData("pose_graphs/CSAIL.g2o") +
                                    " --output_path " + dir.File("csail.g2o"),
                                &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_EQ(Fields(out).at("F_vertices"), "nan");
  EXPECT_NEAR(Number(Fields(out), "F_final"), 31.70, 5e-4 * 31.70) << out;
  EXPECT_EQ(ReadG2o(dir.File("csail.g2o")).vertices.size(), 1045u);
}

// Broken inputs: one error line naming the file and line, exit 1, no output.
TEST(PoseGraphCommand, BadInputIsOneErrorAndNoOutput) {
  TempDir dir;
  const std::string info = " 100 0 0 100 0 1000\n";
  const std::string good = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0" + info;
  struct Case {
    std::string name;
    std::string contents;
    std::string expected;  // after "error: <path>:"
  };
  const std::vector<Case> cases = {
      {"unknown_tag", good + "FIX 0\n", "line 4: unknown tag 'FIX'"},
      {"dangling", good + "EDGE_SE2 1 7 1 0 0" + info, "line 4: edge 1 -> 7 names vertex 7"},
      {"nan",
       "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 nan 0 0\nEDGE_SE2 0 1 1 0 0" + info,
       "line 2: VERTEX_SE2: field 2: expected a finite number, found 'nan'"},
      {"fields", good + "EDGE_SE2 0 1 1 0" + info, "line 4: EDGE_SE2: expected 11 fields"},
      {"twice", good + "VERTEX_SE2 1 2 0 0\n", "line 4: VERTEX_SE2: vertex 1 is defined twice"},
      {"split", good + "VERTEX_SE2 2 2 0 0\n", "line 4: expected a connected pose graph"},
  };
  for (const Case& c : cases) {
    const std::string input = dir.File(c.name + ".g2o");
    test::WriteText(input, c.contents);
    const std::string output_dir = dir.File("out_" + c.name);
    int code = 0;
    const std::string out =
        Lisfm("--input_path " + input + " --output_path " + output_dir + "/graph.g2o", &code);
    EXPECT_EQ(code, 1) << c.name << "\n" << out;
    EXPECT_NE(out.find("error: " + input + ":" + c.expected), std::string::npos) << c.name << "\n"
                                                                                 << out;
    EXPECT_EQ(out.find("error: "), out.rfind("error: ")) << out;  // one error line
    // The output folder was created by the up-front check, but holds nothing.
    EXPECT_FALSE(std::filesystem::exists(output_dir + "/graph.g2o")) << c.name;
    if (std::filesystem::exists(output_dir)) {
      EXPECT_EQ(NumFiles(output_dir), 0u) << c.name;
    }
  }
  // Vertices as the start, but the file has none.
  const std::string edges_only = dir.File("edges_only.g2o");
  test::WriteText(edges_only, "EDGE_SE2 0 1 1 0 0" + info);
  int code = 0;
  std::string out =
      Lisfm("--input_path " + edges_only + " --PoseGraph.initialization vertices", &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find("error: " + edges_only +
                     ": --PoseGraph.initialization vertices needs "
                     "VERTEX records"),
            std::string::npos)
      << out;
  // A missing input file and an output path that is a folder.
  out = Lisfm("--input_path " + dir.File("missing.g2o"), &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find(dir.File("missing.g2o")), std::string::npos) << out;
  out = Lisfm("--input_path " + edges_only + " --output_path " + dir.path(), &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("is a folder"), std::string::npos) << out;
}

TEST(PoseGraphCommand, HelpListsEveryOption) {
  int code = 0;
  const std::string out = Lisfm("-h", &code);
  EXPECT_EQ(code, 0) << out;
  for (const char* option : {"--input_path",
                             "--output_path",
                             "--PoseGraph.initialization",
                             "--Solver.max_num_iterations",
                             "--Solver.function_tolerance",
                             "--Solver.gradient_tolerance",
                             "--Solver.parameter_tolerance",
                             "--Solver.num_threads"}) {
    EXPECT_NE(out.find(option), std::string::npos) << option << "\n" << out;
  }
}

}  // namespace
}  // namespace lisfm
