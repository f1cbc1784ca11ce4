// Closed-form ICP covariances and the cluster-robust sandwich.
//
// Both closed forms use the point-to-plane linearisation at the ICP optimum
// (IcpResult::hessian H = sum w J^T J, xi = [omega; v] on the right, DESIGN.md):
//  - ClosedFormCovariance = sigma^2 H^-1 with sigma^2 = sum w r^2 / (N - 6): the
//    Gauss-Newton / Laplace covariance. It treats correspondences as fixed and
//    residuals as independent, hence over-confident (REFERENCES.md section 4).
//  - CensiCovariance = H^-1 (sum w^2 r_i^2 J_i^T J_i) H^-1: the sandwich form of
//    Censi (ICRA 2007) with each correspondence's own squared residual as its
//    variance (heteroscedasticity-consistent); valid for point-to-plane
//    (Bonnabel et al. 2016).
//  - ClusterSandwich: the cluster-robust ("block") sandwich H^-1 M_c H^-1 with
//    M_c = G/(G-1) sum_c g_c g_c^T, g_c the summed score w r J^T of the
//    correspondences whose source point lies in spatial cell c (Liang & Zeger 1986;
//    Cameron & Miller 2015, "CR1" with the small-sample factor G/(G-1)). It
//    stays valid when residuals are correlated within a cell (shared target normals,
//    voxel centroids, the two scans sampling the same surface differently), which
//    is what dominates the error of LiDAR ICP; the Censi form is its 1-point-cell
//    special case. Also computed: the delete-one-cluster jackknife (CR3), and the
//    scalar "effective variance" that Bayesian ICP tempers its likelihood to.
// Unobservable directions (eigenvalues of H below 1e-12 of the largest) are given
// a variance of 1e12 (m^2 / rad^2) instead of an exception: "unknown".
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "core/geometry.h"
#include "icp/icp.h"

namespace lisfm {

Mat6 ClosedFormCovariance(const IcpResult& result);
Mat6 CensiCovariance(const IcpResult& result);

// Inverse of a symmetric PSD 6x6 with the 1e12 rule above.
Mat6 SafeInverse(const Mat6& information);

// ---- Heteroscedastic per-correspondence variance (plane-fit uncertainty) ----
//
// A point-to-plane residual r = n^T (p - q) (p the mapped source point, q the
// matched target point, n its PCA normal, all in the target frame) carries, beyond
// the range noise, the error of the fitted normal times the tangential offset
// d = (I - n n^T)(p - q): r_err ~ dn^T d. On spinning-LiDAR scans a far target
// point's k neighbours often lie on one or two rings, its normal is badly determined
// about the ring direction, and a source point from the other scan sits across the
// rings from it (|d| large): such residuals are large, shared along the ring
// segment (correlated) and carry the most rotation leverage. The model
//   v_i = plane_variance_weight * l0 + d^T Cov(n) d + floor_m2            (m^2)
// gives them their own variance, with l0 the smallest eigenvalue of the target
// neighbourhood covariance (the out-of-plane scatter: noise of q, and by symmetry of
// p) and, by the asymptotic distribution of a sample covariance's eigenvector
// (Anderson 1963; the plane-fit normal is the eigenvector of l0 among k points),
//   Cov(n) = sum_{j=1,2} min(t_max, l0 l_j / (k (l_j - l0)^2)) e_j e_j^T   (rad^2),
// l0 <= l1 <= l2 the eigenvalues and e_j the eigenvectors of the neighbourhood
// covariance, k the neighbour count. A tilt variance of an in-plane direction
// spread l_j ~ sigma^2 / (k l_j) (sigma^2 = l0), capped at t_max where the
// neighbourhood is a line (one ring) or a blob.
struct PlaneFit {
  Eigen::Vector3d eigenvalues = Eigen::Vector3d::Zero();    // ascending, m^2 (population covariance)
  Eigen::Matrix3d eigenvectors = Eigen::Matrix3d::Identity();  // columns, col(0) the normal
  int count = 0;                                            // points used
};

// PCA of `points` (covariance about their mean; offsets from points[0] for
// stability). count < 3 or a zero spread: count is set but eigenvalues stay zero.
PlaneFit FitPlane(const std::vector<Eigen::Vector3d>& points);

// Cov(n) of the formula above (3x3, rad^2, in the span of e1, e2); zero for count < 3.
Eigen::Matrix3d PlaneFitNormalCovariance(const PlaneFit& fit, double max_tilt_variance_rad2);

struct CorrespondenceVarianceOptions {
  double plane_variance_weight = 2.0;     // multiplies l0 (q's and p's own scatter; 2 = both)
  double max_tilt_variance_rad2 = 0.25;   // t_max: cap of a normal tilt variance (rad^2)
  double floor_m2 = 1e-6;                 // added to every v_i (m^2): 1 mm^2, keeps weights finite
  bool Check() const;
};

// Per-target-point plane statistics of a KdTreeTarget (the same k-neighbourhoods as
// its normals: target.normal_options()), computed lazily the first time a target
// point is asked for and cached (thread-safe, deterministic). Immutable interface.
class CorrespondenceVarianceModel {
 public:
  CorrespondenceVarianceModel(const KdTreeTarget& target, const CorrespondenceVarianceOptions& options);
  ~CorrespondenceVarianceModel();
  // v_i (m^2) of the residual of a match of target point `target_index` with unit
  // normal `normal`, offset = p - q (target frame, m).
  double Variance(uint32_t target_index, const Eigen::Vector3f& normal,
                  const Eigen::Vector3f& offset) const;
  const KdTreeTarget& target() const { return target_; }

