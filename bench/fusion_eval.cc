// Geometry scores of a fused model (scripts/bench_fusion.sh): the distance of every point of
// a PLY point set (our surfels.ply, or Open3D's mesh.ply vertices) to
//  - the vertices of a reference mesh (--vertices_path; nearest vertex, kd-tree): the issue's
//    "within 1 cm (median) of Open3D's ScalableTSDFVolume mesh vertices" metric, and the
//    reverse distance (reference vertex to the nearest point: completeness);
//  - the surface of a reference mesh (--surface_path; exact point-triangle distance with
//    Open3D's t::geometry::RaycastingScene::ComputeDistance, e.g. the simulator's scene.ply).
// Statistics are median, 95th percentile, mean (m) and the fraction within 1 cm.
// Points with a `confidence` property below --min_confidence are left out (0 keeps all).
//
// Usage: lisfm_fusion_eval --points_path P.ply [--vertices_path M.ply] [--surface_path S.ply]
//          [--min_confidence 0] [--output_path scores.json]
// Prints one line per score; writes them as JSON with --output_path.
#include <open3d/core/Tensor.h>
#include <open3d/geometry/TriangleMesh.h>
#include <open3d/io/TriangleMeshIO.h>
#include <open3d/t/geometry/RaycastingScene.h>
#include <open3d/t/geometry/TriangleMesh.h>
#include <open3d/utility/Logging.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <nanoflann.hpp>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {
namespace {

// The vertex element of a PLY file (ascii or binary little endian): every scalar property
// by name, as double.
struct PlyVertices {
  size_t count = 0;
  std::map<std::string, std::vector<double>> properties;
  const std::vector<double>& Get(const std::string& name, const std::string& path) const {
    const auto it = properties.find(name);
    if (it == properties.end()) throw InputError(path, "header", "no vertex property " + name);
    return it->second;
  }
};

int TypeSize(const std::string& type, const std::string& path) {
  static const std::map<std::string, int> kSizes = {{"char", 1},
                                                    {"uchar", 1},
                                                    {"int8", 1},
                                                    {"uint8", 1},
                                                    {"short", 2},
                                                    {"ushort", 2},
                                                    {"int16", 2},
                                                    {"uint16", 2},
                                                    {"int", 4},
                                                    {"uint", 4},
                                                    {"int32", 4},
                                                    {"uint32", 4},
                                                    {"float", 4},
                                                    {"float32", 4},
                                                    {"double", 8},
                                                    {"float64", 8}};
  const auto it = kSizes.find(type);
  if (it == kSizes.end()) throw InputError(path, "header", "unknown PLY type " + type);
  return it->second;
}

double Decode(const char* p, const std::string& type) {
  if (type == "float" || type == "float32") {
    float v;
    std::memcpy(&v, p, 4);
    return v;
  }
  if (type == "double" || type == "float64") {
    double v;
    std::memcpy(&v, p, 8);
    return v;
  }
  if (type == "uchar" || type == "uint8") return static_cast<uint8_t>(*p);
  if (type == "char" || type == "int8") return static_cast<int8_t>(*p);
  if (type == "ushort" || type == "uint16") {
    uint16_t v;
    std::memcpy(&v, p, 2);
    return v;
  }
  if (type == "short" || type == "int16") {
    int16_t v;
    std::memcpy(&v, p, 2);
    return v;
  }
  if (type == "uint" || type == "uint32") {
    uint32_t v;
    std::memcpy(&v, p, 4);
    return v;
  }
  int32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

// Reads the vertex element; it must be the first element (as in the files of lisfm,
// Open3D and the simulator).
PlyVertices ReadPlyVertices(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "file", "cannot be opened");
  std::string line, format;
  std::vector<std::pair<std::string, std::string>> props;  // (type, name)
  bool in_vertex = false, seen_vertex = false;
  PlyVertices out;
  std::getline(in, line);
  if (line.rfind("ply", 0) != 0) throw InputError(path, "line 1", "not a PLY file");
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream s(line);
    std::string word;
    s >> word;
    if (word == "format") {
      s >> format;
    } else if (word == "element") {
      std::string name;
      size_t n = 0;
      s >> name >> n;
      in_vertex = name == "vertex";
      if (in_vertex) {
        out.count = n;
        seen_vertex = true;
      } else if (!seen_vertex) {
        throw InputError(path, "header", "the vertex element must come first");
      }
    } else if (word == "property" && in_vertex) {
      std::string type, name;
      s >> type >> name;
      if (type == "list") throw InputError(path, "header", "list property in vertex element");
      props.push_back({type, name});
    } else if (word == "end_header") {
      break;
    }
  }
  if (!seen_vertex) throw InputError(path, "header", "no vertex element");
  for (const auto& p : props) out.properties[p.second].resize(out.count);
  if (format == "ascii") {
    for (size_t i = 0; i < out.count; ++i) {
      for (const auto& p : props) {
        double v = 0;
        if (!(in >> v)) throw InputError(path, "vertex " + std::to_string(i), "truncated");
        out.properties[p.second][i] = v;
      }
    }
  } else if (format == "binary_little_endian") {
    int stride = 0;
    for (const auto& p : props) stride += TypeSize(p.first, path);
    std::vector<char> buffer(static_cast<size_t>(stride) * out.count);
    if (!in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()))) {
      throw InputError(path, "vertices", "truncated binary vertex data");
    }
    std::vector<std::vector<double>*> columns;
    for (const auto& p : props) columns.push_back(&out.properties[p.second]);
    for (size_t i = 0; i < out.count; ++i) {
      const char* rec = buffer.data() + i * stride;
      for (size_t c = 0; c < props.size(); ++c) {
        (*columns[c])[i] = Decode(rec, props[c].first);
        rec += TypeSize(props[c].first, path);
      }
    }
  } else {
    throw InputError(path, "header", "unsupported PLY format " + format);
  }
  return out;
}

