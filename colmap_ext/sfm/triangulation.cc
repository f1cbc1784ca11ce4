#include "colmap_ext/sfm/triangulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <unordered_map>
#include <vector>

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "colmap_ext/sfm/camera_model_functors.h"
#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"

namespace lisfm {
namespace colmap {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = 3.14159265358979323846;

// Pose and camera of one registered image, computed once per call.
struct ImageGeometry {
  Mat3 rotation;  // cam_from_world
  Vec3 translation;
  Vec3 center;  // camera centre in world
  const Camera* camera = nullptr;
  const SfmImage* image = nullptr;
};

using GeometryMap = std::unordered_map<image_t, ImageGeometry>;

GeometryMap RegisteredGeometry(const MapperState& state) {
  GeometryMap geometry;
  for (const auto& [image_id, image] : state.images) {
    if (!state.IsRegistered(image_id)) continue;
    const auto camera = state.cameras.find(image.camera_id);
    THROW_CHECK_MSG(camera != state.cameras.end(),
                    "image " << image_id << " has unknown camera " << image.camera_id);
    const SE3 cam_from_world = state.CamFromWorld(image_id);
    ImageGeometry g;
    g.rotation = cam_from_world.RotationMatrix();
    g.translation = cam_from_world.translation();
    g.center = -g.rotation.transpose() * g.translation;
    g.camera = &camera->second;
    g.image = &image;
    geometry.emplace(image_id, g);
  }
  return geometry;
}

// One observation of a track in a registered image.
struct Observation {
  const ImageGeometry* geometry = nullptr;
  Vec2 pixel;       // COLMAP pixels
  Vec2 normalized;  // undistorted, z = 1
};

Observation MakeObservation(const ImageGeometry& g, const TrackElement& element) {
  const SfmImage& image = *g.image;
  THROW_CHECK_MSG(element.point2D_idx < image.keypoints.size(),
                  "track element " << element.point2D_idx << " out of range for image "
                                   << element.image_id);
  Observation obs;
  obs.geometry = &g;
  obs.pixel = image.keypoints[element.point2D_idx];
  obs.normalized = image.normalized.size() == image.keypoints.size()
                       ? image.normalized[element.point2D_idx]
                       : g.camera->CamFromImg(obs.pixel);
  return obs;
}

// Depth of X in the observation's camera and its pixel error (kInf when the
// point does not project).
struct Residual {
  double depth = 0.0;
  double error = kInf;
};

Residual Evaluate(const Observation& obs, const Vec3& xyz) {
  Residual r;
  const Vec3 x_in_cam = obs.geometry->rotation * xyz + obs.geometry->translation;
  r.depth = x_in_cam.z();
  Vec2 pixel;
  if (obs.geometry->camera->Project(x_in_cam, &pixel)) r.error = (pixel - obs.pixel).norm();
  return r;
}

bool Passes(const Residual& r, double max_error) {
  return r.depth > 0.0 && r.error <= max_error;
}

// Largest pairwise angle (rad) between the rays from the camera centres to X.
double MaxTriangulationAngle(const std::vector<const Observation*>& obs, const Vec3& xyz) {
  std::vector<Vec3> rays;
  rays.reserve(obs.size());
  for (const Observation* o : obs) rays.push_back((xyz - o->geometry->center).normalized());
  double min_cos = 1.0;
  for (size_t i = 0; i < rays.size(); ++i) {
    for (size_t j = i + 1; j < rays.size(); ++j) min_cos = std::min(min_cos, rays[i].dot(rays[j]));
  }
  return std::acos(std::clamp(min_cos, -1.0, 1.0));
}

// Step 1: DLT on normalised coordinates; false for a point at infinity. The
// null vector of A is the eigenvector of the 4x4 A^T A for its smallest
// eigenvalue (as in COLMAP's TriangulateMultiViewPoint); rows are scaled to
// unit norm first, which balances the equations without changing the null
// space. Its accuracy only has to seed the refinement of step 2.
bool TriangulateLinear(const std::vector<const Observation*>& obs, Vec3* xyz) {
  Eigen::Matrix4d ata = Eigen::Matrix4d::Zero();
  for (const Observation* o : obs) {
    Eigen::Matrix<double, 3, 4> p;
    p.leftCols<3>() = o->geometry->rotation;
    p.col(3) = o->geometry->translation;
    const Vec2& x = o->normalized;
    for (int k = 0; k < 2; ++k) {
      Eigen::RowVector4d row = x(k) * p.row(2) - p.row(k);
      const double n = row.norm();
      if (n > 0.0) row /= n;
      ata += row.transpose() * row;
    }
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> solver(ata);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::Vector4d h = solver.eigenvectors().col(0);  // smallest eigenvalue
  if (!(std::abs(h(3)) > 1e-12 * h.head<3>().norm())) return false;
  *xyz = h.head<3>() / h(3);
  return xyz->allFinite();
}

// Sum of squared pixel errors and, when jtj is given, J^T J and J^T r of the
// stacked (2N x 3) Jacobian (analytic projection, camera_model_functors.h); observations behind the camera contribute nothing
// to the Jacobian and kInf to the cost.
double Cost(const std::vector<const Observation*>& obs,
            const Vec3& xyz,
            Mat3* jtj,
            Vec3* jtr) {
  double cost = 0.0;
  if (jtj != nullptr) {
    jtj->setZero();
    jtr->setZero();
  }
  for (const Observation* o : obs) {
    const Vec3 x_in_cam = o->geometry->rotation * xyz + o->geometry->translation;
    if (!(x_in_cam.z() > 0.0)) return kInf;
    const Camera& camera = *o->geometry->camera;
    Vec2 pixel;
    Eigen::Matrix<double, 2, 3> d_pixel_d_cam;
    VisitCameraModel(camera.model_id, [&](auto model) {
      using Model = decltype(model);
      ProjectWithJacobians<Model>(camera.params.data(), x_in_cam, &pixel,
                                  jtj != nullptr ? &d_pixel_d_cam : nullptr, nullptr);
    });
    const Vec2 r = pixel - o->pixel;
    if (!r.allFinite()) return kInf;
    cost += r.squaredNorm();
    if (jtj == nullptr) continue;
    const Eigen::Matrix<double, 2, 3> j = d_pixel_d_cam * o->geometry->rotation;
    *jtj += j.transpose() * j;
    *jtr += j.transpose() * r;
  }
  return cost;
}

// Step 2: Levenberg-Marquardt on the pixel reprojection error.
void RefinePoint(const std::vector<const Observation*>& obs, int iterations, Vec3* xyz) {
  Mat3 jtj;
  Vec3 jtr;
  double cost = Cost(obs, *xyz, &jtj, &jtr);
  if (!std::isfinite(cost)) return;
  double lambda = 1e-4 * jtj.diagonal().mean();
  for (int it = 0; it < iterations; ++it) {
    Mat3 damped = jtj;
    damped.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
    const Vec3 step = damped.ldlt().solve(-jtr);
    if (!step.allFinite()) return;
    const Vec3 candidate = *xyz + step;
    Mat3 jtj_new;
    Vec3 jtr_new;
    const double cost_new = Cost(obs, candidate, &jtj_new, &jtr_new);
    if (cost_new < cost) {
      *xyz = candidate;
      cost = cost_new;
      jtj = jtj_new;
      jtr = jtr_new;
      lambda = std::max(lambda * 0.1, 1e-15);
      // Converged: the step is below ~1e-10 of the point's scale.
      if (step.norm() <= 1e-10 * (1.0 + xyz->norm())) return;
    } else {
      lambda *= 10.0;
      if (lambda > 1e12 * (1.0 + jtj.diagonal().mean())) return;
    }
  }
}

enum class Outcome { kTriangulated, kDepth, kReprojection, kAngle, kDegenerate };

// What happened to one track; `passes` is parallel to the candidates.
struct TrackSolution {
  Outcome outcome = Outcome::kDegenerate;
  bool robust = false;
  Vec3 xyz = Vec3::Zero();
  std::vector<Residual> residuals;
  std::vector<char> passes;
  size_t num_passing = 0;
  double error_sum = 0.0;  // over passing observations
};

void Classify(const std::vector<Observation>& candidates,
              double max_error,
              const Vec3& xyz,
              TrackSolution* s) {
  s->xyz = xyz;
  s->residuals.resize(candidates.size());
  s->passes.assign(candidates.size(), 0);
  s->num_passing = 0;
  s->error_sum = 0.0;
  for (size_t i = 0; i < candidates.size(); ++i) {
    s->residuals[i] = Evaluate(candidates[i], xyz);
    if (Passes(s->residuals[i], max_error)) {
      s->passes[i] = 1;
      ++s->num_passing;
      s->error_sum += s->residuals[i].error;
    }
  }
}

bool Better(const TrackSolution& a, const TrackSolution& b) {
  return a.num_passing > b.num_passing ||
         (a.num_passing == b.num_passing && a.error_sum < b.error_sum);
}

// Steps 1 + 2 on a subset, then step 3's per-observation checks on all.
// Pair hypotheses skip step 2 (refine = false); the re-fit on their inliers
// refines.
bool Fit(const std::vector<Observation>& candidates,
         const std::vector<const Observation*>& subset,
         const TriangulationOptions& options,
         bool refine,
         TrackSolution* s) {
  Vec3 xyz;
  if (!TriangulateLinear(subset, &xyz)) return false;
  if (refine) RefinePoint(subset, options.num_refinement_iterations, &xyz);
  Classify(candidates, options.max_reprojection_error_px, xyz, s);
  return true;
}

std::vector<const Observation*> Passing(const std::vector<Observation>& candidates,
                                        const TrackSolution& s) {
  std::vector<const Observation*> out;
  for (size_t i = 0; i < candidates.size(); ++i) {
    if (s.passes[i]) out.push_back(&candidates[i]);
  }
  return out;
}

TrackSolution SolveTrack(const std::vector<Observation>& candidates,
                         const TriangulationOptions& options) {
  const double min_angle = options.min_triangulation_angle_deg * kPi / 180.0;
  TrackSolution best;
  std::vector<const Observation*> all;
  for (const Observation& o : candidates) all.push_back(&o);
  bool have_best = Fit(candidates, all, options, /*refine=*/true, &best);

  if (!have_best || best.num_passing < candidates.size()) {
    // Robust step: pair hypotheses, evenly spread over the pair list.
    best.robust = true;
    const size_t n = candidates.size();
    const size_t num_pairs = n * (n - 1) / 2;
    const size_t max_pairs = static_cast<size_t>(options.max_hypothesis_pairs);
    const double stride = num_pairs > max_pairs ? static_cast<double>(num_pairs) / max_pairs : 1.0;
    const size_t num_tries = std::min(num_pairs, max_pairs);
    size_t next = 0, pair_index = 0, tries = 0;
    for (size_t i = 0; i < n && tries < num_tries; ++i) {
      for (size_t j = i + 1; j < n && tries < num_tries; ++j, ++pair_index) {
        if (pair_index != next) continue;
        ++tries;
        next = static_cast<size_t>(std::floor(tries * stride));
        const std::vector<const Observation*> pair = {&candidates[i], &candidates[j]};
        TrackSolution hypothesis;
        if (!Fit(candidates, pair, options, /*refine=*/false, &hypothesis)) continue;
        if (MaxTriangulationAngle(pair, hypothesis.xyz) < min_angle) continue;
        if (!have_best || Better(hypothesis, best)) {
          hypothesis.robust = true;
          best = std::move(hypothesis);
          have_best = true;
        }
      }
    }
    // Re-fit on the inliers while the inlier set improves.
    // The re-fit (maximum likelihood on all inliers) replaces the hypothesis
    // unless it loses inliers.
    for (int round = 0; have_best && round < 2 && best.num_passing >= 2; ++round) {
      TrackSolution refit;
      if (!Fit(candidates, Passing(candidates, best), options, /*refine=*/true, &refit)) break;
      if (refit.num_passing < best.num_passing) break;
      const bool grew = refit.num_passing > best.num_passing;
      refit.robust = true;
      best = std::move(refit);
      if (!grew) break;
    }
  }
  if (!have_best) {
    best.outcome = Outcome::kDegenerate;
    return best;
  }
  if (best.num_passing < 2) {
    size_t num_positive = 0;
    for (const Residual& r : best.residuals) num_positive += r.depth > 0.0 ? 1 : 0;
    best.outcome = num_positive < 2 ? Outcome::kDepth : Outcome::kReprojection;
    return best;
  }
  best.outcome = MaxTriangulationAngle(Passing(candidates, best), best.xyz) < min_angle
                     ? Outcome::kAngle
                     : Outcome::kTriangulated;
  return best;
}

// Per-track counters, summed in track order after the parallel loop.
struct TrackCounts {
  bool considered = false;
  Outcome outcome = Outcome::kDegenerate;
  bool robust = false;
  size_t rejected_depth = 0;
  size_t rejected_reprojection = 0;
  size_t unregistered = 0;
  size_t added = 0;  // RetriangulateTracks
  bool untriangulated_few = false;
  bool untriangulated_angle = false;
};

template <typename Fn>
void ParallelOverTracks(int num_threads, size_t num_tracks, Fn&& fn) {
  tbb::task_arena arena(num_threads > 0 ? num_threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, num_tracks),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t t = range.begin(); t != range.end(); ++t) fn(t);
                      });
  });
}