 private:
  struct Stats {
    float l0 = 0;                 // smallest eigenvalue (m^2)
    float cov[6] = {0, 0, 0, 0, 0, 0};  // Cov(n) upper triangle xx xy xz yy yz zz (rad^2)
  };
  Stats StatsAt(uint32_t index) const;
  const KdTreeTarget& target_;
  CorrespondenceVarianceOptions options_;
  mutable std::vector<Stats> stats_;
  mutable std::unique_ptr<std::atomic<uint8_t>[]> state_;  // 0 unknown, 1 busy, 2 ready
};

struct ClusterSandwich {
  Mat6 hessian = Mat6::Zero();     // H = sum w J^T J over the matched source points
  Mat6 meat = Mat6::Zero();        // M_c = G/(G-1) sum_c g_c g_c^T, g_c = sum_{i in c} w r J^T
  Mat6 covariance = Mat6::Zero();  // CR1: H^-1 M_c H^-1 (SafeInverse), right perturbation
  // CR3, the delete-one-cluster jackknife (G-1)/G sum_c (d_c - mean d)(d_c - mean d)^T
  // with d_c = (H - H_c)^-1 g_c the one-step change of the estimate when cluster c is
  // left out (exact for a linear model; H_c the cluster's own sum w J^T J, its
  // whitened leverage capped at 0.95). Unlike CR1 it does not shrink when a few
  // large clusters dominate a direction (the residuals there were fitted by it).
  // With leverage_power p != 1 the whitened deltas are (I - A_c)^-p W g_c instead
  // (p = 0: the centred CR1 form).
  Mat6 jackknife_covariance = Mat6::Zero();
  // The G centred jackknife deltas (d_c - mean d) in parameter coordinates (the
  // one-step change of the estimate when cell c is left out, right perturbation):
  // jackknife_covariance = (G-1)/G sum of their outer products (+ the null space).
  std::vector<Vec6> jackknife_deltas;
  size_t num_terms = 0;            // matched source points
  size_t num_clusters = 0;         // G: occupied cells with at least one match
  double residual_variance_m2 = 0;   // sum w r^2 / (N - 6): the i.i.d. sigma^2
  // Per-correspondence variance (m^2) that makes the i.i.d. likelihood reproduce a
  // sandwich S on average: sigma^2 = tr(H S) / 6, the mean eigenvalue of S in the
  // metric of H (directions without curvature left out). A likelihood
  // exp(-sum w r^2 / (2 sigma^2)) has Laplace covariance sigma^2 H^-1, whose
  // expected NEES against errors ~ N(0, S) is then exactly 6. For independent
  // homoscedastic residuals it equals residual_variance_m2 (up to N/(N-6) and the
  // weights); larger when neighbouring residuals are correlated. A scalar uses all
  // G x 6 cluster scores at once, so it stays stable with G ~ 20 clusters where the
  // 6x6 matrix S itself is far too noisy to use (docs: bench_icp_covariance.sh).
  double effective_variance_m2 = 0;            // from the jackknife (CR3), used by RegisterBayesian
  double effective_variance_cr1_m2 = 0;        // from CR1: tr(H^-1 M_c) / 6
  // With a CorrespondenceVarianceModel: every term is weighted by
  // variance_reference_m2 / v_i (the IRLS weight times that), where
  // variance_reference_m2 is the mean v_i over the matches; all sums above
  // (hessian, meat, residual variance, effective variances) use those weights, so
  // the variances keep their meaning "per correspondence of average v". 0 without a model.
  double variance_reference_m2 = 0;
};

// The edge (m) of a coarse cubic grid (origin-anchored, source frame) whose
// occupied cells number at least `num_cells`, with fewer cells at a slightly larger
// edge (the count is not monotone in the edge, so this is one crossing, close to
// but not always exactly the coarsest such grid): bisection on log(edge) over
// [1 cm, bounding-box diagonal], 16 steps (relative precision ~1e-4 of the log
// range, i.e. < 0.2 % of the edge for diagonals up to 1 km); cells are counted
// over at most ~4096 evenly strided points of the cloud. Used to
// partition a scan into a fixed number of large spatial clusters, which keeps the
// cluster sandwich meaningful when the error correlation spans whole surfaces
// (Bester, Conley & Hansen, J. Econometrics 2011: few large groups for spatially
// dependent data). Throws InputError for an empty or non-finite cloud; returns
// 1 cm when even that gives fewer cells, and the diagonal when even that gives
// num_cells or more (a cloud around the origin spans up to 8 octants).
double CellSizeForClusterCount(const PointSet& points, size_t num_cells);

// Re-associates every source point at `target_from_source` (same association,
// rejection and robust weights as RegisterPointToPlane with `options`), groups the
// matches by the cubic cell of edge `cell_size_m` (source frame) that holds the
// source point, and returns the cluster-robust sandwich (CR1 and jackknife).
// variance_model (optional; its target must be `target`): heteroscedastic weights,
// see ClusterSandwich::variance_reference_m2. matched_target_indices (optional,
// with a model): per source point the matched target index, IcpTarget::kNoHint if none.
// leverage_power p: the jackknife deltas use (I - A_c)^-p (1: CR3, the exact
// delete-one-cluster change; 0.5: the CR2 / Bell-McCaffrey adjustment).
// cell_size_m = 0 puts every point in its own cluster (the Censi/HC1 form). Throws InputError for bad clouds (as
// RegisterPointToPlane) and when fewer than 7 points or 2 clusters match.
ClusterSandwich ComputeClusterSandwich(const PointSet& source,
                                       const IcpTarget& target,
                                       const SE3& target_from_source,
                                       const IcpOptions& options,
                                       double cell_size_m,
                                       const std::vector<Eigen::Vector3f>& source_normals = {},
                                       const CorrespondenceVarianceModel* variance_model = nullptr,
                                       std::vector<uint32_t>* matched_target_indices = nullptr,
                                       double leverage_power = 1.0);

}  // namespace lisfm
