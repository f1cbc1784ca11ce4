// Check() of every global-SfM options struct rejects an out-of-range value of
// each field it guards, naming that field (table-driven).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "colmap_ext/sfm/bundle_adjustment.h"
#include "colmap_ext/sfm/global_mapper.h"
#include "colmap_ext/sfm/mapper_state.h"
#include "colmap_ext/sfm/rotation_averaging.h"
#include "colmap_ext/sfm/schur_bundle_adjuster.h"
#include "colmap_ext/sfm/sfm_evaluation.h"
#include "colmap_ext/sfm/tracks.h"
#include "colmap_ext/sfm/translation_averaging.h"
#include "colmap_ext/sfm/triangulation.h"
#include "colmap_ext/sfm/view_graph.h"
#include "tests/common/option_check_test.h"

namespace lisfm {
namespace colmap {
namespace {

using test::ExpectCheckRejects;
constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(SfmOptionsCheck, TracksAndTriangulation) {
  using T = TrackOptions;
  ExpectCheckRejects<T>({
      {"min_track_length", [](T* o) { o->min_track_length = 1; }},
      {"max_track_length", [](T* o) { o->max_track_length = -1; }},
      {"max_track_length",
       [](T* o) { o->max_track_length = 1; }},  // below min_track_length
  });
  using R = TriangulationOptions;
  ExpectCheckRejects<R>({
      {"max_reprojection_error_px",
       [](R* o) { o->max_reprojection_error_px = 0.0; }},
      {"min_triangulation_angle_deg",
       [](R* o) { o->min_triangulation_angle_deg = -0.1; }},
      {"min_triangulation_angle_deg",
       [](R* o) { o->min_triangulation_angle_deg = 180.0; }},
      {"num_refinement_iterations",
       [](R* o) { o->num_refinement_iterations = -1; }},
      {"max_hypothesis_pairs", [](R* o) { o->max_hypothesis_pairs = 0; }},
      {"num_threads", [](R* o) { o->num_threads = 0; }},
  });
  using C = TrackCompletionOptions;
  ExpectCheckRejects<C>({
      {"complete_max_reprojection_error_px",
       [](C* o) { o->complete_max_reprojection_error_px = 0.0; }},
      {"complete_max_transitivity", [](C* o) { o->complete_max_transitivity = 0; }},
      {"merge_max_reprojection_error_px",
       [](C* o) { o->merge_max_reprojection_error_px = -1.0; }},
  });
}

TEST(SfmOptionsCheck, BundleAdjustment) {
  using B = BundleAdjustmentOptions;
  ExpectCheckRejects<B>({
      {"loss_type", [](B* o) { o->loss_type = "tukey"; }},
      {"loss_scale", [](B* o) { o->loss_scale = 0.0; }},
      {"max_num_iterations", [](B* o) { o->max_num_iterations = -1; }},
      {"function_tolerance", [](B* o) { o->function_tolerance = -1e-9; }},
      {"gradient_tolerance", [](B* o) { o->gradient_tolerance = -1e-9; }},
      {"parameter_tolerance", [](B* o) { o->parameter_tolerance = -1e-9; }},
      {"max_tracks_per_image", [](B* o) { o->max_tracks_per_image = -1; }},
      {"dense_schur_max_frames", [](B* o) { o->dense_schur_max_frames = -1; }},
      {"solver", [](B* o) { o->solver = "dense"; }},
      {"num_threads", [](B* o) { o->num_threads = 0; }},
      {"ceres_num_threads", [](B* o) { o->ceres_num_threads = 0; }},
  });
  using S = SchurBaOptions;
  ExpectCheckRejects<S>({
      {"loss_type", [](S* o) { o->loss_type = "tukey"; }},
      {"loss_scale", [](S* o) { o->loss_scale = -1.0; }},
      {"max_num_iterations", [](S* o) { o->max_num_iterations = -1; }},
      {"function_tolerance", [](S* o) { o->function_tolerance = -1e-9; }},
      {"gradient_tolerance", [](S* o) { o->gradient_tolerance = kInf; }},
      {"parameter_tolerance", [](S* o) { o->parameter_tolerance = -1e-9; }},
      {"num_threads", [](S* o) { o->num_threads = -2; }},
  });
}

TEST(SfmOptionsCheck, ViewGraphAndRotationAveraging) {
  using V = ViewGraphOptions;
  ExpectCheckRejects<V>({
      {"min_num_inliers", [](V* o) { o->min_num_inliers = 4; }},
      {"min_inlier_ratio", [](V* o) { o->min_inlier_ratio = 1.5; }},
      {"max_error_px", [](V* o) { o->max_error_px = 0.0; }},
      {"num_threads", [](V* o) { o->num_threads = 0; }},
      {"ransac_confidence", [](V* o) { o->ransac_confidence = 1.0; }},
      {"ransac_max_iterations", [](V* o) { o->ransac_max_iterations = 0; }},
      {"ransac_max_num_matches", [](V* o) { o->ransac_max_num_matches = 4; }},
      {"refine_max_num_matches", [](V* o) { o->refine_max_num_matches = 4; }},
  });
  using A = RotationAveragingOptions;
  ExpectCheckRejects<A>({
      {"max_rotation_error_deg", [](A* o) { o->max_rotation_error_deg = 0.0; }},
      {"geman_mcclure_sigma_deg",
       [](A* o) { o->geman_mcclure_sigma_deg = -1.0; }},
      {"max_loop_error_deg", [](A* o) { o->max_loop_error_deg = 0.0; }},
      {"max_l1_iterations", [](A* o) { o->max_l1_iterations = -1; }},
      {"l1_tolerance_rad", [](A* o) { o->l1_tolerance_rad = 0.0; }},
      {"max_irls_iterations", [](A* o) { o->max_irls_iterations = -1; }},
      {"convergence_tolerance_rad",
       [](A* o) { o->convergence_tolerance_rad = 0.0; }},
      {"relative_rotation_sigma_deg",
       [](A* o) { o->relative_rotation_sigma_deg = 0.0; }},
      {"fallback_prior_sigma_rad",
       [](A* o) { o->fallback_prior_sigma_rad = 0.0; }},
  });
}

TEST(SfmOptionsCheck, TranslationAveraging) {
  using T = TranslationAveragingOptions;
  ExpectCheckRejects<T>({
      {"num_projections", [](T* o) { o->num_projections = 0; }},
      {"min_projection_magnitude",
       [](T* o) { o->min_projection_magnitude = 1.0; }},
      {"max_broken_ratio", [](T* o) { o->max_broken_ratio = -0.1; }},
      {"axis_perturbation_sigma",
       [](T* o) { o->axis_perturbation_sigma = -0.1; }},
      {"direction_sigma", [](T* o) { o->direction_sigma = 0.0; }},
      {"direction_loss", [](T* o) { o->direction_loss = "tukey"; }},
      {"direction_loss_threshold",
       [](T* o) { o->direction_loss_threshold = 0.0; }},
      {"min_edge_scale", [](T* o) { o->min_edge_scale = 0.0; }},
      {"min_rig_baseline", [](T* o) { o->min_rig_baseline = -0.01; }},
      {"random_init_extent", [](T* o) { o->random_init_extent = 0.0; }},
      {"max_residual_angle_deg",
       [](T* o) { o->max_residual_angle_deg = kInf; }},
      {"max_num_iterations", [](T* o) { o->max_num_iterations = 0; }},
      {"function_tolerance", [](T* o) { o->function_tolerance = -1e-9; }},
      {"ceres_num_threads", [](T* o) { o->ceres_num_threads = 0; }},
  });
}

TEST(SfmOptionsCheck, MapperAndEvaluation) {
  using L = LoadMapperStateOptions;
  ExpectCheckRejects<L>({
      {"prior_position_sigma", [](L* o) { o->prior_position_sigma = 0.0; }},
      {"prior_rotation_sigma", [](L* o) { o->prior_rotation_sigma = -0.01; }},
  });
  using G = GlobalMapperOptions;
  ExpectCheckRejects<G>({
      {"load.prior_position_sigma",
       [](G* o) { o->load.prior_position_sigma = 0.0; }},
      {"view_graph.min_num_inliers",
       [](G* o) { o->view_graph.min_num_inliers = 0; }},
      {"rotation_averaging.max_rotation_error_deg",
       [](G* o) { o->rotation_averaging.max_rotation_error_deg = 0.0; }},
      {"translation_averaging.num_projections",
       [](G* o) { o->translation_averaging.num_projections = 0; }},
      {"tracks.min_track_length", [](G* o) { o->tracks.min_track_length = 0; }},
      {"triangulation.max_reprojection_error_px",
       [](G* o) { o->triangulation.max_reprojection_error_px = 0.0; }},
      {"bundle_adjustment.loss_scale",
       [](G* o) { o->bundle_adjustment.loss_scale = 0.0; }},
      {"num_refinement_rounds", [](G* o) { o->num_refinement_rounds = -1; }},
      {"refinement_function_tolerance",
       [](G* o) { o->refinement_function_tolerance = -1.0; }},
      {"final_max_num_iterations",
       [](G* o) { o->final_max_num_iterations = -1; }},
      {"min_component_frames", [](G* o) { o->min_component_frames = 0; }},
      {"min_frame_observations", [](G* o) { o->min_frame_observations = -1; }},
      {"initial_reprojection_error_factor",
       [](G* o) { o->initial_reprojection_error_factor = 0.9; }},
      {"min_focal_length_ratio", [](G* o) { o->min_focal_length_ratio = 0.0; }},
      {"min_focal_length_ratio", [](G* o) { o->min_focal_length_ratio = 1.5; }},
      {"max_focal_length_ratio", [](G* o) { o->max_focal_length_ratio = 0.5; }},
      {"max_extra_param", [](G* o) { o->max_extra_param = 0.0; }},
      {"lidar_constraint_tolerance_ms",
       [](G* o) { o->lidar_constraint_tolerance_ms = -1.0; }},
  });
  using E = SfmEvaluationOptions;
  ExpectCheckRejects<E>({
      {"auc_thresholds_deg", [](E* o) { o->auc_thresholds_deg.clear(); }},
      {"auc_thresholds_deg",
       [](E* o) {
         o->auc_thresholds_deg = {1.0, 0.0};
       }},
  });
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