void SortByImage(std::vector<TrackElement>* elements) {
  std::sort(elements->begin(), elements->end(), [](const TrackElement& a, const TrackElement& b) {
    return a.image_id < b.image_id ||
           (a.image_id == b.image_id && a.point2D_idx < b.point2D_idx);
  });
}

// Splits `elements` into observations of registered images (candidates, with
// their elements) and the rest (appended to `unregistered`).
void Gather(const GeometryMap& geometry,
            const std::vector<TrackElement>& elements,
            std::vector<Observation>* candidates,
            std::vector<TrackElement>* candidate_elements,
            std::vector<TrackElement>* unregistered) {
  for (const TrackElement& e : elements) {
    const auto it = geometry.find(e.image_id);
    if (it == geometry.end()) {
      unregistered->push_back(e);
      continue;
    }
    candidates->push_back(MakeObservation(it->second, e));
    candidate_elements->push_back(e);
  }
}

// Applies a solution to a track: passing candidates become `elements`, the
// others go to `rejected` (with `kept_rejected` and `unregistered`).
void Apply(const TrackSolution& s,
           const std::vector<TrackElement>& candidate_elements,
           std::vector<TrackElement> kept_rejected,
           const std::vector<TrackElement>& unregistered,
           Track* track,
           TrackCounts* counts) {
  track->elements.clear();
  track->rejected = std::move(kept_rejected);
  double error_sum = 0.0;
  for (size_t i = 0; i < candidate_elements.size(); ++i) {
    if (s.passes[i]) {
      track->elements.push_back(candidate_elements[i]);
      error_sum += s.residuals[i].error;
    } else {
      track->rejected.push_back(candidate_elements[i]);
      if (s.residuals[i].depth > 0.0) {
        ++counts->rejected_reprojection;
      } else {
        ++counts->rejected_depth;
      }
    }
  }
  track->rejected.insert(track->rejected.end(), unregistered.begin(), unregistered.end());
  SortByImage(&track->elements);
  SortByImage(&track->rejected);
  track->xyz = s.xyz;
  track->triangulated = true;
  track->error = error_sum / static_cast<double>(track->elements.size());
}