std::vector<Eigen::Vector3d> Positions(const PlyVertices& v,
                                       const std::string& path,
                                       double min_confidence) {
  const std::vector<double>& x = v.Get("x", path);
  const std::vector<double>& y = v.Get("y", path);
  const std::vector<double>& z = v.Get("z", path);
  const std::vector<double>* confidence = nullptr;
  if (min_confidence > 0) confidence = &v.Get("confidence", path);
  std::vector<Eigen::Vector3d> out;
  out.reserve(v.count);
  for (size_t i = 0; i < v.count; ++i) {
    if (confidence && (*confidence)[i] < min_confidence) continue;
    out.emplace_back(x[i], y[i], z[i]);
  }
  return out;
}

struct Cloud {
  std::vector<Eigen::Vector3d> pts;
  size_t kdtree_get_point_count() const { return pts.size(); }
  double kdtree_get_pt(size_t i, size_t d) const { return pts[i][d]; }
  template <class B>
  bool kdtree_get_bbox(B&) const {
    return false;
  }
};
using Tree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>, Cloud, 3>;

// Distance of each query to the nearest point of `reference`.
std::vector<double> NearestDistances(const std::vector<Eigen::Vector3d>& queries,
                                     const std::vector<Eigen::Vector3d>& reference) {
  Cloud cloud{reference};
  Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  std::vector<double> out(queries.size());
  tbb::parallel_for(size_t{0}, queries.size(), [&](size_t i) {
    uint32_t index = 0;
    double d2 = 0;
    tree.knnSearch(queries[i].data(), 1, &index, &d2);
    out[i] = std::sqrt(d2);
  });
  return out;
}

nlohmann::ordered_json Statistics(std::vector<double> d) {
  nlohmann::ordered_json j;
  j["count"] = d.size();
  if (d.empty()) return j;
  std::sort(d.begin(), d.end());
  const auto quantile = [&](double q) {
    return d[std::min(d.size() - 1, static_cast<size_t>(q * (d.size() - 1) + 0.5))];
  };
  double sum = 0;
  size_t within_1cm = 0;
  for (double v : d) {
    sum += v;
    if (v <= 0.01) ++within_1cm;
  }
  j["median_m"] = quantile(0.5);
  j["p95_m"] = quantile(0.95);
  j["mean_m"] = sum / d.size();
  j["within_1cm"] = static_cast<double>(within_1cm) / d.size();
  return j;
}

