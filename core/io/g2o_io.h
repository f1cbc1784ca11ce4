// g2o pose-graph files (the format of the g2o / TORO / SE-Sync benchmark graphs),
// 2D and 3D. One record per line, fields separated by blanks:
//   VERTEX_SE2 id x y theta
//   EDGE_SE2 i j dx dy dtheta I11 I12 I13 I22 I23 I33
//   VERTEX_SE3:QUAT id x y z qx qy qz qw
//   EDGE_SE3:QUAT i j dx dy dz dqx dqy dqz dqw I11 I12 ... I16 I22 ... I66
// A vertex is the pose world_from_vertex; an edge is the measured relative pose
// i_from_j = world_from_i^-1 * world_from_j (SE-Sync: R_ij = R_i^T R_j,
// t_ij = R_i^T (t_j - t_i)). The information matrix is given by its upper
// triangle, row-major, in the order of the measurement: (x, y, theta) in 2D;
// translation first, then rotation, in 3D (g2o's EdgeSE3 order). Angles in
// radians; quaternions Hamilton, (x, y, z, w).
//
// Files without VERTEX lines are allowed (manhattan, CSAIL, KITTI): their poses
// are the ids the edges name, and a solver initialises them. When a file has
// vertices, every edge must name defined vertices.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/geometry.h"

namespace lisfm {

struct G2oVertex {
  int64_t id = 0;
  SE3 world_from_vertex;  // 2D: rotation theta about z, z = 0
  int line = 0;           // 1-based line of the record in its file (0: not read from a file)
};

struct G2oEdge {
  int64_t id_i = 0;
  int64_t id_j = 0;
  SE3 i_from_j;  // the measurement; 2D: rotation dtheta about z, dz = 0
  // Information matrix (inverse covariance), symmetric, with positive-definite
  // translation and rotation diagonal blocks (the whole matrix may be
  // indefinite in real files): 3x3 over (dx, dy, dtheta) in 2D; 6x6 over
  // (translation, rotation) in 3D, the rotation block in g2o's units (the
  // quaternion's vector part).
  MatX information;
  int line = 0;  // 1-based line of the record (0: not read from a file)
};

struct G2oGraph {
  int dimension = 0;                // 2 or 3 (0 only for a graph without records)
  std::vector<G2oVertex> vertices;  // file order; may be empty (see above)
  std::vector<G2oEdge> edges;       // file order
};

// Reads a g2o file. Blank lines and lines starting with '#' are skipped.
// Throws InputError("<path>:line N: ...") for an unknown tag, a wrong field
// count, a field that is not a finite number (NaN, inf, text) or an id that is
// not a non-negative integer, a vertex id defined twice, an edge from a vertex
// to itself, an edge naming an undefined vertex when the file defines vertices
// (a dangling edge), 2D and 3D records in one file, a quaternion whose norm
// differs from 1 by more than 1e-4 (smaller errors, e.g. from 6-digit output,
// are normalised), or an information matrix whose translation or rotation
// block is not positive definite;
// InputError("<path>: ...") for a missing file or a file without edges.
G2oGraph ReadG2o(const std::string& path);

// The graph must be connected for its poses to be determined up to one global
// transform. Throws InputError naming `path` and the line of a vertex (or of an
// edge, for files without vertices) that no chain of edges joins to the first
// vertex (smallest id), with the number of connected components.
void CheckG2oConnected(const G2oGraph& graph, const std::string& path);

// Writes `graph` in the format above (vertices by ascending id, then edges in
// order; numbers with 17 significant digits, 2D angles wrapped to (-pi, pi])
// atomically (temporary name + rename). Throws InternalError for a dimension
// other than 2 or 3 or an information matrix of the wrong size.
void WriteG2o(const G2oGraph& graph, const std::string& path);

}  // namespace lisfm
