// Frame-to-model tracking for organised depth frames: projective data
// association and point-to-plane ICP (Newcombe et al. 2011, KinectFusion;
// Keller et al. 2013, point-based fusion).
//
// Frames: the source is the current camera frame, the target the camera frame
// in which the model's vertex and normal maps were rendered (the previous pose).
// The estimate is target_from_source (x_target = T x_source), metres.
//
// Association (one per iteration): a source vertex p_s with normal n_s maps to
// p = T p_s; it is projected with the target intrinsics and rounded to the nearest
// pixel (u, v). The pair (p, q = target vertex at (u, v), n = target normal) is
// valid when 0 <= u < W, 0 <= v < H, q has positive depth and a normal,
// |p - q| < max_correspondence_distance_m and angle(R n_s, n) < max_normal_angle_deg.
//
// Linearisation (left perturbation in the target frame, small angles:
// dR ~ I + [omega]x, T <- (dR, dt) T):
//   r_i = n^T (dR p + dt - q) ~ A_i xi + b_i,  A_i = n^T [-[p]x  I],  b_i = n^T (p - q),
// xi = [omega; dt] (rad, m). Each iteration solves the normal equations
// (sum w A^T A) xi = -(sum w A^T b) by Cholesky (LLT with a tiny Levenberg damping)
// and applies T <- (Exp(omega), dt) T. Weights w are Huber IRLS weights of b_i.
// Unconstrained directions (scaled-Hessian eigenvalues below a tenth of
// degeneracy_threshold times the largest; a corridor's axis) get no step, so the
// initial guess is kept along them (solution remapping, Zhang et al. 2016).
//
// Photometric term (optional; Kerl et al. 2013, Open3D's hybrid RGB-D odometry):
// with intensity images of both frames (IntensityPyramid, on the pixel grids of
// the source and target maps), each geometric match also contributes
//   r_i = I_t(pi(p)) - I_s(u_s, v_s),   A_i = g^T [-[p]x  I],
//   g = dI_t/dp = [gu fx / z,  gv fy / z,  -(gu fx x + gv fy y) / z^2],
// with I_t (pyramid level l: the same grid, blurred) and its central-difference
// gradients (gu, gv) sampled bilinearly at the projection pi(p), I_s the source's
// level l at its own pixel. Both enter the same normal equations: cost = sum w r_geo^2 +
// photometric_weight * sum w r_photo^2 (intensities in [0, 1], geometric residuals
// in m), each with its own Huber IRLS weight. Texture on a plane constrains the
// in-plane motion that depth alone leaves free (a corridor's axis).
//
// Coarse to fine: level l (l = num_levels-1 .. 0) uses every 2^l-th source pixel in
// both directions and a distance threshold of 2^l d_thr (coarse levels pull in
// larger displacements); the target maps stay at full resolution. A level ends
// when a step is below the convergence thresholds or after its iteration budget.
//
// Result: the information matrix is (sum w J^T J) / sigma^2 (with the photometric
// term: its weighted rows included, sigma^2 from the geometric residuals alone) for the right
// perturbation of the estimate (DESIGN.md: T = T_hat Exp(xi), J = A Ad(T_hat)),
// sigma^2 = sum w b^2 / (N - 6), from the last iteration's matches. Degeneracy is
// decided as in RegisterPointToPlane (icp.h): eigenvalue ratios of the translation
// block and of the length-scaled 6x6.
//
// Threads: association and accumulation run in parallel over image rows (TBB); the
// per-row sums are added in row order, so results do not depend on the thread
// count. Failures: maps of inconsistent sizes or bad intrinsics throw InputError;
// too few matches or a degenerate problem are values (converged = false + message).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "icp/icp.h"

