#include "colmap_ext/sfm/translation_averaging.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <queue>
#include <random>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <oneapi/tbb/enumerable_thread_specific.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"

namespace lisfm {
namespace colmap {
namespace {

constexpr char kRejected1DSfM[] = "1dsfm";
constexpr char kRejectedResidual[] = "translation_averaging";
// Broken / used projection weights are accumulated as integers in units of
// 1e-6 so that the parallel sum does not depend on the thread schedule.
constexpr double kWeightQuantum = 1e6;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Camera centre in rig coordinates: p = -R^T t for cam_from_rig = [R | t].
Vec3 CameraCenterInRig(const SE3& cam_from_rig) {
  return -(cam_from_rig.rotation().conjugate() * cam_from_rig.translation());
}

const SE3& CamFromRig(const MapperState& state, camera_t camera_id) {
  const auto it = state.cam_from_rig.find(camera_id);
  THROW_CHECK_MSG(it != state.cam_from_rig.end(),
                  "camera " << camera_id << " has no cam_from_rig");
  return it->second;
}

// One direction observation between two different frames.
struct DirectionEdge {
  size_t edge_index = 0;  // into state.view_graph.edges
  frame_t frame_id1 = 0;
  frame_t frame_id2 = 0;
  image_t image_id1 = 0;
  image_t image_id2 = 0;
  Vec3 direction = Vec3::Zero();  // world, unit: (c2 - c1) / |c2 - c1|, Eq. (1)
  Vec3 offset1 = Vec3::Zero();    // world: c1 - C1 = R1^T p_c1
  Vec3 offset2 = Vec3::Zero();
  double weight = 0.0;
};

// The valid edges between images of two different registered frames of
// `frames`, with their world directions (Eq. 1) from the current rotations.
std::vector<DirectionEdge> CollectDirectionEdges(const MapperState& state,
                                                 const std::unordered_set<frame_t>& frames) {
  std::vector<DirectionEdge> result;
  for (size_t e = 0; e < state.view_graph.edges.size(); ++e) {
    const ViewGraphEdge& edge = state.view_graph.edges[e];
    if (!edge.valid) continue;
    const auto image1 = state.images.find(edge.image_id1);
    const auto image2 = state.images.find(edge.image_id2);
    THROW_CHECK_MSG(image1 != state.images.end() && image2 != state.images.end(),
                    "view-graph edge " << edge.image_id1 << "-" << edge.image_id2
                                       << " names an unknown image");
    const frame_t f1 = image1->second.frame_id;
    const frame_t f2 = image2->second.frame_id;
    if (f1 == f2 || frames.count(f1) == 0 || frames.count(f2) == 0) continue;
    const Vec3 t = edge.cam2_from_cam1.translation();
    const double t_norm = t.norm();
    if (!(t_norm > 1e-12) || !std::isfinite(t_norm)) continue;  // no direction (pure rotation)
    const SfmFrame& frame1 = state.frames.at(f1);
    const SfmFrame& frame2 = state.frames.at(f2);
    const SE3& cam1_from_rig = CamFromRig(state, image1->second.camera_id);
    const SE3& cam2_from_rig = CamFromRig(state, image2->second.camera_id);
    const Quat world_from_rig1 = frame1.rig_from_world.rotation().conjugate();
    const Quat world_from_rig2 = frame2.rig_from_world.rotation().conjugate();
    const Quat world_from_cam2 = world_from_rig2 * cam2_from_rig.rotation().conjugate();
    DirectionEdge d;
    d.edge_index = e;
    d.frame_id1 = f1;
    d.frame_id2 = f2;
    d.image_id1 = edge.image_id1;
    d.image_id2 = edge.image_id2;
    d.direction = -(world_from_cam2 * (t / t_norm));  // Eq. (1)
    d.offset1 = world_from_rig1 * CameraCenterInRig(cam1_from_rig);
    d.offset2 = world_from_rig2 * CameraCenterInRig(cam2_from_rig);
    d.weight = edge.weight > 0.0 ? edge.weight : static_cast<double>(edge.inliers.size());
    result.push_back(d);
  }
  return result;
}

std::unordered_set<frame_t> RegisteredFrames(const MapperState& state,
                                             const std::vector<frame_t>& frame_ids) {
  std::unordered_set<frame_t> frames;
  for (const frame_t id : frame_ids) {
    const auto it = state.frames.find(id);
    THROW_CHECK_MSG(it != state.frames.end(), "unknown frame id " << id);
    if (it->second.registered) frames.insert(id);
  }
  return frames;
}

// Runs the 1dSfM filter on `edges` (directions of camera centres); returns a
// flag per edge: true = rejected.
std::vector<bool> RunFilter1DSfM(const TranslationAveragingOptions& options,
                                 const std::vector<DirectionEdge>& edges) {
  std::vector<bool> rejected(edges.size(), false);
  if (edges.empty()) return rejected;
  // Nodes are images (camera centres): the directions relate camera centres,
  // so the 1-D problem on images is exact also with a rig.
  std::unordered_map<image_t, size_t> node_of;
  std::vector<std::pair<size_t, size_t>> endpoints(edges.size());
  for (size_t e = 0; e < edges.size(); ++e) {
    const size_t n1 = node_of.emplace(edges[e].image_id1, node_of.size()).first->second;
    const size_t n2 = node_of.emplace(edges[e].image_id2, node_of.size()).first->second;
    endpoints[e] = {n1, n2};
  }
  const size_t num_nodes = node_of.size();

  struct Accumulator {
    std::vector<int64_t> broken;
    std::vector<int64_t> used;
  };
  tbb::enumerable_thread_specific<Accumulator> accumulators([&] {
    return Accumulator{std::vector<int64_t>(edges.size(), 0),
                       std::vector<int64_t>(edges.size(), 0)};
  });
  tbb::task_arena arena(options.num_threads > 0 ? options.num_threads
                                                : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(0, options.num_projections, [&](int k) {
      // Each projection has its own RNG: the axes do not depend on threads.
      std::mt19937_64 rng(options.random_seed * 1000003ULL + static_cast<uint64_t>(k));
      std::uniform_int_distribution<size_t> pick(0, edges.size() - 1);
      std::normal_distribution<double> noise(0.0, options.axis_perturbation_sigma);
      Vec3 axis = Vec3::Zero();
      while (!(axis.norm() > 1e-6)) {
        axis = edges[pick(rng)].direction + Vec3(noise(rng), noise(rng), noise(rng));
      }
      axis.normalize();
      std::vector<OrderingArc> arcs;
      std::vector<size_t> arc_edge;
      arcs.reserve(edges.size());
      arc_edge.reserve(edges.size());
      for (size_t e = 0; e < edges.size(); ++e) {
        const double w = edges[e].direction.dot(axis);
        if (std::abs(w) < options.min_projection_magnitude) continue;
        OrderingArc arc;
        arc.from = w > 0 ? endpoints[e].first : endpoints[e].second;
        arc.to = w > 0 ? endpoints[e].second : endpoints[e].first;
        arc.weight = std::abs(w);
        arcs.push_back(arc);
        arc_edge.push_back(e);
      }
      if (arcs.empty()) return;
      const std::vector<size_t> position = OrderNodesGreedyMfas(num_nodes, arcs);
      Accumulator& acc = accumulators.local();
      for (size_t a = 0; a < arcs.size(); ++a) {
        const int64_t w = std::llround(arcs[a].weight * kWeightQuantum);
        acc.used[arc_edge[a]] += w;
        if (position[arcs[a].to] < position[arcs[a].from]) acc.broken[arc_edge[a]] += w;
      }
    });
  });
  std::vector<int64_t> broken(edges.size(), 0);
  std::vector<int64_t> used(edges.size(), 0);
  for (const Accumulator& acc : accumulators) {
    for (size_t e = 0; e < edges.size(); ++e) {
      broken[e] += acc.broken[e];
      used[e] += acc.used[e];
    }
  }
  for (size_t e = 0; e < edges.size(); ++e) {
    if (used[e] == 0) continue;  // never decided: keep
    const double ratio = static_cast<double>(broken[e]) / static_cast<double>(used[e]);
    rejected[e] = ratio > options.max_broken_ratio;
  }
  return rejected;
}

// Union-find over local frame indices.
class UnionFind {
 public:
  explicit UnionFind(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  size_t Find(size_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void Union(size_t a, size_t b) {
    a = Find(a);
    b = Find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<size_t> parent_;
};

// Inverse Cholesky factor W (W^T W = covariance^-1); false if not positive definite.
bool SqrtInformation(const Mat3& covariance, Mat3* sqrt_information) {
  if (!covariance.allFinite()) return false;
  const Eigen::LLT<Mat3> llt(0.5 * (covariance + covariance.transpose()));
  if (llt.info() != Eigen::Success) return false;
  const Mat3 lower = llt.matrixL();
  if (!(lower.diagonal().minCoeff() > 0.0)) return false;
  *sqrt_information = lower.triangularView<Eigen::Lower>().solve(Mat3::Identity());
  return sqrt_information->allFinite();
}

struct LidarLink {
  frame_t frame_id1 = 0;
  frame_t frame_id2 = 0;
  Vec3 delta = Vec3::Zero();  // world: C2 - C1 = R1^T t_12 (m)
  Mat3 covariance = Mat3::Identity();
};

// Frames whose cameras have centres at least min_baseline apart (in rig).
bool FrameHasRigBaseline(const MapperState& state, const SfmFrame& frame, double min_baseline) {
  std::vector<Vec3> centers;
  for (const image_t image_id : frame.image_ids) {
    const auto it = state.images.find(image_id);
    if (it == state.images.end()) continue;
    centers.push_back(CameraCenterInRig(CamFromRig(state, it->second.camera_id)));
  }
  for (size_t i = 0; i < centers.size(); ++i) {
    for (size_t j = i + 1; j < centers.size(); ++j) {
      if ((centers[i] - centers[j]).norm() >= min_baseline) return true;
    }
  }
  return false;
}

// Linear initialisation (Govindu 2001 / Arie-Nachimson et al. 2012 style): the
// positions that minimise sum |(I - d d^T)(C_b - C_a)|^2 subject to |x| = 1,
// with frame `fixed_index` at the origin (the rig offsets are ignored here).
// The smallest eigenvector of that quadratic form is found by inverse
// iteration on its sparse matrix. Returns false if the matrix is singular
// (a graph that is not parallel rigid); the sign is chosen so that the
// baselines agree with the directions on average.
bool LinearInitialPositions(const std::vector<DirectionEdge>& edges,
                            const std::vector<size_t>& used_edges,
                            const std::unordered_map<frame_t, size_t>& local,
                            const std::vector<bool>& solved,
                            size_t fixed_index,
                            uint64_t seed,
                            std::vector<Vec3>* origins) {
  std::vector<int> variable(solved.size(), -1);
  int num_variables = 0;
  for (size_t i = 0; i < solved.size(); ++i) {
    if (solved[i] && i != fixed_index) variable[i] = num_variables++;
  }
  if (num_variables == 0 || used_edges.empty()) return false;
  std::vector<Eigen::Triplet<double>> triplets;
  for (const size_t e : used_edges) {
    const DirectionEdge& d = edges[e];
    const int va = variable[local.at(d.frame_id1)];
    const int vb = variable[local.at(d.frame_id2)];
    const Mat3 projector = Mat3::Identity() - d.direction * d.direction.transpose();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        const double p = projector(r, c);
        if (va >= 0) triplets.emplace_back(3 * va + r, 3 * va + c, p);
        if (vb >= 0) triplets.emplace_back(3 * vb + r, 3 * vb + c, p);
        if (va >= 0 && vb >= 0) {
          triplets.emplace_back(3 * va + r, 3 * vb + c, -p);
          triplets.emplace_back(3 * vb + r, 3 * va + c, -p);
        }
      }
    }
  }
  Eigen::SparseMatrix<double> matrix(3 * num_variables, 3 * num_variables);
  matrix.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(matrix);
  if (solver.info() != Eigen::Success) return false;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::VectorXd x(3 * num_variables);
  for (Eigen::Index k = 0; k < x.size(); ++k) x[k] = normal(rng);
  x.normalize();
  constexpr int kInverseIterations = 30;
  for (int it = 0; it < kInverseIterations; ++it) {
    Eigen::VectorXd y = solver.solve(x);
    if (solver.info() != Eigen::Success || !y.allFinite() || !(y.norm() > 0)) return false;
    x = y / y.norm();
  }
  auto position = [&](size_t i) -> Vec3 {
    return variable[i] < 0 ? Vec3::Zero() : Vec3(x.segment<3>(3 * variable[i]));
  };
  double agreement = 0.0;
  for (const size_t e : used_edges) {
    const DirectionEdge& d = edges[e];
    agreement += d.direction.dot(position(local.at(d.frame_id2)) - position(local.at(d.frame_id1)));
  }
  const double sign = agreement < 0 ? -1.0 : 1.0;
  for (size_t i = 0; i < solved.size(); ++i) {
    if (solved[i]) (*origins)[i] = sign * position(i);
  }
  return true;
}

// ---- Stages of AverageTranslations, in call order ----

// Stage 1 on `edges`: the 1dSfM filter; the rejected edges are invalidated in
// `state` (rejected_by = "1dsfm") and left out of the returned ones.
std::vector<DirectionEdge> RejectEdges1DSfM(const TranslationAveragingOptions& options,
                                            std::vector<DirectionEdge> edges, MapperState* state,
                                            TranslationAveragingStats* stats) {
  const auto filter_start = std::chrono::steady_clock::now();
  const std::vector<bool> rejected = RunFilter1DSfM(options, edges);
  std::vector<DirectionEdge> kept;
  for (size_t e = 0; e < edges.size(); ++e) {
    if (rejected[e]) {
      ViewGraphEdge& edge = state->view_graph.edges[edges[e].edge_index];
      edge.valid = false;
      edge.rejected_by = kRejected1DSfM;
      ++stats->num_rejected_1dsfm;
    } else {
      kept.push_back(edges[e]);
    }
  }
  stats->seconds_1dsfm = SecondsSince(filter_start);
  return kept;
}

// The frames of the problem (sorted ids) and their local indices.
struct LocalFrames {
  std::vector<frame_t> frames;
  std::unordered_map<frame_t, size_t> local;
};

LocalFrames IndexFrames(const std::unordered_set<frame_t>& frame_set) {
  LocalFrames result;
  result.frames.assign(frame_set.begin(), frame_set.end());
  std::sort(result.frames.begin(), result.frames.end());
  for (size_t i = 0; i < result.frames.size(); ++i) result.local[result.frames[i]] = i;
  return result;
}

// The LiDAR constraints between two different frames of `index`, in world
// (Eq. 4) with the current rotations.
std::vector<LidarLink> CollectLidarLinks(const TranslationAveragingOptions& options,
                                         const MapperState& state, const LocalFrames& index) {
  std::vector<LidarLink> lidar_links;
  if (!options.use_lidar_constraints) return lidar_links;
  for (const LidarConstraint& c : state.lidar_constraints) {
    if (c.frame_id1 == c.frame_id2 || index.local.count(c.frame_id1) == 0 ||
        index.local.count(c.frame_id2) == 0) {
      continue;
    }
    const Mat3 world_from_rig1 =
        state.frames.at(c.frame_id1).rig_from_world.RotationMatrix().transpose();
    const Mat3 rig1_from_rig2 = c.rig1_from_rig2.RotationMatrix();
    LidarLink link;
    link.frame_id1 = c.frame_id1;
    link.frame_id2 = c.frame_id2;
    link.delta = world_from_rig1 * c.rig1_from_rig2.translation();  // Eq. (4)
    const Mat3 rotation = world_from_rig1 * rig1_from_rig2;
    link.covariance = rotation * c.covariance.block<3, 3>(3, 3) * rotation.transpose();
    lidar_links.push_back(link);
  }
  return lidar_links;
}

// A connected component of the link graph (direction edges + LiDAR links).
struct LinkComponent {
  size_t size = 0;
  size_t num_priors = 0;
  bool has_lidar = false;
  frame_t first_frame = 0;
};

// Which frames are solved: the components of the link graph whose gauge is
// determined (header comment, "Which frames get a position").
struct SolvedFrames {
  std::unordered_map<size_t, LinkComponent> components;  // by union-find root
  std::unordered_set<size_t> solved_roots;
  std::vector<bool> solved;     // per local frame index
  std::vector<bool> has_prior;  // per local frame index (use_priors and a position prior)
  size_t total_priors = 0;
  bool rig_metric = false;  // a frame with a metric rig baseline
};

SolvedFrames SelectSolvedFrames(const TranslationAveragingOptions& options,
                                const std::vector<DirectionEdge>& edges,
                                const std::vector<LidarLink>& lidar_links,
                                const LocalFrames& index, MapperState* state,
                                TranslationAveragingStats* stats) {
  const std::vector<frame_t>& frames = index.frames;
  SolvedFrames s;
  s.has_prior.resize(frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    s.has_prior[i] = options.use_priors && state->frames.at(frames[i]).has_prior_position;
  }
  if (options.use_rig_baselines_for_scale) {
    for (const frame_t id : frames) {
      if (FrameHasRigBaseline(*state, state->frames.at(id), options.min_rig_baseline)) {
        s.rig_metric = true;
        break;
      }
    }
  }

  UnionFind uf(frames.size());
  for (const DirectionEdge& e : edges) {
    uf.Union(index.local.at(e.frame_id1), index.local.at(e.frame_id2));
  }
  for (const LidarLink& l : lidar_links) {
    uf.Union(index.local.at(l.frame_id1), index.local.at(l.frame_id2));
  }
  for (size_t i = 0; i < frames.size(); ++i) {
    LinkComponent& c = s.components[uf.Find(i)];
    if (c.size == 0) c.first_frame = frames[i];  // frames are sorted: smallest id
    ++c.size;
    c.num_priors += s.has_prior[i] ? 1 : 0;
  }
  for (const LidarLink& l : lidar_links) {
    s.components[uf.Find(index.local.at(l.frame_id1))].has_lidar = true;
  }
  for (const auto& [root, c] : s.components) s.total_priors += c.num_priors;

  if (s.total_priors > 0) {
    for (const auto& [root, c] : s.components) {
      if (c.num_priors >= 1 &&
          (c.num_priors >= 2 || c.has_lidar || s.rig_metric || c.size == 1)) {
        s.solved_roots.insert(root);
      }
    }
  } else {
    // The largest component (a LiDAR-linked one first), ties by the smallest frame id.
    const LinkComponent* best = nullptr;
    size_t best_root = 0;
    for (const auto& [root, c] : s.components) {
      const bool better =
          best == nullptr || (c.has_lidar && !best->has_lidar) ||
          (c.has_lidar == best->has_lidar &&
           (c.size > best->size || (c.size == best->size && c.first_frame < best->first_frame)));
      if (better) {
        best = &c;
        best_root = root;
      }
    }
    s.solved_roots.insert(best_root);
  }

  s.solved.assign(frames.size(), false);
  for (size_t i = 0; i < frames.size(); ++i) {
    s.solved[i] = s.solved_roots.count(uf.Find(i)) > 0;
    if (!s.solved[i]) {
      state->frames.at(frames[i]).registered = false;
      ++stats->num_frames_unregistered;
    }
  }
  if (stats->num_frames_unregistered > 0) {
    LogWarning("translation averaging: {} of {} frames have no determined position (not "
               "connected to the solved part after filtering); they are unregistered",
               stats->num_frames_unregistered, frames.size());
  }
  return s;
}

// Frame origins (world) being solved, per local index, and the local indices
// held constant (translation gauge).
struct Origins {
  std::vector<Vec3> origins;
  std::vector<size_t> fixed;
};

// Starting origins: the priors (or the first frame of each solved component
// at the origin), LiDAR constraints chained from those, then the current
// poses (init_from_current) or random positions in a cube for the rest.
Origins InitialOrigins(const TranslationAveragingOptions& options, const MapperState& state,
                       const LocalFrames& index, const SolvedFrames& s,
                       const std::vector<LidarLink>& lidar_links) {
  const std::vector<frame_t>& frames = index.frames;
  Origins o;
  o.origins.assign(frames.size(), Vec3::Zero());
  std::vector<bool> initialised(frames.size(), false);
  std::mt19937_64 rng(options.random_seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Vec3 init_center = Vec3::Zero();
  double init_extent = options.random_init_extent;
  if (s.total_priors > 0) {
    Eigen::AlignedBox3d box;
    for (size_t i = 0; i < frames.size(); ++i) {
      if (!s.solved[i] || !s.has_prior[i]) continue;
      o.origins[i] = state.frames.at(frames[i]).prior_position;
      initialised[i] = true;
      box.extend(o.origins[i]);
    }
    init_center = box.center();
    init_extent = std::max(init_extent, 0.5 * box.diagonal().maxCoeff());
  } else {
    for (const size_t root : s.solved_roots) {
      const size_t i = index.local.at(s.components.at(root).first_frame);
      o.origins[i] = Vec3::Zero();
      initialised[i] = true;
      o.fixed.push_back(i);
    }
  }
  // Chain LiDAR constraints (breadth first) from the initialised frames.
  {
    std::vector<std::vector<std::pair<size_t, Vec3>>> lidar_adjacency(frames.size());
    for (const LidarLink& l : lidar_links) {
      const size_t i = index.local.at(l.frame_id1);
      const size_t j = index.local.at(l.frame_id2);
      lidar_adjacency[i].push_back({j, l.delta});
      lidar_adjacency[j].push_back({i, -l.delta});
    }
    std::queue<size_t> queue;
    for (size_t i = 0; i < frames.size(); ++i) {
      if (initialised[i]) queue.push(i);
    }
    Eigen::AlignedBox3d box;
    while (!queue.empty()) {
      const size_t i = queue.front();
      queue.pop();
      box.extend(o.origins[i]);
      for (const auto& [j, delta] : lidar_adjacency[i]) {
        if (initialised[j] || !s.solved[j]) continue;
        o.origins[j] = o.origins[i] + delta;
        initialised[j] = true;
        queue.push(j);
      }
    }
    if (s.total_priors == 0 && !box.isEmpty()) {
      init_center = box.center();
      init_extent = std::max(init_extent, 0.5 * box.diagonal().maxCoeff());
    }
  }
  for (size_t i = 0; i < frames.size(); ++i) {
    if (!s.solved[i]) continue;
    if (options.init_from_current) {
      const SE3& pose = state.frames.at(frames[i]).rig_from_world;
      o.origins[i] = -(pose.rotation().conjugate() * pose.translation());
    } else if (!initialised[i]) {
      o.origins[i] = init_center + init_extent * Vec3(uniform(rng), uniform(rng), uniform(rng));
    }
  }
  return o;
}

// Without priors the random start is replaced by the linear solution (random
// starts of (2) on sparse view graphs end in poor local minima), scaled to the
// LiDAR constraints when there are some.
void LinearStart(const TranslationAveragingOptions& options,
                 const std::vector<DirectionEdge>& edges, const std::vector<size_t>& used_edges,
                 const std::vector<LidarLink>& lidar_links, const LocalFrames& index,
                 const SolvedFrames& s, Origins* o) {
  if (s.total_priors != 0 || options.init_from_current || o->fixed.empty()) return;
  const std::vector<frame_t>& frames = index.frames;
  std::vector<Vec3> linear = o->origins;
  if (!LinearInitialPositions(edges, used_edges, index.local, s.solved, o->fixed[0],
                              options.random_seed, &linear)) {
    LogDebug("translation averaging: linear initialisation failed; other start kept");
    return;
  }
  // With LiDAR constraints, give the linear solution their scale (least squares).
  double numerator = 0.0;
  double denominator = 0.0;
  for (const LidarLink& l : lidar_links) {
    const size_t i = index.local.at(l.frame_id1);
    const size_t j = index.local.at(l.frame_id2);
    if (!s.solved[i] || !s.solved[j]) continue;
    numerator += l.delta.dot(linear[j] - linear[i]);
    denominator += (linear[j] - linear[i]).squaredNorm();
  }
  const double scale = denominator > 0 && numerator > 0 ? numerator / denominator : 1.0;
  const size_t f = o->fixed[0];
  for (size_t i = 0; i < frames.size(); ++i) {
    if (s.solved[i]) o->origins[i] = o->origins[f] + scale * (linear[i] - linear[f]);
  }
}

// One robust solve (Stage 2) of the origins from the used direction edges,
// the priors and the LiDAR links, with the gauge of the header comment.
// Updates the solve counts, gauge and Ceres fields of `stats`.
void SolvePositions(const TranslationAveragingOptions& options, int round,
                    const std::vector<DirectionEdge>& edges,
                    const std::vector<size_t>& used_edges,
                    const std::vector<LidarLink>& lidar_links, const LocalFrames& index,
                    const SolvedFrames& s, const MapperState& state, Origins* o,
                    TranslationAveragingStats* stats) {
  const std::vector<frame_t>& frames = index.frames;
  std::vector<Vec3>& origins = o->origins;
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  std::vector<double> scales(used_edges.size());
  for (size_t k = 0; k < used_edges.size(); ++k) {
    const DirectionEdge& d = edges[used_edges[k]];
    double* origin1 = origins[index.local.at(d.frame_id1)].data();
    double* origin2 = origins[index.local.at(d.frame_id2)].data();
    // Start each scale at its least-squares value for the current positions.
    const Vec3 baseline = (Vec3(origin2) + d.offset2) - (Vec3(origin1) + d.offset1);
    scales[k] = std::max(options.min_edge_scale,
                         d.direction.dot(baseline) / std::max(baseline.squaredNorm(), 1e-12));
    const double loss_scale = options.direction_loss_threshold / options.direction_sigma;
    ceres::LossFunction* loss = nullptr;
    if (options.direction_loss == "huber") {
      loss = new ceres::HuberLoss(loss_scale);
    } else if (options.direction_loss == "cauchy") {
      loss = new ceres::CauchyLoss(loss_scale);
    }
    problem.AddResidualBlock(
        BataDirectionCost::Create(d.direction, d.offset1, d.offset2, options.direction_sigma),
        loss, origin1, origin2, &scales[k]);
    problem.SetParameterLowerBound(&scales[k], 0, options.min_edge_scale);
  }
  stats->num_edges_used = used_edges.size();
  stats->num_prior_residuals = 0;
  stats->num_lidar_residuals = 0;
  size_t num_bad_covariances = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    if (!s.solved[i] || !s.has_prior[i]) continue;
    const SfmFrame& frame = state.frames.at(frames[i]);
    ceres::CostFunction* cost = WhitenedPositionCost::CreatePrior(
        frame.prior_position, frame.prior_position_covariance);
    if (cost == nullptr) {
      ++num_bad_covariances;
      continue;
    }
    problem.AddResidualBlock(cost, nullptr, origins[i].data());
    ++stats->num_prior_residuals;
  }
  for (const LidarLink& l : lidar_links) {
    const size_t i = index.local.at(l.frame_id1);
    const size_t j = index.local.at(l.frame_id2);
    if (!s.solved[i] || !s.solved[j]) continue;
    ceres::CostFunction* cost = WhitenedPositionCost::CreateRelative(l.delta, l.covariance);
    if (cost == nullptr) {
      ++num_bad_covariances;
      continue;
    }
    problem.AddResidualBlock(cost, nullptr, origins[i].data(), origins[j].data());
    ++stats->num_lidar_residuals;
  }
  if (num_bad_covariances > 0 && round == 0) {
    LogWarning("translation averaging: skipped {} priors / LiDAR constraints whose position "
               "covariance is not positive definite",
               num_bad_covariances);
  }
  for (size_t i = 0; i < frames.size(); ++i) {
    if (s.solved[i] && !problem.HasParameterBlock(origins[i].data())) {
      // A frame without residuals (a single-frame component): keeps its value.
      problem.AddParameterBlock(origins[i].data(), 3);
      problem.SetParameterBlockConstant(origins[i].data());
    }
  }

  // Gauge.
  if (stats->num_prior_residuals == 0 && o->fixed.empty()) {
    // Priors were announced but none was usable: fall back to a fixed frame.
    for (const size_t root : s.solved_roots) {
      const size_t i = index.local.at(s.components.at(root).first_frame);
      origins[i].setZero();
      o->fixed.push_back(i);
    }
  }
  if (stats->num_prior_residuals > 0) {
    stats->metric = true;
    stats->gauge = "none fixed: metric, in the frame of the position priors";
  } else {
    for (const size_t i : o->fixed) problem.SetParameterBlockConstant(origins[i].data());
    stats->metric = stats->num_lidar_residuals > 0 || s.rig_metric;
    if (stats->metric) {
      stats->gauge = fmt::format("frame {} fixed at the origin; scale from {}",
                                 frames[o->fixed[0]],
                                 stats->num_lidar_residuals > 0 ? "LiDAR constraints"
                                                                : "rig baselines");
    } else {
      // Scale: left free in the solve (a one-dimensional null space that the
      // Levenberg-Marquardt damping handles, as in GLOMAP; holding one s_ij
      // fixed instead collapses the solution when that edge is an outlier),
      // then fixed by NormaliseScale: the median baseline of the used edges becomes 1.
      stats->gauge = fmt::format(
          "frame {} fixed at the origin; scale: median baseline of the used edges = 1",
          frames[o->fixed[0]]);
    }
  }

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type =
      ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE) ||
              ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE)
          ? ceres::SPARSE_SCHUR
          : ceres::DENSE_SCHUR;
  solver_options.max_num_iterations = options.max_num_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  // One thread by default: Ceres 2.1's multi-threaded Schur elimination and
  // cost sum add up in thread-timing order (not reproducible bit for bit).
  solver_options.num_threads = options.ceres_num_threads;
  solver_options.logging_type = options.verbose ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = options.verbose;
  ceres::Solver::Summary summary;
  if (problem.NumResidualBlocks() > 0) {
    ceres::Solve(solver_options, &problem, &summary);
    stats->converged = summary.IsSolutionUsable();
    stats->iterations += static_cast<int>(summary.iterations.size());
    if (round == 0) stats->initial_cost = summary.initial_cost;
    stats->final_cost = summary.final_cost;
    stats->message = summary.message;
  } else {
    stats->converged = true;
    stats->message = "nothing to solve";
  }
  if (!stats->converged) {
    LogWarning("translation averaging: Ceres found no usable solution ({})", stats->message);
  }
}

// Invalidates the used edges whose direction differs from the solution's
// baseline by more than max_residual_angle_deg (rejected_by =
// "translation_averaging") and removes them from `used_edges`; returns
// whether any was removed.
bool RejectContradictedEdges(const TranslationAveragingOptions& options,
                             const std::vector<DirectionEdge>& edges, const LocalFrames& index,
                             const Origins& o, std::vector<size_t>* used_edges,
                             MapperState* state, TranslationAveragingStats* stats) {
  const double max_angle = options.max_residual_angle_deg * M_PI / 180.0;
  std::vector<size_t> kept;
  for (const size_t e : *used_edges) {
    const DirectionEdge& d = edges[e];
    const Vec3 baseline = (o.origins[index.local.at(d.frame_id2)] + d.offset2) -
                          (o.origins[index.local.at(d.frame_id1)] + d.offset1);
    const double cos_angle = baseline.norm() > 0 ? baseline.normalized().dot(d.direction) : -1.0;
    if (std::acos(std::clamp(cos_angle, -1.0, 1.0)) <= max_angle) {
      kept.push_back(e);
      continue;
    }
    ViewGraphEdge& edge = state->view_graph.edges[d.edge_index];
    edge.valid = false;
    edge.rejected_by = kRejectedResidual;
    ++stats->num_rejected_residual;
  }
  if (kept.size() == used_edges->size()) return false;
  *used_edges = std::move(kept);
  return true;
}

// Explicit scale gauge without metric information: the origins are scaled
// about the fixed frame so that the median baseline of the used edges is 1.
void NormaliseScale(const std::vector<DirectionEdge>& edges,
                    const std::vector<size_t>& used_edges, const LocalFrames& index,
                    const SolvedFrames& s, Origins* o) {
  std::vector<Vec3>& origins = o->origins;
  std::vector<double> baselines;
  for (const size_t e : used_edges) {
    const DirectionEdge& d = edges[e];
    baselines.push_back(((origins[index.local.at(d.frame_id2)] + d.offset2) -
                         (origins[index.local.at(d.frame_id1)] + d.offset1))
                            .norm());
  }
  if (baselines.empty()) return;
  std::nth_element(baselines.begin(), baselines.begin() + baselines.size() / 2, baselines.end());
  const double median = baselines[baselines.size() / 2];
  if (!(median > 0 && std::isfinite(median))) return;
  const Vec3 anchor = origins[o->fixed[0]];
  for (size_t i = 0; i < origins.size(); ++i) {
    if (s.solved[i]) origins[i] = anchor + (origins[i] - anchor) / median;
  }
}

}  // namespace

