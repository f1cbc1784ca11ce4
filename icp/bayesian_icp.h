// Bayesian ICP: posterior over target_from_source by stochastic-gradient
// Langevin dynamics on SE(3) (Maken, Ramos, Ott, ICRA 2020, arXiv 2004.07973).
//
// Posterior: p(T | clouds) ∝ exp(-U(T)), U(T) = sum_i rho(r_i(T)) / sigma^2 + U_prior(T), where
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
#include "icp/icp_covariance.h"

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

// Optional Gaussian prior on the pose: U_prior(T) = e^T information e / 2 with
// e = Log(mean^-1 T) (right perturbation, xi = [omega; v]). Zero information (the
// default) is the flat prior. The gradient and curvature use d e / d xi ~ I (the
// right Jacobian J_r^-1(e) = I + O(|e|); a prior wide enough to matter along an
// unobservable direction is a few degrees / decimetres, where that is a few %).
struct PosePrior {
  SE3 mean;
  Mat6 information = Mat6::Zero();  // inverse covariance (1/rad^2, 1/m^2 blocks)
};

// Samples exp(-sum_i w-weighted r_i^2 / (2 sigma^2) - U_prior) (the IRLS surrogate of
// the robust kernel at each sample) starting at `mode` (e.g. the ICP optimum), with
// sigma = noise_sigma (> 0). Throws InternalError for bad options.
SgldResult SampleSgld(const SgldModel& model,
                      const SE3& mode,
                      double noise_sigma,
                      const SgldOptions& options,
                      const PosePrior& prior = PosePrior());

// The association the Bayesian noise model is calibrated with: the IcpOptions defaults
// except for
//  - a Cauchy kernel of scale 0.05 m instead of Huber 0.1 m: matches without a true
//    counterpart (surfaces seen in one scan only) keep pulling through a Huber kernel,
//    and 0.03 m took 49 of 50 iterations on a real BALM pair;
//  - min_planarity 0.1: beyond a few metres the neighbours of a floor or ceiling point lie
//    on one LiDAR ring, a linear neighbourhood (planarity (l1 - l0) / l2 near 0) whose PCA
//    normal the range noise tilts alike over a whole sector, a bias no noise model sees;
//  - field_of_view_gate and visibility_gate_m 0.1 m: a source point on a surface the
//    target scan could not see (outside its vertical field of view, or behind another
//    surface) still matches the nearest surface the target did see, on stairs another
//    tread.
// Each was chosen on the tuning scenes (docs/BENCHMARKS.md, "Bayesian ICP covariance
// calibration"). The view gates assume clouds in their sensor frames (spin axis z); turn
// them off for other clouds (lisfm icp: --Bayesian.field_of_view_gate 0
// --Bayesian.visibility_gate 0).
IcpOptions BayesianDefaultIcpOptions();

