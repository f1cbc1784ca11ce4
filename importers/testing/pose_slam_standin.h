// A stand-in for `lisfm pose_slam` output, built from a `lisfm lio` run, for the
// database importer's tests and benchmark (never linked by the product):
//   trajectory.txt            lio's trajectory (TUM, world_from_imu per scan end)
//   keyframes.txt             lio's keyframes (keyframes/keyframes.csv as TUM)
//   constraints.txt           Bayesian ICP (icp/bayesian_icp.h) between keyframe pairs,
//                             started from lio's relative pose; lisfm format. Pairs as
//                             pose_slam's default candidate rule (FL2BIPS): per keyframe
//                             the 25 nearest by position with an index step in [5, 25],
//                             plus index steps 1..4
//   keyframe_covariances.txt  one constant covariance per keyframe
// The real pose_slam writes the same four files (its optimised poses, its own
// constraints and marginals), so a test replaces this folder by its output.
#pragma once

#include <string>

namespace lisfm {
namespace test {

struct PoseSlamStandInOptions {
  double max_pair_distance_m = 10.0;  // m, candidates farther apart are not tried
  int max_pairs_per_keyframe = 25;    // nearest candidates per keyframe
  int min_index_step = 5;             // candidates' index step range; smaller steps always
  int max_index_step = 25;
  double source_voxel_m = 0.25;                // m, source downsampling of the ICP
  double target_voxel_m = 0.1;                 // m, target downsampling of the ICP
  int sgld_iterations = 300;                   // SGLD iterations of the Bayesian ICP
  double keyframe_sigma_rotation_rad = 0.005;  // constant keyframe marginal, per axis
  double keyframe_sigma_translation_m = 0.02;  // constant keyframe marginal, per axis
  bool point_to_plane_only = false;            // skip the SGLD chain: ICP + a constant covariance
};

// Writes the four files into `output_dir` (created). Returns the number of
// constraints. Throws InputError for a missing lio file.
size_t WritePoseSlamStandIn(const std::string& lio_path,
                            const std::string& output_dir,
                            const PoseSlamStandInOptions& options = {});

}  // namespace test
}  // namespace lisfm