namespace lisfm {

// An organised (image-shaped) map in a camera frame: row-major, width*height.
// A pixel is valid when its normal is non-zero (then its vertex has z > 0).
struct VertexNormalMap {
  int width = 0, height = 0;              // pixels
  std::vector<Eigen::Vector3f> vertices;  // camera frame (m)
  std::vector<Eigen::Vector3f> normals;   // unit, pointing towards the camera; zero = invalid
  void Resize(int w, int h);              // sizes both arrays; contents unspecified
  bool Valid(size_t i) const { return normals[i].squaredNorm() > 0.f; }
  size_t NumValid() const;
};

// Vertices of a depth image (metres, row-major, 0 or non-finite = invalid) and
// normals from least-squares slopes along the pixel's row and column over a
// window of r = normal_window_px pixels each side,
//   n = d_u x d_v,  d_u = sum_{k=1..r} k (v(u+k) - v(u-k)),  d_v likewise,
// oriented towards the camera (r = 1: central differences). Depth noise sigma gives
// a normal noise ~ sigma / (pixel footprint r^1.5): a wider window smooths the
// normals of noisy depth. A pixel gets a normal only when its 4r neighbours are
// valid and the k-th is within k max_depth_jump (fraction of its depth, > 0) of its
// depth (no normals across depth discontinuities). Depths outside [min_depth_m,
// max_depth_m] are invalid.
// Creases (crease_rejection_sigma > 0): a normal whose window spans two planes (a
// room's edge) mixes them and biases point-to-plane residuals in the motion's
// direction. On a plane the points of a row (column) are collinear, so a pixel
// whose window points leave the line along n, max_{k,axis} |n . (v(-k) + v(+k) -
// 2 v)| / z^2, by more than crease_rejection_sigma times the frame's RMS of that
// score (clipped at the same multiple, so depth noise sets the scale and the
// creases themselves do not) loses its normal. Reuses out's storage.
void ComputeVertexNormalMap(const std::vector<float>& depth_m,
                            const PinholeIntrinsics& intrinsics,
                            double min_depth_m,
                            double max_depth_m,
                            double max_depth_jump,
                            VertexNormalMap* out,
                            int normal_window_px = 1,
                            double crease_rejection_sigma = 0);

// Intensity images of one frame for the photometric term, all on the frame's own
// pixel grid: level l is the intensity in [0, 1] blurred by a Gaussian of sigma
// 0.75 * 2^l pixels (coarse levels widen the basin of convergence), with its
// central-difference gradients (intensity per pixel).
struct IntensityPyramid {
  struct Level {
    std::vector<float> intensity, grad_u, grad_v;  // row-major, width x height
  };
  int width = 0, height = 0;
  std::vector<Level> levels;
  bool empty() const { return levels.empty(); }
};

// Builds `out` (num_levels >= 1) from a row-major width x height intensity image in
// [0, 1]; reuses out's storage.
void BuildIntensityPyramid(const std::vector<float>& intensity,
                           int width,
                           int height,
                           int num_levels,
                           IntensityPyramid* out);

struct ProjectiveIcpOptions {
  int num_levels = 3;                 // pyramid levels (source strides 2^l), 1..5
  int max_iterations_per_level = 10;  // Gauss-Newton iterations per level, >= 1
  double max_correspondence_distance_m =
      0.1;                             // d_thr: reject |T p - q| above this (m; x 2^l at level l)
  double max_normal_angle_deg = 30.0;  // theta_thr: reject normals further apart (deg)
  double huber_threshold_m = 0.01;     // Huber IRLS scale on b_i (m; 0 = plain least squares)
  double convergence_rotation_rad = 1e-4;   // a level ends when |omega| of a step is below (rad)
  double convergence_translation_m = 1e-4;  // ... and |dt| is below (m)
  int min_inliers = 100;                    // fewer matches: not converged
  double degeneracy_threshold = 0.02;       // as IcpOptions::degeneracy_threshold
  // Weight of the photometric term against the geometric one (intensity in [0, 1]
  // against metres; 0 = depth only). Open3D's hybrid term weighs depth 0.968 and
  // intensity 0.032: the default is their ratio, 0.032 / 0.968.
  double photometric_weight = 0.033;
  // Huber scale of the intensity residual ([0, 1] units; 0.02 ~ 5 of 255 levels):
  // real RGB-D colour (exposure, RGB-depth registration) has outliers.
  double photometric_huber = 0.02;
  bool Check() const;
};

struct ProjectiveIcpResult {
  SE3 target_from_source;
  bool converged = false;           // last step small, enough inliers, not degenerate
  bool degenerate = false;          // eigenvalue ratios below degeneracy_threshold (see above)
  int iterations = 0;               // Gauss-Newton iterations over all levels
  size_t num_inliers = 0;           // matches of the last iteration (finest level)
  double rmse_m = 0;                // RMS point-to-plane residual of those matches (m)
  size_t num_photometric = 0;       // of those, matches with a photometric row
  Mat6 information = Mat6::Zero();  // right perturbation of target_from_source (1/rad^2, 1/m^2)
  Vec6 scaled_eigenvalues = Vec6::Zero();  // of D H D, D = diag(1/L I3, I3), ascending
  std::string message;
};

// The 1x6 A_i and the scalar b_i above for a transformed source point p = T p_s
// (target frame) against target point q with unit normal n.
double ProjectivePointToPlane(const Eigen::Vector3d& p,
                              const Eigen::Vector3d& q,
                              const Eigen::Vector3d& n,
                              Eigen::Matrix<double, 1, 6>* a);

// The photometric row for a transformed source point p = T p_s (target frame)
// whose source intensity is source_intensity, against one level of the target's
// pyramid (pixel grid of K): returns false when p is behind the camera or projects
// outside [0, W - 1) x [0, H - 1); else sets r and the 1x6 A above.
bool ProjectivePhotometric(const Eigen::Vector3d& p,
                           double source_intensity,
                           const IntensityPyramid::Level& level,
                           const PinholeIntrinsics& K,
                           double* residual,
                           Eigen::Matrix<double, 1, 6>* a);

// Registers `source` (current frame) to `target` (the model rendered with
// `target_intrinsics`). Source maps may have any size (their pixels are only
// iterated); throws InputError when a map's arrays do not match its size or the
// intrinsics do not match the target, InternalError for bad options.
// source_intensity / target_intensity: pyramids on the grids of the source and
// target maps (both or neither; empty or photometric_weight 0 = depth only), with at
// least num_levels levels.
ProjectiveIcpResult RegisterProjective(const VertexNormalMap& source,
                                       const VertexNormalMap& target,
                                       const PinholeIntrinsics& target_intrinsics,
                                       const SE3& initial_target_from_source,
                                       const ProjectiveIcpOptions& options,
                                       const IntensityPyramid* source_intensity = nullptr,
                                       const IntensityPyramid* target_intensity = nullptr);

}  // namespace lisfm