void Print(const std::string& name, const nlohmann::ordered_json& s) {
  if (s["count"].get<size_t>() == 0) {
    std::printf("%s: no points\n", name.c_str());
    return;
  }
  std::printf("%s: %zu points, median %.2f mm, p95 %.2f mm, mean %.2f mm, %.1f %% within 1 cm\n",
              name.c_str(),
              s["count"].get<size_t>(),
              1e3 * s["median_m"].get<double>(),
              1e3 * s["p95_m"].get<double>(),
              1e3 * s["mean_m"].get<double>(),
              100 * s["within_1cm"].get<double>());
}

int Run(int argc, char** argv) {
  std::map<std::string, std::string> kv;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key.rfind("--", 0) != 0) throw UsageError("expected --option value, found " + key);
    kv[key.substr(2)] = argv[i + 1];
  }
  if (argc % 2 == 0 || !kv.count("points_path")) {
    throw UsageError(
        "usage: lisfm_fusion_eval --points_path P.ply [--vertices_path M.ply] "
        "[--surface_path S.ply] [--min_confidence 0] [--output_path scores.json]");
  }
  for (const auto& [k, v] : kv) {
    if (k != "points_path" && k != "vertices_path" && k != "surface_path" &&
        k != "min_confidence" && k != "output_path") {
      throw UsageError("unknown option --" + k);
    }
  }
  double min_confidence = 0;
  if (kv.count("min_confidence") && !ParseDouble(kv["min_confidence"], &min_confidence)) {
    throw UsageError("--min_confidence: not a number");
  }
  open3d::utility::SetVerbosityLevel(open3d::utility::VerbosityLevel::Error);
  const std::string points_path = kv["points_path"];
  const std::vector<Eigen::Vector3d> points =
      Positions(ReadPlyVertices(points_path), points_path, min_confidence);
  nlohmann::ordered_json scores;
  scores["points_path"] = points_path;
  scores["points"] = points.size();
  scores["min_confidence"] = min_confidence;
  if (kv.count("vertices_path")) {
    const std::string path = kv["vertices_path"];
    const std::vector<Eigen::Vector3d> vertices = Positions(ReadPlyVertices(path), path, 0);
    scores["vertices_path"] = path;
    scores["to_vertices"] = Statistics(NearestDistances(points, vertices));
    scores["vertices_to_points"] = Statistics(NearestDistances(vertices, points));
    Print("points -> reference vertices", scores["to_vertices"]);
    Print("reference vertices -> points (completeness)", scores["vertices_to_points"]);
  }
  if (kv.count("surface_path")) {
    const std::string path = kv["surface_path"];
    open3d::geometry::TriangleMesh legacy;
    if (!open3d::io::ReadTriangleMesh(path, legacy) || legacy.triangles_.empty()) {
      throw InputError(path, "file", "Open3D could not read a triangle mesh");
    }
    open3d::t::geometry::RaycastingScene scene;
    scene.AddTriangles(open3d::t::geometry::TriangleMesh::FromLegacy(legacy));
    std::vector<float> flat(points.size() * 3);
    for (size_t i = 0; i < points.size(); ++i) {
      for (int d = 0; d < 3; ++d) flat[3 * i + d] = static_cast<float>(points[i][d]);
    }
    const open3d::core::Tensor query(
        flat, {static_cast<int64_t>(points.size()), 3}, open3d::core::Float32);
    const open3d::core::Tensor distance = scene.ComputeDistance(query);
    const std::vector<float> values = distance.ToFlatVector<float>();
    scores["surface_path"] = path;
    scores["to_surface"] = Statistics(std::vector<double>(values.begin(), values.end()));
    Print("points -> reference surface", scores["to_surface"]);
  }
  if (kv.count("output_path")) WriteFileAtomically(kv["output_path"], scores.dump(2) + "\n");
  return 0;
}

}  // namespace
}  // namespace lisfm

int main(int argc, char** argv) {
  try {
    return lisfm::Run(argc, argv);
  } catch (const lisfm::UsageError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