struct BayesianIcpOptions {
  IcpOptions icp = BayesianDefaultIcpOptions();  // association, kernel and the initial ICP
  // k of the target's PCA normals the noise model is calibrated with. RegisterBayesian
  // receives a built target, so this is for the caller that builds the KdTreeTarget
  // (lisfm icp --method bayesian and the calibration bench do). 20 rather than the
  // ICP's 10: normals of 10 neighbours on a spinning LiDAR's ring-structured samples are
  // tilted along the ray by the range noise, a bias shared by whole surfaces
  // (docs/BENCHMARKS.md, "Bayesian ICP covariance calibration"). Not the ICP's default:
  // with the Huber kernel, k = 20 slid 1.96 m along the real pair BALM full34->full33.
  int normal_neighbors = 20;
  SgldOptions sgld;
  // Likelihood sigma (m). 0 (default): estimated per pair from the data as
  //   sigma = noise_sigma_scale * sqrt(ClusterSandwich::effective_variance_m2),
  // the cluster-robust (jackknife) sandwich (icp_covariance.h) at the ICP optimum
  // with the source cut into num_correlation_cells cubic cells (a coarse grid
  // with that many occupied cells, so the cells grow with the scene), or into cells
  // of edge correlation_length_m when num_correlation_cells = 0 (edge 0: every
  // point its own cell, the heteroscedastic i.i.d. variance).
  // Why: point-to-plane residuals of real scans are not independent. Neighbouring
  // residuals share target normals, voxel centroids and the different sampling of
  // the same surface in the two scans, so the error of the estimate does not shrink
  // with the point count as N independent residuals would make it (the i.i.d.
  // likelihood is 8x over-confident in variance on simulated office pairs). The
  // sandwich measures, per pair, how much the residual scores add up within a cell;
  // the likelihood is then tempered (power residual_variance / sigma^2 of the i.i.d.
  // likelihood: a generalised-Bayes "magnitude adjustment", Ribatet, Cooley &
  // Davison 2012) so that its Laplace covariance sigma^2 H^-1 has the sandwich's
  // expected NEES of 6. The chain keeps the shape of the re-associated posterior.
  // No point count, scene or noise level enters. For residuals that really are
  // independent (synthetic i.i.d. noise) the sandwich reduces to the residual variance.
  // On top, block_tempering rescales the posterior's rotation and translation blocks
  // separately to the jackknife.
  // noise_sigma_scale and num_correlation_cells are fitted on three simulated office
  // tuning scenes only, before any held-out scene is simulated: 48 cells gave the widest
  // range of scales at which the pooled tuning pairs meet both target bands (coverage of
  // the 95 % ellipsoid 92-98 %, mean NEES 5-7), and the scale is the geometric middle of
  // that range. Held-out hall + staircase pairs meet both bands, at the lower edge of the
  // coverage band; the staircase alone is over-confident and a degenerate corridor is not
  // calibrated (docs/BENCHMARKS.md, "Bayesian ICP covariance calibration").
  double noise_sigma_m = 0;
  double noise_sigma_scale = 1.063;   // multiplies the estimated sigma (fitted, see above)
  double correlation_length_m = 0.0;  // fixed cell edge (m); used when num_correlation_cells = 0
  int num_correlation_cells = 48;     // cells per pair (see above); 0: correlation_length_m
  // Prior on T around the initial guess, per axis 1-sigma (0 = flat along that
  // block). Set it to the initial guess's own uncertainty (odometry, IMU) to make the
  // posterior proper along directions the clouds do not observe (a corridor's
  // axis); with a flat prior the chain there wanders as far as its length lets it.
  // Caveat: the chain starts at the ICP optimum, which along such an axis can be far
  // (0.3 m on the bench's corridor) from the prior mean, and 1000 steps do not fully
  // relax it there; treat a `degenerate` ICP's weak axis with care either way.
  double prior_sigma_rotation_rad = 0;
  double prior_sigma_translation_m = 0;
  // Heteroscedastic per-correspondence variance v_i (CorrespondenceVarianceModel,
  // icp_covariance.h: plane-fit scatter + normal uncertainty x tangential offset) in
  // the likelihood and the sandwich: weights w_i v_ref / v_i, re-evaluated at every
  // re-association of the chain. Used only when sigma is estimated (noise_sigma_m =
  // 0) and the target is a KdTreeTarget; the ICP point estimate is unchanged.
  // Experimental, off by default: noise_sigma_scale is not calibrated with it.
  bool plane_fit_variance = false;
  CorrespondenceVarianceOptions correspondence_variance;
  // Per-pair rotation/translation block tempering: after the chain, the posterior's
  // two 3x3 blocks (covariance and kept samples) are rescaled about its mean by
  // f_b = tr(L_bb^-1 A_bb) / 3, L = sigma_eff^2 H^-1 the tempered Laplace covariance
  // and A the jackknife sandwich: each block's expected NEES under A made 3.
  // Clamped to [1/16, 16] (BayesianIcpResult::block_factors). Used only when sigma
  // is estimated; with a prior the factors (from the data alone) scale the whole
  // posterior, prior-dominated directions included. On by default: a scalar
  // temperature keeps the shape of H^-1, which on large scenes holds more rotation
  // information than the correlated errors support (docs/BENCHMARKS.md, "Bayesian ICP
  // covariance calibration").
  bool block_tempering = true;
  // Leverage power p of the cluster deltas (ComputeClusterSandwich): each cell's
  // whitened score is multiplied by (I - A_c)^-p, A_c its leverage. 1: CR3, the exact
  // delete-one-cell jackknife; 0: no leverage adjustment, i.e. the centred CR1
  // sandwich. 1 by default: on stairs the vertical rests on the few cells holding tread
  // matches, whose own residuals the estimate fitted (high leverage), so CR1
  // under-states it (docs/BENCHMARKS.md, "Bayesian ICP covariance calibration").
  double jackknife_leverage_power = 1.0;
  // Correspondence distance (m) of the likelihood's association: after the ICP
  // (which converges with icp.max_correspondence_distance_m from the initial
  // guess), the estimate is refined by a second ICP with this distance, and the
  // sandwich and the chain associate with it. 0, or not below the ICP's: off.
  // Points without a counterpart in the other scan then stop pulling through the
  // kernel's tail from up to icp.max_correspondence_distance_m away (0.2 m: more
  // accurate on stairs). Experimental, off by default: noise_sigma_scale is not
  // calibrated with it.
  double refine_max_correspondence_distance_m = 0.0;
  bool Check() const;
  // The association of the likelihood (sandwich and chain): icp, with the
  // correspondence distance narrowed by refine_max_correspondence_distance_m.
  IcpOptions LikelihoodAssociation() const;
};

struct BayesianIcpResult {
  IcpResult icp;          // the point estimate the chain starts from
  SgldResult posterior;   // mean, covariance (6x6, right perturbation), samples
  double noise_sigma_m = 0;  // sigma used in the likelihood
  // Likelihood variance over the i.i.d. residual variance (sigma^2 /
  // residual_variance_m2 of the sandwich pass): the per-pair variance inflation
  // factor ("design effect"); 1 for independent residuals. 0 when noise_sigma_m was given.
  double variance_inflation = 0;
  size_t num_clusters = 0;  // occupied cells of the sandwich (0 when noise_sigma_m was given)
  double cell_size_m = 0;   // cell edge of the sandwich (m)
  // Rotation / translation block factors applied to the posterior (1, 1 unless
  // BayesianIcpOptions::block_tempering).
  Eigen::Vector2d block_factors = Eigen::Vector2d::Ones();
  // Effective number of cells behind each block factor, (sum_c v_c)^2 / sum_c v_c^2
  // with v_c the cell's jackknife term delta_c,b^T L_bb^-1 delta_c,b (G when all cells
  // contribute alike, 1 when one cell dominates); 0 when sigma was given.
  Eigen::Vector2d block_effective_cells = Eigen::Vector2d::Zero();
};

// Runs RegisterPointToPlane from `initial`, estimates the likelihood sigma (see
// BayesianIcpOptions), then SGLD around the ICP result with correspondences
// re-associated at every sample (and the prior, if any, centred at `initial`).
// Failures: as RegisterPointToPlane (InputError for bad clouds), and InputError
// when the ICP result matches fewer than 7 points / 2 cells.
BayesianIcpResult RegisterBayesian(const PointSet& source,
                                   const IcpTarget& target,
                                   const SE3& initial_target_from_source,
                                   const BayesianIcpOptions& options,
                                   const std::vector<Eigen::Vector3f>& source_normals = {});

}  // namespace lisfm
