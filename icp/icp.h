// Point-to-plane ICP with two association modes behind one interface.
//
// Conventions (DESIGN.md): the estimate is target_from_source (x_target =
// T * x_source); increments and uncertainty live on the right, T = T_hat Exp(xi),
// xi = [omega; v] (rotation first), rad and m.
//
// Residual of source point p matched to target point q with target normal n:
//   r = n^T (T p - q).
// With T = T_hat Exp(xi) and Exp(xi) p ~ p + omega x p + v, and m = R_hat^T n:
//   r(xi) ~ r + m^T(-[p]x omega + v)   =>   J = [ (p x m)^T , m^T ]   (1x6).
// This is A_i = n_i^T [-[p_i]x  I] written in the source frame (the right
// perturbation). Each iteration (one association of every source point of
// the current level) solves the 6x6 normal equations
// (sum w J^T J) xi = -(sum w J^T r) by Cholesky (LDLT with a tiny Levenberg
// damping so that degenerate directions do not blow up), then T <- T Exp(xi),
// and re-solves up to max_inner_iterations times on the same matches (IRLS
// re-weighting; no nearest-neighbour search) until a step is below the
// convergence thresholds. Weights w come from the robust kernel (IRLS).
// Correspondences are rejected by distance |Tp - q| > max_correspondence_distance_m,
// by the normal angle when source normals are given, and by target planarity.
// Speed: coarse-to-fine source subsets (coarse_stride), a tracked nearest
// neighbour per source point (IcpTarget::MatchTracked: no search while the point
// cannot have changed its nearest target point), and the Besl & McKay (1992)
// extrapolation of aligned, shrinking successive steps (see icp.cc); none of
// them changes the fixed point, only how fast it is reached. Convergence is
// always decided by a plain step of an association at full resolution.
//
// Failures: bad user input (empty, tiny or non-finite clouds, size mismatches)
// throws InputError; an unusable solve (too few inliers) is a value:
// converged = false with a message. A geometrically degenerate problem (a plane,
// a corridor) is reported with degenerate = true and converged = false.
// Threads: the per-iteration association and accumulation are TBB parallel
// deterministic reductions; results do not depend on the thread count.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "icp/nearest_neighbors.h"
#include "icp/normals.h"

