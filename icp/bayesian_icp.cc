#include "icp/bayesian_icp.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "core/errors.h"
#include "core/option_check.h"
#include "icp/icp_covariance.h"
#include "icp/icp_internal.h"

namespace lisfm {

namespace {

// Per-batch sums: sum (g_i(T) - g_i(T0)) and the curvature sum w J^T J.
struct BatchSums {
  Vec6 gradient_difference = Vec6::Zero();
  Mat6 curvature = Mat6::Zero();
};

// Point-to-plane terms re-associated at every pose (the ICP SgldModel).
class PointToPlaneModel : public SgldModel {
 public:
  // variance_model (optional): each term's IRLS weight is multiplied by
  // variance_reference_m2 / v_i, v_i re-evaluated for the match made at each pose.
  PointToPlaneModel(const PointSet& source,
                    const std::vector<Eigen::Vector3f>& normals,
                    const IcpTarget& target,
                    const IcpOptions& options,
                    const CorrespondenceVarianceModel* variance_model = nullptr,
                    double variance_reference_m2 = 0)
      : source_(source),
        normals_(normals),
        target_(target),
        base_(SE3(), options),
        variance_model_(variance_model),
        variance_reference_m2_(variance_reference_m2) {}

  // Per source point, the target index of its match at the mode (kNoHint: none),
  // e.g. ComputeClusterSandwich's matched_target_indices; used as search hints.
  void SetHints(std::vector<uint32_t> hints) { hints_ = std::move(hints); }

  size_t NumTerms() const override { return source_.size(); }

  bool Term(size_t i, const SE3& T, double* residual, Eigen::Matrix<double, 1, 6>* jacobian,
            double* weight) const override {
    internal::LinearizationContext ctx = base_;
    ctx.rotation_f = T.RotationMatrix().cast<float>();
    ctx.translation_f = T.translation().cast<float>();
    internal::LinearizedTerm term;
    const Eigen::Vector3f n = normals_.empty() ? Eigen::Vector3f::Zero() : normals_[i];
    if (variance_model_ == nullptr) {
      if (!internal::LinearizePoint(target_, ctx, source_[i], n, &term)) return false;
      *weight = term.weight;
    } else {
      // MatchWithHint returns Match()'s result and the matched index; the hint (this
      // point's match at the mode, read-only here) only bounds the search.
      const Eigen::Vector3f p_t = ctx.rotation_f * source_[i] + ctx.translation_f;
      const Eigen::Vector3f n_t = ctx.rotation_f * n;
      Eigen::Vector3f q, nq;
      uint32_t hint = hints_.empty() ? IcpTarget::kNoHint : hints_[i];
      if (!target_.MatchWithHint(p_t, n_t, ctx.criteria, &q, &nq, &hint)) {
        return false;
      }
      internal::LinearizeMatch(ctx, source_[i], q, nq, &term);
      *weight = term.weight * variance_reference_m2_ / variance_model_->Variance(hint, nq, p_t - q);
    }
    *residual = term.residual;
    *jacobian = term.jacobian;
    return true;
  }

