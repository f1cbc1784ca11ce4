#include "colmap_ext/sfm/rotation_averaging.h"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <numeric>
#include <queue>
#include <unordered_map>

#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"

namespace lisfm {
namespace colmap {

bool RotationAveragingOptions::Check() const {
  CHECK_OPTION_GT(max_rotation_error_deg, 0.0);
  CHECK_OPTION_GT(geman_mcclure_sigma_deg, 0.0);
  CHECK_OPTION_GT(max_loop_error_deg, 0.0);
  CHECK_OPTION_GE(max_l1_iterations, 0);
  CHECK_OPTION_GT(l1_tolerance_rad, 0.0);
  CHECK_OPTION_GE(max_irls_iterations, 0);
  CHECK_OPTION_GT(convergence_tolerance_rad, 0.0);
  CHECK_OPTION_GT(relative_rotation_sigma_deg, 0.0);
  CHECK_OPTION_GT(fallback_prior_sigma_rad, 0.0);
  return true;
}

namespace {

constexpr double kDegToRad = M_PI / 180.0;

Quat CamFromRigRotation(const MapperState& state, camera_t camera_id) {
  const auto it = state.cam_from_rig.find(camera_id);
  return it == state.cam_from_rig.end() ? Quat::Identity()
                                        : it->second.rotation();
}

// A relative rotation between frames a and b (indices into the local frame
// list): rotation_ba = R_b R_a^T.
struct Measurement {
  size_t a = 0;
  size_t b = 0;
  Quat rotation_ba = Quat::Identity();
  double information = 1.0;  // 1 / sigma^2 (rad^-2)
  double tree_weight = 0.0;  // spanning-tree priority (larger first)
  int edge_index = -1;       // view-graph edge, or -1 for a LiDAR constraint
  bool active = true;
};

struct Prior {
  bool has = false;
  Quat rotation = Quat::Identity();  // rig_from_world
  double information = 0.0;          // rad^-2
};

class UnionFind {
 public:
  explicit UnionFind(size_t n) : parent_(n) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  size_t Find(size_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  bool Unite(size_t a, size_t b) {
    a = Find(a);
    b = Find(b);
    if (a == b) return false;
    parent_[std::max(a, b)] = std::min(a, b);
    return true;
  }

 private:
  std::vector<size_t> parent_;
};

// Largest connected part (ties: the one with the smallest index) over the
// active measurements; frames with no active measurement are never in it.
std::vector<bool> LargestConnectedPart(
    size_t num_frames, const std::vector<Measurement>& measurements) {
  UnionFind uf(num_frames);
  std::vector<bool> linked(num_frames, false);
  for (const Measurement& m : measurements) {
    if (!m.active) continue;
    uf.Unite(m.a, m.b);
    linked[m.a] = linked[m.b] = true;
  }
  std::vector<size_t> size(num_frames, 0);
  for (size_t i = 0; i < num_frames; ++i) {
    if (linked[i]) ++size[uf.Find(i)];
  }
  size_t best_root = 0, best_size = 0;
  for (size_t i = 0; i < num_frames; ++i) {
    if (size[i] > best_size) {
      best_size = size[i];
      best_root = i;
    }
  }
  std::vector<bool> part(num_frames, false);
  if (best_size == 0) return part;
  for (size_t i = 0; i < num_frames; ++i)
    part[i] = linked[i] && uf.Find(i) == best_root;
  return part;
}

// Residual u_ab = Log(R_a^T R_ba^T R_b) in world coordinates (rad).
Vec3 Residual(const Measurement& m, const std::vector<Quat>& rotations) {
  return so3::Log(rotations[m.a].conjugate() * m.rotation_ba.conjugate() *
                  rotations[m.b]);
}

// Number of triangles (a, b, c) that close within `max_loop_error` (rad)
// through each measurement, using for the other two sides the measurement
// with the largest tree weight of each frame pair (Zach et al., "Disambiguating
// visual relations using loop constraints", CVPR 2010). Outlier relative
// rotations close (almost) no loop, so spanning trees built on this count
// avoid them.
std::vector<int> ConsistentTriangles(
    const std::vector<bool>& part,
    const std::vector<Measurement>& measurements,
    const std::vector<size_t>& used,
    double max_loop_error) {
  const size_t n = part.size();
  // Best measurement per frame pair and the sorted neighbour lists.
  std::unordered_map<uint64_t, size_t> best;
  auto key = [n](size_t a, size_t b) {
    return static_cast<uint64_t>(std::min(a, b)) * n + std::max(a, b);
  };
  for (size_t i : used) {
    const Measurement& m = measurements[i];
    auto [it, inserted] = best.emplace(key(m.a, m.b), i);
    if (!inserted && m.tree_weight > measurements[it->second].tree_weight)
      it->second = i;
  }
  std::vector<std::vector<size_t>> neighbors(n);
  for (const auto& [k, i] : best) {
    neighbors[measurements[i].a].push_back(measurements[i].b);
    neighbors[measurements[i].b].push_back(measurements[i].a);
  }
  for (auto& list : neighbors) std::sort(list.begin(), list.end());
  // Rotation to_from_from implied by the best measurement of a pair.
  auto relative = [&](size_t from, size_t to) {
    const Measurement& m = measurements[best.at(key(from, to))];
    return m.a == from ? m.rotation_ba : m.rotation_ba.conjugate();
  };
  std::vector<int> count(measurements.size(), 0);
  std::vector<size_t> common;
  for (size_t i : used) {
    const Measurement& m = measurements[i];
    common.clear();
    std::set_intersection(neighbors[m.a].begin(),
                          neighbors[m.a].end(),
                          neighbors[m.b].begin(),
                          neighbors[m.b].end(),
                          std::back_inserter(common));
    for (size_t c : common) {
      // a -> b (this measurement) -> c -> a must be the identity.
      const Quat loop = relative(c, m.a) * relative(m.b, c) * m.rotation_ba;
      if (so3::AngularDistance(loop, Quat::Identity()) < max_loop_error)
        ++count[i];
    }
  }
  return count;
}

// Maximum spanning tree (Kruskal) over the active measurements inside `part`,
// ranked by consistent triangles then tree weight; rotations propagated from
// the prior frames (or from `root`).
std::string InitializeRotations(const std::vector<bool>& part,
                                const std::vector<Measurement>& measurements,
                                const std::vector<Prior>& priors,
                                size_t root,
                                double max_loop_error,
                                std::vector<Quat>* rotations) {
  const size_t n = part.size();
  std::vector<size_t> order;
  for (size_t i = 0; i < measurements.size(); ++i) {
    const Measurement& m = measurements[i];
    if (m.active && part[m.a] && part[m.b]) order.push_back(i);
  }
  const std::vector<int> triangles =
      ConsistentTriangles(part, measurements, order, max_loop_error);
  std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) {
    const Measurement& mx = measurements[x];
    const Measurement& my = measurements[y];
    // LiDAR links (infinite weight) first, then loop support, then weight.
    if (std::isinf(mx.tree_weight) != std::isinf(my.tree_weight))
      return std::isinf(mx.tree_weight);
    if (triangles[x] != triangles[y]) return triangles[x] > triangles[y];
    return mx.tree_weight > my.tree_weight;
  });
  UnionFind uf(n);
  std::vector<std::vector<size_t>> tree(n);  // measurement indices per frame
  for (size_t i : order) {
    if (uf.Unite(measurements[i].a, measurements[i].b)) {
      tree[measurements[i].a].push_back(i);
      tree[measurements[i].b].push_back(i);
    }
  }
  std::vector<bool> visited(n, false);
  std::queue<size_t> queue;
  size_t num_priors = 0;
  for (size_t i = 0; i < n; ++i) {
    if (part[i] && priors[i].has) {
      (*rotations)[i] = priors[i].rotation;
      visited[i] = true;
      queue.push(i);
      ++num_priors;
    }
  }
  if (num_priors == 0) {
    visited[root] = true;
    queue.push(root);
  }
  size_t num_propagated = 0;
  while (!queue.empty()) {
    const size_t x = queue.front();
    queue.pop();
    for (size_t mi : tree[x]) {
      const Measurement& m = measurements[mi];
      const size_t y = m.a == x ? m.b : m.a;
      if (visited[y]) continue;
      visited[y] = true;
      // R_b = R_ba R_a, R_a = R_ba^T R_b.
      (*rotations)[y] = (m.a == x ? m.rotation_ba * (*rotations)[x]
                                  : m.rotation_ba.conjugate() * (*rotations)[x])
                            .normalized();
      ++num_propagated;
      queue.push(y);
    }
  }
  if (num_priors == 0) return "spanning_tree";
  return num_propagated == 0 ? "priors" : "priors+spanning_tree";
}

enum class Loss { kHuber, kGemanMcClure };

// IRLS on the linearised problem (header comment). `fixed` is the gauge
// frame or n when the priors fix the gauge. Returns the iterations run and
// sets *converged.
int RefineRotations(const RotationAveragingOptions& options,
                    const std::vector<bool>& part,
                    const std::vector<Measurement>& measurements,
                    const std::vector<Prior>& priors,
                    size_t fixed,
                    Loss loss,
                    int max_iterations,
                    double tolerance,
                    std::vector<Quat>* rotations,
                    bool* converged) {
  const size_t n = part.size();
  std::vector<int> unknown(n, -1);
  int num_unknowns = 0;
  for (size_t i = 0; i < n; ++i) {
    if (part[i] && i != fixed) unknown[i] = num_unknowns++;
  }
  *converged = false;
  if (num_unknowns == 0) {
    *converged = true;
    return 0;
  }
  const double huber = options.relative_rotation_sigma_deg * kDegToRad;
  const double sigma_gm = options.geman_mcclure_sigma_deg * kDegToRad;
  auto robust_weight = [&](double r) {
    if (loss == Loss::kHuber) return r <= huber ? 1.0 : huber / r;
    const double s2 = sigma_gm * sigma_gm;
    const double w = s2 / (s2 + r * r);
    return w * w;
  };
  int iteration = 0;
  for (; iteration < max_iterations; ++iteration) {
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::MatrixX3d rhs = Eigen::MatrixX3d::Zero(num_unknowns, 3);
    for (const Measurement& m : measurements) {
      if (!m.active || !part[m.a] || !part[m.b]) continue;
      const Vec3 u = Residual(m, *rotations);
      const double w = m.information * robust_weight(u.norm());
      // Minimise w |w_b - w_a + u|^2.
      const int ia = unknown[m.a], ib = unknown[m.b];
      if (ia >= 0) {
        triplets.emplace_back(ia, ia, w);
        rhs.row(ia) += w * u.transpose();
      }
      if (ib >= 0) {
        triplets.emplace_back(ib, ib, w);
        rhs.row(ib) -= w * u.transpose();
      }
      if (ia >= 0 && ib >= 0) {
        triplets.emplace_back(ia, ib, -w);
        triplets.emplace_back(ib, ia, -w);
      }
    }
    for (size_t i = 0; i < n; ++i) {
      if (unknown[i] < 0 || !priors[i].has) continue;
      // Minimise w_p |w_i + u_i|^2, u_i = Log(R_prior^T R_i).
      const Vec3 u = so3::Log(priors[i].rotation.conjugate() * (*rotations)[i]);
      triplets.emplace_back(unknown[i], unknown[i], priors[i].information);
      rhs.row(unknown[i]) -= priors[i].information * u.transpose();
    }
    Eigen::SparseMatrix<double> lhs(num_unknowns, num_unknowns);
    lhs.setFromTriplets(triplets.begin(), triplets.end());
    // Conjugate gradients with an incomplete-Cholesky preconditioner: exact
    // in one step for chain-like (sequence) graphs, whose factor has no
    // fill-in, and a few iterations for well-connected graphs, where a
    // direct factorisation of the Laplacian fills in (random graphs of
    // 1000 frames: ~0.2 s per solve with SimplicialLDLT).
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double>,
                             Eigen::Lower | Eigen::Upper,
                             Eigen::IncompleteCholesky<double>>
        solver;
    solver.setTolerance(1e-10);
    solver.compute(lhs);
    if (solver.info() != Eigen::Success) {
      LogWarning("Rotation averaging: singular linear system at iteration {}",
                 iteration);
      break;
    }
    const Eigen::MatrixX3d step = solver.solve(rhs);
    double max_step = 0.0;
    for (size_t i = 0; i < n; ++i) {
      if (unknown[i] < 0) continue;
      const Vec3 w = step.row(unknown[i]).transpose();
      (*rotations)[i] = ((*rotations)[i] * so3::Exp(w)).normalized();
      max_step = std::max(max_step, w.norm());
    }
    if (max_step < tolerance) {
      *converged = true;
      ++iteration;
      break;
    }
  }
  return iteration;
}

}  // namespace

Quat RelativeFrameRotation(const MapperState& state,
                           const ViewGraphEdge& edge) {
  const SfmImage& image1 = state.images.at(edge.image_id1);
  const SfmImage& image2 = state.images.at(edge.image_id2);
  const Quat c1 = CamFromRigRotation(state, image1.camera_id);
  const Quat c2 = CamFromRigRotation(state, image2.camera_id);
  // R_b R_a^T = C_j^T R_ij C_i (header comment).
  return (c2.conjugate() * edge.cam2_from_cam1.rotation() * c1).normalized();
}

RotationAveragingStats AverageRotations(const RotationAveragingOptions& options,
                                        const std::vector<frame_t>& frame_ids,
                                        MapperState* state) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  RotationAveragingStats stats;
  stats.num_input_frames = frame_ids.size();