namespace lisfm {

enum class RobustKernel { kNone, kHuber, kCauchy, kGemanMcClure };

// "none", "huber", "cauchy", "geman_mcclure"; throws UsageError otherwise.
RobustKernel RobustKernelFromString(const std::string& name);
std::string RobustKernelToString(RobustKernel kernel);

// IRLS weight w(r) = rho'(r) / r for scale k (m):
//   Huber   rho = r^2/2 (|r| <= k), k|r| - k^2/2 else;   w = min(1, k/|r|)
//   Cauchy  rho = k^2/2 log(1 + r^2/k^2);                 w = 1 / (1 + r^2/k^2)
//   Geman-McClure rho = r^2 k^2 / (2 (k^2 + r^2));        w = k^4 / (k^2 + r^2)^2
double RobustWeight(RobustKernel kernel, double r, double k);
double RobustLoss(RobustKernel kernel, double r, double k);

struct IcpOptions {
  int max_iterations = 50;                   // associations (outer iterations), each + a Gauss-Newton solve
  int max_inner_iterations = 5;              // extra GN/IRLS solves on the same matches per association (0 = none)
  double max_correspondence_distance_m = 1.0;  // reject |Tp - q| above this (m)
  double max_normal_angle_deg = 45.0;        // reject when source/target normals differ more (deg; used when source normals are given)
  double min_planarity = 0.0;                // ignore target points with lower planarity, [0, 1]
  // KdTreeTarget with estimated normals only: ignore target points whose normal is
  // not determined by their neighbourhood, i.e. with contrast (l1 - l0) / l1 below
  // this (l0 <= l1 <= l2 the eigenvalues of the neighbourhood's covariance), [0, 1]. Unlike
  // min_planarity ((l1 - l0) / l2) it does not depend on the neighbourhood's length
  // l2: the neighbours of a far floor point on one LiDAR ring (a long thin line, curved,
  // thickened by the range noise mostly along the ray) have planarity near 0 but a
  // determined normal (l0 / l1 ~ sin^2 of the grazing angle), while a straight line
  // (l0 ~ l1) has none. 0 = off.
  double min_normal_contrast = 0.0;
  std::string kernel = "huber";              // none | huber | cauchy | geman_mcclure
  double kernel_scale_m = 0.1;               // robust kernel scale k (m)
  double convergence_rotation_rad = 1e-4;    // stop when |omega| of a step is below (rad)
  double convergence_translation_m = 1e-4;   // ... and |v| is below (m)
  int min_inliers = 12;                      // fewer matches -> not converged
  int coarse_stride = 4;                     // k: the finest coarse level uses every k-th source point (1 = off)
  // Coarse levels at most: every 2^(L-1) k-th, ..., 2k-th, k-th source point; a level is
  // used only when its subset keeps at least coarse_min_points source points. Why these
  // values: see icp.cc.
  int coarse_levels = 3;
  int coarse_min_points = 600;
  double degeneracy_threshold = 0.02;        // min/max eigenvalue ratio of the translation Hessian; a tenth of it for the scaled 6x6 (see icp.cc)
  // KdTreeTarget only (others ignore it): no match for a source point that the
  // target scan could not have observed, i.e. (in the target frame, seen from the
  // target's viewpoint) at an elevation outside the 0.1-99.9 % range of the target
  // points' own elevations, or farther than the farthest target point. For scans in
  // their sensor frame with the spin axis along z (the vertical field of view of a
  // spinning LiDAR). Why: such points still find the nearest surface the target did
  // see and pull towards it; on stairs that is another tread, a vertical bias that
  // grows with the vertical motion between the scans. RegisterPointToPlane decides
  // the gate once per source point (at its first association, MatchState::in_view).
  // Off by default (a user's target need not be in its sensor frame); on, with
  // visibility_gate_m, in BayesianDefaultIcpOptions (docs/BENCHMARKS.md, "Bayesian ICP
  // covariance calibration").
  bool field_of_view_gate = false;
  // KdTreeTarget only: no match for a source point (in the target frame) that lies
  // more than this (m) plus 2 % of its range behind the nearest target point in
  // its direction, i.e. hidden from the target's viewpoint by a surface the target
  // scanned (a spherical range image of the target: bins of 0.5 deg azimuth x 1 deg
  // elevation, a 32-ring LiDAR's ring spacing; a bin without target points hides
  // nothing). 0 = off. Same scope and same once-per-source-point decision in
  // RegisterPointToPlane as field_of_view_gate. Why: a source point on a surface the
  // target could not see (a tread behind a flight of stairs) still finds the nearest
  // surface the target did see. Off by default; 0.1 m in BayesianDefaultIcpOptions,
  // where with field_of_view_gate it raised the simulated stair tower's coverage of the
  // 95 % ellipsoid from 55 to 72 % (docs/BENCHMARKS.md, "Bayesian ICP covariance
  // calibration").
  double visibility_gate_m = 0.0;
  // With visibility_gate_m > 0: a source point farther than that bound is still visible
  // when it is not behind the surface element (point and normal) of its bin's nearest
  // target point: its range r <= 1.02 t + visibility_gate_m, with t the range at which
  // its ray meets that element's plane (infinite when the ray does not meet the plane
  // from the front). Why: a floor or ceiling seen at grazing incidence spans a long range
  // interval within one bin (at range r from a sensor h above it, r^2 / h per radian of
  // elevation: 13.4 to 16.0 m across one 1 deg bin at 15 m, h = 1.4 m), so the nearest
  // range alone hides most of the bin's own surface.
  bool visibility_follows_surface = false;
  bool Check() const;
};

// What an admissible match satisfies (IcpOptions in the form the targets use).
struct MatchCriteria {
  float max_distance_m = 1.f;        // |Tp - q| at most this (m)
  float min_cos_normal_angle = 0.f;  // |n_source . n_target| at least this, when the source normal is given
  float min_planarity = 0.f;         // target points with lower planarity are not matched
  bool field_of_view_gate = false;   // IcpOptions::field_of_view_gate (KdTreeTarget)
  float visibility_gate_m = 0.f;     // IcpOptions::visibility_gate_m (KdTreeTarget; 0 = off)
  bool visibility_follows_surface = false;  // IcpOptions::visibility_follows_surface
  float min_normal_contrast = 0.f;   // IcpOptions::min_normal_contrast (KdTreeTarget)
  bool HasViewGates() const { return field_of_view_gate || visibility_gate_m > 0.f; }
};

// Where source points find their matches. Match() receives a source point and
// (optionally, zero if unknown) its normal, both already mapped into the target
// frame, and returns the matched target point and its unit normal, or false
// when no admissible match exists. Implementations are immutable and thread-safe.
class IcpTarget {
 public:
  virtual ~IcpTarget() = default;
  virtual bool Match(const Eigen::Vector3f& point,
                     const Eigen::Vector3f& normal,
                     const MatchCriteria& criteria,
                     Eigen::Vector3f* target_point,
                     Eigen::Vector3f* target_normal) const = 0;
  virtual size_t size() const = 0;
  // Match() with a warm start: *hint is the target index of this source point's
  // previous match (kNoHint if none) and is updated on success. The result must
  // equal Match()'s; targets that index points override it to search faster
  // (KdTreeTarget: the distance to the previous match bounds the search). The
  // default ignores the hint.
  static constexpr uint32_t kNoHint = 0xffffffffu;
  virtual bool MatchWithHint(const Eigen::Vector3f& point,
                             const Eigen::Vector3f& normal,
                             const MatchCriteria& criteria,
                             Eigen::Vector3f* target_point,
                             Eigen::Vector3f* target_normal,
                             uint32_t* /*hint*/) const {
    return Match(point, normal, criteria, target_point, target_normal);
  }
  // What one source point carries from one association to the next
  // (MatchTracked); start from the default.
  struct MatchState {
    uint32_t index = kNoHint;                          // target index of the last match
    Eigen::Vector3f anchor = Eigen::Vector3f::Zero();  // query of the last tree search
    // The nearest point stays `index` while the query is closer than this to
    // anchor (m); <= 0: unknown, search.
    float margin_m = -1.f;
    // MatchCriteria::field_of_view_gate and visibility_gate_m, decided at the first
    // call and then kept (-1: not decided yet): a gate re-decided at every pose lets
    // a registration drift towards poses where fewer points are in view, since a
    // point out of view costs nothing (1 of 100 simulated staircase pairs drifted to no
    // match at all).
    int8_t in_view = -1;
  };
  // Match() with state carried across calls for one source point. The result
  // must equal Match()'s, except that MatchCriteria::field_of_view_gate and
  // visibility_gate_m are decided at the first call and kept
  // (MatchState::in_view). KdTreeTarget: a
  // search also finds the second-nearest point; while later queries stay within
  // half the gap between the two distances of the searched position, the nearest
  // point cannot have changed (triangle inequality) and no search is made. The
  // default is MatchWithHint on state->index.
  virtual bool MatchTracked(const Eigen::Vector3f& point,
                            const Eigen::Vector3f& normal,
                            const MatchCriteria& criteria,
                            Eigen::Vector3f* target_point,
                            Eigen::Vector3f* target_normal,
                            MatchState* state) const {
    return MatchWithHint(point, normal, criteria, target_point, target_normal, &state->index);
  }
};

// Unorganised clouds (LiDAR): nearest neighbour in a KD-tree.
// Normals are estimated lazily: the first time a target point is matched, its
// PCA normal (EstimateNormalAt) is computed and cached, so only the target points
// that ever take part in a match pay for a normal (typically a third to a half of
// a target twice as dense as the source). The result is identical to estimating
// all normals up front and does not depend on the thread count. The cache is
// internally synchronised (atomic per-point state): Match() stays const and
// thread-safe.
class KdTreeTarget : public IcpTarget {
 public:
  // Builds the tree; normals are oriented towards `viewpoint`. Throws InputError
  // for non-finite or fewer than 3 points, InternalError for bad options.
  KdTreeTarget(PointSet points,
               const NormalOptions& normal_options,
               const Eigen::Vector3f& viewpoint = Eigen::Vector3f::Zero());
  // Uses given normals (planarity 1). Throws InputError on a size mismatch.
  KdTreeTarget(PointSet points, std::vector<Eigen::Vector3f> normals);
  ~KdTreeTarget() override;