void UpdateError(const GeometryMap& geometry, Track* track) {
  double sum = 0.0;
  for (const TrackElement& e : track->elements) {
    sum += Evaluate(MakeObservation(geometry.at(e.image_id), e), track->xyz).error;
  }
  track->error = track->elements.empty() ? -1.0 : sum / static_cast<double>(track->elements.size());
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

bool TriangulationOptions::Check() const {
  CHECK_OPTION_GT(max_reprojection_error_px, 0.0);
  CHECK_OPTION_MSG(min_triangulation_angle_deg,
                   min_triangulation_angle_deg >= 0.0 && min_triangulation_angle_deg < 180.0,
                   "in [0, 180)");
  CHECK_OPTION_GE(num_refinement_iterations, 0);
  CHECK_OPTION_GE(max_hypothesis_pairs, 1);
  CHECK_OPTION_MSG(num_threads, num_threads == -1 || num_threads >= 1, "-1 or >= 1");
  return true;
}

TriangulationStats TriangulateTracks(const TriangulationOptions& options, MapperState* state) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  const GeometryMap geometry = RegisteredGeometry(*state);
  std::vector<TrackCounts> counts(state->tracks.size());

  ParallelOverTracks(options.num_threads, state->tracks.size(), [&](size_t t) {
    Track& track = state->tracks[t];
    TrackCounts& c = counts[t];
    std::vector<Observation> candidates;
    std::vector<TrackElement> candidate_elements, unregistered;
    Gather(geometry, track.elements, &candidates, &candidate_elements, &unregistered);
    c.unregistered = unregistered.size();
    if (!unregistered.empty()) {
      track.elements = candidate_elements;
      track.rejected.insert(track.rejected.end(), unregistered.begin(), unregistered.end());
      SortByImage(&track.rejected);
    }
    track.triangulated = false;
    track.error = -1.0;
    if (candidates.size() < 2) return;
    c.considered = true;
    const TrackSolution s = SolveTrack(candidates, options);
    c.outcome = s.outcome;
    c.robust = s.robust;
    if (s.outcome != Outcome::kTriangulated) return;
    Apply(s, candidate_elements, track.rejected, {}, &track, &c);
  });

  TriangulationStats stats;
  double error_sum = 0.0;
  for (size_t t = 0; t < counts.size(); ++t) {
    const TrackCounts& c = counts[t];
    stats.num_observations_unregistered += c.unregistered;
    if (!c.considered) continue;
    ++stats.num_tracks_considered;
    stats.num_tracks_robust += c.robust ? 1 : 0;
    switch (c.outcome) {
      case Outcome::kTriangulated: {
        const Track& track = state->tracks[t];
        ++stats.num_tracks_triangulated;
        stats.num_observations_rejected_depth += c.rejected_depth;
        stats.num_observations_rejected_reprojection += c.rejected_reprojection;
        stats.num_observations += track.elements.size();
        error_sum += track.error * static_cast<double>(track.elements.size());
        break;
      }
      case Outcome::kDepth: ++stats.num_tracks_failed_depth; break;
      case Outcome::kReprojection: ++stats.num_tracks_failed_reprojection; break;
      case Outcome::kAngle: ++stats.num_tracks_failed_angle; break;
      case Outcome::kDegenerate: ++stats.num_tracks_failed_degenerate; break;
    }
  }
  stats.mean_reprojection_error_px =
      stats.num_observations > 0 ? error_sum / static_cast<double>(stats.num_observations) : 0.0;
  stats.seconds = SecondsSince(start);
  LogInfo(
      "triangulation: {} of {} tracks triangulated ({} observations, mean error {:.3f} px, {} "
      "robust); failed: {} depth, {} reprojection, {} angle, {} degenerate; rejected "
      "observations: {} depth, {} reprojection, {} unregistered; {:.3f} s",
      stats.num_tracks_triangulated, stats.num_tracks_considered, stats.num_observations,
      stats.mean_reprojection_error_px, stats.num_tracks_robust, stats.num_tracks_failed_depth,
      stats.num_tracks_failed_reprojection, stats.num_tracks_failed_angle,
      stats.num_tracks_failed_degenerate, stats.num_observations_rejected_depth,
      stats.num_observations_rejected_reprojection, stats.num_observations_unregistered,
      stats.seconds);
  return stats;
}