  const size_t n = frame_ids.size();
  std::unordered_map<frame_t, size_t> index;
  std::vector<Quat> rotations(n);
  std::vector<Prior> priors(n);
  for (size_t i = 0; i < n; ++i) {
    const auto it = state->frames.find(frame_ids[i]);
    THROW_CHECK_MSG(it != state->frames.end(),
                    "unknown frame " << frame_ids[i]);
    THROW_CHECK_MSG(index.emplace(frame_ids[i], i).second,
                    "duplicate frame " << frame_ids[i]);
    const SfmFrame& frame = it->second;
    rotations[i] = frame.rig_from_world.rotation();
    if (options.use_rotation_priors && frame.has_prior_rotation) {
      const double sigma = frame.prior_rotation_sigma > 0.0
                               ? frame.prior_rotation_sigma
                               : options.fallback_prior_sigma_rad;
      priors[i].has = true;
      priors[i].rotation = frame.prior_rig_from_world_rotation.normalized();
      priors[i].information = 1.0 / (sigma * sigma);
    }
  }

  // Measurements.
  const double edge_sigma = options.relative_rotation_sigma_deg * kDegToRad;
  const double edge_information = 1.0 / (edge_sigma * edge_sigma);
  std::vector<Measurement> measurements;
  double weight_sum = 0.0;
  for (size_t e = 0; e < state->view_graph.edges.size(); ++e) {
    const ViewGraphEdge& edge = state->view_graph.edges[e];
    if (!edge.valid) continue;
    const auto it1 = state->images.find(edge.image_id1);
    const auto it2 = state->images.find(edge.image_id2);
    THROW_CHECK_MSG(it1 != state->images.end() && it2 != state->images.end(),
                    "view-graph edge with unknown images "
                        << edge.image_id1 << ", " << edge.image_id2);
    const frame_t frame1 = it1->second.frame_id, frame2 = it2->second.frame_id;
    if (frame1 == frame2) continue;
    const auto ia = index.find(frame1), ib = index.find(frame2);
    if (ia == index.end() || ib == index.end()) continue;
    Measurement m;
    m.a = ia->second;
    m.b = ib->second;
    m.rotation_ba = RelativeFrameRotation(*state, edge);
    m.information = edge_information;
    m.tree_weight = edge.weight;
    m.edge_index = static_cast<int>(e);
    measurements.push_back(m);
    weight_sum += edge.weight;
  }
  stats.num_edge_measurements = measurements.size();
  if (options.weight_by_num_inliers && weight_sum > 0.0) {
    const double mean_weight = weight_sum / measurements.size();
    for (Measurement& m : measurements) {
      m.information *=
          state->view_graph.edges[m.edge_index].weight / mean_weight;
    }
  }
  if (options.use_lidar_constraints) {
    for (const LidarConstraint& constraint : state->lidar_constraints) {
      const auto ia = index.find(constraint.frame_id1),
                 ib = index.find(constraint.frame_id2);
      if (ia == index.end() || ib == index.end() || ia->second == ib->second)
        continue;
      const double variance =
          constraint.covariance.topLeftCorner<3, 3>().trace() / 3.0;
      Measurement m;
      m.a = ia->second;
      m.b = ib->second;
      // rig_a_from_rig_b: R_a R_b^T = R_ab  =>  R_b R_a^T = R_ab^T.
      m.rotation_ba = constraint.rig1_from_rig2.rotation().conjugate();
      m.information = variance > 0.0 ? 1.0 / variance : edge_information;
      m.tree_weight = std::numeric_limits<double>::infinity();
      measurements.push_back(m);
      ++stats.num_lidar_measurements;
    }
  }

