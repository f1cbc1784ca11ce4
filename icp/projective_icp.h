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
// Coarse to fine: level l (l = num_levels-1 .. 0) uses every 2^l-th source pixel in
// both directions and a distance threshold of 2^l d_thr (coarse levels pull in
// larger displacements); the target maps stay at full resolution. A level ends
// when a step is below the convergence thresholds or after its iteration budget.
//
// Result: the information matrix is (sum w J^T J) / sigma^2 for the right
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
// normals by central differences, n = (v(u+1) - v(u-1)) x (v(w+1) - v(w-1)),
// oriented towards the camera. A pixel gets a normal only when its four
// neighbours are valid and within max_depth_jump (fraction of its depth, > 0) of
// its depth (no normals across depth discontinuities). Depths outside
// [min_depth_m, max_depth_m] are invalid. Reuses out's storage.
void ComputeVertexNormalMap(const std::vector<float>& depth_m,
                            const PinholeIntrinsics& intrinsics,
                            double min_depth_m,
                            double max_depth_m,
                            double max_depth_jump,
                            VertexNormalMap* out);

struct ProjectiveIcpOptions {
  int num_levels = 3;                 // pyramid levels (source strides 2^l), 1..5
  int max_iterations_per_level = 10;  // Gauss-Newton iterations per level, >= 1
  double max_correspondence_distance_m =
      0.1;                             // d_thr: reject |T p - q| above this (m; x 2^l at level l)
  double max_normal_angle_deg = 30.0;  // theta_thr: reject normals further apart (deg)
  double huber_threshold_m = 0.01;     // Huber IRLS scale on b_i (m; 0 = plain least squares)
  double convergence_rotation_rad = 1e-5;   // a level ends when |omega| of a step is below (rad)
  double convergence_translation_m = 1e-5;  // ... and |dt| is below (m)
  int min_inliers = 100;                    // fewer matches: not converged
  double degeneracy_threshold = 0.02;       // as IcpOptions::degeneracy_threshold
  bool Check() const;
};

struct ProjectiveIcpResult {
  SE3 target_from_source;
  bool converged = false;           // last step small, enough inliers, not degenerate
  bool degenerate = false;          // eigenvalue ratios below degeneracy_threshold (see above)
  int iterations = 0;               // Gauss-Newton iterations over all levels
  size_t num_inliers = 0;           // matches of the last iteration (finest level)
  double rmse_m = 0;                // RMS point-to-plane residual of those matches (m)
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

// Registers `source` (current frame) to `target` (the model rendered with
// `target_intrinsics`). Source maps may have any size (their pixels are only
// iterated); throws InputError when a map's arrays do not match its size or the
// intrinsics do not match the target, InternalError for bad options.
ProjectiveIcpResult RegisterProjective(const VertexNormalMap& source,
                                       const VertexNormalMap& target,
                                       const PinholeIntrinsics& target_intrinsics,
                                       const SE3& initial_target_from_source,
                                       const ProjectiveIcpOptions& options);

}  // namespace lisfm