  bool Match(const Eigen::Vector3f& point,
             const Eigen::Vector3f& normal,
             const MatchCriteria& criteria,
             Eigen::Vector3f* target_point,
             Eigen::Vector3f* target_normal) const override;
  bool MatchWithHint(const Eigen::Vector3f& point,
                     const Eigen::Vector3f& normal,
                     const MatchCriteria& criteria,
                     Eigen::Vector3f* target_point,
                     Eigen::Vector3f* target_normal,
                     uint32_t* hint) const override;
  bool MatchTracked(const Eigen::Vector3f& point,
                    const Eigen::Vector3f& normal,
                    const MatchCriteria& criteria,
                    Eigen::Vector3f* target_point,
                    Eigen::Vector3f* target_normal,
                    MatchState* state) const override;
  size_t size() const override { return tree_.size(); }
  const KdTree& tree() const { return tree_; }
  // Unit normal (zero when invalid) and planarity of target point `index`,
  // estimated now unless cached.
  void NormalAt(size_t index, Eigen::Vector3f* normal, float* planarity) const;
  // ... and its contrast (l1 - l0) / l1 (EstimateNormalAt; 1 for given normals).
  void NormalAt(size_t index, Eigen::Vector3f* normal, float* planarity, float* contrast) const;
  // How many normals have been estimated and cached so far.
  size_t NumNormalsEstimated() const;
  // The neighbourhood options of the estimated normals (defaults when normals were given).
  const NormalOptions& normal_options() const { return normal_options_; }