bool TranslationAveragingOptions::Check() const {
  CHECK_OPTION_GE(num_projections, 1);
  CHECK_OPTION_GE(ceres_num_threads, 1);
  CHECK_OPTION_MSG(min_projection_magnitude,
                   min_projection_magnitude >= 0.0 && min_projection_magnitude < 1.0, "in [0, 1)");
  CHECK_OPTION_MSG(max_broken_ratio, max_broken_ratio >= 0.0 && max_broken_ratio <= 1.0,
                   "in [0, 1]");
  CHECK_OPTION_GE(axis_perturbation_sigma, 0.0);
  CHECK_OPTION_GT(direction_sigma, 0.0);
  CHECK_OPTION_MSG(direction_loss,
                   direction_loss == "huber" || direction_loss == "cauchy" ||
                       direction_loss == "none",
                   "one of huber, cauchy, none");
  CHECK_OPTION_GT(direction_loss_threshold, 0.0);
  CHECK_OPTION_GT(min_edge_scale, 0.0);
  CHECK_OPTION_GE(min_rig_baseline, 0.0);
  CHECK_OPTION_GT(random_init_extent, 0.0);
  CHECK_OPTION_MSG(max_residual_angle_deg, true, "finite");
  CHECK_OPTION_GE(max_num_iterations, 1);
  CHECK_OPTION_GE(function_tolerance, 0.0);
  return true;
}

