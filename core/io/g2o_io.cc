#include "core/io/g2o_io.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <unordered_map>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {
namespace {

constexpr double kQuaternionNormTolerance = 1e-4;

constexpr const char* kVertex2 = "VERTEX_SE2";
constexpr const char* kEdge2 = "EDGE_SE2";
constexpr const char* kVertex3 = "VERTEX_SE3:QUAT";
constexpr const char* kEdge3 = "EDGE_SE3:QUAT";

// Field counts after the tag.
constexpr int kNumVertex2 = 1 + 3;
constexpr int kNumEdge2 = 2 + 3 + 6;
constexpr int kNumVertex3 = 1 + 7;
constexpr int kNumEdge3 = 2 + 7 + 21;

SE3 Planar(double x, double y, double theta) {
  return SE3(Quat(Eigen::AngleAxisd(theta, Vec3::UnitZ())), Vec3(x, y, 0.0));
}

double PlanarAngle(const SE3& pose) {
  const Mat3 R = pose.RotationMatrix();
  return std::atan2(R(1, 0), R(0, 0));
}

// Parses the fields of one record; every failure names the file and line.
class RecordParser {
 public:
  RecordParser(const LineReader& reader, const std::vector<std::string>& fields)
      : reader_(reader), fields_(fields) {}

  [[noreturn]] void Fail(const std::string& message) const {
    throw InputError(reader_.path(), reader_.Where(), message);
  }

  void ExpectCount(int count, const char* layout) const {
    const int found = static_cast<int>(fields_.size()) - 1;
    if (found != count) {
      Fail(fmt::format(
          "{}: expected {} fields after the tag ({}), found {}", fields_[0], count, layout, found));
    }
  }

  // Field k (1-based after the tag).
  double Number(size_t k) const {
    double value = 0.0;
    if (!ParseDouble(fields_[k], &value)) {
      Fail(fmt::format(
          "{}: field {}: expected a finite number, found '{}'", fields_[0], k, fields_[k]));
    }
    return value;
  }

  int64_t Id(size_t k) const {
    int64_t value = 0;
    if (!ParseInt64(fields_[k], &value) || value < 0) {
      Fail(fmt::format("{}: field {}: expected a non-negative integer vertex id, found '{}'",
                       fields_[0],
                       k,
                       fields_[k]));
    }
    return value;
  }

  // Quaternion from fields k..k+3 in the order x y z w.
  Quat UnitQuaternion(size_t k) const {
    Quat q(Number(k + 3), Number(k), Number(k + 1), Number(k + 2));
    const double norm = q.norm();
    if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
      Fail(fmt::format("{}: expected a unit quaternion (|q| - 1 within {}), found |q| = {:.9g}",
                       fields_[0],
                       kQuaternionNormTolerance,
                       norm));
    }
    return q.normalized();
  }

  // Upper triangle (row-major) of an n x n information matrix from field k on.
  // Its translation block (the first n / 2 rows and columns, 2 in 2D) and its
  // rotation block (the rest) must be positive definite; the whole matrix need
  // not be (cubicle.g2o's is indefinite through its off-diagonal block).
  MatX Information(size_t k, int n) const {
    MatX information(n, n);
    for (int r = 0; r < n; ++r) {
      for (int c = r; c < n; ++c) information(r, c) = information(c, r) = Number(k++);
    }
    const int num_translation = n == 3 ? 2 : 3;
    CheckPositiveDefinite(information.topLeftCorner(num_translation, num_translation),
                          "translation");
    CheckPositiveDefinite(information.bottomRightCorner(n - num_translation, n - num_translation),
                          "rotation");
    return information;
  }

  void CheckPositiveDefinite(const MatX& block, const char* what) const {
    const Eigen::SelfAdjointEigenSolver<MatX> solver(block, Eigen::EigenvaluesOnly);
    const double min_eigenvalue = solver.eigenvalues().minCoeff();
    if (solver.info() != Eigen::Success || !(min_eigenvalue > 0.0)) {
      Fail(
          fmt::format("{}: expected a positive-definite {} block of the information matrix, "
                      "found minimum eigenvalue {:.6g}",
                      fields_[0],
                      what,
                      min_eigenvalue));
    }
  }