FilterStats FilterTracks(const TriangulationOptions& options, MapperState* state) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  const GeometryMap geometry = RegisteredGeometry(*state);
  const double min_angle = options.min_triangulation_angle_deg * kPi / 180.0;
  std::vector<TrackCounts> counts(state->tracks.size());

  ParallelOverTracks(options.num_threads, state->tracks.size(), [&](size_t t) {
    Track& track = state->tracks[t];
    if (!track.triangulated) return;
    TrackCounts& c = counts[t];
    c.considered = true;
    std::vector<Observation> kept;
    std::vector<TrackElement> kept_elements;
    for (const TrackElement& e : track.elements) {
      const auto it = geometry.find(e.image_id);
      if (it == geometry.end()) {
        ++c.unregistered;
        track.rejected.push_back(e);
        continue;
      }
      Observation obs = MakeObservation(it->second, e);
      const Residual r = Evaluate(obs, track.xyz);
      if (Passes(r, options.max_reprojection_error_px)) {
        kept.push_back(obs);
        kept_elements.push_back(e);
      } else {
        track.rejected.push_back(e);
        if (r.depth > 0.0) {
          ++c.rejected_reprojection;
        } else {
          ++c.rejected_depth;
        }
      }
    }
    track.elements = std::move(kept_elements);
    SortByImage(&track.rejected);
    std::vector<const Observation*> kept_ptrs;
    for (const Observation& o : kept) kept_ptrs.push_back(&o);
    if (kept.size() < 2) {
      c.untriangulated_few = true;
    } else if (MaxTriangulationAngle(kept_ptrs, track.xyz) < min_angle) {
      c.untriangulated_angle = true;
    }
    if (c.untriangulated_few || c.untriangulated_angle) {
      track.triangulated = false;
      track.error = -1.0;
    } else {
      UpdateError(geometry, &track);
    }
  });

  FilterStats stats;
  for (size_t t = 0; t < counts.size(); ++t) {
    const TrackCounts& c = counts[t];
    if (!c.considered) continue;
    ++stats.num_tracks_checked;
    stats.num_observations_rejected_depth += c.rejected_depth;
    stats.num_observations_rejected_reprojection += c.rejected_reprojection;
    stats.num_observations_unregistered += c.unregistered;
    stats.num_tracks_untriangulated_few_observations += c.untriangulated_few ? 1 : 0;
    stats.num_tracks_untriangulated_angle += c.untriangulated_angle ? 1 : 0;
    if (state->tracks[t].triangulated) {
      ++stats.num_tracks_triangulated;
      stats.num_observations += state->tracks[t].elements.size();
    }
  }
  stats.seconds = SecondsSince(start);
  LogInfo(
      "filter: {} of {} tracks kept ({} observations); rejected observations: {} depth, {} "
      "reprojection, {} unregistered; untriangulated: {} with < 2 observations, {} by angle; "
      "{:.3f} s",
      stats.num_tracks_triangulated, stats.num_tracks_checked, stats.num_observations,
      stats.num_observations_rejected_depth, stats.num_observations_rejected_reprojection,
      stats.num_observations_unregistered, stats.num_tracks_untriangulated_few_observations,
      stats.num_tracks_untriangulated_angle, stats.seconds);
  return stats;
}