ceres::CostFunction* WhitenedPositionCost::CreatePrior(const Vec3& prior, const Mat3& covariance) {
  Mat3 w;
  if (!SqrtInformation(covariance, &w)) return nullptr;
  return new ceres::AutoDiffCostFunction<WhitenedPositionCost, 3, 3>(
      new WhitenedPositionCost(prior, w));
}

ceres::CostFunction* WhitenedPositionCost::CreateRelative(const Vec3& delta,
                                                          const Mat3& covariance) {
  Mat3 w;
  if (!SqrtInformation(covariance, &w)) return nullptr;
  return new ceres::AutoDiffCostFunction<WhitenedPositionCost, 3, 3, 3>(
      new WhitenedPositionCost(delta, w));
}

std::vector<size_t> OrderNodesGreedyMfas(size_t num_nodes, const std::vector<OrderingArc>& arcs) {
  // Remaining in/out weights and arc counts (counts decide source / sink exactly).
  std::vector<double> in_weight(num_nodes, 0.0);
  std::vector<double> out_weight(num_nodes, 0.0);
  std::vector<size_t> in_count(num_nodes, 0);
  std::vector<size_t> out_count(num_nodes, 0);
  std::vector<std::vector<size_t>> incident(num_nodes);
  for (size_t a = 0; a < arcs.size(); ++a) {
    const OrderingArc& arc = arcs[a];
    THROW_CHECK_LT(arc.from, num_nodes);
    THROW_CHECK_LT(arc.to, num_nodes);
    if (arc.from == arc.to) continue;  // a self-loop constrains nothing
    out_weight[arc.from] += arc.weight;
    in_weight[arc.to] += arc.weight;
    ++out_count[arc.from];
    ++in_count[arc.to];
    incident[arc.from].push_back(a);
    incident[arc.to].push_back(a);
  }
  auto score = [&](size_t n) { return (out_weight[n] + 1.0) / (in_weight[n] + 1.0); };
  // Highest score first, then the smaller index.
  auto before = [](const std::pair<double, size_t>& a, const std::pair<double, size_t>& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  };
  std::set<std::pair<double, size_t>, decltype(before)> by_score(before);
  std::vector<double> key(num_nodes);
  std::vector<size_t> sources;  // stacks; entries may be stale (checked on pop)
  std::vector<size_t> sinks;
  for (size_t n = num_nodes; n-- > 0;) {
    key[n] = score(n);
    by_score.emplace(key[n], n);
    if (in_count[n] == 0) {
      sources.push_back(n);
    } else if (out_count[n] == 0) {
      sinks.push_back(n);
    }
  }
  std::vector<bool> placed(num_nodes, false);
  std::vector<size_t> front;
  std::vector<size_t> back;  // placed from the end, in reverse
  auto place = [&](size_t node, bool at_front) {
    placed[node] = true;
    by_score.erase({key[node], node});
    (at_front ? front : back).push_back(node);
    for (const size_t a : incident[node]) {
      const OrderingArc& arc = arcs[a];
      const size_t other = arc.from == node ? arc.to : arc.from;
      if (placed[other]) continue;
      by_score.erase({key[other], other});
      if (arc.from == node) {
        in_weight[other] -= arc.weight;
        if (--in_count[other] == 0) sources.push_back(other);
      } else {
        out_weight[other] -= arc.weight;
        if (--out_count[other] == 0) sinks.push_back(other);
      }
      key[other] = score(other);
      by_score.emplace(key[other], other);
    }
  };
  // Eades, Lin & Smyth (1993): sources to the front, sinks to the back, else
  // the node with the best out/in ratio (1dSfM's variant) to the front.
  while (front.size() + back.size() < num_nodes) {
    if (!sources.empty()) {
      const size_t n = sources.back();
      sources.pop_back();
      if (!placed[n] && in_count[n] == 0) place(n, true);
    } else if (!sinks.empty()) {
      const size_t n = sinks.back();
      sinks.pop_back();
      if (!placed[n] && out_count[n] == 0) place(n, false);
    } else {
      place(by_score.begin()->second, true);
    }
  }
  std::vector<size_t> position(num_nodes, 0);
  size_t next = 0;
  for (const size_t n : front) position[n] = next++;
  for (auto it = back.rbegin(); it != back.rend(); ++it) position[*it] = next++;
  return position;
}

