#include "colmap_ext/sfm/view_graph.h"

#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>

#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"
#include "core/work_list.h"

namespace lisfm {
namespace colmap {

bool ViewGraphOptions::Check() const {
  CHECK_OPTION_GE(min_num_inliers, 5);
  CHECK_OPTION_MSG(min_inlier_ratio, min_inlier_ratio >= 0.0 && min_inlier_ratio <= 1.0,
                   "in [0, 1]");
  CHECK_OPTION_GT(max_error_px, 0.0);
  CHECK_OPTION_MSG(num_threads, num_threads == -1 || num_threads >= 1, "-1 or >= 1");
  CHECK_OPTION_MSG(ransac_confidence, ransac_confidence > 0.0 && ransac_confidence < 1.0,
                   "in (0, 1)");
  CHECK_OPTION_GE(ransac_max_iterations, 1);
  CHECK_OPTION_GE(ransac_max_num_matches, 5);
  CHECK_OPTION_GE(refine_max_num_matches, 5);
  return true;
}

namespace {

// Sampson error (Hartley & Zisserman 2003, Eq. 11.9) of x2^T E x1 = 0 on the
// normalised plane, as a signed residual whose square is the Sampson distance.
// Invariant to the scale of E.
template <typename T>
T SampsonResidual(const Eigen::Matrix<T, 3, 3>& E,
                  const Vec2& x1,
                  const Vec2& x2) {
  const Eigen::Matrix<T, 3, 1> h1(T(x1.x()), T(x1.y()), T(1));
  const Eigen::Matrix<T, 3, 1> h2(T(x2.x()), T(x2.y()), T(1));
  const Eigen::Matrix<T, 3, 1> e_x1 = E * h1;
  const Eigen::Matrix<T, 3, 1> et_x2 = E.transpose() * h2;
  const T numerator = h2.dot(e_x1);
  const T denominator = e_x1(0) * e_x1(0) + e_x1(1) * e_x1(1) +
                        et_x2(0) * et_x2(0) + et_x2(1) * et_x2(1);
  // denominator > 0 unless E x1 and E^T x2 both vanish (x1 at an epipole).
  using std::sqrt;
  return numerator / sqrt(denominator + T(1e-30));
}

Mat3 EssentialFromPose(const SE3& cam2_from_cam1) {
  return Hat(cam2_from_cam1.translation()) * cam2_from_cam1.RotationMatrix();
}

}  // namespace

double SampsonResidual(const Mat3& E, const Vec2& x1, const Vec2& x2) {
  return SampsonResidual<double>(E, x1, x2);
}

double SampsonCost(const SE3& cam2_from_cam1,
                   const std::vector<Vec2>& x1,
                   const std::vector<Vec2>& x2,
                   double loss_scale) {
  THROW_CHECK_EQ(x1.size(), x2.size());
  const Mat3 E = EssentialFromPose(
      SE3(cam2_from_cam1.rotation(), cam2_from_cam1.translation().normalized()));
  const double c2 = loss_scale * loss_scale;
  double cost = 0.0;
  for (size_t i = 0; i < x1.size(); ++i) {
    const double r = SampsonResidual<double>(E, x1[i], x2[i]);
    cost += 0.5 * c2 * std::log1p(r * r / c2);
  }
  return cost;
}

// Levenberg-Marquardt with analytic Jacobians. Residual r = n / sqrt(d) with
// n = h2^T E h1, a = E h1, b = E^T h2, d = a0^2 + a1^2 + b0^2 + b1^2, so
// dr/dE = h2 h1^T / sqrt(d) - n / (2 d^1.5) dd/dE with dd/dE_kl = 2 a_k h1_l
// (k < 2) + 2 h2_k b_l (l < 2). Parameters: R <- Exp(dtheta) R (E = [t]x R:
// dE/dtheta_j = [t]x [e_j]x R) and t <- normalise(t + B beta) with B an
// orthonormal basis of the plane orthogonal to t (dE/dbeta_m = [b_m]x R);
// <G, [v]x M> = v . vee(G M^T - M G^T) turns dr/dE into the 5 derivatives.
// Cauchy loss by iteratively reweighted least squares.
SE3 RefineRelativePose(const SE3& initial,
                       const std::vector<Vec2>& x1,
                       const std::vector<Vec2>& x2,
                       double loss_scale) {
  THROW_CHECK_EQ(x1.size(), x2.size());
  THROW_CHECK_GT(loss_scale, 0.0);
  const double c2 = loss_scale * loss_scale;
  Mat3 R = initial.RotationMatrix();
  Vec3 t = initial.translation().normalized();
  auto vee_skew = [](const Mat3& m) {  // vee(m - m^T)
    return Vec3(m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1));
  };
  auto basis = [](const Vec3& v, Vec3* b1, Vec3* b2) {
    const Vec3 axis = std::abs(v.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
    *b1 = v.cross(axis).normalized();
    *b2 = v.cross(*b1);
  };
  auto cost_of = [&](const Mat3& R_, const Vec3& t_) {
    const Mat3 E = Hat(t_) * R_;
    double cost = 0.0;
    for (size_t i = 0; i < x1.size(); ++i) {
      const double r = SampsonResidual<double>(E, x1[i], x2[i]);
      cost += 0.5 * c2 * std::log1p(r * r / c2);
    }
    return cost;
  };
  double cost = cost_of(R, t);
  double lambda = 1e-4;
  for (int iteration = 0; iteration < 50; ++iteration) {
    const Mat3 E = Hat(t) * R;
    Vec3 b1, b2;
    basis(t, &b1, &b2);
    Eigen::Matrix<double, 5, 5> H = Eigen::Matrix<double, 5, 5>::Zero();
    Eigen::Matrix<double, 5, 1> g = Eigen::Matrix<double, 5, 1>::Zero();
    for (size_t i = 0; i < x1.size(); ++i) {
      const Vec3 h1 = x1[i].homogeneous();
      const Vec3 h2 = x2[i].homogeneous();
      const Vec3 a = E * h1;
      const Vec3 b = E.transpose() * h2;
      const double n = h2.dot(a);
      const double d = a(0) * a(0) + a(1) * a(1) + b(0) * b(0) + b(1) * b(1) + 1e-30;
      const double sqrt_d = std::sqrt(d);
      const double r = n / sqrt_d;
      Mat3 dd = Mat3::Zero();
      for (int k = 0; k < 2; ++k) dd.row(k) += 2.0 * a(k) * h1.transpose();
      for (int l = 0; l < 2; ++l) dd.col(l) += 2.0 * b(l) * h2;
      const Mat3 G = h2 * h1.transpose() / sqrt_d - n / (2.0 * d * sqrt_d) * dd;
      Eigen::Matrix<double, 1, 5> J;
      // d r / d theta_j = <G, [t]x [e_j]x R> = <-[t]x G R^T, [e_j]x>.
      J.head<3>() = vee_skew(-Hat(t) * G * R.transpose()).transpose();
      const Vec3 dv = vee_skew(G * R.transpose());
      J(3) = b1.dot(dv);
      J(4) = b2.dot(dv);
      const double w = 1.0 / (1.0 + r * r / c2);  // Cauchy rho'(r^2)
      H.noalias() += w * J.transpose() * J;
      g.noalias() += w * r * J.transpose();
    }
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::Matrix<double, 5, 5> damped = H;
      damped.diagonal() += lambda * H.diagonal().cwiseMax(1e-12);
      const Eigen::Matrix<double, 5, 1> step = damped.ldlt().solve(-g);
      if (!step.allFinite()) return SE3(Quat(R).normalized(), t);
      const Mat3 R_new = so3::ExpMatrix(step.head<3>()) * R;
      const Vec3 t_new = (t + step(3) * b1 + step(4) * b2).normalized();
      const double cost_new = cost_of(R_new, t_new);
      if (cost_new < cost) {
        const double decrease = cost - cost_new;
        R = R_new;
        t = t_new;
        cost = cost_new;
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = true;
        if (decrease <= 1e-10 * cost || step.norm() <= 1e-12) {
          return SE3(Quat(R).normalized(), t);
        }
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  return SE3(Quat(R).normalized(), t);
}

namespace {

// Ray angle (rad) between R x1 and x2, used when the two centres coincide.
double RayAngle(const Mat3& R, const Vec2& x1, const Vec2& x2) {
  const Vec3 r1 = R * x1.homogeneous();
  const Vec3 r2 = x2.homogeneous();
  return std::atan2(r1.cross(r2).norm(), r1.dot(r2));
}

// Indices (into x1/x2) of the correspondences consistent with a known pose.
std::vector<size_t> ConsistentMatches(const SE3& cam2_from_cam1,
                                      const std::vector<Vec2>& x1,
                                      const std::vector<Vec2>& x2,
                                      double threshold) {
  std::vector<size_t> kept;
  const double baseline = cam2_from_cam1.translation().norm();
  const Mat3 R = cam2_from_cam1.RotationMatrix();
  if (baseline < 1e-12) {
    for (size_t i = 0; i < x1.size(); ++i) {
      if (RayAngle(R, x1[i], x2[i]) <= threshold) kept.push_back(i);
    }
    return kept;
  }
  const Mat3 E = EssentialFromPose(cam2_from_cam1);
  for (size_t i = 0; i < x1.size(); ++i) {
    if (std::abs(SampsonResidual<double>(E, x1[i], x2[i])) <= threshold)
      kept.push_back(i);
  }
  return kept;
}

enum class PairKind { kEstimate, kKnownPose };

struct PairJob {
  image_t image_id1 = kInvalidImageId;
  image_t image_id2 = kInvalidImageId;
  PairKind kind = PairKind::kEstimate;
  SE3 known_cam2_from_cam1;  // kKnownPose only
  Mat3 database_E = Mat3::Zero();  // kEstimate: the matcher's E when usable
  bool metric = false;
  double threshold = 0.0;  // normalised-plane units
  size_t geometry_index = 0;  // into the database's two_view_geometries list
  // Filled by FillMatches() just before the pair is processed.
  std::vector<std::pair<point2D_t, point2D_t>> matches;
  std::vector<Vec2> x1, x2;
};

// The inlier matches of `geometry` and their normalised coordinates into
// `job`; an index beyond an image's keypoints is an InputError naming the pair.
void FillMatches(const std::string& database_path,
                 image_pair_t pair_id,
                 const TwoViewGeometry& geometry,
                 const SfmImage& image1,
                 const SfmImage& image2,
                 PairJob* job) {
  const size_t num_inliers = static_cast<size_t>(geometry.inlier_matches.rows());
  job->matches.reserve(num_inliers);
  job->x1.reserve(num_inliers);
  job->x2.reserve(num_inliers);
  for (size_t i = 0; i < num_inliers; ++i) {
    const point2D_t idx1 = geometry.inlier_matches(i, 0);
    const point2D_t idx2 = geometry.inlier_matches(i, 1);
    if (idx1 >= image1.normalized.size() || idx2 >= image2.normalized.size()) {
      throw InputError(database_path,
                       "two_view_geometries pair_id " + std::to_string(pair_id),
                       "expected inlier matches within the keypoints of images " +
                           std::to_string(job->image_id1) + " (" +
                           std::to_string(image1.normalized.size()) + ") and " +
                           std::to_string(job->image_id2) + " (" +
                           std::to_string(image2.normalized.size()) + "), found match (" +
                           std::to_string(idx1) + ", " + std::to_string(idx2) + ")");
    }
    job->matches.emplace_back(idx1, idx2);
    job->x1.push_back(image1.normalized[idx1]);
    job->x2.push_back(image2.normalized[idx2]);
  }
}

// Exact bytes of one pair's result (work_list.h): [has edge], then the edge's
// ids, pose, metric flag, weight and inlier matches.
std::string EncodeEdge(const std::optional<ViewGraphEdge>& edge) {
  ByteWriter writer;
  writer.Put<uint8_t>(edge ? 1 : 0);
  if (!edge) return writer.Take();
  writer.Put<image_t>(edge->image_id1);
  writer.Put<image_t>(edge->image_id2);
  writer.PutSe3(edge->cam2_from_cam1);
  writer.Put<uint8_t>(edge->metric ? 1 : 0);
  writer.Put<uint8_t>(edge->valid ? 1 : 0);
  writer.Put<double>(edge->weight);
  writer.Put<uint64_t>(edge->inliers.size());
  for (const auto& [idx1, idx2] : edge->inliers) {
    writer.Put<point2D_t>(idx1);
    writer.Put<point2D_t>(idx2);
  }
  return writer.Take();
}

std::optional<ViewGraphEdge> DecodeEdge(const std::string& bytes) {
  ByteReader reader(bytes);
  if (reader.Get<uint8_t>() == 0) {
    THROW_CHECK(reader.AtEnd());
    return std::nullopt;
  }
  ViewGraphEdge edge;
  edge.image_id1 = reader.Get<image_t>();
  edge.image_id2 = reader.Get<image_t>();
  edge.cam2_from_cam1 = reader.GetSe3();
  edge.metric = reader.Get<uint8_t>() != 0;
  edge.valid = reader.Get<uint8_t>() != 0;
  edge.weight = reader.Get<double>();
  const uint64_t num_inliers = reader.Get<uint64_t>();
  edge.inliers.reserve(num_inliers);
  for (uint64_t i = 0; i < num_inliers; ++i) {
    const point2D_t idx1 = reader.Get<point2D_t>();
    const point2D_t idx2 = reader.Get<point2D_t>();
    edge.inliers.emplace_back(idx1, idx2);
  }
  THROW_CHECK(reader.AtEnd());
  return edge;
}

// Result of one pair: an edge, or nothing when too few inliers remain.
std::optional<ViewGraphEdge> ProcessPair(const PairJob& job,
                                         const ViewGraphOptions& options) {
  ViewGraphEdge edge;
  edge.image_id1 = job.image_id1;
  edge.image_id2 = job.image_id2;
  std::vector<size_t> kept;
  if (job.kind == PairKind::kKnownPose) {
    edge.cam2_from_cam1 = job.known_cam2_from_cam1;
    edge.metric = job.metric;
    kept = ConsistentMatches(
        job.known_cam2_from_cam1, job.x1, job.x2, job.threshold);
  } else {
    // RANSAC and the cheirality vote run on at most ransac_max_num_matches
    // matches (an even stride through the list; deterministic), the
    // refinement and the final inlier test on all of them.
    const size_t num_matches = job.x1.size();
    const size_t num_samples = std::min(
        num_matches, static_cast<size_t>(options.ransac_max_num_matches));
    const int n = static_cast<int>(num_samples);
    cv::Mat points1(n, 2, CV_64F), points2(n, 2, CV_64F);
    for (int i = 0; i < n; ++i) {
      const size_t k = static_cast<size_t>(i) * num_matches / num_samples;
      points1.at<double>(i, 0) = job.x1[k].x();
      points1.at<double>(i, 1) = job.x1[k].y();
      points2.at<double>(i, 0) = job.x2[k].x();
      points2.at<double>(i, 1) = job.x2[k].y();
    }
    const cv::Mat identity = cv::Mat::eye(3, 3, CV_64F);
    cv::Mat mask;
    cv::Mat E;
    if (!job.database_E.isZero()) {
      // The matcher's E (estimated on the same undistorted normalised
      // coordinates); its inlier set is the whole list.
      E = cv::Mat(3, 3, CV_64F);
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) E.at<double>(r, c) = job.database_E(r, c);
      }
      mask = cv::Mat(n, 1, CV_8U, cv::Scalar(1));
    } else {
      E = cv::findEssentialMat(points1,
                               points2,
                               identity,
                               cv::USAC_ACCURATE,
                               options.ransac_confidence,
                               job.threshold,
                               options.ransac_max_iterations,
                               mask);
      if (E.rows < 3 || E.cols != 3 || mask.empty()) return std::nullopt;
      E = E.rowRange(0, 3).clone();
    }
    cv::Mat R_cv, t_cv, triangulated;
    // The cheirality vote between the four decompositions of E runs on at
    // most kMaxVoteMatches inliers (even stride): it triangulates every point
    // for every hypothesis, and a few hundred votes decide as well as 1000.
    constexpr int kMaxVoteMatches = 250;
    std::vector<int> vote_rows;
    for (int i = 0; i < n; ++i) {
      if (mask.at<uchar>(i) != 0) vote_rows.push_back(i);
    }
    const int num_votes = std::min<int>(kMaxVoteMatches, static_cast<int>(vote_rows.size()));
    if (num_votes < 5) return std::nullopt;
    cv::Mat vote1(num_votes, 2, CV_64F), vote2(num_votes, 2, CV_64F);
    for (int i = 0; i < num_votes; ++i) {
      const int row = vote_rows[static_cast<size_t>(i) * vote_rows.size() / num_votes];
      points1.row(row).copyTo(vote1.row(i));
      points2.row(row).copyTo(vote2.row(i));
    }
    cv::Mat pose_mask(num_votes, 1, CV_8U, cv::Scalar(1));
    // Points beyond 1000 baselines count as "at infinity" (COLMAP's
    // cheirality test uses the same bound); they vote for no hypothesis.
    const int num_cheiral = cv::recoverPose(E,
                                            vote1,
                                            vote2,
                                            identity,
                                            R_cv,
                                            t_cv,
                                            1000.0,
                                            pose_mask,
                                            triangulated);
    if (num_cheiral < 5) return std::nullopt;
    Mat3 R;
    Vec3 t;
    for (int r = 0; r < 3; ++r) {
      t(r) = t_cv.at<double>(r, 0);
      for (int c = 0; c < 3; ++c) R(r, c) = R_cv.at<double>(r, c);
    }
    SE3 cam2_from_cam1(Quat(R).normalized(), t.normalized());
    if (options.refine_relative_poses) {
      // At most refine_max_num_matches of them (even stride): beyond a few
      // thousand matches the pose no longer improves, the time does grow.
      const std::vector<size_t> consistent =
          ConsistentMatches(cam2_from_cam1, job.x1, job.x2, job.threshold);
      const size_t num_refine =
          std::min(consistent.size(),
                   static_cast<size_t>(options.refine_max_num_matches));
      std::vector<Vec2> in1, in2;
      for (size_t j = 0; j < num_refine; ++j) {
        const size_t i = consistent[j * consistent.size() / num_refine];
        in1.push_back(job.x1[i]);
        in2.push_back(job.x2[i]);
      }
      // Cauchy scale: a quarter of the inlier threshold (1 px at the
      // defaults, about the keypoint noise), so that wrong matches that
      // slipped under the threshold barely pull the pose.
      cam2_from_cam1 =
          RefineRelativePose(cam2_from_cam1, in1, in2, 0.25 * job.threshold);
    }
    edge.cam2_from_cam1 = cam2_from_cam1;
    edge.metric = false;
    kept = ConsistentMatches(cam2_from_cam1, job.x1, job.x2, job.threshold);
  }
  if (static_cast<int>(kept.size()) < options.min_num_inliers)
    return std::nullopt;
  edge.inliers.reserve(kept.size());
  for (size_t i : kept) edge.inliers.push_back(job.matches[i]);
  edge.weight = static_cast<double>(kept.size());
  edge.valid = true;
  return edge;
}

bool IsUsableConfig(int config) {
  switch (static_cast<TwoViewConfig>(config)) {
    case TwoViewConfig::kCalibrated:
    case TwoViewConfig::kUncalibrated:
    case TwoViewConfig::kPlanar:
    case TwoViewConfig::kPanoramic:
    case TwoViewConfig::kPlanarOrPanoramic:
      return true;
    default:
      return false;
  }
}

}  // namespace

ViewGraphStats BuildViewGraph(const Database& database,
                              const ViewGraphOptions& options,
                              MapperState* state,
                              const WorkListRunner& runner) {
  THROW_CHECK(state != nullptr);
  THROW_CHECK_OPTIONS(options);
  const auto start = std::chrono::steady_clock::now();
  ViewGraphStats stats;

  const auto geometries = database.ReadAllTwoViewGeometries();
  stats.num_pairs_in_database = geometries.size();
  if (geometries.empty()) {
    throw InputError(
        database.path(),
        "table two_view_geometries",
        "expected at least one image pair with a two-view geometry, found none "
        "(run colmap exhaustive_matcher or matches_importer first)");
  }
  const std::unordered_map<image_pair_t, size_t> num_raw_matches =
      database.ReadAllNumMatches();

  std::vector<PairJob> jobs;
  jobs.reserve(geometries.size());
  for (size_t g = 0; g < geometries.size(); ++g) {
    const auto& [pair_id, geometry] = geometries[g];
    image_t image_id1 = kInvalidImageId, image_id2 = kInvalidImageId;
    PairIdToImagePair(pair_id, &image_id1, &image_id2);
    const auto it1 = state->images.find(image_id1);
    const auto it2 = state->images.find(image_id2);
    if (it1 == state->images.end() || it2 == state->images.end()) {
      ++stats.num_skipped_unknown_images;
      continue;
    }
    if (state->view_graph.edge_index.count(pair_id) > 0)
      continue;  // already an edge
    if (!IsUsableConfig(geometry.config)) {
      ++stats.num_skipped_config;
      continue;
    }
    const size_t num_inliers =
        static_cast<size_t>(geometry.inlier_matches.rows());
    const auto raw_it = num_raw_matches.find(pair_id);
    const double ratio =
        (raw_it == num_raw_matches.end() || raw_it->second == 0)
            ? 1.0
            : std::min(1.0, static_cast<double>(num_inliers) / raw_it->second);
    if (static_cast<int>(num_inliers) < options.min_num_inliers ||
        ratio < options.min_inlier_ratio) {
      ++stats.num_rejected_few_inliers;
      continue;
    }
    const SfmImage& image1 = it1->second;
    const SfmImage& image2 = it2->second;
    PairJob job;
    job.image_id1 = image_id1;
    job.image_id2 = image_id2;
    job.geometry_index = g;
    const double focal =
        0.5 * (state->cameras.at(image1.camera_id).MeanFocalLength() +
               state->cameras.at(image2.camera_id).MeanFocalLength());
    THROW_CHECK_GT(focal, 0.0);
    job.threshold = options.max_error_px / focal;
    if (image1.frame_id == image2.frame_id) {
      // Same rig frame: cam2_from_cam1 = cam2_from_rig * rig_from_cam1
      // (metric).
      job.kind = PairKind::kKnownPose;
      job.metric = true;
      job.known_cam2_from_cam1 =
          state->cam_from_rig.at(image2.camera_id) *
          state->cam_from_rig.at(image1.camera_id).Inverse();
    } else if (options.use_database_essential &&
               geometry.config == static_cast<int>(TwoViewConfig::kCalibrated) &&
               geometry.E.allFinite() && geometry.E.norm() > 0.0) {
      job.database_E = geometry.E;
    } else if (!options.reestimate_relative_poses &&
               geometry.tvec.norm() > 0.0) {
      job.kind = PairKind::kKnownPose;
      const Quat q(geometry.qvec(0),
                   geometry.qvec(1),
                   geometry.qvec(2),
                   geometry.qvec(3));
      job.known_cam2_from_cam1 =
          SE3(q.normalized(), geometry.tvec.normalized());
    }
    jobs.push_back(std::move(job));
  }

  // The pairs `items` (indices into jobs): matches read and checked in list
  // order, then estimated in parallel; each result depends on its pair only.
  tbb::task_arena arena(options.num_threads > 0 ? options.num_threads
                                                : tbb::task_arena::automatic);
  const auto process = [&](const std::vector<size_t>& items) {
    for (size_t i : items) {
      PairJob& job = jobs[i];
      const auto& [pair_id, geometry] = geometries[job.geometry_index];
      FillMatches(database.path(),
                  pair_id,
                  geometry,
                  state->images.at(job.image_id1),
                  state->images.at(job.image_id2),
                  &job);
    }
    std::vector<std::optional<ViewGraphEdge>> edges(items.size());
    arena.execute([&] {
      tbb::parallel_for(size_t{0}, items.size(), [&](size_t k) {
        PairJob& job = jobs[items[k]];
        edges[k] = ProcessPair(job, options);
        job.matches = {};  // the pair is done: its matches go
        job.x1 = {};
        job.x2 = {};
      });
    });
    return edges;
  };
  std::vector<std::optional<ViewGraphEdge>> results;
  if (!runner) {
    std::vector<size_t> all(jobs.size());
    std::iota(all.begin(), all.end(), size_t{0});
    results = process(all);
  } else {
    // Cost of a pair ~ its inlier matches (RANSAC, polish and inlier test
    // are linear in them); a known pose only tests each match once.
    std::vector<double> costs(jobs.size());
    for (size_t i = 0; i < jobs.size(); ++i) {
      const double n =
          static_cast<double>(geometries[jobs[i].geometry_index].second.inlier_matches.rows());
      costs[i] = jobs[i].kind == PairKind::kKnownPose ? 0.1 * n : n;
    }
    const std::optional<std::vector<std::string>> encoded =
        runner(costs, [&](const std::vector<size_t>& items) {
          const std::vector<std::optional<ViewGraphEdge>> edges = process(items);
          std::vector<std::string> bytes;
          bytes.reserve(edges.size());
          for (const auto& edge : edges) bytes.push_back(EncodeEdge(edge));
          return bytes;
        });
    if (!encoded) {
      stats.share_only = true;
      return stats;
    }
    THROW_CHECK_EQ(encoded->size(), jobs.size());
    results.reserve(jobs.size());
    for (const std::string& bytes : *encoded) results.push_back(DecodeEdge(bytes));
  }

  for (size_t i = 0; i < jobs.size(); ++i) {
    if (!results[i]) {
      ++stats.num_rejected_reestimation;
      continue;
    }
    const bool intra = state->images.at(jobs[i].image_id1).frame_id ==
                       state->images.at(jobs[i].image_id2).frame_id;
    if (intra) ++stats.num_intra_frame_edges;
    stats.num_inlier_matches += results[i]->inliers.size();
    state->view_graph.AddEdge(std::move(*results[i]));
    ++stats.num_edges;
  }
  stats.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  LogInfo(
      "View graph: {} pairs in the database, {} edges ({} within a rig frame), "
      "skipped {} (unknown images) + {} (config), rejected {} (few inliers) + "
      "{} "
      "(re-estimation), {} inlier matches, {:.2f} s",
      stats.num_pairs_in_database,
      stats.num_edges,
      stats.num_intra_frame_edges,
      stats.num_skipped_unknown_images,
      stats.num_skipped_config,
      stats.num_rejected_few_inliers,
      stats.num_rejected_reestimation,
      stats.num_inlier_matches,
      stats.seconds);
  return stats;
}

std::vector<std::vector<frame_t>> FrameComponents(const MapperState& state) {
  // Union-find over frame indices.
  std::vector<frame_t> ids;
  std::unordered_map<frame_t, size_t> index;
  for (const auto& [frame_id, frame] : state.frames) {
    index[frame_id] = ids.size();
    ids.push_back(frame_id);
  }
  std::vector<size_t> parent(ids.size());
  std::iota(parent.begin(), parent.end(), size_t{0});
  auto find = [&](size_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  };
  auto unite = [&](frame_t a, frame_t b) {
    const auto ia = index.find(a);
    const auto ib = index.find(b);
    if (ia == index.end() || ib == index.end()) return;
    const size_t ra = find(ia->second), rb = find(ib->second);
    if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
  };
  for (const ViewGraphEdge& edge : state.view_graph.edges) {
    if (!edge.valid) continue;
    const auto it1 = state.images.find(edge.image_id1);
    const auto it2 = state.images.find(edge.image_id2);
    if (it1 == state.images.end() || it2 == state.images.end()) continue;
    if (it1->second.frame_id == it2->second.frame_id) continue;
    unite(it1->second.frame_id, it2->second.frame_id);
  }
  for (const LidarConstraint& constraint : state.lidar_constraints) {
    unite(constraint.frame_id1, constraint.frame_id2);
  }
  std::unordered_map<size_t, size_t> component_of_root;
  std::vector<std::vector<frame_t>> components;
  for (size_t i = 0; i < ids.size(); ++i) {  // ids ascend (std::map order)
    const size_t root = find(i);
    auto [it, inserted] = component_of_root.emplace(root, components.size());
    if (inserted) components.emplace_back();
    components[it->second].push_back(ids[i]);
  }
  std::stable_sort(
      components.begin(),
      components.end(),
      [](const std::vector<frame_t>& a, const std::vector<frame_t>& b) {
        return a.size() > b.size();
      });
  return components;
}

}  // namespace colmap
}  // namespace lisfm