  G2oVertex Vertex2() const {
    ExpectCount(kNumVertex2, "id x y theta");
    return {Id(1), Planar(Number(2), Number(3), Number(4)), reader_.line_number()};
  }

  G2oVertex Vertex3() const {
    ExpectCount(kNumVertex3, "id x y z qx qy qz qw");
    const Vec3 t(Number(2), Number(3), Number(4));
    return {Id(1), SE3(UnitQuaternion(5), t), reader_.line_number()};
  }

  G2oEdge Edge2() const {
    ExpectCount(kNumEdge2, "i j dx dy dtheta I11 I12 I13 I22 I23 I33");
    G2oEdge edge;
    edge.id_i = Id(1);
    edge.id_j = Id(2);
    edge.i_from_j = Planar(Number(3), Number(4), Number(5));
    edge.information = Information(6, 3);
    edge.line = reader_.line_number();
    CheckDistinct(edge);
    return edge;
  }

  G2oEdge Edge3() const {
    ExpectCount(kNumEdge3, "i j dx dy dz dqx dqy dqz dqw + 21 information entries");
    G2oEdge edge;
    edge.id_i = Id(1);
    edge.id_j = Id(2);
    const Vec3 t(Number(3), Number(4), Number(5));
    edge.i_from_j = SE3(UnitQuaternion(6), t);
    edge.information = Information(10, 6);
    edge.line = reader_.line_number();
    CheckDistinct(edge);
    return edge;
  }

 private:
  void CheckDistinct(const G2oEdge& edge) const {
    if (edge.id_i == edge.id_j) {
      Fail(fmt::format("{}: expected an edge between two vertices, found vertex {} to itself",
                       fields_[0],
                       edge.id_i));
    }
  }

  const LineReader& reader_;
  const std::vector<std::string>& fields_;
};

