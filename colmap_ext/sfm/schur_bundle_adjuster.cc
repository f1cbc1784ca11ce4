#include "colmap_ext/sfm/schur_bundle_adjuster.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include <Eigen/Cholesky>

#include "colmap_ext/sfm/camera_model_functors.h"
#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {
namespace colmap {
namespace {

constexpr int kMaxFreeParams = 12;  // the largest COLMAP model (FULL_OPENCV)
constexpr double kMinDiagonal = 1e-6;  // Ceres' min_lm_diagonal
constexpr double kMaxDiagonal = 1e32;  // Ceres' max_lm_diagonal
constexpr double kMinRelativeDecrease = 1e-3;  // Ceres' min_relative_decrease
constexpr double kInitialRadius = 1e4;  // Ceres' initial_trust_region_radius

using Clock = std::chrono::steady_clock;
double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Robust loss rho(s), s = squared residual norm, and rho'(s) (Ceres' forms).
struct Loss {
  enum Type { kTrivial, kHuber, kCauchy } type = kTrivial;
  double b = 1.0;  // scale^2
  void Evaluate(double s, double* rho, double* rho1) const {
    switch (type) {
      case kTrivial:
        *rho = s;
        *rho1 = 1.0;
        return;
      case kHuber:
        if (s > b) {
          const double r = std::sqrt(s);
          *rho = 2.0 * r * std::sqrt(b) - b;
          *rho1 = std::sqrt(b) / r;
        } else {
          *rho = s;
          *rho1 = 1.0;
        }
        return;
      case kCauchy: {
        const double sum = 1.0 + s / b;
        *rho = b * std::log(sum);
        *rho1 = 1.0 / sum;
        return;
      }
    }
  }
};

// Weighted residual and Jacobians of one observation (IRLS: scaled by
// sqrt(rho'(s))). Camera columns: frame [dtheta; dt] then the free intrinsics.
struct LinearisedObservation {
  Eigen::Vector2d r;
  Eigen::Matrix<double, 2, 6> j_frame;
  Eigen::Matrix<double, 2, 3> j_point;
  Eigen::Matrix<double, 2, kMaxFreeParams> j_intrinsics;
};

// The current value of every parameter.
struct State {
  std::vector<Quat> q;
  std::vector<Mat3> R;
  std::vector<Vec3> t;
  std::vector<std::vector<double>> params;
  std::vector<Vec3> points;
  Quat qx = Quat::Identity();  // X = rig_from_prior (when the problem has it)
  Vec3 tx = Vec3::Zero();
};

// The problem's values (rotations normalised).
State StateFromProblem(const SchurBaProblem& problem) {
  State x;
  for (const SchurBaFrame& f : problem.frames) {
    x.q.push_back(f.rig_from_world_rotation.normalized());
    x.R.push_back(x.q.back().toRotationMatrix());
    x.t.push_back(f.rig_from_world_translation);
  }
  for (const SchurBaCamera& c : problem.cameras) x.params.push_back(c.params);
  x.points = problem.points;
  x.qx = problem.rig_from_prior_rotation.normalized();
  x.tx = problem.rig_from_prior_translation;
  return x;
}

// d q / d dtheta for q <- Exp(dtheta) * q at dtheta = 0, rows (x, y, z, w).
Eigen::Matrix<double, 4, 3> QuaternionTangentJacobian(const Quat& q) {
  Eigen::Matrix<double, 4, 3> J;
  const Vec3 v = q.vec();
  J.topRows<3>() = 0.5 * (q.w() * Mat3::Identity() - Hat(v));
  J.row(3) = -0.5 * v.transpose();
  return J;
}

// Residual (and, with lin != nullptr, weighted Jacobians) of observation o;
// returns 0.5 rho(|r|^2).
template <typename Model>
double EvaluateObservation(const SchurBaObservation& o,
                           const State& x,
                           const SchurBaCamera& camera,
                           const Loss& loss,
                           LinearisedObservation* lin) {
  const std::vector<int>& free_indices = camera.free_indices;
  constexpr int N = Model::kNumParams;
  const Mat3& R = x.R[o.frame];
  const Vec3& point = x.points[o.point];
  const Vec3 rotated = R * point;
  const Vec3 x_in_cam =
      camera.cam_from_rig_rotation * (rotated + x.t[o.frame]) + camera.cam_from_rig_translation;
  const double* params = x.params[o.camera].data();
  Eigen::Vector2d pixel;
  if (lin == nullptr) {
    ProjectWithJacobians<Model>(params, x_in_cam, &pixel, nullptr, nullptr);
    const double s = (pixel - o.observed).squaredNorm();
    double rho, rho1;
    loss.Evaluate(s, &rho, &rho1);
    return 0.5 * rho;
  }
  Eigen::Matrix<double, 2, 3> d_cam;
  double d_params[2 * N];
  ProjectWithJacobians<Model>(params, x_in_cam, &pixel, &d_cam, d_params);
  const Eigen::Vector2d r = pixel - o.observed;
  double rho, rho1;
  loss.Evaluate(r.squaredNorm(), &rho, &rho1);
  const double w = std::sqrt(rho1);
  const Eigen::Matrix<double, 2, 3> d_rig = w * d_cam * camera.cam_from_rig_rotation;
  lin->r = w * r;
  lin->j_frame.leftCols<3>() = -d_rig * Hat(rotated);
  lin->j_frame.rightCols<3>() = d_rig;
  lin->j_point = d_rig * R;
  for (size_t k = 0; k < free_indices.size(); ++k) {
    lin->j_intrinsics(0, k) = w * d_params[free_indices[k]];
    lin->j_intrinsics(1, k) = w * d_params[N + free_indices[k]];
  }
  return 0.5 * rho;
}

double EvaluateObservation(const SchurBaProblem& problem,
                           const SchurBaObservation& o,
                           const State& x,
                           const Loss& loss,
                           LinearisedObservation* lin) {
  const SchurBaCamera& camera = problem.cameras[o.camera];
  return VisitCameraModel(camera.model_id, [&](auto model) {
    using Model = decltype(model);
    return EvaluateObservation<Model>(o, x, camera, loss, lin);
  });
}

// Residual and tangent Jacobians (columns: frame1 [dtheta; dt], frame2
// [dtheta; dt]) of a pose term; returns 0.5 |r|^2.
double EvaluatePoseTerm(const SchurBaPoseTerm& term,
                        const State& x,
                        Eigen::VectorXd* residual,
                        Eigen::MatrixXd* jacobian) {
  const int m = term.cost->num_residuals();
  residual->resize(m);
  std::vector<double> q1(x.q[term.frame1].coeffs().data(),
                         x.q[term.frame1].coeffs().data() + 4);
  std::vector<double> t1(x.t[term.frame1].data(), x.t[term.frame1].data() + 3);
  std::vector<double> q2, t2;
  std::vector<const double*> blocks;
  if (term.kind == SchurBaPoseTerm::kRotation) {
    blocks = {q1.data()};
  } else {
    blocks = {q1.data(), t1.data()};
  }
  if (term.kind == SchurBaPoseTerm::kRelative) {
    q2.assign(x.q[term.frame2].coeffs().data(), x.q[term.frame2].coeffs().data() + 4);
    t2.assign(x.t[term.frame2].data(), x.t[term.frame2].data() + 3);
    blocks.push_back(q2.data());
    blocks.push_back(t2.data());
  }
  if (jacobian == nullptr) {
    THROW_CHECK(term.cost->Evaluate(blocks.data(), residual->data(), nullptr));
    return 0.5 * residual->squaredNorm();
  }
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  std::vector<RowMajor> raw;
  std::vector<double*> raw_ptrs;
  for (size_t b = 0; b < blocks.size(); ++b) {
    raw.emplace_back(m, (b % 2 == 0) ? 4 : 3);
  }
  for (RowMajor& j : raw) raw_ptrs.push_back(j.data());
  THROW_CHECK(term.cost->Evaluate(blocks.data(), residual->data(), raw_ptrs.data()));
  const int num_frames = term.kind == SchurBaPoseTerm::kRelative ? 2 : 1;
  jacobian->setZero(m, 6 * num_frames);
  for (int f = 0; f < num_frames; ++f) {
    const int frame = f == 0 ? term.frame1 : term.frame2;
    jacobian->block(0, 6 * f, m, 3) = raw[2 * f] * QuaternionTangentJacobian(x.q[frame]);
    if (term.kind != SchurBaPoseTerm::kRotation) {
      jacobian->block(0, 6 * f + 3, m, 3) = raw[2 * f + 1];
    }
  }
  return 0.5 * residual->squaredNorm();
}

// A pose term through X (uses_rig_from_prior): residual and, with
// jacobians != nullptr, one m x 3 tangent Jacobian per parameter group with
// the group's first variable: frame f rotation 6f / translation 6f + 3, X
// rotation x_offset / translation x_offset + 3 (blocks in the cost function's
// order, SchurBaPoseTerm); X's translation block along the columns of
// x_translation_axes. Returns 0.5 |r|^2.
struct TangentBlock {
  int offset = 0;
  Eigen::MatrixXd jacobian;
};
double EvaluatePriorFrameTerm(const SchurBaPoseTerm& term,
                              const State& x,
                              int x_offset,
                              const Mat3& x_translation_axes,
                              Eigen::VectorXd* residual,
                              std::vector<TangentBlock>* jacobians) {
  const int m = term.cost->num_residuals();
  residual->resize(m);
  struct Group {
    std::vector<double> values;
    int offset;
    const Quat* q;  // rotation group: its quaternion; translation: null
  };
  std::vector<Group> groups;
  auto add_rotation = [&](const Quat& q, int offset) {
    groups.push_back({std::vector<double>(q.coeffs().data(), q.coeffs().data() + 4), offset, &q});
  };
  auto add_translation = [&](const Vec3& t, int offset) {
    groups.push_back({std::vector<double>(t.data(), t.data() + 3), offset, nullptr});
  };
  add_rotation(x.q[term.frame1], 6 * term.frame1);
  if (term.kind != SchurBaPoseTerm::kRotation) {
    add_translation(x.t[term.frame1], 6 * term.frame1 + 3);
  }
  if (term.kind == SchurBaPoseTerm::kRelative) {
    add_rotation(x.q[term.frame2], 6 * term.frame2);
    add_translation(x.t[term.frame2], 6 * term.frame2 + 3);
  }
  if (term.kind != SchurBaPoseTerm::kPose) add_rotation(x.qx, x_offset);
  if (term.kind != SchurBaPoseTerm::kRotation) add_translation(x.tx, x_offset + 3);
  std::vector<const double*> blocks;
  for (const Group& g : groups) blocks.push_back(g.values.data());
  if (jacobians == nullptr) {
    THROW_CHECK(term.cost->Evaluate(blocks.data(), residual->data(), nullptr));
    return 0.5 * residual->squaredNorm();
  }
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  std::vector<RowMajor> raw;
  std::vector<double*> raw_ptrs;
  for (const Group& g : groups) raw.emplace_back(m, static_cast<int>(g.values.size()));
  for (RowMajor& j : raw) raw_ptrs.push_back(j.data());
  THROW_CHECK(term.cost->Evaluate(blocks.data(), residual->data(), raw_ptrs.data()));
  jacobians->clear();
  for (size_t k = 0; k < groups.size(); ++k) {
    TangentBlock block;
    block.offset = groups[k].offset;
    if (groups[k].q != nullptr) {
      block.jacobian = raw[k] * QuaternionTangentJacobian(*groups[k].q);
    } else if (groups[k].offset == x_offset + 3) {
      block.jacobian = raw[k] * x_translation_axes;
    } else {
      block.jacobian = raw[k];
    }
    jacobians->push_back(std::move(block));
  }
  return 0.5 * residual->squaredNorm();
}

class Solver {
 public:
  Solver(const SchurBaOptions& options, SchurBaProblem* problem)
      : options_(options), problem_(*problem) {
    if (options.loss_type == "huber") {
      loss_.type = Loss::kHuber;
    } else if (options.loss_type == "cauchy") {
      loss_.type = Loss::kCauchy;
    } else {
      THROW_CHECK_MSG(options.loss_type == "trivial",
                      "unknown loss type " << options.loss_type);
    }
    loss_.b = options.loss_scale * options.loss_scale;
    const int num_frames = static_cast<int>(problem->frames.size());
    num_vars_ = 6 * num_frames;
    for (const SchurBaCamera& camera : problem->cameras) {
      THROW_CHECK_LE(camera.free_indices.size(), static_cast<size_t>(kMaxFreeParams));
      camera_offset_.push_back(num_vars_);
      num_vars_ += static_cast<int>(camera.free_indices.size());
    }
    if (problem->has_rig_from_prior) {
      x_offset_ = num_vars_;
      num_vars_ += 6;
    }
    fixed_.assign(num_vars_, 0);
    for (int f = 0; f < num_frames; ++f) {
      for (int k = 0; k < 6; ++k) fixed_[6 * f + k] = problem->frames[f].fixed[k] ? 1 : 0;
    }
    if (problem->has_rig_from_prior) {
      for (int k = 0; k < 6; ++k) fixed_[x_offset_ + k] = problem->rig_from_prior_fixed[k] ? 1 : 0;
    }
    // Point ranges of the observations (sorted by point).
    point_begin_.assign(problem->points.size() + 1, 0);
    for (size_t i = 0; i < problem->observations.size(); ++i) {
      const SchurBaObservation& o = problem->observations[i];
      THROW_CHECK(o.frame >= 0 && o.frame < num_frames);
      THROW_CHECK(o.camera >= 0 && o.camera < static_cast<int>(problem->cameras.size()));
      THROW_CHECK(o.point >= 0 && o.point < static_cast<int>(problem->points.size()));
      if (i > 0) THROW_CHECK_MSG(o.point >= problem->observations[i - 1].point,
                                 "observations must be sorted by point");
      ++point_begin_[o.point + 1];
    }
    for (size_t p = 0; p < problem->points.size(); ++p) point_begin_[p + 1] += point_begin_[p];
    for (const SchurBaPoseTerm& term : problem->pose_terms) {
      THROW_CHECK(term.cost != nullptr);
      THROW_CHECK(term.frame1 >= 0 && term.frame1 < num_frames);
      THROW_CHECK(term.kind != SchurBaPoseTerm::kRelative ||
                  (term.frame2 >= 0 && term.frame2 < num_frames));
      THROW_CHECK_MSG(!term.uses_rig_from_prior || problem->has_rig_from_prior,
                      "a pose term uses rig_from_prior, but the problem has none");
    }
    x_ = FromProblem();
    lin_.resize(problem->observations.size());
    V_.resize(problem->points.size());
    g_point_.resize(problem->points.size());
    V_inv_.resize(problem->points.size());
    dx_point_.resize(problem->points.size());
  }