  auto gauge_frame = [&](const std::vector<bool>& part) {
    for (size_t i = 0; i < n; ++i) {
      if (part[i] && priors[i].has) return n;  // priors fix the gauge
    }
    for (size_t i = 0; i < n; ++i) {
      if (part[i]) return i;  // first frame of frame_ids in the part
    }
    return n;
  };
  // Invalidates edges above the threshold; returns how many.
  const double max_error = options.max_rotation_error_deg * kDegToRad;
  auto reject = [&](const std::vector<bool>& part) {
    size_t num_rejected = 0;
    for (Measurement& m : measurements) {
      if (!m.active || m.edge_index < 0 || !part[m.a] || !part[m.b]) continue;
      if (Residual(m, rotations).norm() > max_error) {
        m.active = false;
        ViewGraphEdge& edge = state->view_graph.edges[m.edge_index];
        edge.valid = false;
        edge.rejected_by = "rotation_averaging";
        ++num_rejected;
      }
    }
    return num_rejected;
  };

  std::vector<bool> part = LargestConnectedPart(n, measurements);
  if (std::find(part.begin(), part.end(), true) != part.end()) {
    size_t fixed = gauge_frame(part);
    stats.initialization =
        InitializeRotations(part,
                            measurements,
                            priors,
                            fixed == n ? 0 : fixed,
                            options.max_loop_error_deg * kDegToRad,
                            &rotations);
    for (size_t i = 0; i < n; ++i)
      stats.num_prior_frames += part[i] && priors[i].has;
    bool converged = false;
    stats.num_iterations += RefineRotations(options,
                                            part,
                                            measurements,
                                            priors,
                                            fixed,
                                            Loss::kHuber,
                                            options.max_l1_iterations,
                                            options.l1_tolerance_rad,
                                            &rotations,
                                            &converged);
    stats.num_iterations += RefineRotations(options,
                                            part,
                                            measurements,
                                            priors,
                                            fixed,
                                            Loss::kGemanMcClure,
                                            options.max_irls_iterations,
                                            options.convergence_tolerance_rad,
                                            &rotations,
                                            &converged);
    stats.num_rejected_edges = reject(part);
    if (stats.num_rejected_edges > 0) {
      part = LargestConnectedPart(n, measurements);
      fixed = gauge_frame(part);
      stats.num_iterations += RefineRotations(options,
                                              part,
                                              measurements,
                                              priors,
                                              fixed,
                                              Loss::kGemanMcClure,
                                              options.max_irls_iterations,
                                              options.convergence_tolerance_rad,
                                              &rotations,
                                              &converged);
      stats.num_rejected_edges += reject(part);
      part = LargestConnectedPart(n, measurements);
    }
    stats.converged = converged;
  }