// Disjoint sets over indices 0..n-1 (path halving, union by index).
class DisjointSets {
 public:
  explicit DisjointSets(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  size_t Find(size_t a) {
    while (parent_[a] != a) a = parent_[a] = parent_[parent_[a]];
    return a;
  }
  void Join(size_t a, size_t b) {
    a = Find(a);
    b = Find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<size_t> parent_;
};

std::string FormatNumber(double value) { return fmt::format("{:.17g}", value); }

}  // namespace

G2oGraph ReadG2o(const std::string& path) {
  CheckFileExists(path, "g2o file");
  LineReader reader(path);
  G2oGraph graph;
  int dimension_line = 0;
  std::unordered_map<int64_t, int> vertex_line;  // id -> line
  std::string line;
  while (reader.Next(&line)) {
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    const std::vector<std::string> fields = SplitString(trimmed, " \t");
    const std::string& tag = fields[0];
    const RecordParser parser(reader, fields);
    int dimension = 0;
    if (tag == kVertex2 || tag == kEdge2) {
      dimension = 2;
    } else if (tag == kVertex3 || tag == kEdge3) {
      dimension = 3;
    } else {
      parser.Fail(fmt::format(
          "unknown tag '{}' (expected {}, {}, {} or {})", tag, kVertex2, kEdge2, kVertex3, kEdge3));
    }
    if (graph.dimension == 0) {
      graph.dimension = dimension;
      dimension_line = reader.line_number();
    } else if (dimension != graph.dimension) {
      parser.Fail(fmt::format("{}: a {}D record in a {}D graph (line {} is {}D)",
                              tag,
                              dimension,
                              graph.dimension,
                              dimension_line,
                              graph.dimension));
    }
    if (tag == kVertex2 || tag == kVertex3) {
      G2oVertex vertex = dimension == 2 ? parser.Vertex2() : parser.Vertex3();
      const auto [it, inserted] = vertex_line.emplace(vertex.id, vertex.line);
      if (!inserted) {
        parser.Fail(fmt::format(
            "{}: vertex {} is defined twice (first on line {})", tag, vertex.id, it->second));
      }
      graph.vertices.push_back(vertex);
    } else {
      graph.edges.push_back(dimension == 2 ? parser.Edge2() : parser.Edge3());
    }
  }
  if (graph.edges.empty()) {
    throw InputError(
        path, "", "expected at least one edge (EDGE_SE2 or EDGE_SE3:QUAT), found none");
  }
  if (!graph.vertices.empty()) {
    for (const G2oEdge& edge : graph.edges) {
      for (const int64_t id : {edge.id_i, edge.id_j}) {
        if (vertex_line.count(id) == 0) {
          throw InputError(path,
                           "line " + std::to_string(edge.line),
                           fmt::format("edge {} -> {} names vertex {}, which the file does not "
                                       "define (a dangling edge)",
                                       edge.id_i,
                                       edge.id_j,
                                       id));
        }
      }
    }
  }
  return graph;
}

void CheckG2oConnected(const G2oGraph& graph, const std::string& path) {
  // Ids in order of appearance (vertices first), each with the line naming it first.
  std::vector<int64_t> ids;
  std::vector<int> lines;
  std::unordered_map<int64_t, size_t> index;
  const auto add = [&](int64_t id, int line) {
    if (index.emplace(id, ids.size()).second) {
      ids.push_back(id);
      lines.push_back(line);
    }
  };
  for (const G2oVertex& vertex : graph.vertices) add(vertex.id, vertex.line);
  for (const G2oEdge& edge : graph.edges) {
    add(edge.id_i, edge.line);
    add(edge.id_j, edge.line);
  }
  if (ids.empty()) return;
  DisjointSets sets(ids.size());
  for (const G2oEdge& edge : graph.edges) sets.Join(index.at(edge.id_i), index.at(edge.id_j));
  const size_t first = static_cast<size_t>(std::min_element(ids.begin(), ids.end()) - ids.begin());
  size_t num_components = 0;
  size_t unreached = ids.size();
  for (size_t k = 0; k < ids.size(); ++k) {
    if (sets.Find(k) == k) ++num_components;
    if (unreached == ids.size() && sets.Find(k) != sets.Find(first)) unreached = k;
  }
  if (num_components > 1) {
    throw InputError(path,
                     "line " + std::to_string(lines[unreached]),
                     fmt::format("expected a connected pose graph, found vertex {} joined to the "
                                 "first vertex {} by no chain of edges ({} connected components)",
                                 ids[unreached],
                                 ids[first],
                                 num_components));
  }
}

void WriteG2o(const G2oGraph& graph, const std::string& path) {
  THROW_CHECK_MSG(graph.dimension == 2 || graph.dimension == 3,
                  "WriteG2o: dimension " << graph.dimension);
  const bool planar = graph.dimension == 2;
  std::vector<const G2oVertex*> vertices;
  for (const G2oVertex& vertex : graph.vertices) vertices.push_back(&vertex);
  std::sort(vertices.begin(), vertices.end(), [](const G2oVertex* a, const G2oVertex* b) {
    return a->id < b->id;
  });
  std::ostringstream out;
  std::vector<std::string> fields;
  const auto flush = [&] {
    for (size_t k = 0; k < fields.size(); ++k) out << (k ? " " : "") << fields[k];
    out << '\n';
    fields.clear();
  };
  const auto add_pose = [&](const SE3& pose) {
    const Vec3& t = pose.translation();
    if (planar) {
      for (const double v : {t.x(), t.y(), PlanarAngle(pose)}) fields.push_back(FormatNumber(v));
    } else {
      const Quat& q = pose.rotation();
      for (const double v : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) {
        fields.push_back(FormatNumber(v));
      }
    }
  };
  for (const G2oVertex* vertex : vertices) {
    fields.push_back(planar ? kVertex2 : kVertex3);
    fields.push_back(std::to_string(vertex->id));
    add_pose(vertex->world_from_vertex);
    flush();
  }
  const int n = planar ? 3 : 6;
  for (const G2oEdge& edge : graph.edges) {
    THROW_CHECK_MSG(edge.information.rows() == n && edge.information.cols() == n,
                    "WriteG2o: information of size " << edge.information.rows() << "x"
                                                     << edge.information.cols());
    fields.push_back(planar ? kEdge2 : kEdge3);
    fields.push_back(std::to_string(edge.id_i));
    fields.push_back(std::to_string(edge.id_j));
    add_pose(edge.i_from_j);
    for (int r = 0; r < n; ++r) {
      for (int c = r; c < n; ++c) fields.push_back(FormatNumber(edge.information(r, c)));
    }
    flush();
  }
  WriteFileAtomically(path, out.str());
}

}  // namespace lisfm