 private:
  const PointSet& source_;
  const std::vector<Eigen::Vector3f>& normals_;
  const IcpTarget& target_;
  internal::LinearizationContext base_;
  const CorrespondenceVarianceModel* variance_model_;
  double variance_reference_m2_;
  std::vector<uint32_t> hints_;  // per source point: target index of its match at the mode
};

}  // namespace

bool SgldOptions::Check() const {
  CHECK_OPTION_GE(num_iterations, 1);
  CHECK_OPTION_GE(burn_in, 0);
  CHECK_OPTION_LT(burn_in, num_iterations);
  CHECK_OPTION_GE(thinning, 1);
  CHECK_OPTION_GE(batch_size, 1);
  CHECK_OPTION_MSG(step_size, step_size > 0 && step_size < 2, "in (0, 2)");
  CHECK_OPTION_MSG(metric_decay, metric_decay >= 0 && metric_decay < 1, "in [0, 1)");
  CHECK_OPTION_GT(damping_sigma_rotation_rad, 0.0);
  CHECK_OPTION_GT(damping_sigma_translation_m, 0.0);
  return true;
}

IcpOptions BayesianDefaultIcpOptions() {
  IcpOptions options;
  options.kernel = "cauchy";
  options.kernel_scale_m = 0.05;
  options.min_planarity = 0.1;
  options.field_of_view_gate = true;  // why: see bayesian_icp.h
  options.visibility_gate_m = 0.1;
  return options;
}

IcpOptions BayesianIcpOptions::LikelihoodAssociation() const {
  IcpOptions association = icp;
  if (refine_max_correspondence_distance_m > 0) {
    association.max_correspondence_distance_m =
        std::min(icp.max_correspondence_distance_m, refine_max_correspondence_distance_m);
  }
  return association;
}

bool BayesianIcpOptions::Check() const {
  CHECK_OPTION_NESTED(icp);
  CHECK_OPTION_MSG(normal_neighbors, normal_neighbors >= 3 && normal_neighbors <= 64, "in [3, 64]");
  CHECK_OPTION_NESTED(sgld);
  CHECK_OPTION_GE(noise_sigma_m, 0.0);
  CHECK_OPTION_GT(noise_sigma_scale, 0.0);
  CHECK_OPTION_GE(correlation_length_m, 0.0);
  CHECK_OPTION_MSG(num_correlation_cells, num_correlation_cells == 0 || num_correlation_cells >= 2,
                   "0 or >= 2");
  CHECK_OPTION_GE(prior_sigma_rotation_rad, 0.0);
  CHECK_OPTION_GE(prior_sigma_translation_m, 0.0);
  CHECK_OPTION_NESTED(correspondence_variance);
  CHECK_OPTION_GE(jackknife_leverage_power, 0.0);
  CHECK_OPTION_GE(refine_max_correspondence_distance_m, 0.0);
  return true;
}

SgldResult SampleSgld(const SgldModel& model,
                      const SE3& mode,
                      double noise_sigma,
                      const SgldOptions& options,
                      const PosePrior& prior) {
  THROW_CHECK_OPTIONS(options);
  THROW_CHECK_MSG(prior.information.allFinite() &&
                      Eigen::SelfAdjointEigenSolver<Mat6>(prior.information).eigenvalues()(0) >= 0,
                  "PosePrior information must be finite and positive semi-definite");
  const bool has_prior = !prior.information.isZero(0.0);
  const SE3 prior_mean_inverse = prior.mean.Inverse();
  // Prior gradient Lambda e, e = Log(mean^-1 T), and its curvature Lambda (see header).
  auto prior_gradient = [&](const SE3& T) -> Vec6 {
    return has_prior ? Vec6(prior.information * (prior_mean_inverse * T).Log()) : Vec6::Zero();
  };
  THROW_CHECK_GT(noise_sigma, 0.0);
  const size_t n = model.NumTerms();
  THROW_CHECK_GT(n, 0u);
  const double inv_var = 1.0 / (noise_sigma * noise_sigma);

  // Control variate: per-term gradients at the mode, and their sum; one association
  // pass (the curvature terms sqrt(w) J / sigma are kept for the reduction).
  std::vector<Vec6> mode_gradients(n, Vec6::Zero());
  std::vector<Vec6> mode_scaled_jacobians(n, Vec6::Zero());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
    double residual, weight;
    Eigen::Matrix<double, 1, 6> J;
    for (size_t i = r.begin(); i != r.end(); ++i) {
      if (model.Term(i, mode, &residual, &J, &weight)) {
        mode_gradients[i] = J.transpose() * (weight * residual * inv_var);
        mode_scaled_jacobians[i] = J.transpose() * std::sqrt(weight * inv_var);
      }
    }
  });
  BatchSums mode_sums = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<size_t>(0, n, 1024), BatchSums(),
      [&](const tbb::blocked_range<size_t>& r, BatchSums s) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          s.gradient_difference += mode_gradients[i];
          s.curvature.noalias() += mode_scaled_jacobians[i] * mode_scaled_jacobians[i].transpose();
        }
        return s;
      },
      [](BatchSums a, const BatchSums& b) {
        a.gradient_difference += b.gradient_difference;
        a.curvature += b.curvature;
        return a;
      });
  const Vec6 mode_gradient = mode_sums.gradient_difference;
  const Mat6 prior_curvature = 0.5 * (prior.information + prior.information.transpose());

  Vec6 damping;
  damping << Eigen::Vector3d::Constant(1.0 / std::pow(options.damping_sigma_rotation_rad, 2)),
      Eigen::Vector3d::Constant(1.0 / std::pow(options.damping_sigma_translation_m, 2));
  Mat6 metric = mode_sums.curvature + prior_curvature;
  metric.diagonal() += damping;

  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  std::normal_distribution<double> normal(0.0, 1.0);
  const size_t batch = static_cast<size_t>(options.batch_size);
  const double scale = static_cast<double>(n) / static_cast<double>(batch);
  const double eps = options.step_size;
  const double noise_scale = std::sqrt(eps * (1.0 - eps / 4.0));
  std::vector<size_t> indices(batch);

  SgldResult result;
  std::vector<SE3> kept;
  kept.reserve(static_cast<size_t>((options.num_iterations - options.burn_in) / options.thinning + 1));
  SE3 T = mode;
  for (int it = 0; it < options.num_iterations; ++it) {
    for (auto& i : indices) i = pick(rng);
    const BatchSums sums = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, batch, 32), BatchSums(),
        [&](const tbb::blocked_range<size_t>& r, BatchSums s) {
          double residual, weight;
          Eigen::Matrix<double, 1, 6> J;
          for (size_t k = r.begin(); k != r.end(); ++k) {
            const size_t i = indices[k];
            s.gradient_difference -= mode_gradients[i];
            if (model.Term(i, T, &residual, &J, &weight)) {
              s.gradient_difference += J.transpose() * (weight * residual * inv_var);
              s.curvature.noalias() += J.transpose() * J * (weight * inv_var);
            }
          }
          return s;
        },
        [](BatchSums a, const BatchSums& b) {
          a.gradient_difference += b.gradient_difference;
          a.curvature += b.curvature;
          return a;
        });
    result.num_term_evaluations += batch;
    const Vec6 gradient = mode_gradient + scale * sums.gradient_difference + prior_gradient(T);
    Mat6 batch_metric = scale * sums.curvature + prior_curvature;
    batch_metric.diagonal() += damping;
    metric = options.metric_decay * metric + (1.0 - options.metric_decay) * batch_metric;
    const Eigen::LLT<Mat6> llt(metric);
    THROW_CHECK_MSG(llt.info() == Eigen::Success, "SGLD preconditioner is not positive definite");
    Vec6 eta;
    for (int k = 0; k < 6; ++k) eta(k) = normal(rng);
    const Vec6 step = -0.5 * eps * llt.solve(gradient) + noise_scale * llt.matrixU().solve(eta);
    T = T * SE3::Exp(step);
    if (it >= options.burn_in && (it - options.burn_in) % options.thinning == 0) kept.push_back(T);
  }

  // Frechet mean on SE(3) by right-tangent averaging, then the covariance.
  SE3 mean = mode;
  for (int iter = 0; iter < 10; ++iter) {
    Vec6 delta = Vec6::Zero();
    for (const SE3& s : kept) delta += (mean.Inverse() * s).Log();
    delta /= static_cast<double>(kept.size());
    mean = mean * SE3::Exp(delta);
    if (delta.norm() < 1e-12) break;
  }
  Mat6 cov = Mat6::Zero();
  for (const SE3& s : kept) {
    const Vec6 xi = (mean.Inverse() * s).Log();
    cov += xi * xi.transpose();
  }
  result.mean = mean;
  result.covariance = kept.size() > 1 ? Mat6(cov / static_cast<double>(kept.size() - 1)) : cov;
  result.num_samples = kept.size();
  if (options.keep_samples) result.samples = std::move(kept);
  return result;
}