size_t RetriangulateTracks(const TriangulationOptions& options, MapperState* state) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  const GeometryMap geometry = RegisteredGeometry(*state);
  std::vector<TrackCounts> counts(state->tracks.size());

  ParallelOverTracks(options.num_threads, state->tracks.size(), [&](size_t t) {
    Track& track = state->tracks[t];
    TrackCounts& c = counts[t];
    if (track.triangulated) {
      if (track.rejected.empty()) return;
      std::vector<TrackElement> still_rejected;
      for (const TrackElement& e : track.rejected) {
        const auto it = geometry.find(e.image_id);
        const bool image_taken =
            std::any_of(track.elements.begin(), track.elements.end(),
                        [&](const TrackElement& k) { return k.image_id == e.image_id; });
        if (it == geometry.end() || image_taken ||
            !Passes(Evaluate(MakeObservation(it->second, e), track.xyz),
                    options.max_reprojection_error_px)) {
          still_rejected.push_back(e);
          continue;
        }
        track.elements.push_back(e);
        ++c.added;
      }
      if (c.added == 0) return;
      track.rejected = std::move(still_rejected);
      SortByImage(&track.elements);
      UpdateError(geometry, &track);
      return;
    }
    std::vector<TrackElement> all = track.elements;
    all.insert(all.end(), track.rejected.begin(), track.rejected.end());
    SortByImage(&all);
    std::vector<Observation> candidates;
    std::vector<TrackElement> candidate_elements, unregistered;
    Gather(geometry, all, &candidates, &candidate_elements, &unregistered);
    if (candidates.size() < 2) return;
    const TrackSolution s = SolveTrack(candidates, options);
    if (s.outcome != Outcome::kTriangulated) return;
    Apply(s, candidate_elements, {}, unregistered, &track, &c);
    c.added = track.elements.size();
  });

  size_t added = 0, num_tracks = 0;
  for (const TrackCounts& c : counts) {
    added += c.added;
    num_tracks += c.added > 0 ? 1 : 0;
  }
  LogInfo("retriangulation: {} observations added to {} tracks; {:.3f} s", added, num_tracks,
          SecondsSince(start));
  return added;
}

