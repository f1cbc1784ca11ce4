// Bayesian ICP: posterior over target_from_source by stochastic-gradient
// Langevin dynamics on SE(3) (Maken, Ramos, Ott, ICRA 2020, arXiv 2004.07973).
//
// Posterior: p(T | clouds) ∝ exp(-U(T)), U(T) = sum_i rho(r_i(T)) / sigma^2, where
// r_i is the point-to-plane residual of source point i *re-associated at T* (a
// point without an admissible match contributes a constant) and rho the robust
// kernel of IcpOptions. Each iteration draws a mini-batch B of source points
// (with replacement), re-associates them at the current sample, and steps
//   xi = -(eps/2) M^-1 g_hat + sqrt(eps (1 - eps/4)) M^-1/2 eta,   T <- T Exp(xi)
// (preconditioned SGLD, Li et al. AAAI 2016, Eq. 4), where
//  - g_hat = g(T0) + (N/B) sum_{i in B} (g_i(T) - g_i(T0)) is the mini-batch
//    gradient with a control variate at the ICP optimum T0 (Baker et al.,
//    "Control variates for stochastic gradient MCMC", 2019): unbiased for the
//    re-associated gradient, with variance that vanishes near T0, so a large step
//    can be used without the mini-batch noise inflating the posterior;
//  - M is the RMSprop-style preconditioner: an exponential moving average
//    (decay `metric_decay`) of the mini-batch Gauss-Newton curvature
//    (N/B) sum w_i J_i^T J_i / sigma^2 plus a small damping diag(1/s_rot^2, 1/s_trans^2)
//    that bounds steps along unobservable directions. (RMSprop averages g^2, whose
//    expectation is this curvature; the full 6x6 form makes the step isotropic in
//    the posterior's own metric, which Maken et al. get by normalising clouds.)
//  - the noise variance eps (1 - eps/4) instead of eps makes the Euler scheme
//    exact for a Gaussian target (the discretised Ornstein-Uhlenbeck chain then
//    has the target's stationary covariance), removing the O(eps) bias.
// After `burn_in` iterations every `thinning`-th sample is kept. The mean is the
// SE(3) Frechet mean (right-tangent iterations); the covariance is
// E[xi xi^T] with T_k = mean Exp(xi_k) (DESIGN.md convention, xi = [omega; v]).
//
// Threads: the mini-batch association runs in parallel (TBB); the chain is
// deterministic for a given seed and independent of the thread count.
// Failures: as RegisterPointToPlane (InputError for bad clouds).
#pragma once

#include <cstdint>
#include <vector>

#include "icp/icp.h"

namespace lisfm {

struct SgldOptions {
  int num_iterations = 1000;   // SGLD iterations including burn-in
  int burn_in = 100;           // iterations discarded at the start
  int thinning = 2;            // keep every k-th sample after burn-in
  int batch_size = 100;        // mini-batch of correspondences (50..300 in the paper)
  double step_size = 0.5;      // eps, in the preconditioned metric, (0, 2)
  double metric_decay = 0.99;  // EMA decay of the preconditioner (RMSprop beta)
  double damping_sigma_rotation_rad = 0.05;  // preconditioner damping scale (rad)
  double damping_sigma_translation_m = 0.5;  // preconditioner damping scale (m)
  uint64_t seed = 1;           // RNG seed of the chain
  bool keep_samples = false;   // return the kept samples
  bool Check() const;
};

// A sum-of-squares model for the sampler: term i at pose T gives a residual, its
// 1x6 Jacobian (right perturbation) and an IRLS weight, or false when the term has
// no admissible association at T. Must be thread-safe.
class SgldModel {
 public:
  virtual ~SgldModel() = default;
  virtual size_t NumTerms() const = 0;
  virtual bool Term(size_t i, const SE3& T, double* residual,
                    Eigen::Matrix<double, 1, 6>* jacobian, double* weight) const = 0;
};

struct SgldResult {
  SE3 mean;
  Mat6 covariance = Mat6::Zero();
  std::vector<SE3> samples;  // when keep_samples
  size_t num_samples = 0;
  size_t num_term_evaluations = 0;  // associations made along the chain
};

// Samples exp(-sum_i w-weighted r_i^2 / (2 sigma^2)) (the IRLS surrogate of the
// robust kernel at each sample) starting at `mode` (e.g. the ICP optimum), with
// sigma = noise_sigma (> 0). Throws InternalError for bad options.
SgldResult SampleSgld(const SgldModel& model,
                      const SE3& mode,
                      double noise_sigma,
                      const SgldOptions& options);

struct BayesianIcpOptions {
  IcpOptions icp;            // association, kernel and the initial ICP
  SgldOptions sgld;
  // Likelihood sigma (m). 0 (default): derived from the ICP residuals as
  //   sigma = noise_sigma_scale * sqrt(residual variance) * sqrt(points per cell),
  // where "points per cell" = source points / occupied cells of edge
  // correlation_length_m (1 when correlation_length_m = 0). Point-to-plane
  // residuals of real scans are not independent: neighbouring residuals share
  // target normals, voxel centroids and the different sampling of the same
  // surface in the two scans, so the error of the estimate does not shrink with
  // the point count the way N independent residuals would make it. Model A
  // inflates sigma by a constant; model B (correlation_length_m > 0) counts one
  // independent error per occupied cell (tempered likelihood, power N_eff / N).
  // The scale was calibrated on simulated office scan pairs only and checked on
  // held-out hall and staircase pairs (scripts/bench_icp_covariance.sh,
  // docs/BENCHMARKS.md (ICP section)). Default (model A): scale 3.15, no cells. Use scale 1 and
  // no cells for residuals that really are independent (synthetic i.i.d. noise).
  double noise_sigma_m = 0;
  double noise_sigma_scale = 3.15;
  double correlation_length_m = 0.0;
  bool Check() const;
};

struct BayesianIcpResult {
  IcpResult icp;          // the point estimate the chain starts from
  SgldResult posterior;   // mean, covariance (6x6, right perturbation), samples
  double noise_sigma_m = 0;  // sigma used in the likelihood
  double points_per_cell = 1;  // source points / occupied correlation cells (1 when off)
};

// Runs RegisterPointToPlane from `initial`, then SGLD around its result with
// correspondences re-associated at every sample.
BayesianIcpResult RegisterBayesian(const PointSet& source,
                                   const IcpTarget& target,
                                   const SE3& initial_target_from_source,
                                   const BayesianIcpOptions& options,
                                   const std::vector<Eigen::Vector3f>& source_normals = {});

}  // namespace lisfm