  size_t num_residuals = 0;
  for (const Measurement& m : measurements) {
    if (!m.active || m.edge_index < 0 || !part[m.a] || !part[m.b]) continue;
    const double r = Residual(m, rotations).norm() / kDegToRad;
    stats.mean_residual_deg += r;
    stats.max_residual_deg = std::max(stats.max_residual_deg, r);
    ++num_residuals;
  }
  if (num_residuals > 0) stats.mean_residual_deg /= num_residuals;
  for (size_t i = 0; i < n; ++i) {
    SfmFrame& frame = state->frames.at(frame_ids[i]);
    frame.registered = part[i];
    if (part[i]) {
      frame.rig_from_world.SetRotation(rotations[i]);
      ++stats.num_registered_frames;
    }
  }
  stats.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  LogInfo(
      "Rotation averaging: {} of {} frames registered ({} edges, {} LiDAR, {} "
      "priors; init "
      "{}), {} edges rejected, {} iterations{}, residual mean {:.3f} max "
      "{:.3f} deg, {:.2f} s",
      stats.num_registered_frames,
      stats.num_input_frames,
      stats.num_edge_measurements,
      stats.num_lidar_measurements,
      stats.num_prior_frames,
      stats.initialization.empty() ? "none" : stats.initialization,
      stats.num_rejected_edges,
      stats.num_iterations,
      stats.converged ? "" : " (not converged)",
      stats.mean_residual_deg,
      stats.max_residual_deg,
      stats.seconds);
  return stats;
}

}  // namespace colmap
}  // namespace lisfm