namespace {

// The correspondence graph over the keypoints of registered images: dense
// node ids in (image_id, point2D_idx) order, adjacency in CSR form (sorted,
// without duplicates).
class CorrespondenceGraph {
 public:
  CorrespondenceGraph(const std::vector<ViewGraphEdge>& correspondences, const MapperState& state) {
    size_t num_nodes = 0;
    for (const auto& [image_id, image] : state.images) {
      if (!state.IsRegistered(image_id)) continue;
      offset_[image_id] = num_nodes;
      num_nodes += image.keypoints.size();
    }
    node_image_.resize(num_nodes);
    for (const auto& [image_id, offset] : offset_) {
      const size_t n = state.images.at(image_id).keypoints.size();
      std::fill(node_image_.begin() + offset, node_image_.begin() + offset + n, image_id);
    }
    std::vector<std::pair<size_t, size_t>> links;
    for (const ViewGraphEdge& edge : correspondences) {
      const auto it1 = offset_.find(edge.image_id1);
      const auto it2 = offset_.find(edge.image_id2);
      if (it1 == offset_.end() || it2 == offset_.end() || edge.image_id1 == edge.image_id2) {
        continue;
      }
      const size_t n1 = state.images.at(edge.image_id1).keypoints.size();
      const size_t n2 = state.images.at(edge.image_id2).keypoints.size();
      for (const auto& [idx1, idx2] : edge.inliers) {
        if (idx1 >= n1 || idx2 >= n2) continue;
        links.emplace_back(it1->second + idx1, it2->second + idx2);
        links.emplace_back(it2->second + idx2, it1->second + idx1);
      }
    }
    std::sort(links.begin(), links.end());
    links.erase(std::unique(links.begin(), links.end()), links.end());
    num_links_ = links.size() / 2;
    begin_.assign(num_nodes + 1, 0);
    for (const auto& link : links) ++begin_[link.first + 1];
    for (size_t k = 0; k < num_nodes; ++k) begin_[k + 1] += begin_[k];
    neighbours_.reserve(links.size());
    for (const auto& link : links) neighbours_.push_back(link.second);
  }

  size_t NumLinks() const { return num_links_; }
  // kNone for an image that is not registered or an index out of range.
  size_t Node(const TrackElement& e, const MapperState& state) const {
    const auto it = offset_.find(e.image_id);
    if (it == offset_.end() || e.point2D_idx >= state.images.at(e.image_id).keypoints.size()) {
      return kNone;
    }
    return it->second + e.point2D_idx;
  }
  TrackElement Element(size_t node) const {
    const image_t image_id = node_image_[node];
    return TrackElement{image_id, static_cast<point2D_t>(node - offset_.at(image_id))};
  }
  const size_t* begin(size_t node) const { return neighbours_.data() + begin_[node]; }
  const size_t* end(size_t node) const { return neighbours_.data() + begin_[node + 1]; }

