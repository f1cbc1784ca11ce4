// Check() of every ICP options struct rejects an out-of-range value of each
// field it guards, naming that field (table-driven).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "icp/bayesian_icp.h"
#include "icp/icp.h"
#include "icp/icp_covariance.h"
#include "icp/normals.h"
#include "icp/testing/sim_pairs.h"
#include "tests/common/option_check_test.h"

namespace lisfm {
namespace {

using test::ExpectCheckRejects;

TEST(IcpOptionsCheck, Icp) {
  using I = IcpOptions;
  ExpectCheckRejects<I>({
      {"max_iterations", [](I* o) { o->max_iterations = 0; }},
      {"max_inner_iterations", [](I* o) { o->max_inner_iterations = -1; }},
      {"max_correspondence_distance_m",
       [](I* o) { o->max_correspondence_distance_m = 0.0; }},
      {"max_normal_angle_deg", [](I* o) { o->max_normal_angle_deg = 0.0; }},
      {"max_normal_angle_deg", [](I* o) { o->max_normal_angle_deg = 180.5; }},
      {"min_planarity", [](I* o) { o->min_planarity = -0.1; }},
      {"min_planarity", [](I* o) { o->min_planarity = 1.1; }},
      {"kernel", [](I* o) { o->kernel = "tukey"; }},
      {"kernel_scale_m", [](I* o) { o->kernel_scale_m = 0.0; }},
      {"convergence_rotation_rad",
       [](I* o) { o->convergence_rotation_rad = -1e-9; }},
      {"convergence_translation_m",
       [](I* o) { o->convergence_translation_m = std::nan(""); }},
      {"min_inliers", [](I* o) { o->min_inliers = 5; }},
      {"coarse_stride", [](I* o) { o->coarse_stride = 0; }},
      {"coarse_levels", [](I* o) { o->coarse_levels = 9; }},
      {"coarse_min_points", [](I* o) { o->coarse_min_points = 0; }},
      {"degeneracy_threshold", [](I* o) { o->degeneracy_threshold = -0.01; }},
      {"visibility_gate_m", [](I* o) { o->visibility_gate_m = -0.1; }},
  });
  using N = NormalOptions;
  ExpectCheckRejects<N>({
      {"num_neighbors", [](N* o) { o->num_neighbors = 2; }},
      {"num_neighbors", [](N* o) { o->num_neighbors = 65; }},
      {"max_radius_m", [](N* o) { o->max_radius_m = 0.0; }},
  });
}

TEST(IcpOptionsCheck, BayesianIcp) {
  using S = SgldOptions;
  ExpectCheckRejects<S>({
      {"num_iterations", [](S* o) { o->num_iterations = 0; }},
      {"burn_in", [](S* o) { o->burn_in = -1; }},
      {"burn_in", [](S* o) { o->burn_in = o->num_iterations; }},
      {"thinning", [](S* o) { o->thinning = 0; }},
      {"batch_size", [](S* o) { o->batch_size = 0; }},
      {"step_size", [](S* o) { o->step_size = 0.0; }},
      {"step_size", [](S* o) { o->step_size = 2.0; }},
      {"metric_decay", [](S* o) { o->metric_decay = 1.0; }},
      {"damping_sigma_rotation_rad",
       [](S* o) { o->damping_sigma_rotation_rad = 0.0; }},
      {"damping_sigma_translation_m",
       [](S* o) { o->damping_sigma_translation_m = 0.0; }},
  });
  using C = CorrespondenceVarianceOptions;
  ExpectCheckRejects<C>({
      {"plane_variance_weight", [](C* o) { o->plane_variance_weight = -1.0; }},
      {"max_tilt_variance_rad2",
       [](C* o) { o->max_tilt_variance_rad2 = -1.0; }},
      {"floor_m2", [](C* o) { o->floor_m2 = 0.0; }},
  });
  using B = BayesianIcpOptions;
  ExpectCheckRejects<B>({
      {"icp.kernel_scale_m", [](B* o) { o->icp.kernel_scale_m = 0.0; }},
      {"normal_neighbors", [](B* o) { o->normal_neighbors = 2; }},
      {"normal_neighbors", [](B* o) { o->normal_neighbors = 65; }},
      {"sgld.thinning", [](B* o) { o->sgld.thinning = 0; }},
      {"noise_sigma_m", [](B* o) { o->noise_sigma_m = -0.01; }},
      {"noise_sigma_scale", [](B* o) { o->noise_sigma_scale = 0.0; }},
      {"correlation_length_m", [](B* o) { o->correlation_length_m = -1.0; }},
      {"num_correlation_cells", [](B* o) { o->num_correlation_cells = 1; }},
      {"num_correlation_cells", [](B* o) { o->num_correlation_cells = -1; }},
      {"prior_sigma_rotation_rad",
       [](B* o) { o->prior_sigma_rotation_rad = -0.1; }},
      {"prior_sigma_translation_m",
       [](B* o) { o->prior_sigma_translation_m = -0.1; }},
      {"correspondence_variance.floor_m2",
       [](B* o) { o->correspondence_variance.floor_m2 = 0; }},
      {"jackknife_leverage_power",
       [](B* o) { o->jackknife_leverage_power = -0.5; }},
      {"refine_max_correspondence_distance_m",
       [](B* o) { o->refine_max_correspondence_distance_m = -0.2; }},
  });
}

TEST(IcpOptionsCheck, SimulatedScanPairs) {
  using P = test::SimScanPairOptions;
  ExpectCheckRejects<P>({
      {"azimuth_steps", [](P* o) { o->azimuth_steps = 0; }},
      {"range_sigma_m", [](P* o) { o->range_sigma_m = -0.01; }},
      {"min_baseline_m", [](P* o) { o->min_baseline_m = -0.1; }},
      {"max_baseline_m",
       [](P* o) { o->max_baseline_m = 0.1; }},  // below min_baseline_m
      {"max_relative_yaw_deg", [](P* o) { o->max_relative_yaw_deg = -1.0; }},
      {"init_sigma_rotation_deg",
       [](P* o) { o->init_sigma_rotation_deg = -1.0; }},
      {"init_sigma_translation_m",
       [](P* o) { o->init_sigma_translation_m = -1.0; }},
  });
}

}  // namespace
}  // namespace lisfm