 private:
  // The normal checks of a nearest point `index` (planarity, normal angle);
  // fills the outputs when it is accepted.
  bool AcceptMatch(uint32_t index,
                   const Eigen::Vector3f& normal,
                   const MatchCriteria& criteria,
                   Eigen::Vector3f* target_point,
                   Eigen::Vector3f* target_normal) const;
  // The field of view of IcpOptions::field_of_view_gate and the range image of
  // visibility_gate_m, each computed on first use.
  struct FieldOfView;
  bool InFieldOfView(const Eigen::Vector3f& point) const;
  bool Visible(const Eigen::Vector3f& point, float tolerance_m, bool follow_surface) const;
  // The gates of `criteria` that apply to `point` (true: it may be matched).
  bool InView(const Eigen::Vector3f& point, const MatchCriteria& criteria) const {
    return (!criteria.field_of_view_gate || InFieldOfView(point)) &&
           (criteria.visibility_gate_m <= 0.f ||
            Visible(point, criteria.visibility_gate_m, criteria.visibility_follows_surface));
  }
  KdTree tree_;
  NormalOptions normal_options_;
  Eigen::Vector3f viewpoint_ = Eigen::Vector3f::Zero();
  std::unique_ptr<FieldOfView> field_of_view_;
  mutable Normals normals_;  // written once per point under state_
  mutable std::vector<float> contrast_;  // (l1 - l0) / l1 per point, written with normals_
  mutable std::unique_ptr<std::atomic<uint8_t>[]> state_;  // 0 unknown, 1 being computed, 2 ready
};

struct PinholeIntrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels; u = fx x/z + cx
  int width = 0, height = 0;              // pixels
};

// Organised RGB-D vertex maps: the target frame is the target camera frame;
// a point is projected, rounded to the nearest pixel, and matched to that
// pixel's vertex if it is inside the image, the vertex is valid (z > 0), closer
// than criteria.max_distance_m and (with source normals) within the normal angle.
class ProjectiveTarget : public IcpTarget {
 public:
  // vertex_map: width*height row-major points in the camera frame (non-finite or
  // z <= 0 = no depth). Normals from EstimateOrganizedNormals. Throws InputError on
  // a size mismatch, bad intrinsics or when no pixel is valid.
  ProjectiveTarget(PointSet vertex_map, const PinholeIntrinsics& intrinsics);

  bool Match(const Eigen::Vector3f& point,
             const Eigen::Vector3f& normal,
             const MatchCriteria& criteria,
             Eigen::Vector3f* target_point,
             Eigen::Vector3f* target_normal) const override;
  size_t size() const override { return vertex_map_.size(); }

 private:
  PointSet vertex_map_;
  Normals normals_;
  PinholeIntrinsics intrinsics_;
};

struct IcpResult {
  SE3 target_from_source;
  bool converged = false;   // step below the thresholds, enough inliers, not degenerate
  bool degenerate = false;  // Hessian min/max eigenvalue ratios below threshold (IcpOptions)
  int iterations = 0;       // associations (outer iterations)
  size_t num_inliers = 0;
  double rmse_m = 0;               // RMS point-to-plane residual of the inliers (m)
  double residual_variance_m2 = 0;  // sum w r^2 / (N - 6), the closed form's sigma^2
  // sum w J^T J (xi on the right) at the estimate over the matches of the last
  // association (made within the convergence thresholds of it); if not converged,
  // at the last linearisation point with fresh matches.
  Mat6 hessian = Mat6::Zero();
  Mat6 gradient_outer = Mat6::Zero();  // sum w^2 r^2 J^T J (Censi/sandwich "meat")
  Vec6 scaled_eigenvalues = Vec6::Zero();  // eigenvalues of D H D, D = diag(1/L I3, I3), ascending
  double characteristic_length_m = 1;  // L: RMS distance of inlier source points from their centroid
  std::string message;
};

// One point-to-plane residual and its 1x6 Jacobian w.r.t. the right
// perturbation xi at T (see the header comment).
double PointToPlaneResidual(const SE3& target_from_source,
                            const Vec3& source_point,
                            const Vec3& target_point,
                            const Vec3& target_normal,
                            Eigen::Matrix<double, 1, 6>* jacobian);

// Registers `source` (source frame) to `target`. source_normals: empty or one per
// source point (source frame) for the normal-angle test. Throws InputError for
// empty/tiny/non-finite input or mismatched sizes, InternalError for bad options.
IcpResult RegisterPointToPlane(const PointSet& source,
                               const IcpTarget& target,
                               const SE3& initial_target_from_source,
                               const IcpOptions& options,
                               const std::vector<Eigen::Vector3f>& source_normals = {});

// Checks a source cloud (and its optional normals) for RegisterPointToPlane.
void CheckIcpSource(const PointSet& source, const std::vector<Eigen::Vector3f>& source_normals);

}  // namespace lisfm