  SchurBaSummary Run() {
    const int threads = options_.num_threads > 0
                            ? options_.num_threads
                            : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    tbb::task_arena arena(threads);
    SchurBaSummary summary;
    arena.execute([&] { RunInArena(&summary); });
    ToProblem();
    return summary;
  }

 private:
  State FromProblem() const { return StateFromProblem(problem_); }

  void ToProblem() {
    for (size_t f = 0; f < problem_.frames.size(); ++f) {
      problem_.frames[f].rig_from_world_rotation = x_.q[f];
      problem_.frames[f].rig_from_world_translation = x_.t[f];
    }
    for (size_t c = 0; c < problem_.cameras.size(); ++c) problem_.cameras[c].params = x_.params[c];
    problem_.points = x_.points;
    if (problem_.has_rig_from_prior) {
      problem_.rig_from_prior_rotation = x_.qx;
      problem_.rig_from_prior_translation = x_.tx;
    }
  }

  // Cost at x (no Jacobians).
  double Cost(const State& x) const {
    const auto& obs = problem_.observations;
    double cost = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, obs.size(), 1024), 0.0,
        [&](const tbb::blocked_range<size_t>& range, double sum) {
          for (size_t i = range.begin(); i != range.end(); ++i) {
            sum += EvaluateObservation(problem_, obs[i], x, loss_, nullptr);
          }
          return sum;
        },
        std::plus<double>());
    Eigen::VectorXd r;
    for (const SchurBaPoseTerm& term : problem_.pose_terms) {
      cost += term.uses_rig_from_prior
                  ? EvaluatePriorFrameTerm(
                        term, x, x_offset_, problem_.rig_from_prior_translation_axes, &r, nullptr)
                  : EvaluatePoseTerm(term, x, &r, nullptr);
    }
    return cost;
  }

  // Jacobians at x_: per observation, per point V / g, and the camera block U,
  // g_cam, with the cost.
  double Linearise() {
    const auto& obs = problem_.observations;
    struct Acc {
      Eigen::MatrixXd U;
      Eigen::VectorXd g;
      double cost = 0.0;
    };
    Acc init{Eigen::MatrixXd::Zero(num_vars_, num_vars_), Eigen::VectorXd::Zero(num_vars_), 0.0};
    const size_t num_points = problem_.points.size();
    Acc total = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, num_points, Grain()), init,
        [&](const tbb::blocked_range<size_t>& range, Acc acc) {
          for (size_t p = range.begin(); p != range.end(); ++p) {
            Mat3 V = Mat3::Zero();
            Vec3 g = Vec3::Zero();
            for (size_t i = point_begin_[p]; i < point_begin_[p + 1]; ++i) {
              LinearisedObservation& l = lin_[i];
              acc.cost += EvaluateObservation(problem_, obs[i], x_, loss_, &l);
              V.noalias() += l.j_point.transpose() * l.j_point;
              g.noalias() += l.j_point.transpose() * l.r;
              const int fo = 6 * obs[i].frame;
              const int co = camera_offset_[obs[i].camera];
              const int nc = NumFree(obs[i].camera);
              acc.U.block<6, 6>(fo, fo).noalias() += l.j_frame.transpose() * l.j_frame;
              acc.g.segment<6>(fo).noalias() += l.j_frame.transpose() * l.r;
              if (nc > 0) {
                const auto ji = l.j_intrinsics.leftCols(nc);
                acc.U.block(co, co, nc, nc).noalias() += ji.transpose() * ji;
                acc.U.block(fo, co, 6, nc).noalias() += l.j_frame.transpose() * ji;
                acc.U.block(co, fo, nc, 6).noalias() += ji.transpose() * l.j_frame;
                acc.g.segment(co, nc).noalias() += ji.transpose() * l.r;
              }
            }
            V_[p] = V;
            g_point_[p] = g;
          }
          return acc;
        },
        [](Acc a, const Acc& b) {
          a.U += b.U;
          a.g += b.g;
          a.cost += b.cost;
          return a;
        });
    U_ = std::move(total.U);
    g_cam_ = std::move(total.g);
    double cost = total.cost;
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    std::vector<TangentBlock> blocks;
    for (const SchurBaPoseTerm& term : problem_.pose_terms) {
      if (term.uses_rig_from_prior) {
        cost += EvaluatePriorFrameTerm(
            term, x_, x_offset_, problem_.rig_from_prior_translation_axes, &r, &blocks);
        for (const TangentBlock& a : blocks) {
          g_cam_.segment<3>(a.offset) += a.jacobian.transpose() * r;
          for (const TangentBlock& b : blocks) {
            U_.block<3, 3>(a.offset, b.offset) += a.jacobian.transpose() * b.jacobian;
          }
        }
        continue;
      }
      cost += EvaluatePoseTerm(term, x_, &r, &J);
      const int f1 = 6 * term.frame1;
      U_.block<6, 6>(f1, f1) += J.leftCols<6>().transpose() * J.leftCols<6>();
      g_cam_.segment<6>(f1) += J.leftCols<6>().transpose() * r;
      if (term.kind == SchurBaPoseTerm::kRelative) {
        const int f2 = 6 * term.frame2;
        U_.block<6, 6>(f2, f2) += J.rightCols<6>().transpose() * J.rightCols<6>();
        U_.block<6, 6>(f1, f2) += J.leftCols<6>().transpose() * J.rightCols<6>();
        U_.block<6, 6>(f2, f1) += J.rightCols<6>().transpose() * J.leftCols<6>();
        g_cam_.segment<6>(f2) += J.rightCols<6>().transpose() * r;
      }
    }
    return cost;
  }

  int NumFree(int camera) const {
    return static_cast<int>(problem_.cameras[camera].free_indices.size());
  }

  size_t Grain() const {
    return std::max<size_t>(256, problem_.points.size() / 64);
  }

  static double Clamp(double d) { return std::min(std::max(d, kMinDiagonal), kMaxDiagonal); }

  // Solves the damped normal equations (lambda = 1 / radius) by the Schur
  // complement; fills dx_cam_ / dx_point_ and the model cost decrease.
  bool SolveStep(double lambda, double* model_decrease) {
    const auto& obs = problem_.observations;
    struct Acc {
      Eigen::MatrixXd S;
      Eigen::VectorXd b;
    };
    Acc init{Eigen::MatrixXd::Zero(num_vars_, num_vars_), Eigen::VectorXd::Zero(num_vars_)};
    using IBlock = Eigen::Matrix<double, Eigen::Dynamic, 3, 0, kMaxFreeParams, 3>;
    using Mat63 = Eigen::Matrix<double, 6, 3>;
    Acc total = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, problem_.points.size(), Grain()), init,
        [&](const tbb::blocked_range<size_t>& range, Acc acc) {
          // W = J_cam^T J_point of the point: frame rows per observation
          // (Wf), intrinsics rows per distinct camera (Wi, summed over the
          // observations in that camera: they share the variables); T = W V^-1.
          std::vector<Mat63, Eigen::aligned_allocator<Mat63>> Wf, Tf;
          std::vector<IBlock> Wi, Ti;
          std::vector<int> cams;  // distinct cameras with free intrinsics
          for (size_t p = range.begin(); p != range.end(); ++p) {
            Mat3 Vd = V_[p];
            for (int k = 0; k < 3; ++k) Vd(k, k) += lambda * Clamp(V_[p](k, k));
            const Mat3 V_inv = Vd.inverse();
            V_inv_[p] = V_inv;
            const size_t begin = point_begin_[p];
            const size_t n = point_begin_[p + 1] - begin;
            Wf.resize(n);
            Tf.resize(n);
            cams.clear();
            Wi.clear();
            for (size_t a = 0; a < n; ++a) {
              const LinearisedObservation& l = lin_[begin + a];
              const SchurBaObservation& o = obs[begin + a];
              Wf[a].noalias() = l.j_frame.transpose() * l.j_point;
              Tf[a].noalias() = Wf[a] * V_inv;
              acc.b.segment<6>(6 * o.frame).noalias() -= Tf[a] * g_point_[p];
              const int nc = NumFree(o.camera);
              if (nc == 0) continue;
              size_t k = std::find(cams.begin(), cams.end(), o.camera) - cams.begin();
              if (k == cams.size()) {
                cams.push_back(o.camera);
                Wi.push_back(IBlock::Zero(nc, 3));
              }
              Wi[k].noalias() += l.j_intrinsics.leftCols(nc).transpose() * l.j_point;
            }
            Ti.resize(cams.size());
            for (size_t k = 0; k < cams.size(); ++k) {
              Ti[k].noalias() = Wi[k] * V_inv;
              acc.b.segment(camera_offset_[cams[k]], NumFree(cams[k])).noalias() -=
                  Ti[k] * g_point_[p];
            }
            // S -= W V^-1 W^T block by block (upper pairs, mirrored).
            for (size_t a = 0; a < n; ++a) {
              const int fa = 6 * obs[begin + a].frame;
              for (size_t c = a; c < n; ++c) {
                const int fc = 6 * obs[begin + c].frame;
                const Mat6 B = Tf[a] * Wf[c].transpose();
                acc.S.block<6, 6>(fa, fc) -= B;
                if (c != a) acc.S.block<6, 6>(fc, fa) -= B.transpose();
              }
              for (size_t k = 0; k < cams.size(); ++k) {
                const int ck = camera_offset_[cams[k]];
                const int nk = NumFree(cams[k]);
                const Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxFreeParams> B =
                    Tf[a] * Wi[k].transpose();
                acc.S.block(fa, ck, 6, nk) -= B;
                acc.S.block(ck, fa, nk, 6) -= B.transpose();
              }
            }
            for (size_t k = 0; k < cams.size(); ++k) {
              const int ck = camera_offset_[cams[k]];
              const int nk = NumFree(cams[k]);
              for (size_t m = k; m < cams.size(); ++m) {
                const int cm = camera_offset_[cams[m]];
                const int nm = NumFree(cams[m]);
                const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxFreeParams,
                                    kMaxFreeParams>
                    B = Ti[k] * Wi[m].transpose();
                acc.S.block(ck, cm, nk, nm) -= B;
                if (m != k) acc.S.block(cm, ck, nm, nk) -= B.transpose();
              }
            }
          }
          return acc;
        },
        [](Acc a, const Acc& b) {
          a.S += b.S;
          a.b += b.b;
          return a;
        });
    Eigen::MatrixXd S = U_ + total.S;
    Eigen::VectorXd rhs = -(g_cam_ + total.b);
    for (int k = 0; k < num_vars_; ++k) S(k, k) += lambda * Clamp(U_(k, k));
    for (int k = 0; k < num_vars_; ++k) {
      if (!fixed_[k]) continue;
      S.row(k).setZero();
      S.col(k).setZero();
      S(k, k) = 1.0;
      rhs(k) = 0.0;
    }
    Eigen::LLT<Eigen::MatrixXd> llt(S);
    if (llt.info() != Eigen::Success) return false;
    dx_cam_ = llt.solve(rhs);
    if (!dx_cam_.allFinite()) return false;
    // Back-substitution: dx_p = V^-1 (-g_p - sum W^T dx_cam).
    const double decrease = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, problem_.points.size(), Grain()), 0.0,
        [&](const tbb::blocked_range<size_t>& range, double sum) {
          for (size_t p = range.begin(); p != range.end(); ++p) {
            Vec3 rhs_p = -g_point_[p];
            for (size_t i = point_begin_[p]; i < point_begin_[p + 1]; ++i) {
              const LinearisedObservation& l = lin_[i];
              const int fo = 6 * obs[i].frame;
              const int co = camera_offset_[obs[i].camera];
              const int nc = NumFree(obs[i].camera);
              // J_p^T J_cam dx_cam
              Eigen::Vector2d j_dx = l.j_frame * dx_cam_.segment<6>(fo);
              if (nc > 0) j_dx += l.j_intrinsics.leftCols(nc) * dx_cam_.segment(co, nc);
              rhs_p -= l.j_point.transpose() * j_dx;
            }
            dx_point_[p] = V_inv_[p] * rhs_p;
            // Model decrease terms of the point: -0.5 g^T dx + 0.5 lambda dx^T D dx.
            sum += -0.5 * g_point_[p].dot(dx_point_[p]);
            for (int k = 0; k < 3; ++k) {
              sum += 0.5 * lambda * Clamp(V_[p](k, k)) * dx_point_[p](k) * dx_point_[p](k);
            }
          }
          return sum;
        },
        std::plus<double>());
    double cam_decrease = 0.0;
    for (int k = 0; k < num_vars_; ++k) {
      if (fixed_[k]) continue;
      cam_decrease += -0.5 * g_cam_(k) * dx_cam_(k) +
                      0.5 * lambda * Clamp(U_(k, k)) * dx_cam_(k) * dx_cam_(k);
    }
    *model_decrease = decrease + cam_decrease;
    return std::isfinite(*model_decrease);
  }

  State Step() const {
    State x = x_;
    for (size_t f = 0; f < x.q.size(); ++f) {
      const Vec3 dtheta = dx_cam_.segment<3>(6 * f);
      x.q[f] = (so3::Exp(dtheta) * x.q[f]).normalized();
      x.R[f] = x.q[f].toRotationMatrix();
      x.t[f] += dx_cam_.segment<3>(6 * f + 3);
    }
    if (problem_.has_rig_from_prior) {
      x.qx = (so3::Exp(Vec3(dx_cam_.segment<3>(x_offset_))) * x.qx).normalized();
      x.tx += problem_.rig_from_prior_translation_axes * dx_cam_.segment<3>(x_offset_ + 3);
    }
    for (size_t c = 0; c < x.params.size(); ++c) {
      const auto& free = problem_.cameras[c].free_indices;
      for (size_t k = 0; k < free.size(); ++k) {
        x.params[c][free[k]] += dx_cam_(camera_offset_[c] + static_cast<int>(k));
      }
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, x.points.size(), 4096),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t p = range.begin(); p != range.end(); ++p) {
                          x.points[p] += dx_point_[p];
                        }
                      });
    return x;
  }

  double StepNorm() const {
    double sq = dx_cam_.squaredNorm();
    for (const Vec3& d : dx_point_) sq += d.squaredNorm();
    return std::sqrt(sq);
  }

  double ParameterNorm() const {
    double sq = 0.0;
    for (size_t f = 0; f < x_.q.size(); ++f) sq += 1.0 + x_.t[f].squaredNorm();
    if (problem_.has_rig_from_prior) sq += 1.0 + x_.tx.squaredNorm();
    for (const auto& params : x_.params) {
      for (double v : params) sq += v * v;
    }
    for (const Vec3& p : x_.points) sq += p.squaredNorm();
    return std::sqrt(sq);
  }

  double GradientMaxNorm() const {
    double m = 0.0;
    for (int k = 0; k < num_vars_; ++k) {
      if (!fixed_[k]) m = std::max(m, std::abs(g_cam_(k)));
    }
    for (const Vec3& g : g_point_) m = std::max(m, g.cwiseAbs().maxCoeff());
    return m;
  }

  void RunInArena(SchurBaSummary* summary) {
    auto t0 = Clock::now();
    double cost = Linearise();
    summary->evaluation_seconds += SecondsSince(t0);
    summary->initial_cost = cost;
    summary->num_iterations = 1;
    double radius = kInitialRadius;
    double nu = 2.0;
    summary->termination = "NO_CONVERGENCE: maximum number of iterations reached";
    if (problem_.observations.empty() && problem_.pose_terms.empty()) {
      summary->termination = "CONVERGENCE: empty problem";
      summary->converged = true;
    } else if (GradientMaxNorm() <= options_.gradient_tolerance) {
      summary->termination = "CONVERGENCE: gradient tolerance reached";
      summary->converged = true;
    }
    for (int iteration = 0; !summary->converged && iteration < options_.max_num_iterations;
         ++iteration) {
      ++summary->num_iterations;
      const double lambda = 1.0 / radius;
      double model_decrease = 0.0;
      t0 = Clock::now();
      const bool solved = SolveStep(lambda, &model_decrease);
      summary->linear_solver_seconds += SecondsSince(t0);
      if (!solved || !(model_decrease > 0.0)) {
        radius /= nu;
        nu *= 2.0;
        continue;
      }
      if (StepNorm() <= options_.parameter_tolerance *
                            (ParameterNorm() + options_.parameter_tolerance)) {
        summary->termination = "CONVERGENCE: parameter tolerance reached";
        summary->converged = true;
        break;
      }
      t0 = Clock::now();
      const State candidate = Step();
      const double new_cost = Cost(candidate);
      summary->evaluation_seconds += SecondsSince(t0);
      const double rho = (cost - new_cost) / model_decrease;
      if (!std::isfinite(new_cost) || !(rho > kMinRelativeDecrease)) {
        radius /= nu;
        nu *= 2.0;
        continue;
      }
      const double relative_decrease = (cost - new_cost) / cost;
      x_ = candidate;
      ++summary->num_successful_steps;
      radius /= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3));
      radius = std::min(radius, 1e16);  // Ceres' max_trust_region_radius
      nu = 2.0;
      t0 = Clock::now();
      const double relinearised_cost = Linearise();
      summary->evaluation_seconds += SecondsSince(t0);
      cost = relinearised_cost;
      if (std::abs(relative_decrease) <= options_.function_tolerance) {
        summary->termination = "CONVERGENCE: function tolerance reached";
        summary->converged = true;
      } else if (GradientMaxNorm() <= options_.gradient_tolerance) {
        summary->termination = "CONVERGENCE: gradient tolerance reached";
        summary->converged = true;
      }
    }
    summary->final_cost = cost;
  }

  const SchurBaOptions& options_;
  SchurBaProblem& problem_;
  Loss loss_;
  int num_vars_ = 0;
  int x_offset_ = -1;  // first variable of X (has_rig_from_prior)
  std::vector<int> camera_offset_;
  std::vector<char> fixed_;
  std::vector<size_t> point_begin_;
  State x_;
  std::vector<LinearisedObservation> lin_;
  std::vector<Mat3> V_;
  std::vector<Vec3> g_point_;
  std::vector<Mat3> V_inv_;
  std::vector<Vec3> dx_point_;
  Eigen::MatrixXd U_;
  Eigen::VectorXd g_cam_;
  Eigen::VectorXd dx_cam_;
};

}  // namespace