  static constexpr size_t kNone = std::numeric_limits<size_t>::max();

 private:
  std::unordered_map<image_t, size_t> offset_;
  std::vector<image_t> node_image_;
  std::vector<size_t> begin_;
  std::vector<size_t> neighbours_;
  size_t num_links_ = 0;
};

bool HasImage(const std::vector<TrackElement>& elements, image_t image_id) {
  return std::any_of(elements.begin(), elements.end(), [&](const TrackElement& e) {
    return e.image_id == image_id;
  });
}

bool Contains(const std::vector<TrackElement>& elements, const TrackElement& e) {
  return std::any_of(elements.begin(), elements.end(), [&](const TrackElement& k) {
    return k.image_id == e.image_id && k.point2D_idx == e.point2D_idx;
  });
}

// Removes `e` from `elements`; true when it was there.
bool Remove(const TrackElement& e, std::vector<TrackElement>* elements) {
  const auto it = std::find_if(elements->begin(), elements->end(), [&](const TrackElement& k) {
    return k.image_id == e.image_id && k.point2D_idx == e.point2D_idx;
  });
  if (it == elements->end()) return false;
  elements->erase(it);
  return true;
}

// Completion of track `t` (see CompleteAndMergeTracks); returns the number of
// observations added and counts those taken from other tracks in `*taken`.
size_t CompleteTrack(const TrackCompletionOptions& options,
                     const CorrespondenceGraph& graph,
                     const GeometryMap& geometry,
                     int t,
                     MapperState* state,
                     size_t* taken) {
  Track& track = state->tracks[t];
  std::vector<std::pair<size_t, int>> queue;  // (node, links from the original track)
  for (const TrackElement& e : track.elements) {
    const size_t node = graph.Node(e, *state);
    if (node != CorrespondenceGraph::kNone) queue.emplace_back(node, 0);
  }
  size_t added = 0;
  for (size_t q = 0; q < queue.size(); ++q) {
    const auto [node, depth] = queue[q];
    if (depth >= options.complete_max_transitivity) continue;
    for (const size_t* nb = graph.begin(node); nb != graph.end(node); ++nb) {
      const TrackElement e = graph.Element(*nb);
      if (HasImage(track.elements, e.image_id)) continue;
      std::vector<int>& track_ids = state->images.at(e.image_id).track_ids;
      const int owner = track_ids[e.point2D_idx];
      if (owner == t) continue;  // among the track's own rejected observations
      if (owner >= 0 && state->tracks[owner].triangulated &&
          Contains(state->tracks[owner].elements, e)) {
        continue;
      }
      const Observation obs = MakeObservation(geometry.at(e.image_id), e);
      if (!Passes(Evaluate(obs, track.xyz), options.complete_max_reprojection_error_px)) continue;
      if (owner >= 0) {
        Track& other = state->tracks[owner];
        if (!Remove(e, &other.elements)) Remove(e, &other.rejected);
        ++*taken;
      }
      track_ids[e.point2D_idx] = t;
      track.elements.push_back(e);
      queue.emplace_back(*nb, depth + 1);
      ++added;
    }
  }
  if (added > 0) {
    SortByImage(&track.elements);
    UpdateError(geometry, &track);
  }
  return added;
}

// Re-triangulates the union of tracks t1 and t2 (no image in common) and
// merges t2 into t1 when every observation passes; true when merged.
bool MergeTracks(const TrackCompletionOptions& options,
                 const TriangulationOptions& triangulation,
                 const GeometryMap& geometry,
                 int t1,
                 int t2,
                 MapperState* state) {
  Track& a = state->tracks[t1];
  Track& b = state->tracks[t2];
  std::vector<TrackElement> merged = a.elements;
  merged.insert(merged.end(), b.elements.begin(), b.elements.end());
  SortByImage(&merged);
  std::vector<Observation> obs;
  obs.reserve(merged.size());
  for (const TrackElement& e : merged) obs.push_back(MakeObservation(geometry.at(e.image_id), e));
  std::vector<const Observation*> ptrs;
  for (const Observation& o : obs) ptrs.push_back(&o);
  // Start from the observation-weighted mean of the two points (COLMAP's merge
  // hypothesis) and refine on the pixel error of all observations.
  const double wa = static_cast<double>(a.elements.size());
  const double wb = static_cast<double>(b.elements.size());
  Vec3 xyz = (wa * a.xyz + wb * b.xyz) / (wa + wb);
  RefinePoint(ptrs, triangulation.num_refinement_iterations, &xyz);
  double error_sum = 0.0;
  for (const Observation& o : obs) {
    const Residual r = Evaluate(o, xyz);
    if (!Passes(r, options.merge_max_reprojection_error_px)) return false;
    error_sum += r.error;
  }
  if (MaxTriangulationAngle(ptrs, xyz) < triangulation.min_triangulation_angle_deg * kPi / 180.0) {
    return false;
  }
  for (const std::vector<TrackElement>* list : {&b.elements, &b.rejected}) {
    for (const TrackElement& e : *list) {
      state->images.at(e.image_id).track_ids[e.point2D_idx] = t1;
    }
  }
  a.rejected.insert(a.rejected.end(), b.rejected.begin(), b.rejected.end());
  SortByImage(&a.rejected);
  a.elements = std::move(merged);
  a.xyz = xyz;
  a.error = error_sum / static_cast<double>(a.elements.size());
  b.elements.clear();
  b.rejected.clear();
  b.triangulated = false;
  b.error = -1.0;
  return true;
}

}  // namespace

