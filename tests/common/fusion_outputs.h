// Shared checks of `lisfm fusion` outputs for the end-to-end tests of both modes:
// the payload of a binary PLY, the surfels' distances to the simulator's scene
// mesh, and the failure expectation (exit code, message, no output folder left).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "core/file_utils.h"
#include "core/types.h"
#include "tests/common/point_triangle_distance.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace test {

// The binary payload of a little-endian PLY after its header, and the vertex count.
inline std::string PlyPayload(const std::string& path, size_t* num_vertices) {
  const std::string data = ReadFile(path);
  const size_t end = data.find("end_header\n");
  EXPECT_NE(end, std::string::npos) << path;
  std::istringstream header(data.substr(0, end));
  std::string line;
  *num_vertices = 0;
  while (std::getline(header, line)) {
    if (line.rfind("element vertex ", 0) == 0) *num_vertices = std::stoul(line.substr(15));
  }
  return data.substr(end + 11);
}

// Exact distances (m, ascending) of every stride-th surfel of `surfels_ply` (lisfm
// fusion's 35-byte records) to the triangles of `scene_ply` (the simulator's mesh:
// float vertices, three per triangle, in order). Fails the test and returns nothing
// when a file does not have that layout or there are at most min_surfels surfels.
inline std::vector<double> SurfelDistancesToScene(const std::string& surfels_ply,
                                                  const std::string& scene_ply,
                                                  size_t stride,
                                                  size_t min_surfels) {
  size_t num_vertices = 0;
  const std::string mesh = PlyPayload(scene_ply, &num_vertices);
  if (mesh.size() < num_vertices * 12) {
    ADD_FAILURE() << scene_ply << ": " << mesh.size() << " bytes for " << num_vertices
                  << " vertices";
    return {};
  }
  std::vector<float> v(num_vertices * 3);
  std::memcpy(v.data(), mesh.data(), num_vertices * 12);
  // Surfels: 35 bytes each (6 floats, 3 bytes, 2 floats).
  size_t num_surfels = 0;
  const std::string surfels = PlyPayload(surfels_ply, &num_surfels);
  if (surfels.size() != num_surfels * 35 || num_surfels <= min_surfels) {
    ADD_FAILURE() << surfels_ply << ": " << surfels.size() << " bytes for " << num_surfels
                  << " surfels (expected 35 each, more than " << min_surfels << ")";
    return {};
  }
  std::vector<double> distances;
  for (size_t i = 0; i < num_surfels; i += stride) {
    float p[3];
    std::memcpy(p, surfels.data() + 35 * i, 12);
    const Vec3 x(p[0], p[1], p[2]);
    double best = 1e9;
    for (size_t k = 0; k + 2 < num_vertices; k += 3) {
      const Vec3 a(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
      const Vec3 b(v[3 * k + 3], v[3 * k + 4], v[3 * k + 5]);
      const Vec3 c(v[3 * k + 6], v[3 * k + 7], v[3 * k + 8]);
      best = std::min(best, PointTriangleDistance(x, a, b, c));
    }
    distances.push_back(best);
  }
  std::sort(distances.begin(), distances.end());
  return distances;
}

// Runs `command --output_path output_path` and expects exit `code`, `message` in
// the output, and neither the output folder nor a temporary one left behind.
inline void ExpectCommandFails(const std::string& command,
                               int code,
                               const std::string& message,
                               const std::string& output_path) {
  std::string out;
  EXPECT_EQ(RunCommand(command + " --output_path " + output_path, &out), code) << out;
  EXPECT_NE(out.find(message), std::string::npos) << out;
  EXPECT_FALSE(FileExists(output_path) || DirExists(output_path)) << output_path;
  std::string ls;
  RunCommand("ls -d " + output_path + ".tmp-* 2>/dev/null | wc -l", &ls);
  EXPECT_EQ(Trim(ls), "0") << "a temporary output folder was left behind";
}

}  // namespace test
}  // namespace lisfm