bool SchurBaOptions::Check() const {
  CHECK_OPTION_MSG(loss_type,
                   loss_type == "trivial" || loss_type == "huber" || loss_type == "cauchy",
                   "one of trivial, huber, cauchy");
  CHECK_OPTION_GT(loss_scale, 0.0);
  CHECK_OPTION_GE(max_num_iterations, 0);
  CHECK_OPTION_GE(function_tolerance, 0.0);
  CHECK_OPTION_GE(gradient_tolerance, 0.0);
  CHECK_OPTION_GE(parameter_tolerance, 0.0);
  CHECK_OPTION_MSG(num_threads, num_threads == -1 || num_threads >= 1, "-1 or >= 1");
  return true;
}

SchurBaObservationLinearisation LineariseSchurBaObservation(const SchurBaProblem& problem,
                                                            int observation) {
  THROW_CHECK(observation >= 0 && observation < static_cast<int>(problem.observations.size()));
  const SchurBaObservation& o = problem.observations[observation];
  THROW_CHECK(o.frame >= 0 && o.frame < static_cast<int>(problem.frames.size()));
  THROW_CHECK(o.camera >= 0 && o.camera < static_cast<int>(problem.cameras.size()));
  THROW_CHECK(o.point >= 0 && o.point < static_cast<int>(problem.points.size()));
  const std::vector<int>& free_indices = problem.cameras[o.camera].free_indices;
  THROW_CHECK_LE(free_indices.size(), static_cast<size_t>(kMaxFreeParams));
  const State x = StateFromProblem(problem);
  LinearisedObservation lin;
  EvaluateObservation(problem, o, x, Loss(), &lin);
  SchurBaObservationLinearisation result;
  result.residual = lin.r;
  result.d_frame = lin.j_frame;
  result.d_point = lin.j_point;
  result.d_free_params = lin.j_intrinsics.leftCols(free_indices.size());
  return result;
}

SchurBaSummary SolveSchurBundleAdjustment(const SchurBaOptions& options,
                                          SchurBaProblem* problem) {
  THROW_CHECK(problem != nullptr);
  THROW_CHECK_OPTIONS(options);
  Solver solver(options, problem);
  return solver.Run();
}

}  // namespace colmap
}  // namespace lisfm