BayesianIcpResult RegisterBayesian(const PointSet& source,
                                   const IcpTarget& target,
                                   const SE3& initial,
                                   const BayesianIcpOptions& options,
                                   const std::vector<Eigen::Vector3f>& source_normals) {
  THROW_CHECK_OPTIONS(options);
  BayesianIcpResult result;
  result.icp = RegisterPointToPlane(source, target, initial, options.icp, source_normals);
  // The likelihood's association: the ICP's, with the correspondence distance
  // narrowed to refine_max_correspondence_distance_m once the ICP has converged
  // (the ICP estimate is refined with it first, so the chain starts at its mode).
  const IcpOptions association = options.LikelihoodAssociation();
  if (association.max_correspondence_distance_m < options.icp.max_correspondence_distance_m) {
    IcpResult refined = RegisterPointToPlane(source, target, result.icp.target_from_source,
                                             association, source_normals);
    refined.iterations += result.icp.iterations;
    result.icp = std::move(refined);
  }
  double sigma = options.noise_sigma_m;
  std::unique_ptr<CorrespondenceVarianceModel> variance_model;
  double variance_reference_m2 = 0;
  std::vector<uint32_t> mode_matches;
  if (sigma <= 0) {
    const auto* kd_target = dynamic_cast<const KdTreeTarget*>(&target);
    if (options.plane_fit_variance && kd_target != nullptr) {
      variance_model =
          std::make_unique<CorrespondenceVarianceModel>(*kd_target, options.correspondence_variance);
    }
    // Per-pair likelihood scale from the cluster-robust sandwich at the ICP optimum.
    const size_t cells = static_cast<size_t>(options.num_correlation_cells);
    result.cell_size_m =
        cells > 0 ? CellSizeForClusterCount(source, cells) : options.correlation_length_m;
    const ClusterSandwich sandwich =
        ComputeClusterSandwich(source, target, result.icp.target_from_source, association,
                               result.cell_size_m, source_normals, variance_model.get(),
                               &mode_matches, options.jackknife_leverage_power);
    variance_reference_m2 = sandwich.variance_reference_m2;
    sigma = options.noise_sigma_scale * std::sqrt(sandwich.effective_variance_m2);
    if (options.block_tempering) {
      // Block factors f_b = tr(L_bb^-1 A_bb) / 3, L = sigma_eff^2 H^-1 the tempered
      // Laplace covariance and A the jackknife: the expected NEES / 3 of each 3x3
      // marginal of L under errors ~ N(0, A). Clamped to [1/16, 16] (a cell alone
      // determining a block makes the jackknife block arbitrarily large or small).
      const Mat6 laplace = sandwich.effective_variance_m2 * SafeInverse(sandwich.hessian);
      const Mat6& jack = sandwich.jackknife_covariance;
      const Eigen::LLT<Eigen::Matrix3d> l_rot(laplace.topLeftCorner<3, 3>());
      const Eigen::LLT<Eigen::Matrix3d> l_trans(laplace.bottomRightCorner<3, 3>());
      const double f_rot = l_rot.solve(jack.topLeftCorner<3, 3>()).trace() / 3.0;
      const double f_trans = l_trans.solve(jack.bottomRightCorner<3, 3>()).trace() / 3.0;
      auto clamp_factor = [](double f) {
        return std::isfinite(f) && f > 0 ? std::clamp(f, 1.0 / 16.0, 16.0) : 1.0;
      };
      result.block_factors << clamp_factor(f_rot), clamp_factor(f_trans);
      // Diagnostic: how many cells share each block's jackknife variance.
      Eigen::Vector2d sum = Eigen::Vector2d::Zero(), sum_sq = Eigen::Vector2d::Zero();
      for (const Vec6& d : sandwich.jackknife_deltas) {
        const Eigen::Vector2d v(d.head<3>().dot(l_rot.solve(d.head<3>())),
                                d.tail<3>().dot(l_trans.solve(d.tail<3>())));
        sum += v;
        sum_sq += v.cwiseProduct(v);
      }
      for (int b = 0; b < 2; ++b) {
        result.block_effective_cells(b) = sum_sq(b) > 0 ? sum(b) * sum(b) / sum_sq(b) : 0.0;
      }
    }
    result.num_clusters = sandwich.num_clusters;
    // A perfect fit (synthetic data) has zero residuals: floor sigma at 1 um.
    sigma = std::max(sigma, 1e-6);
    result.variance_inflation =
        sandwich.residual_variance_m2 > 0 ? sigma * sigma / sandwich.residual_variance_m2 : 0.0;
  }
  result.noise_sigma_m = std::max(sigma, 1e-6);
  PosePrior prior;
  prior.mean = initial;
  Vec6 prior_precision = Vec6::Zero();
  if (options.prior_sigma_rotation_rad > 0) {
    prior_precision.head<3>().setConstant(1.0 / std::pow(options.prior_sigma_rotation_rad, 2));
  }
  if (options.prior_sigma_translation_m > 0) {
    prior_precision.tail<3>().setConstant(1.0 / std::pow(options.prior_sigma_translation_m, 2));
  }
  prior.information = prior_precision.asDiagonal();
  PointToPlaneModel model(source, source_normals, target, association, variance_model.get(),
                          variance_reference_m2);
  model.SetHints(std::move(mode_matches));
  result.posterior = SampleSgld(model, result.icp.target_from_source, result.noise_sigma_m,
                                options.sgld, prior);
  if (result.block_factors != Eigen::Vector2d::Ones()) {
    // Rescale the rotation and translation blocks of the posterior about its mean.
    Vec6 d;
    d << Eigen::Vector3d::Constant(std::sqrt(result.block_factors(0))),
        Eigen::Vector3d::Constant(std::sqrt(result.block_factors(1)));
    result.posterior.covariance = d.asDiagonal() * result.posterior.covariance * d.asDiagonal();
    const SE3 mean_inverse = result.posterior.mean.Inverse();
    for (SE3& sample : result.posterior.samples) {
      sample = result.posterior.mean * SE3::Exp(d.asDiagonal() * (mean_inverse * sample).Log());
    }
  }
  return result;
}

}  // namespace lisfm