bool TrackCompletionOptions::Check() const {
  CHECK_OPTION_GT(complete_max_reprojection_error_px, 0.0);
  CHECK_OPTION_GE(complete_max_transitivity, 1);
  CHECK_OPTION_GT(merge_max_reprojection_error_px, 0.0);
  return true;
}

TrackCompletionStats CompleteAndMergeTracks(const TrackCompletionOptions& options,
                                            const TriangulationOptions& triangulation,
                                            const std::vector<ViewGraphEdge>& correspondences,
                                            MapperState* state) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_OPTIONS(options);
  THROW_CHECK_OPTIONS(triangulation);
  const auto start = std::chrono::steady_clock::now();
  TrackCompletionStats stats;
  if (!options.complete && !options.merge) return stats;
  const GeometryMap geometry = RegisteredGeometry(*state);
  const CorrespondenceGraph graph(correspondences, *state);
  stats.num_correspondences = graph.NumLinks();
  const int num_tracks = static_cast<int>(state->tracks.size());

  if (options.complete) {
    for (int t = 0; t < num_tracks; ++t) {
      if (!state->tracks[t].triangulated) continue;
      const size_t added =
          CompleteTrack(options, graph, geometry, t, state, &stats.num_observations_taken);
      stats.num_observations_completed += added;
      stats.num_tracks_completed += added > 0 ? 1 : 0;
    }
  }
  if (options.merge) {
    for (int t1 = 0; t1 < num_tracks; ++t1) {
      // Rescan t1 after every merge (its observations changed); each merge
      // empties a track, so this ends.
      bool rescan = true;
      while (rescan && state->tracks[t1].triangulated) {
        rescan = false;
        const std::vector<TrackElement> elements = state->tracks[t1].elements;
        std::set<int> tried;
        for (size_t i = 0; i < elements.size() && !rescan; ++i) {
          const size_t node = graph.Node(elements[i], *state);
          if (node == CorrespondenceGraph::kNone) continue;
          for (const size_t* nb = graph.begin(node); nb != graph.end(node); ++nb) {
            const TrackElement e = graph.Element(*nb);
            const int t2 = state->images.at(e.image_id).track_ids[e.point2D_idx];
            if (t2 < 0 || t2 == t1 || !state->tracks[t2].triangulated ||
                !Contains(state->tracks[t2].elements, e) || !tried.insert(t2).second) {
              continue;
            }
            const Track& b = state->tracks[t2];
            if (std::any_of(b.elements.begin(), b.elements.end(), [&](const TrackElement& k) {
                  return HasImage(elements, k.image_id);
                })) {
              continue;
            }
            ++stats.num_merge_candidates;
            const size_t merged_size = b.elements.size();
            if (MergeTracks(options, triangulation, geometry, t1, t2, state)) {
              ++stats.num_merges;
              stats.num_observations_merged += merged_size;
              rescan = true;
              break;
            }
          }
        }
      }
    }
  }
  stats.seconds = SecondsSince(start);
  LogInfo(
      "track completion: {} observations added to {} tracks ({} taken from other tracks); "
      "merging: {} of {} candidate track pairs merged ({} observations); {} correspondences; "
      "{:.3f} s",
      stats.num_observations_completed,
      stats.num_tracks_completed,
      stats.num_observations_taken,
      stats.num_merges,
      stats.num_merge_candidates,
      stats.num_observations_merged,
      stats.num_correspondences,
      stats.seconds);
  return stats;
}

}  // namespace colmap
}  // namespace lisfm