size_t FilterEdges1DSfM(const TranslationAveragingOptions& options,
                        const std::vector<frame_t>& frame_ids,
                        MapperState* state) {
  THROW_CHECK(state != nullptr);
  const std::vector<DirectionEdge> edges =
      CollectDirectionEdges(*state, RegisteredFrames(*state, frame_ids));
  const std::vector<bool> rejected = RunFilter1DSfM(options, edges);
  size_t num_rejected = 0;
  for (size_t e = 0; e < edges.size(); ++e) {
    if (!rejected[e]) continue;
    ViewGraphEdge& edge = state->view_graph.edges[edges[e].edge_index];
    edge.valid = false;
    edge.rejected_by = kRejected1DSfM;
    ++num_rejected;
  }
  return num_rejected;
}

TranslationAveragingStats AverageTranslations(const TranslationAveragingOptions& options,
                                              const std::vector<frame_t>& frame_ids,
                                              MapperState* state) {
  THROW_CHECK(state != nullptr);
  if (!options.Check()) {
    const OptionCheckFailure& f = LastOptionCheckFailure();
    throw InputError("translation averaging options", "field TranslationAveraging." + f.name,
                     "expected " + f.requirement + ", found " + f.value);
  }
  const auto start = std::chrono::steady_clock::now();
  TranslationAveragingStats stats;
  const std::unordered_set<frame_t> frame_set = RegisteredFrames(*state, frame_ids);
  stats.num_frames = frame_set.size();
  if (frame_set.empty()) {
    stats.message = "no registered frames";
    stats.seconds = SecondsSince(start);
    return stats;
  }

  // Stage 1: 1dSfM.
  std::vector<DirectionEdge> edges = CollectDirectionEdges(*state, frame_set);
  stats.num_edges_input = edges.size();
  if (options.filter_1dsfm) edges = RejectEdges1DSfM(options, std::move(edges), state, &stats);

  // The frames whose gauge is determined, and their start.
  const LocalFrames index = IndexFrames(frame_set);
  const std::vector<LidarLink> lidar_links = CollectLidarLinks(options, *state, index);
  const SolvedFrames solved = SelectSolvedFrames(options, edges, lidar_links, index, state, &stats);
  Origins origins = InitialOrigins(options, *state, index, solved, lidar_links);
  std::vector<size_t> used_edges;  // into `edges`
  for (size_t e = 0; e < edges.size(); ++e) {
    if (solved.solved[index.local.at(edges[e].frame_id1)] &&
        solved.solved[index.local.at(edges[e].frame_id2)]) {
      used_edges.push_back(e);
    }
  }
  LinearStart(options, edges, used_edges, lidar_links, index, solved, &origins);

  // Stage 2: solved in rounds, the second without the edges that the first
  // solution contradicts.
  const int num_rounds = options.max_residual_angle_deg > 0 ? 2 : 1;
  for (int round = 0; round < num_rounds; ++round) {
    SolvePositions(options, round, edges, used_edges, lidar_links, index, solved, *state,
                   &origins, &stats);
    if (round + 1 == num_rounds) break;
    if (!RejectContradictedEdges(options, edges, index, origins, &used_edges, state, &stats)) {
      break;  // nothing changed: no second round
    }
  }
  if (!stats.metric && !origins.fixed.empty()) {
    NormaliseScale(edges, used_edges, index, solved, &origins);
  }

  // Write back: rig_from_world.t = -R C.
  for (size_t i = 0; i < index.frames.size(); ++i) {
    if (!solved.solved[i]) continue;
    SfmFrame& frame = state->frames.at(index.frames[i]);
    frame.rig_from_world.SetTranslation(-(frame.rig_from_world.rotation() * origins.origins[i]));
    ++stats.num_frames_solved;
  }
  stats.seconds = SecondsSince(start);
  LogInfo("translation averaging: {} of {} frames positioned ({} unregistered); {} direction "
          "edges in, {} rejected by 1dSfM, {} after the solve, {} used; {} priors, {} LiDAR "
          "constraints; {}; {} iterations, cost {:.4g} -> {:.4g}; {:.3f} s (1dSfM {:.3f} s)",
          stats.num_frames_solved, stats.num_frames, stats.num_frames_unregistered,
          stats.num_edges_input, stats.num_rejected_1dsfm, stats.num_rejected_residual,
          stats.num_edges_used, stats.num_prior_residuals, stats.num_lidar_residuals,
          stats.gauge, stats.iterations, stats.initial_cost, stats.final_cost, stats.seconds,
          stats.seconds_1dsfm);
  return stats;
}

}  // namespace colmap
}  // namespace lisfm
