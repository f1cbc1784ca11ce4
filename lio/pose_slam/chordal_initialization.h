// SE-Sync's objective and its chordal initialisation for pose graphs with
// isotropic weights (Rosen et al., "SE-Sync", IJRR 2019; Carlone et al.,
// "Initialization techniques for 3D SLAM", ICRA 2015).
#pragma once

#include <vector>

#include "core/geometry.h"

namespace lisfm {

// A relative-pose measurement i_from_j with SE-Sync's isotropic weights:
// kappa on the rotation (chordal, ||R_j - R_i R~||_F^2), tau on the translation (1/m^2).
struct ChordalMeasurement {
  int i = 0;
  int j = 0;
  SE3 i_from_j;
  double kappa = 1.0;
  double tau = 1.0;
};

// F(R, t) = sum kappa ||R_j - R_i R~_ij||_F^2 + tau ||t_j - t_i - R_i t~_ij||^2
// (eq. (12), no factor 1/2) at the poses world_from_i (2D poses as rotations
// about z with z = 0 give the 2D value).
double ChordalObjective(const std::vector<ChordalMeasurement>& measurements,
                        const std::vector<SE3>& world_from_pose);

// The chordal initialisation in `dimension` 2 or 3 (2D measurements are
// rotations about z with zero z translation), with pose 0 as the gauge
// (world_from_0 = identity):
//  1. rotations: the linear least-squares minimiser of
//     sum kappa ||R_j - R_i R~_ij||_F^2 over unconstrained d x d matrices
//     (R_0 = I), each projected to the nearest rotation (SVD, det +1);
//  2. translations: with those rotations fixed, the linear least-squares
//     minimiser of sum tau ||t_j - t_i - R_i t~_ij||^2 (t_0 = 0).
// Both are sparse symmetric positive-definite systems (a block Laplacian),
// solved with a sparse LDL^T factorisation. Exact for noise-free measurements.
// Throws InternalError when the graph over 0..num_poses-1 is not connected (the
// system is singular) or an index is out of range.
std::vector<SE3> ChordalInitialization(int dimension,
                                       int num_poses,
                                       const std::vector<ChordalMeasurement>& measurements);

}  // namespace lisfm
