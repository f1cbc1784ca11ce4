#include "apps/option_sections.h"

#include <string>
#include <utility>
#include <vector>

namespace lisfm {
namespace {

using R = OptionRange;

const std::vector<std::string> kRobustKernels = {
    "none", "huber", "cauchy", "geman_mcclure"};

std::vector<std::pair<std::string, AlignmentType>> AlignmentChoices(
    const std::vector<AlignmentType>& order) {
  std::vector<std::pair<std::string, AlignmentType>> choices;
  for (const AlignmentType a : order)
    choices.emplace_back(AlignmentTypeName(a), a);
  return choices;
}

}  // namespace

void AddDatabaseImporterOptions(OptionManager* options, DatabaseImporterOptions* importer) {
  CovisibilityOptions* c = &importer->covisibility;
  ImporterPriorOptions* p = &importer->priors;
  options->AddDouble("DatabaseImporter.max_point_distance_m", &c->max_point_distance_m,
                     "m, a point of scan i is a co-visible point when scan j has a point "
                     "within this",
                     R::GreaterThan(0));
  options->AddChoice("DatabaseImporter.covisibility_source", &c->source, {"map", "constraints"},
                     "LiDAR co-visibility from every keyframe scan in one map (image pairs by "
                     "shared visible map points), or from the constrained scan pairs only");
  options->AddDouble("DatabaseImporter.max_view_angle_deg", &c->max_view_angle_deg,
                     "deg, map co-visibility: largest angle between the two images' rays to a "
                     "shared point",
                     R::GreaterThan(0).AndAtMost(180));
  options->AddDouble("DatabaseImporter.max_point_range_m", &c->max_point_range_m,
                     "m, map co-visibility: farthest map point an image counts (0 = no limit)",
                     R::AtLeast(0));
  options->AddChoice("DatabaseImporter.score", &c->score, {"count", "fraction", "area"},
                     "ranking score of a co-visible pair (map): solid angle of the shared "
                     "surface (sum of voxel^2 / (range_a range_b)), votes, or votes over the "
                     "smaller number of map points the two images see");
  options->AddDouble("DatabaseImporter.scan_voxel_size_m", &c->scan_voxel_size_m,
                     "m, voxel downsampling of the projected points and z-buffers (0 = off)",
                     R::AtLeast(0));
  options->AddDouble("DatabaseImporter.max_image_time_offset_s", &c->max_image_time_offset_s,
                     "s, an image belongs to the keyframe scan nearest in time, at most this far",
                     R::GreaterThan(0));
  options->AddInt("DatabaseImporter.zbuffer_cell_px", &c->zbuffer_cell_px,
                  "px, z-buffer cell edge of the visibility test", R::AtLeast(1));
  options->AddDouble("DatabaseImporter.point_footprint_m", &c->point_footprint_m,
                     "m, diameter of the surface patch each scan point covers in the z-buffer",
                     R::AtLeast(0));
  options->AddDouble("DatabaseImporter.occlusion_tolerance_m", &c->occlusion_tolerance_m,
                     "m, a point is visible up to this behind the nearest scan point of its cell",
                     R::AtLeast(0));
  options->AddDouble("DatabaseImporter.occlusion_tolerance_ratio",
                     &c->occlusion_tolerance_ratio,
                     "relative depth margin of the visibility test (fraction of the range)",
                     R::AtLeast(0));
  options->AddInt("DatabaseImporter.min_count", &c->min_count,
                  "co-visible points an image pair needs to be listed", R::AtLeast(1));
  options->AddInt("DatabaseImporter.max_pairs_per_image", &c->max_pairs_per_image,
                  "best co-visibility pairs kept per image (a pair stays when either image "
                  "keeps it)",
                  R::AtLeast(1));
  options->AddInt("DatabaseImporter.num_temporal_neighbors", &c->num_temporal_neighbors,
                  "successive images of the same camera paired with each image", R::AtLeast(0));
  options->AddBool("DatabaseImporter.intra_rig_pairs", &c->intra_rig_pairs,
                   "pair the cameras of one rig frame whose views overlap");
  options->AddDouble("DatabaseImporter.min_view_overlap", &c->min_view_overlap,
                     "fraction of one camera's rays (at view_overlap_depth_m) the other sees "
                     "for an intra-rig pair",
                     R::Between(0, 1));
  options->AddDouble("DatabaseImporter.view_overlap_depth_m", &c->view_overlap_depth_m,
                     "m, depth of the intra-rig view-overlap test", R::GreaterThan(0));
  options->AddInt("DatabaseImporter.fallback_num_neighbors", &c->fallback_num_neighbors,
                  "without constraints: nearest images by prior position paired with each",
                  R::AtLeast(1));
  options->AddInt("DatabaseImporter.num_threads", &c->num_threads, "threads (-1 = all cores)",
                  R::AtLeast(1).Or(-1));
  options->AddDouble("DatabaseImporter.min_position_sigma_m", &p->min_position_sigma_m,
                     "m, floor of the prior position sigma per axis", R::GreaterThan(0));
  options->AddDouble("DatabaseImporter.drift_m_per_s", &p->drift_m_per_s,
                     "m/s, position sigma growth with the time to the nearest keyframe (priors, "
                     "constraints)",
                     R::AtLeast(0));
  options->AddDouble("DatabaseImporter.drift_rad_per_s", &p->drift_rad_per_s,
                     "rad/s, rotation sigma growth with the time between a keyframe and its rig "
                     "frame (constraints)",
                     R::AtLeast(0));
  options->AddDouble("DatabaseImporter.max_extrapolation_s", &p->max_extrapolation_s,
                     "s, images at most this far outside the pose_slam trajectory keep the end "
                     "pose as prior; farther ones are left out",
                     R::AtLeast(0));
  options->AddDouble("DatabaseImporter.max_frame_time_offset_s", &p->max_frame_time_offset_s,
                     "s, a constraint's keyframe is moved to the nearest rig frame at most "
                     "this far away",
                     R::GreaterThan(0));
  options->AddStructCheck([importer] { return importer->Check(); });
}

void AddProjectiveIcpOptions(OptionManager* options, ProjectiveIcpOptions* icp) {
  options->AddInt("ProjectiveIcp.num_levels", &icp->num_levels,
                  "coarse-to-fine levels (level l uses every 2^l-th pixel)", R::Between(1, 5));
  options->AddInt("ProjectiveIcp.max_iterations_per_level", &icp->max_iterations_per_level,
                  "Gauss-Newton iterations per level", R::AtLeast(1));
  options->AddDouble("ProjectiveIcp.max_correspondence_distance_m",
                     &icp->max_correspondence_distance_m,
                     "reject matches farther apart than this at the finest level (m; x 2^l "
                     "at level l)",
                     R::GreaterThan(0));
  options->AddDouble("ProjectiveIcp.max_normal_angle_deg", &icp->max_normal_angle_deg,
                     "reject matches whose normals differ more (deg)",
                     R::GreaterThan(0).AndAtMost(180));
  options->AddDouble("ProjectiveIcp.huber_threshold_m", &icp->huber_threshold_m,
                     "Huber scale of the point-to-plane residual (m; 0 = least squares)",
                     R::AtLeast(0));
  options->AddDouble("ProjectiveIcp.convergence_rotation_rad", &icp->convergence_rotation_rad,
                     "a level ends when a step rotates less (rad) ...", R::AtLeast(0));
  options->AddDouble("ProjectiveIcp.convergence_translation_m",
                     &icp->convergence_translation_m, "... and translates less (m)",
                     R::AtLeast(0));
  options->AddInt("ProjectiveIcp.min_inliers", &icp->min_inliers,
                  "fewer matches: the frame keeps the initial guess (Fusion.constant_velocity)",
                  R::AtLeast(6));
  options->AddDouble("ProjectiveIcp.degeneracy_threshold", &icp->degeneracy_threshold,
                     "min/max Hessian eigenvalue ratio below which the result is degenerate",
                     R::AtLeast(0));
  options->AddDouble("ProjectiveIcp.photometric_weight", &icp->photometric_weight,
                     "weight of the intensity residual (colour, [0, 1]) against the "
                     "point-to-plane one (m) in tracking; default Open3D's hybrid ratio "
                     "0.032/0.968 (0 = depth only)",
                     R::AtLeast(0));
  options->AddDouble("ProjectiveIcp.photometric_huber", &icp->photometric_huber,
                     "Huber scale of the intensity residual ([0, 1]; 0 = least squares)",
                     R::AtLeast(0));
  options->AddStructCheck([icp] { return icp->Check(); });
}

void AddSurfelFusionOptions(OptionManager* options, SurfelFusionOptions* fusion) {
  options->AddDouble("Fusion.max_merge_distance_m", &fusion->max_merge_distance_m,
                     "merge an observation into a surfel closer than this along its normal (m)",
                     R::GreaterThan(0));
  options->AddDouble("Fusion.max_merge_angle_deg", &fusion->max_merge_angle_deg,
                     "... whose normal differs less than this (deg)",
                     R::GreaterThan(0).AndAtMost(180));
  options->AddInt("Fusion.association_radius_px", &fusion->association_radius_px,
                  "search window radius around a pixel for its surfel (pixels)", R::Between(0, 3));
  options->AddInt("Fusion.unstable_age_frames", &fusion->unstable_age_frames,
                  "remove surfels first seen more than this many frames ago ...", R::AtLeast(0));
  options->AddDouble("Fusion.unstable_min_confidence", &fusion->unstable_min_confidence,
                     "... with a confidence (merged observations) below this (0 = keep all)",
                     R::AtLeast(0));
  options->AddDouble("Fusion.output_min_confidence", &fusion->output_min_confidence,
                     "write surfels with at least this confidence", R::AtLeast(0));
  options->AddStructCheck([fusion] { return fusion->Check(); });
}

void AddLidarFusionOptions(OptionManager* options, LidarFusionOptions* lidar) {
  options->AddDouble("LidarFusion.azimuth_resolution_deg", &lidar->azimuth_resolution_deg,
                     "range image column width (deg; 360 / this columns)", R::Between(0.01, 10));
  options->AddDouble("LidarFusion.elevation_resolution_deg", &lidar->elevation_resolution_deg,
                     "range image row spacing (deg; 0 = one row per ring of the scan)",
                     R::AtLeast(0).AndAtMost(10));
  options->AddDouble("LidarFusion.min_range_m", &lidar->min_range_m,
                     "ignore returns closer than this (m)", R::AtLeast(0));
  options->AddDouble("LidarFusion.max_range_m", &lidar->max_range_m,
                     "ignore returns farther than this (m)", R::GreaterThan(0));
  options->RequireLess("LidarFusion.min_range_m", "LidarFusion.max_range_m");
  options->AddDouble("LidarFusion.max_range_jump", &lidar->max_range_jump,
                     "no normal difference to a neighbour whose range differs more than this "
                     "fraction of the range",
                     R::GreaterThan(0));
  options->AddDouble("LidarFusion.max_incidence_deg", &lidar->max_incidence_deg,
                     "drop returns seen more obliquely (angle between normal and ray, deg)",
                     R::GreaterThan(0).AndAtMost(90));
  options->AddStructCheck([lidar] { return lidar->Check(); });
}

void AddRgbdFusionOptions(OptionManager* options, RgbdFusionOptions* rgbd) {
  options->AddInt("Fusion.downsample_factor", &rgbd->downsample_factor,
                  "use every k-th pixel in both directions (2: 640x480 -> 320x240)",
                  R::Between(1, 8));
  options->AddDouble("Fusion.min_depth_m", &rgbd->min_depth_m, "ignore depths below (m)",
                     R::AtLeast(0));
  options->AddDouble("Fusion.max_depth_m", &rgbd->max_depth_m, "ignore depths above (m)",
                     R::GreaterThan(0));
  options->RequireLess("Fusion.min_depth_m", "Fusion.max_depth_m");
  options->AddDouble("Fusion.max_depth_jump", &rgbd->max_depth_jump,
                     "no normal across a neighbour depth step above this fraction of the depth",
                     R::GreaterThan(0));
  options->AddInt("Fusion.normal_window_px", &rgbd->normal_window_px,
                  "normals from depth slopes over this many pixels each side (1 = central "
                  "differences; wider = smoother normals of noisy depth)",
                  R::Between(1, 5));
  options->AddDouble("Fusion.crease_rejection_sigma", &rgbd->crease_rejection_sigma,
                     "drop the normals of pixels whose window spans a crease: off-plane score "
                     "above this many RMS of the frame's (0 = keep them)",
                     R::AtLeast(0));
  options->AddDouble("Fusion.max_incidence_deg", &rgbd->max_incidence_deg,
                     "drop pixels seen more obliquely (angle between normal and ray, deg)",
                     R::GreaterThan(0).AndAtMost(90));
  options->AddBool("Fusion.bilateral_filter", &rgbd->bilateral_filter,
                   "bilateral filter of the depth before fusion");
  options->AddDouble("Fusion.bilateral_sigma_px", &rgbd->bilateral_sigma_px,
                     "bilateral filter: spatial sigma (pixels)", R::GreaterThan(0));
  options->AddDouble("Fusion.bilateral_sigma_depth_m", &rgbd->bilateral_sigma_depth_m,
                     "bilateral filter: depth sigma (m)", R::GreaterThan(0));
  options->AddInt("Fusion.model_splat_px", &rgbd->model_splat_px,
                  "tracking target: a surfel covers up to this many pixels around its own",
                  R::Between(0, 3));
  options->AddBool("Fusion.constant_velocity", &rgbd->constant_velocity,
                   "tracking starts from the previous motion applied again (0: from the "
                   "previous pose)");
  options->AddStructCheck([rgbd] { return rgbd->Check(); });
}

void AddIcpOptions(OptionManager* options, IcpOptions* icp) {
  options->AddInt("Icp.max_iterations",
                  &icp->max_iterations,
                  "associations (nearest-neighbour passes), each followed by "
                  "Gauss-Newton solves",
                  R::AtLeast(1));
  options->AddInt("Icp.max_inner_iterations",
                  &icp->max_inner_iterations,
                  "extra Gauss-Newton solves on the same matches per "
                  "association (0 = none)",
                  R::AtLeast(0));
  options->AddDouble("Icp.max_correspondence_distance_m",
                     &icp->max_correspondence_distance_m,
                     "reject matches farther than this (m)",
                     R::GreaterThan(0));
  options->AddAlias("Icp.max_correspondence_distance",
                    "Icp.max_correspondence_distance_m");
  options->AddDouble(
      "Icp.max_normal_angle_deg",
      &icp->max_normal_angle_deg,
      "reject matches whose source and target normals differ more (deg; only "
      "when the source has normals)",
      R::GreaterThan(0).AndAtMost(180));
  options->AddDouble("Icp.min_planarity",
                     &icp->min_planarity,
                     "ignore target points with lower planarity",
                     R::Between(0, 1));
  options->AddChoice(
      "Icp.kernel", &icp->kernel, kRobustKernels, "robust kernel");
  options->AddDouble("Icp.kernel_scale_m",
                     &icp->kernel_scale_m,
                     "robust kernel scale (m)",
                     R::GreaterThan(0));
  options->AddAlias("Icp.kernel_scale", "Icp.kernel_scale_m");
  options->AddDouble("Icp.convergence_rotation_rad",
                     &icp->convergence_rotation_rad,
                     "step threshold (rad)",
                     R::AtLeast(0));
  options->AddAlias("Icp.convergence_rotation", "Icp.convergence_rotation_rad");
  options->AddDouble("Icp.convergence_translation_m",
                     &icp->convergence_translation_m,
                     "step threshold (m)",
                     R::AtLeast(0));
  options->AddAlias("Icp.convergence_translation",
                    "Icp.convergence_translation_m");
  options->AddInt("Icp.min_inliers",
                  &icp->min_inliers,
                  "fewer matches end the registration as not converged",
                  R::AtLeast(6));
  options->AddInt("Icp.coarse_stride",
                  &icp->coarse_stride,
                  "the finest coarse level uses every k-th source point (1 = "
                  "no coarse levels)",
                  R::AtLeast(1));
  options->AddInt(
      "Icp.coarse_levels",
      &icp->coarse_levels,
      "coarse levels at most (every 2^(L-1) k-th, ..., k-th source point)",
      R::Between(0, 8));
  options->AddInt(
      "Icp.coarse_min_points",
      &icp->coarse_min_points,
      "a coarse level is used only with at least this many source points",
      R::AtLeast(1));
  options->AddDouble("Icp.degeneracy_threshold",
                     &icp->degeneracy_threshold,
                     "min/max eigenvalue ratio of the scaled Hessian",
                     R::AtLeast(0));
  options->AddBool(
      "Icp.field_of_view_gate",
      &icp->field_of_view_gate,
      "no match for source points outside the target scan's elevation band or "
      "range (target in its sensor frame, spin axis z)");
  options->AddDouble(
      "Icp.visibility_gate_m",
      &icp->visibility_gate_m,
      "no match for source points hidden more than this (m, + 2 % of the "
      "range) "
      "behind the target scan's surface seen from its sensor (0 = off)",
      R::AtLeast(0));
  options->AddAlias("Icp.visibility_gate", "Icp.visibility_gate_m");
  options->AddStructCheck([icp] { return icp->Check(); });
}

void AddNormalOptions(OptionManager* options, NormalOptions* normals) {
  options->AddInt("Icp.num_neighbors",
                  &normals->num_neighbors,
                  "k of the PCA normals",
                  R::Between(3, 64));
  options->AddAlias("Icp.normal_neighbors", "Icp.num_neighbors");
  options->AddDouble("Icp.max_radius_m",
                     &normals->max_radius_m,
                     "max neighbour distance for normals (m)",
                     R::GreaterThan(0));
  options->AddAlias("Icp.normal_radius", "Icp.max_radius_m");
  options->AddStructCheck([normals] { return normals->Check(); });
}

void AddSgldOptions(OptionManager* options, SgldOptions* sgld) {
  options->AddInt("Bayesian.num_iterations",
                  &sgld->num_iterations,
                  "SGLD iterations including burn-in",
                  R::AtLeast(1));
  options->AddAlias("Bayesian.iterations", "Bayesian.num_iterations");
  options->AddInt("Bayesian.burn_in",
                  &sgld->burn_in,
                  "SGLD burn-in iterations",
                  R::AtLeast(0));
  options->RequireLess("Bayesian.burn_in", "Bayesian.num_iterations");
  options->AddInt("Bayesian.thinning",
                  &sgld->thinning,
                  "keep every k-th sample",
                  R::AtLeast(1));
  options->AddInt("Bayesian.batch_size",
                  &sgld->batch_size,
                  "correspondences per mini-batch",
                  R::AtLeast(1));
  options->AddDouble("Bayesian.step_size",
                     &sgld->step_size,
                     "SGLD step in the preconditioned metric",
                     R::GreaterThan(0).AndLessThan(2));
  options->AddDouble("Bayesian.metric_decay",
                     &sgld->metric_decay,
                     "EMA decay of the preconditioner (RMSprop beta)",
                     R::AtLeast(0).AndLessThan(1));
  options->AddDouble("Bayesian.damping_sigma_rotation_rad",
                     &sgld->damping_sigma_rotation_rad,
                     "preconditioner damping scale (rad)",
                     R::GreaterThan(0));
  options->AddDouble("Bayesian.damping_sigma_translation_m",
                     &sgld->damping_sigma_translation_m,
                     "preconditioner damping scale (m)",
                     R::GreaterThan(0));
  options->AddUint64("Bayesian.seed", &sgld->seed, "random seed of the chain");
  options->AddStructCheck([sgld] { return sgld->Check(); });
}

void AddBayesianIcpOptions(OptionManager* options, BayesianIcpOptions* bayes) {
  IcpOptions* icp = &bayes->icp;
  options->AddChoice("Bayesian.kernel",
                     &icp->kernel,
                     kRobustKernels,
                     "robust kernel of --method bayesian (replaces Icp.kernel; "
                     "calibrated with "
                     "cauchy)");
  options->AddDouble("Bayesian.kernel_scale_m",
                     &icp->kernel_scale_m,
                     "robust kernel scale of --method bayesian (m; replaces "
                     "Icp.kernel_scale_m)",
                     R::GreaterThan(0));
  options->AddAlias("Bayesian.kernel_scale", "Bayesian.kernel_scale_m");
  options->AddInt("Bayesian.normal_neighbors",
                  &bayes->normal_neighbors,
                  "k of the target normals of --method bayesian (replaces "
                  "Icp.num_neighbors)",
                  R::Between(3, 64));
  options->AddDouble("Bayesian.min_planarity",
                     &icp->min_planarity,
                     "ignore target points with lower planarity in --method "
                     "bayesian (replaces "
                     "Icp.min_planarity; calibrated with 0.1, pose_slam's with 0)",
                     R::Between(0, 1));
  options->AddBool("Bayesian.field_of_view_gate",
                   &icp->field_of_view_gate,
                   "Icp.field_of_view_gate of --method bayesian (replaces it; "
                   "calibrated with 1; "
                   "set 0 for clouds not in their sensor frame)");
  options->AddDouble(
      "Bayesian.visibility_gate_m",
      &icp->visibility_gate_m,
      "Icp.visibility_gate_m of --method bayesian (m; replaces it; calibrated "
      "with 0.1; set 0 for clouds not in their sensor frame)",
      R::AtLeast(0));
  options->AddAlias("Bayesian.visibility_gate", "Bayesian.visibility_gate_m");
  options->AddBool("Bayesian.visibility_follows_surface",
                   &icp->visibility_follows_surface,
                   "with Bayesian.visibility_gate_m: a source point behind the nearest "
                   "target range of its bin is still visible when it is not behind that "
                   "target point's surface element (point and normal; grazing floors, "
                   "ceilings; pose_slam's calibration uses it)");
  options->AddDouble("Bayesian.min_normal_contrast",
                     &icp->min_normal_contrast,
                     "ignore target points whose normal is not determined, contrast "
                     "(l1 - l0) / l1 of the neighbourhood's eigenvalues l0 <= l1 <= l2 "
                     "below this (0 = off; pose_slam's calibration uses 0.5)",
                     R::Between(0, 1));
  AddSgldOptions(options, &bayes->sgld);
  options->AddDouble("Bayesian.noise_sigma_m",
                     &bayes->noise_sigma_m,
                     "likelihood sigma (m), 0 = from the pair's residuals",
                     R::AtLeast(0));
  options->AddAlias("Bayesian.noise_sigma", "Bayesian.noise_sigma_m");
  options->AddDouble(
      "Bayesian.correlation_length_m",
      &bayes->correlation_length_m,
      "cell edge of the noise estimate (m) when num_correlation_cells = 0",
      R::AtLeast(0));
  options->AddInt("Bayesian.num_correlation_cells",
                  &bayes->num_correlation_cells,
                  "spatial cells of the per-pair (cluster sandwich) noise "
                  "estimate (0 = cells of "
                  "correlation_length_m)",
                  R::AtLeast(2).Or(0));
  options->AddDouble(
      "Bayesian.jackknife_leverage_power",
      &bayes->jackknife_leverage_power,
      "leverage adjustment of the cluster sandwich: 0 = CR1, 1 = CR3 jackknife "
      "(calibrated)",
      R::AtLeast(0));
  options->AddAlias("Bayesian.leverage_power",
                    "Bayesian.jackknife_leverage_power");
  options->AddDouble("Bayesian.refine_max_correspondence_distance_m",
                     &bayes->refine_max_correspondence_distance_m,
                     "after the ICP, refine it and associate the posterior "
                     "within this distance "
                     "(m; 0 = Icp.max_correspondence_distance_m)",
                     R::AtLeast(0));
  options->AddAlias("Bayesian.refine_max_correspondence_distance",
                    "Bayesian.refine_max_correspondence_distance_m");
  options->AddDouble("Bayesian.noise_sigma_scale",
                     &bayes->noise_sigma_scale,
                     "multiplies the per-pair likelihood sigma (fitted on "
                     "simulated office-type "
                     "pairs)",
                     R::GreaterThan(0));
  options->AddBool("Bayesian.plane_fit_variance",
                   &bayes->plane_fit_variance,
                   "per-correspondence variance from the target plane fit "
                   "(normal uncertainty x "
                   "offset)");
  CorrespondenceVarianceOptions* variance = &bayes->correspondence_variance;
  options->AddDouble(
      "Bayesian.plane_variance_weight",
      &variance->plane_variance_weight,
      "plane_fit_variance: weight of the plane-fit scatter (2 = both clouds)",
      R::AtLeast(0));
  options->AddDouble(
      "Bayesian.max_tilt_variance_rad2",
      &variance->max_tilt_variance_rad2,
      "plane_fit_variance: cap of a normal tilt variance (rad^2)",
      R::AtLeast(0));
  options->AddDouble("Bayesian.floor_m2",
                     &variance->floor_m2,
                     "plane_fit_variance: added to every variance (m^2)",
                     R::GreaterThan(0));
  options->AddBool("Bayesian.block_tempering",
                   &bayes->block_tempering,
                   "rescale the rotation / translation blocks of the posterior "
                   "to the cluster "
                   "jackknife");
  options->AddDouble(
      "Bayesian.prior_sigma_rotation_rad",
      &bayes->prior_sigma_rotation_rad,
      "Gaussian prior on the pose around --init_path, rotation sigma (rad; 0 = "
      "flat)",
      R::AtLeast(0));
  options->AddAlias("Bayesian.prior_sigma_rotation",
                    "Bayesian.prior_sigma_rotation_rad");
  options->AddDouble("Bayesian.prior_sigma_translation_m",
                     &bayes->prior_sigma_translation_m,
                     "Gaussian prior on the pose around --init_path, "
                     "translation sigma (m; 0 = "
                     "flat)",
                     R::AtLeast(0));
  options->AddAlias("Bayesian.prior_sigma_translation",
                    "Bayesian.prior_sigma_translation_m");
  options->AddStructCheck([bayes] { return bayes->Check(); });
}

void AddLioOptions(OptionManager* options, LioOptions* lio) {
  options->AddDouble("Lio.imu_noise_inflation",
                     &lio->imu_noise_inflation,
                     "factor on the rig's IMU noise densities",
                     R::GreaterThan(0));
  options->AddInt("Lio.point_stride",
                  &lio->point_stride,
                  "keep every n-th raw point before down-sampling (1 = all)",
                  R::AtLeast(1));
  options->AddDouble("Lio.scan_voxel_size",
                     &lio->scan_voxel_size,
                     "m, scan down-sampling voxel (0 = off)",
                     R::AtLeast(0));
  options->AddDouble("Lio.min_range",
                     &lio->min_range,
                     "m, closer points are dropped (blind zone)",
                     R::AtLeast(0));
  options->AddDouble("Lio.max_range",
                     &lio->max_range,
                     "m, farther points are dropped",
                     R::GreaterThan(0));
  options->RequireLess("Lio.min_range", "Lio.max_range");
  options->AddInt("Lio.num_neighbours",
                  &lio->num_neighbours,
                  "k of the plane fit",
                  R::AtLeast(3));
  options->AddDouble("Lio.max_neighbour_distance",
                     &lio->max_neighbour_distance,
                     "m, farthest allowed plane neighbour",
                     R::GreaterThan(0));
  options->AddDouble("Lio.max_plane_residual",
                     &lio->max_plane_residual,
                     "m, max distance of a neighbour to its plane",
                     R::GreaterThan(0));
  options->AddDouble("Lio.max_point_residual",
                     &lio->max_point_residual,
                     "m, points farther from their plane are not used",
                     R::GreaterThan(0));
  options->AddDouble("Lio.point_noise_std",
                     &lio->point_noise_std,
                     "m, point-to-plane noise std",
                     R::GreaterThan(0));
  options->AddInt("Lio.max_iterations",
                  &lio->max_iterations,
                  "IEKF iterations per scan",
                  R::AtLeast(1));
  options->AddDouble(
      "Lio.convergence_rotation",
      &lio->convergence_rotation,
      "rad, stop when the step is below this and convergence_translation",
      R::GreaterThan(0));
  options->AddDouble("Lio.convergence_translation",
                     &lio->convergence_translation,
                     "m",
                     R::GreaterThan(0));
  options->AddDouble("Lio.reassociate_translation",
                     &lio->reassociate_translation,
                     "m: after convergence, search neighbours again only if "
                     "the pose moved more",
                     R::AtLeast(0));
  options->AddDouble("Lio.reassociate_rotation",
                     &lio->reassociate_rotation,
                     "rad: ... or rotated more than this since the last search",
                     R::AtLeast(0));
  options->AddDouble("Lio.degeneracy_threshold",
                     &lio->degeneracy_threshold,
                     "eigenvalue of the per-point information HᵀH/N below "
                     "which a direction is "
                     "weak",
                     R::AtLeast(0));
  options->AddDouble("Lio.keyframe_distance",
                     &lio->keyframe_distance,
                     "m between keyframes",
                     R::GreaterThan(0));
  options->AddDouble("Lio.keyframe_angle_deg",
                     &lio->keyframe_angle_deg,
                     "deg between keyframes",
                     R::GreaterThan(0));
  options->AddBool("Lio.estimate_extrinsic",
                   &lio->estimate_extrinsic,
                   "estimate every LiDAR's T_imu_lidar online (FAST-LIO2 "
                   "extrinsic_est_en); the rig.yaml value is the prior; "
                   "estimates in calibration.yaml");
  options->AddBool("Lio.estimate_time_offset",
                   &lio->estimate_time_offset,
                   "estimate every LiDAR's time offset to the IMU online; the "
                   "rig.yaml value is the prior; estimates in calibration.yaml");
  options->AddDouble("Lio.extrinsic_rotation_std_deg",
                     &lio->extrinsic_rotation_std_deg,
                     "deg, prior 1-sigma of the rig.yaml LiDAR rotation "
                     "(with Lio.estimate_extrinsic)",
                     R::GreaterThan(0));
  options->AddDouble("Lio.extrinsic_translation_std",
                     &lio->extrinsic_translation_std,
                     "m, prior 1-sigma of the rig.yaml LiDAR translation "
                     "(with Lio.estimate_extrinsic)",
                     R::GreaterThan(0));
  options->AddDouble("Lio.time_offset_std_ms",
                     &lio->time_offset_std_ms,
                     "ms, prior 1-sigma of the rig.yaml LiDAR time offset "
                     "(with Lio.estimate_time_offset)",
                     R::GreaterThan(0));
  options->AddBool("Lio.estimate_gyro_scale",
                   &lio->estimate_gyro_scale,
                   "estimate the gyroscope's scale-factor and cross-axis error matrix E "
                   "(measured = (I + E) true + bias; 9 states) online");
  options->AddDouble("Lio.gyro_scale_std",
                     &lio->gyro_scale_std,
                     "prior 1-sigma of each entry of E (fraction; Bosch BMI085 datasheet: "
                     "sensitivity tolerance and cross-axis sensitivity 1 % typ; with "
                     "Lio.estimate_gyro_scale)",
                     R::GreaterThan(0));
  AddVoxelMapOptions(options, &lio->map);
  AddImuInitializerOptions(options, &lio->init);
  options->AddStructCheck([lio] { return lio->Check(); });
}

void AddVoxelMapOptions(OptionManager* options, VoxelMapOptions* map) {
  options->AddDouble("Map.voxel_size",
                     &map->voxel_size,
                     "m, iVox hash voxel edge",
                     R::GreaterThan(0));
  options->AddDouble("Map.resolution",
                     &map->resolution,
                     "m, min spacing of map points",
                     R::AtLeast(0));
  options->RequireLess("Map.resolution", "Map.voxel_size");
  options->AddInt("Map.max_points_per_voxel",
                  &map->max_points_per_voxel,
                  "points per voxel",
                  R::AtLeast(1));
  options->AddUint64("Map.max_voxels",
                     &map->max_voxels,
                     "voxels kept (least recently used dropped first)",
                     R::AtLeast(1));
  options->AddStructCheck([map] { return map->Check(); });
}

void AddImuInitializerOptions(OptionManager* options,
                              ImuInitializerOptions* init) {
  options->AddDouble("Init.min_duration_s",
                     &init->min_duration_s,
                     "s of stationary IMU data for the initialisation",
                     R::GreaterThan(0));
  options->AddInt("Init.min_samples",
                  &init->min_samples,
                  "IMU samples of the stationary window, at least",
                  R::AtLeast(10));
  options->AddDouble("Init.max_gyro_std",
                     &init->max_gyro_std,
                     "rad/s: above this the IMU is not static",
                     R::GreaterThan(0));
  options->AddDouble("Init.max_accel_std",
                     &init->max_accel_std,
                     "m/s^2: above this the IMU is not static",
                     R::GreaterThan(0));
  options->AddDouble("Init.gravity_magnitude",
                     &init->gravity_magnitude,
                     "m/s^2",
                     R::GreaterThan(0));
  options->AddStructCheck([init] { return init->Check(); });
}

void AddPoseGraphSolverOptions(OptionManager* options, PoseGraphSolverOptions* solver) {
  options->AddInt("Solver.max_num_iterations",
                  &solver->max_num_iterations,
                  "Levenberg-Marquardt iterations at most",
                  R::AtLeast(1));
  options->AddDouble("Solver.function_tolerance",
                     &solver->function_tolerance,
                     "stop when the relative cost change is below this",
                     R::AtLeast(0));
  options->AddDouble("Solver.gradient_tolerance",
                     &solver->gradient_tolerance,
                     "stop when the largest projected gradient entry is below this",
                     R::AtLeast(0));
  options->AddDouble("Solver.parameter_tolerance",
                     &solver->parameter_tolerance,
                     "stop when the relative step size is below this",
                     R::AtLeast(0));
  options->AddInt("Solver.num_threads",
                  &solver->num_threads,
                  "threads for the residual and Jacobian evaluation (-1 = all cores)",
                  R::AtLeast(1).Or(-1));
  options->AddStructCheck([solver] { return solver->Check(); });
}

void AddPoseGraphOptions(OptionManager* options, G2oOptimizationOptions* pose_graph) {
  options->AddChoice("PoseGraph.initialization",
                     &pose_graph->initialization,
                     {"chordal", "vertices"},
                     "start of Levenberg-Marquardt: the chordal initialisation, or the "
                     "file's VERTEX poses");
  AddPoseGraphSolverOptions(options, &pose_graph->solver);
  options->AddStructCheck([pose_graph] { return pose_graph->Check(); });
}

void AddPoseSlamOptions(OptionManager* options, PoseSlamOptions* pose_slam) {
  PoseSlamOptions* o = pose_slam;
  options->AddInt("PoseSlam.knn", &o->knn, "candidate pairs: nearest keyframes by position",
                  R::AtLeast(1));
  options->AddInt("PoseSlam.min_index_step", &o->min_index_step,
                  "candidate pairs: smallest keyframe index difference", R::AtLeast(1));
  options->AddInt("PoseSlam.max_index_step", &o->max_index_step,
                  "candidate pairs: largest keyframe index difference", R::AtLeast(1));
  options->AddBool("PoseSlam.use_icp_pairs", &o->use_icp_pairs,
                   "Bayesian ICP factors between the candidate pairs");
  options->AddBool("PoseSlam.use_imu", &o->use_imu,
                   "IMU preintegration factors with velocities and biases");
  options->AddBool("PoseSlam.piecewise_bias", &o->piecewise_bias,
                   "a new bias variable at each rest (0: one bias for the recording)");
  options->AddBool("PoseSlam.use_zero_velocity", &o->use_zero_velocity,
                   "zero-velocity and identity-pose factors at rests");
  options->AddDouble("PoseSlam.source_voxel_size", &o->source_voxel_size,
                     "m, source cloud downsampling of the pair registration", R::GreaterThan(0));
  options->AddDouble("PoseSlam.target_voxel_size", &o->target_voxel_size,
                     "m, target cloud downsampling of the pair registration", R::GreaterThan(0));
  options->AddDouble("PoseSlam.max_translation_difference", &o->max_translation_difference,
                     "m, reject an ICP pair farther from lio's relative pose", R::GreaterThan(0));
  options->AddDouble("PoseSlam.max_rotation_difference_deg", &o->max_rotation_difference_deg,
                     "deg, reject an ICP pair farther from lio's relative pose",
                     R::GreaterThan(0));
  options->AddChoice("PoseSlam.icp_loss", &o->icp_loss.kernel, {"none", "huber", "cauchy"},
                     "robust loss on the ICP factors");
  options->AddDouble("PoseSlam.icp_loss_scale", &o->icp_loss.scale,
                     "residual norm (sigmas) where the ICP loss bends", R::GreaterThan(0));
  options->AddDouble("PoseSlam.outlier_chi2", &o->outlier_chi2,
                     "second pass without ICP factors whose squared normalised residual "
                     "exceeds this",
                     R::GreaterThan(0));
  options->AddDouble("PoseSlam.odometry_sigma_rotation_deg", &o->odometry_sigma_rotation_deg,
                     "deg, 1-sigma of lio's relative rotation between consecutive keyframes "
                     "(floor)",
                     R::GreaterThan(0));
  options->AddDouble("PoseSlam.odometry_sigma_rotation_deg_per_m",
                     &o->odometry_sigma_rotation_deg_per_m,
                     "deg per m travelled, added to the odometry rotation sigma", R::AtLeast(0));
  options->AddDouble("PoseSlam.odometry_sigma_translation", &o->odometry_sigma_translation,
                     "m, 1-sigma of lio's relative translation between consecutive keyframes "
                     "(floor)",
                     R::GreaterThan(0));
  options->AddDouble("PoseSlam.odometry_sigma_translation_per_m",
                     &o->odometry_sigma_translation_per_m,
                     "m per m travelled, added to the odometry translation sigma", R::AtLeast(0));
  options->AddDouble("PoseSlam.imu_gyro_error", &o->imu_gyro_error,
                     "unmodelled gyro error (scale, misalignment) as a fraction of the rotation "
                     "angle between keyframes",
                     R::AtLeast(0));
  options->AddDouble("PoseSlam.imu_accel_error", &o->imu_accel_error,
                     "unmodelled accelerometer error as a fraction of the integrated specific "
                     "force between keyframes",
                     R::AtLeast(0));
  options->AddDouble("PoseSlam.bias_instability_gyro", &o->bias_instability_gyro,
                     "rad/s, 1-sigma departure of the gyro bias from its piecewise constant",
                     R::AtLeast(0));
  options->AddDouble("PoseSlam.bias_instability_accel", &o->bias_instability_accel,
                     "m/s^2, 1-sigma departure of the accelerometer bias from its piecewise "
                     "constant",
                     R::AtLeast(0));
  options->AddDouble("PoseSlam.bias_prior_gyro", &o->bias_prior_gyro,
                     "rad/s, 1-sigma prior of the first gyro bias around 0", R::GreaterThan(0));
  options->AddDouble("PoseSlam.bias_prior_accel", &o->bias_prior_accel,
                     "m/s^2, 1-sigma prior of the first accelerometer bias around 0",
                     R::GreaterThan(0));
  options->AddDouble("PoseSlam.gravity", &o->gravity, "m/s^2, along -z of lio's world frame",
                     R::GreaterThan(0));
  options->AddDouble("PoseSlam.max_imu_gap", &o->preintegration.max_sample_gap_s,
                     "s, a longer gap between IMU samples between keyframes is an error",
                     R::GreaterThan(0));
  StationaryDetectionOptions* s = &o->stationary;
  options->AddDouble("Stationary.window", &s->window_s, "s, sliding test window",
                     R::GreaterThan(0));
  options->AddDouble("Stationary.max_gyro_std", &s->max_gyro_std,
                     "rad/s, gyro scatter in a still window", R::GreaterThan(0));
  options->AddDouble("Stationary.max_accel_std", &s->max_accel_std,
                     "m/s^2, accelerometer scatter in a still window", R::GreaterThan(0));
  options->AddDouble("Stationary.max_gyro_mean", &s->max_gyro_mean,
                     "rad/s, norm of a still window's mean rate", R::GreaterThan(0));
  options->AddDouble("Stationary.min_duration", &s->min_duration_s,
                     "s, shorter still stretches are not rests", R::GreaterThan(0));
  ZeroVelocityOptions* z = &o->zero_velocity;
  options->AddDouble("ZeroVelocity.velocity_sigma", &z->velocity_sigma,
                     "m/s, 1-sigma of a velocity at rest", R::GreaterThan(0));
  options->AddDouble("ZeroVelocity.rotation_sigma", &z->rotation_sigma,
                     "rad, 1-sigma of the rotation between two nodes of one rest",
                     R::GreaterThan(0));
  options->AddDouble("ZeroVelocity.translation_sigma", &z->translation_sigma,
                     "m, 1-sigma of the translation between two nodes of one rest",
                     R::GreaterThan(0));
  options->AddInt("num_threads", &o->num_threads, "threads (-1 = all cores)",
                  R::AtLeast(1).Or(-1));
  AddBayesianIcpOptions(options, &o->bayesian);
  AddPoseGraphSolverOptions(options, &o->solver);
  options->AddStructCheck([o] { return o->Check(); });
}

void AddTrajectoryEvaluationOptions(OptionManager* options,
                                    TrajectoryEvaluationOptions* eval) {
  options->AddEnum(
      "alignment",
      &eval->alignment,
      AlignmentChoices(
          {AlignmentType::kSE3, AlignmentType::kSim3, AlignmentType::kNone}),
      "alignment of the estimate to the reference");
  options->AddAlias("align", "alignment");
  options->AddStructCheck([eval] { return eval->Check(); });
}

void AddSfmEvaluationOptions(OptionManager* options,
                             colmap::SfmEvaluationOptions* eval) {
  options->AddEnum(
      "alignment",
      &eval->alignment,
      AlignmentChoices(
          {AlignmentType::kSim3, AlignmentType::kSE3, AlignmentType::kNone}),
      "alignment of the estimated camera centres to the reference (se3 for "
      "metric "
      "models)");
  options->AddStructCheck([eval] { return eval->Check(); });
}

void AddWalkingOptions(OptionManager* options, sim::WalkingOptions* walk) {
  options->AddInt("Walk.num_stops",
                  &walk->num_stops,
                  "rests of a generated walk, each a HILTI-style control-point "
                  "survey (controlpoints.txt): at the start, at the end and at "
                  "equal time steps between (3: start, middle, end)",
                  R::Between(2, 1000));
  options->AddDouble("Walk.speed",
                     &walk->speed,
                     "mean speed of a generated walk (m/s)",
                     R::GreaterThan(0));
  options->AddDouble("Walk.stationary_s",
                     &walk->stationary_s,
                     "length of each rest of a generated walk (s; at most "
                     "duration / (2 num_stops))",
                     R::AtLeast(0));
  options->AddStructCheck([walk] { return walk->Check(); });
}

void AddDynamicsOptions(OptionManager* options, sim::DynamicsOptions* dynamics) {
  options->AddDouble(
      "Dynamics.people_per_100m",
      &dynamics->people_per_100m,
      "error source dynamics: people walking the scene's route, per 100 m of "
      "it (no published figure; HILTI 2022 names people moving among the "
      "difficulties of its construction sequences; 0 = none)",
      R::Between(0, 100));
  options->AddDouble(
      "Dynamics.speed",
      &dynamics->speed,
      "mean walking speed of the people, m/s, each +-15 % (comfortable gait "
      "speed of adults 1.27-1.46 m/s, Bohannon 1997)",
      R::GreaterThan(0).AndAtMost(3));
  options->AddStructCheck([dynamics] { return dynamics->Check(); });
}

void AddSimulatorOptions(OptionManager* options, sim::SimulatorOptions* sim) {
  options->AddString(
      "scene",
      &sim->scene,
      "office | staircase | hall | site, or a configs/sim_*.yaml scene file");
  options->AddString(
      "trajectory_path",
      &sim->trajectory_path,
      "TUM file of real motion (world_from_imu) to follow instead of walking");
  options->AddDouble("duration",
                     &sim->duration,
                     "sequence length in s, > 0.5 (with --trajectory_path: at "
                     "most the file's, "
                     "<= 0 all)",
                     R::AtMost(1e5));
  options->AddDouble("camera_rate",
                     &sim->camera_rate,
                     "rig frames per second (0: none)",
                     R::Between(0, 100));
  options->AddString(
      "lidars", &sim->lidars, "comma list: spinning, livox (or none)");
  options->AddDouble(
      "noise_scale",
      &sim->noise_scale,
      "multiplies all sensor noise and biases (0: exact measurements)",
      R::Between(0, 100));
  options->AddInt(
      "seed", &sim->seed, "seed of scene, texture, motion and noise");
  options->AddRequiredString(
      "output_path", &sim->output_path, "sequence folder to create");
  options->AddInt("supersampling",
                  &sim->supersampling,
                  "camera rays per pixel = n x n",
                  R::Between(1, 8));
  options->AddBool("color", &sim->color, "colour images instead of grayscale");
  options->AddBool("rgbd", &sim->rgbd, "add an RGB-D camera (rgbd0/, 640x480)");
  options->AddDouble("rgbd_rate",
                     &sim->rgbd_rate,
                     "RGB-D frames per second",
                     R::GreaterThan(0).AndAtMost(100));
  options->AddBool(
      "overwrite", &sim->overwrite, "replace an existing output folder");
  options->AddString("error_sources",
                     &sim->error_sources,
                     "error sources beyond white noise and bias random walk, each sized by "
                     "its section: calibration (true extrinsics and time offsets differ from "
                     "rig.yaml; truth/rig.yaml), imu (scale factor, misalignment, "
                     "temperature bias drift; truth/imu_errors.yaml), lidar (incidence "
                     "noise, mixed pixels, material intensity, dropouts, maximum range), "
                     "camera (auto exposure and gain, sensor noise, motion blur, "
                     "lighting), dynamics (people walking through the scene; "
                     "truth/people.csv); a comma list, all, or none (the clean "
                     "recording; --noise_scale 0 turns all off)");
  AddCalibrationErrorOptions(options, &sim->calibration_error);
  AddImuErrorOptions(options, &sim->imu_error);
  AddLidarErrorOptions(options, &sim->lidar_errors);
  AddCameraErrorOptions(options, &sim->camera_errors);
  AddMaterialOptions(options, &sim->materials);
  AddWalkingOptions(options, &sim->walk);
  AddDynamicsOptions(options, &sim->dynamics);
  options->AddStructCheck([sim] { return sim->Check(); });
}

void AddCalibrationErrorOptions(OptionManager* options, sim::CalibrationErrorOptions* calibration) {
  options->AddDouble("CalibrationError.lidar_translation_sigma_m",
                     &calibration->lidar_translation_sigma_m,
                     "m, 1-sigma per axis of each LiDAR's true position minus rig.yaml's, "
                     "IMU frame; RMS length sqrt(3) x this (HILTI 2022: calibration errors "
                     "of a few mm; 0: off)",
                     R::Between(0, 1));
  options->AddDouble("CalibrationError.lidar_rotation_sigma_deg",
                     &calibration->lidar_rotation_sigma_deg,
                     "deg, 1-sigma per axis of each LiDAR's true orientation error about its "
                     "own axes; RMS angle sqrt(3) x this, 0.2 deg (HILTI 2022 order; 0: off)",
                     R::Between(0, 30));
  options->AddDouble("CalibrationError.lidar_time_offset_sigma_s",
                     &calibration->lidar_time_offset_sigma_s,
                     "s, 1-sigma of each LiDAR's true minus rig.yaml time offset (order of "
                     "the HILTI 2022 Kalibr timeshift_cam_imu, 1.7-1.9 ms; 0: off)",
                     R::Between(0, 1));
  options->AddDouble("CalibrationError.camera_translation_sigma_m",
                     &calibration->camera_translation_sigma_m,
                     "m, 1-sigma per axis of each camera's true position minus rig.yaml's, "
                     "IMU frame (HILTI 2022: calibration errors of a few mm; 0: off)",
                     R::Between(0, 1));
  options->AddDouble("CalibrationError.camera_rotation_sigma_deg",
                     &calibration->camera_rotation_sigma_deg,
                     "deg, 1-sigma per axis of each camera's true orientation error about "
                     "its own axes (RMS angle 0.2 deg; 0: off)",
                     R::Between(0, 30));
  options->AddDouble("CalibrationError.camera_time_offset_sigma_s",
                     &calibration->camera_time_offset_sigma_s,
                     "s, 1-sigma of the true minus rig.yaml timeshift_cam_imu shared by all "
                     "cameras (one trigger; HILTI 2022 Kalibr timeshift_cam_imu 1.71-1.94 "
                     "ms; 0: off)",
                     R::Between(0, 1));
  options->AddDouble("CalibrationError.camera_time_offset_spread_s",
                     &calibration->camera_time_offset_spread_s,
                     "s, 1-sigma per camera around the shared offset (std of the five HILTI "
                     "2022 Kalibr timeshift_cam_imu values, 0.09 ms; 0: off)",
                     R::Between(0, 1));
  options->AddStructCheck([calibration] { return calibration->Check(); });
}

void AddImuErrorOptions(OptionManager* options, sim::ImuErrorOptions* imu) {
  options->AddDouble("ImuError.gyro_scale_sigma_percent",
                     &imu->gyro_scale_sigma_percent,
                     "%, 1-sigma per axis of the gyroscope scale-factor error (BMI085 "
                     "datasheet: sensitivity tolerance +-1 % typ, typ = 1 sigma; 0: off)",
                     R::Between(0, 10));
  options->AddDouble("ImuError.accel_scale_sigma_percent",
                     &imu->accel_scale_sigma_percent,
                     "%, 1-sigma per axis of the accelerometer scale-factor error (BMI085 "
                     "datasheet: sensitivity tolerance +-0.5 % typ; 0: off)",
                     R::Between(0, 10));
  options->AddDouble("ImuError.gyro_cross_axis_sigma_percent",
                     &imu->gyro_cross_axis_sigma_percent,
                     "%, 1-sigma of each off-diagonal entry of the gyroscope misalignment "
                     "(BMI085 datasheet: cross-axis sensitivity +-1 % typ; 0: off)",
                     R::Between(0, 10));
  options->AddDouble("ImuError.accel_cross_axis_sigma_percent",
                     &imu->accel_cross_axis_sigma_percent,
                     "%, 1-sigma of each off-diagonal entry of the accelerometer "
                     "misalignment (BMI085 datasheet: cross-axis sensitivity +-0.5 % typ; "
                     "0: off)",
                     R::Between(0, 10));
  options->AddDouble("ImuError.gyro_temperature_coefficient_dps_per_k",
                     &imu->gyro_temperature_coefficient_dps_per_k,
                     "deg/s/K, 1-sigma per axis of the gyroscope bias temperature "
                     "coefficient (BMI085 datasheet: zero-rate offset TCO +-0.015 deg/s/K "
                     "typ; 0: no drift)",
                     R::Between(0, 1));
  options->AddDouble("ImuError.accel_temperature_coefficient_mg_per_k",
                     &imu->accel_temperature_coefficient_mg_per_k,
                     "mg/K, 1-sigma per axis of the accelerometer bias temperature "
                     "coefficient (BMI085 datasheet: zero-g offset TCO +-0.2 mg/K typ; 0: "
                     "no drift)",
                     R::Between(0, 10));
  options->AddDouble("ImuError.temperature_sigma_k",
                     &imu->temperature_sigma_k,
                     "K, standard deviation of the IMU temperature around its mean, a "
                     "smooth random process (a handheld device warming and moving between "
                     "rooms; 0: no drift)",
                     R::Between(0, 50));
  options->AddDouble("ImuError.temperature_time_constant_s",
                     &imu->temperature_time_constant_s,
                     "s, time constant of the temperature process (autocorrelation "
                     "(1 + l/tau) exp(-l/tau))",
                     R::Between(1, 1e5));
  options->AddStructCheck([imu] { return imu->Check(); });
}

void AddLidarErrorOptions(OptionManager* options, sim::LidarErrorOptions* errors) {
  options->AddDouble("LidarErrors.incidence_noise_gain",
                     &errors->incidence_noise_gain,
                     "range noise sigma grows as 1 + g (1/cos(incidence) - 1), 1/cos capped "
                     "at 10 (1: proportional to the footprint stretch 1/cos, Soudarissanane "
                     "et al., ISPRS J. 2011; base sigma XT-32 datasheet +-1 cm; 0 = off)",
                     R::AtLeast(0));
  options->AddDouble("LidarErrors.beam_divergence_mrad",
                     &errors->beam_divergence_mrad,
                     "full beam divergence of the mixed-pixel model, mrad (the XT-32 datasheet "
                     "does not give it; Ouster OS0 datasheet: 0.18 deg = 3.1 mrad FWHM; "
                     "0 = no mixed pixels)",
                     R::AtLeast(0));
  options->AddDouble("LidarErrors.mixed_pixel_max_separation_m",
                     &errors->mixed_pixel_max_separation_m,
                     "echoes of one beam closer than this merge into a point between the "
                     "surfaces, m (about the pulse length c*tau/2 of a few-ns pulse)",
                     R::AtLeast(0));
  options->AddBool("LidarErrors.material_intensity",
                   &errors->material_intensity,
                   "intensity = 100 x apparent reflectivity of the material (Hesai "
                   "reflectivity scale; 0: from the texture albedo)");
  options->AddDouble("LidarErrors.range_at_10_percent_m",
                     &errors->range_at_10_percent_m,
                     "maximum range of a 10 % diffuse target at normal incidence, m; at "
                     "apparent reflectivity rho it is this x sqrt(rho / 0.1) (XT-32 datasheet: "
                     "80 m at 10 %; 0 = off)",
                     R::AtLeast(0));
  options->AddDouble("LidarErrors.dropout_reflectivity",
                     &errors->dropout_reflectivity,
                     "apparent reflectivity at which half of the pulses return nothing "
                     "(dark and glossy surfaces, grazing incidence; 0 = no dropouts)",
                     R::Between(0, 1));
}

void AddCameraErrorOptions(OptionManager* options, sim::CameraErrorOptions* errors) {
  options->AddBool("CameraErrors.auto_exposure",
                   &errors->auto_exposure,
                   "auto exposure and gain follow the scene brightness (0: fixed "
                   "reference_exposure_ms at gain 1)");
  options->AddDouble("CameraErrors.ae_target_median_dn",
                     &errors->ae_target_median_dn,
                     "auto-exposure target of the image median, DN (Alphasense "
                     "autoexp_target_median default 70)",
                     R::GreaterThan(0).AndLessThan(255));
  options->AddDouble("CameraErrors.ae_time_constant_s",
                     &errors->ae_time_constant_s,
                     "time constant of the exposure's lag behind the brightness, s",
                     R::AtLeast(0));
  options->AddDouble("CameraErrors.ae_rate_hz",
                     &errors->ae_rate_hz,
                     "auto-exposure updates per second (the camera's own frame rate)",
                     R::GreaterThan(0));
  options->AddDouble("CameraErrors.min_exposure_ms",
                     &errors->min_exposure_ms,
                     "shortest exposure, ms (Alphasense min_exp_time_us default 50)",
                     R::GreaterThan(0));
  options->AddDouble("CameraErrors.max_exposure_ms",
                     &errors->max_exposure_ms,
                     "longest exposure before the gain rises, ms, >= min_exposure_ms "
                     "(Alphasense max_exp_time_us default 10000)");
  options->AddDouble("CameraErrors.max_gain",
                     &errors->max_gain,
                     "highest analog gain (Alphasense: gain 255 = x5.6 sensitivity)",
                     R::AtLeast(1));
  options->AddDouble("CameraErrors.reference_exposure_ms",
                     &errors->reference_exposure_ms,
                     "exposure at gain 1 that renders radiance 0.5 (albedo x shading x "
                     "light) at 128 DN, ms: the scene's brightness",
                     R::GreaterThan(0));
  options->AddBool("CameraErrors.shot_noise",
                   &errors->shot_noise,
                   "Poisson noise of the collected electrons");
  options->AddDouble("CameraErrors.full_well_e",
                     &errors->full_well_e,
                     "electrons at 255 DN and gain 1 (Sony IMX287, the Alphasense Core "
                     "0.4 MP sensor: about 22 ke- saturation in EMVA 1288 sheets)",
                     R::GreaterThan(0));
  options->AddDouble("CameraErrors.read_noise_e",
                     &errors->read_noise_e,
                     "temporal dark noise, electrons (IMX287 EMVA 1288 sheets: about 7 e-; "
                     "0 = off)",
                     R::AtLeast(0));
  options->AddBool("CameraErrors.motion_blur",
                   &errors->motion_blur,
                   "blur along each pixel's image motion during the exposure");
  options->AddDouble("CameraErrors.light_level_ratio",
                     &errors->light_level_ratio,
                     "ratio of the brightest to the darkest area's light level (about "
                     "50-500 lux on an indoor site; HILTI 2022 FL2BIPS-GTSFM report: "
                     "lighting changes are frequent; 1 = uniform)",
                     R::AtLeast(1));
  options->AddDouble("CameraErrors.light_cell_m",
                     &errors->light_cell_m,
                     "spacing of the light-level lattice (about a room), m",
                     R::GreaterThan(0));
  options->AddDouble("CameraErrors.light_change_amplitude",
                     &errors->light_change_amplitude,
                     "relative slow change of each area's light over time (0 = off)",
                     R::AtLeast(0).AndLessThan(1));
  options->AddDouble("CameraErrors.light_change_period_s",
                     &errors->light_change_period_s,
                     "period of that change, s",
                     R::GreaterThan(0));
}

void AddMaterialOptions(OptionManager* options, sim::MaterialOptions* materials) {
  options->AddDouble("Materials.texture_poor_fraction",
                     &materials->texture_poor_fraction,
                     "fraction of wall and ceiling surfaces that are plain painted plaster or "
                     "bare concrete (HILTI 2022 FL2BIPS-GTSFM report: \"texture-less "
                     "appearance (such as wall, roof) [is] frequent in construction sites\")",
                     R::Between(0, 1));
}

void AddGlobalMapperOptions(OptionManager* options,
                            colmap::GlobalMapperOptions* mapper) {
  options->AddDouble("Mapper.initial_reprojection_error_factor",
                     &mapper->initial_reprojection_error_factor,
                     "the first triangulation (poses from averaging) keeps observations "
                     "within this times Triangulation.max_reprojection_error_px",
                     R::AtLeast(1));
  options->AddDouble("Mapper.min_focal_length_ratio",
                     &mapper->min_focal_length_ratio,
                     "a camera whose focal length / max(width, height) falls below this in "
                     "bundle adjustment is reset to its prior and held",
                     R::GreaterThan(0).AndAtMost(1));
  options->AddDouble("Mapper.max_focal_length_ratio",
                     &mapper->max_focal_length_ratio,
                     "a camera whose focal length / max(width, height) rises above this in "
                     "bundle adjustment is reset to its prior and held",
                     R::AtLeast(1));
  options->AddDouble("Mapper.max_extra_param",
                     &mapper->max_extra_param,
                     "a camera whose distortion parameter |k| rises above this in bundle "
                     "adjustment is reset to its prior and held",
                     R::GreaterThan(0));
  options->AddInt("Mapper.num_refinement_rounds",
                  &mapper->num_refinement_rounds,
                  "rounds of bundle adjustment -> filter -> retriangulate "
                  "before the final BA",
                  R::AtLeast(0));
  options->AddDouble(
      "Mapper.refinement_function_tolerance",
      &mapper->refinement_function_tolerance,
      "relative cost change that ends a refinement round's bundle adjustment",
      R::AtLeast(0));
  options->AddBool("Mapper.final_full_bundle_adjustment",
                   &mapper->final_full_bundle_adjustment,
                   "the final bundle adjustment uses every point");
  options->AddInt("Mapper.final_max_num_iterations",
                  &mapper->final_max_num_iterations,
                  "iteration cap of the final full bundle adjustment",
                  R::AtLeast(0));
  options->AddInt("Mapper.min_component_frames",
                  &mapper->min_component_frames,
                  "components with fewer frames are not reconstructed",
                  R::AtLeast(1));
  options->AddBool("Mapper.reconstruct_all_components",
                   &mapper->reconstruct_all_components,
                   "one model per component (false: only the largest)");
  options->AddInt("Mapper.min_frame_observations",
                  &mapper->min_frame_observations,
                  "frames seeing fewer triangulated points are dropped",
                  R::AtLeast(0));
  options->AddDouble(
      "Mapper.lidar_constraint_tolerance_ms",
      &mapper->lidar_constraint_tolerance_ms,
      "ms, constraint stamps attach to frames within this tolerance",
      R::AtLeast(0));
  options->AddBool("Mapper.read_colors",
                   &mapper->read_colors,
                   "read point colours from the images");
  options->AddBool("Mapper.skip_rotation_averaging",
                   &mapper->skip_rotation_averaging,
                   "no rotation averaging: frames take their prior rotations "
                   "(frames without "
                   "one are dropped)");
  options->AddBool(
      "Mapper.skip_translation_averaging",
      &mapper->skip_translation_averaging,
      "no translation averaging: frames take their prior positions (frames "
      "without one are dropped)");
  options->AddBool(
      "Mapper.skip_bundle_adjustment",
      &mapper->skip_bundle_adjustment,
      "no bundle adjustment (refinement rounds and final); tracks are still "
      "filtered");
  options->AddBool("Mapper.skip_retriangulation",
                   &mapper->skip_retriangulation,
                   "no retriangulation in the refinement rounds");
  AddLoadMapperStateOptions(options, &mapper->load);
  AddViewGraphOptions(options, &mapper->view_graph);
  AddRotationAveragingOptions(options, &mapper->rotation_averaging);
  AddTranslationAveragingOptions(options, &mapper->translation_averaging);
  AddTrackOptions(options, &mapper->tracks);
  AddTriangulationOptions(options, &mapper->triangulation);
  AddTrackCompletionOptions(options, &mapper->track_completion);
  options->AddBool("TrackCompletion.database_matches",
                   &mapper->track_completion_database_matches,
                   "completion and merging also follow the inlier matches of the database's "
                   "two-view geometries (besides the view graph's edges)");
  AddBundleAdjustmentOptions(options, &mapper->bundle_adjustment);
  options->AddStructCheck([mapper] { return mapper->Check(); });
}

void AddLoadMapperStateOptions(OptionManager* options,
                               colmap::LoadMapperStateOptions* load) {
  options->AddBool(
      "Priors.use_priors", &load->use_priors, "use the database's pose priors");
  options->AddAlias("Priors.use", "Priors.use_priors");
  options->AddDouble(
      "Priors.prior_position_sigma",
      &load->prior_position_sigma,
      "m, prior position std where the database has no covariance",
      R::GreaterThan(0));
  options->AddAlias("Priors.position_sigma", "Priors.prior_position_sigma");
  options->AddDouble("Priors.prior_rotation_sigma",
                     &load->prior_rotation_sigma,
                     "rad, prior rotation std",
                     R::GreaterThan(0));
  options->AddAlias("Priors.rotation_sigma", "Priors.prior_rotation_sigma");
  options->AddStructCheck([load] { return load->Check(); });
}

void AddViewGraphOptions(OptionManager* options,
                         colmap::ViewGraphOptions* view_graph) {
  options->AddInt("ViewGraph.min_num_inliers",
                  &view_graph->min_num_inliers,
                  "pairs with fewer inlier matches are ignored",
                  R::AtLeast(5));
  options->AddDouble("ViewGraph.min_inlier_ratio",
                     &view_graph->min_inlier_ratio,
                     "pairs with a lower inlier ratio are ignored",
                     R::Between(0, 1));
  options->AddDouble("ViewGraph.max_error_px",
                     &view_graph->max_error_px,
                     "px, RANSAC threshold of the relative pose re-estimation",
                     R::GreaterThan(0));
  options->AddBool(
      "ViewGraph.reestimate_relative_poses",
      &view_graph->reestimate_relative_poses,
      "re-estimate relative poses (5-point RANSAC) from the inlier matches");
  options->AddBool(
      "ViewGraph.use_database_essential",
      &view_graph->use_database_essential,
      "CALIBRATED pairs: start from the database's E instead of a new RANSAC");
  options->AddDouble("ViewGraph.ransac_confidence",
                     &view_graph->ransac_confidence,
                     "RANSAC success probability",
                     R::GreaterThan(0).AndLessThan(1));
  options->AddInt("ViewGraph.ransac_max_iterations",
                  &view_graph->ransac_max_iterations,
                  "RANSAC iteration cap",
                  R::AtLeast(1));
  options->AddInt("ViewGraph.ransac_max_num_matches",
                  &view_graph->ransac_max_num_matches,
                  "RANSAC on at most this many matches (an even subsample)",
                  R::AtLeast(5));
  options->AddBool("ViewGraph.refine_relative_poses",
                   &view_graph->refine_relative_poses,
                   "Sampson least-squares polish after RANSAC");
  options->AddInt("ViewGraph.refine_max_num_matches",
                  &view_graph->refine_max_num_matches,
                  "the polish uses at most this many matches",
                  R::AtLeast(5));
  options->AddStructCheck([view_graph] { return view_graph->Check(); });
}

void AddRotationAveragingOptions(
    OptionManager* options,
    colmap::RotationAveragingOptions* rotation_averaging) {
  colmap::RotationAveragingOptions* ra = rotation_averaging;
  options->AddDouble(
      "RotationAveraging.max_rotation_error_deg",
      &ra->max_rotation_error_deg,
      "deg, edges with a larger residual are removed and the average re-run",
      R::GreaterThan(0));
  options->AddDouble("RotationAveraging.geman_mcclure_sigma_deg",
                     &ra->geman_mcclure_sigma_deg,
                     "deg, robust loss scale",
                     R::GreaterThan(0));
  options->AddDouble(
      "RotationAveraging.max_loop_error_deg",
      &ra->max_loop_error_deg,
      "deg, a triangle of relative rotations closing within this is consistent",
      R::GreaterThan(0));
  options->AddInt("RotationAveraging.max_l1_iterations",
                  &ra->max_l1_iterations,
                  "L1 IRLS iterations before Geman-McClure (0 = none)",
                  R::AtLeast(0));
  options->AddDouble("RotationAveraging.l1_tolerance_rad",
                     &ra->l1_tolerance_rad,
                     "rad, the L1 stage stops when max |update| is below",
                     R::GreaterThan(0));
  options->AddInt("RotationAveraging.max_irls_iterations",
                  &ra->max_irls_iterations,
                  "Geman-McClure IRLS iterations",
                  R::AtLeast(0));
  options->AddDouble("RotationAveraging.convergence_tolerance_rad",
                     &ra->convergence_tolerance_rad,
                     "rad, stop when max |update| is below",
                     R::GreaterThan(0));
  options->AddDouble("RotationAveraging.relative_rotation_sigma_deg",
                     &ra->relative_rotation_sigma_deg,
                     "deg, per-axis std of an edge's relative rotation",
                     R::GreaterThan(0));
  options->AddBool("RotationAveraging.use_rotation_priors",
                   &ra->use_rotation_priors,
                   "unary prior terms and prior initialisation");
  options->AddDouble("RotationAveraging.fallback_prior_sigma_rad",
                     &ra->fallback_prior_sigma_rad,
                     "rad, prior std where the frame has none",
                     R::GreaterThan(0));
  options->AddBool("RotationAveraging.use_lidar_constraints",
                   &ra->use_lidar_constraints,
                   "LiDAR relative rotations as measurements");
  options->AddBool(
      "RotationAveraging.weight_by_num_inliers",
      &ra->weight_by_num_inliers,
      "scale edge information by the edge's inliers / mean inliers");
  options->AddStructCheck([ra] { return ra->Check(); });
}

void AddTranslationAveragingOptions(
    OptionManager* options,
    colmap::TranslationAveragingOptions* translation_averaging) {
  colmap::TranslationAveragingOptions* ta = translation_averaging;
  options->AddBool("TranslationAveraging.filter_1dsfm",
                   &ta->filter_1dsfm,
                   "1dSfM outlier filtering of the relative directions");
  options->AddInt("TranslationAveraging.num_projections",
                  &ta->num_projections,
                  "1dSfM random projections",
                  R::AtLeast(1));
  options->AddDouble("TranslationAveraging.min_projection_magnitude",
                     &ta->min_projection_magnitude,
                     "1dSfM: projections |d . axis| below this are left out",
                     R::AtLeast(0).AndLessThan(1));
  options->AddDouble(
      "TranslationAveraging.max_broken_ratio",
      &ta->max_broken_ratio,
      "1dSfM: edges inconsistent in more than this fraction of projections are "
      "removed",
      R::Between(0, 1));
  options->AddDouble(
      "TranslationAveraging.axis_perturbation_sigma",
      &ta->axis_perturbation_sigma,
      "1dSfM: std of the noise added to a sampled direction to form an axis",
      R::AtLeast(0));
  options->AddDouble("TranslationAveraging.direction_sigma",
                     &ta->direction_sigma,
                     "rad, expected angular noise of an edge direction",
                     R::GreaterThan(0));
  options->AddChoice("TranslationAveraging.direction_loss",
                     &ta->direction_loss,
                     {"cauchy", "huber", "none"},
                     "robust loss on the direction residuals");
  options->AddDouble("TranslationAveraging.direction_loss_threshold",
                     &ta->direction_loss_threshold,
                     "scale of the direction loss (~rad)",
                     R::GreaterThan(0));
  options->AddDouble("TranslationAveraging.min_edge_scale",
                     &ta->min_edge_scale,
                     "lower bound of the per-edge scales",
                     R::GreaterThan(0));
  options->AddBool("TranslationAveraging.use_priors",
                   &ta->use_priors,
                   "use the frames' position priors");
  options->AddBool("TranslationAveraging.use_lidar_constraints",
                   &ta->use_lidar_constraints,
                   "use the LiDAR relative translations");
  options->AddBool("TranslationAveraging.use_rig_baselines_for_scale",
                   &ta->use_rig_baselines_for_scale,
                   "metric rig baselines fix the scale (no scale gauge)");
  options->AddDouble("TranslationAveraging.min_rig_baseline",
                     &ta->min_rig_baseline,
                     "m, rig baselines shorter than this do not fix the scale",
                     R::AtLeast(0));
  options->AddBool("TranslationAveraging.init_from_current",
                   &ta->init_from_current,
                   "initialise from the frames' current positions");
  options->AddDouble("TranslationAveraging.random_init_extent",
                     &ta->random_init_extent,
                     "half side of the cube of random initial positions",
                     R::GreaterThan(0));
  options->AddDouble("TranslationAveraging.max_residual_angle_deg",
                     &ta->max_residual_angle_deg,
                     "deg, edges disagreeing more with the positions are "
                     "removed and the solve "
                     "re-run (<= 0: one solve)");
  options->AddInt("TranslationAveraging.max_num_iterations",
                  &ta->max_num_iterations,
                  "Ceres iterations",
                  R::AtLeast(1));
  options->AddInt("TranslationAveraging.ceres_num_threads",
                  &ta->ceres_num_threads,
                  "Ceres threads (1: the same result bit for bit from run to run)",
                  R::AtLeast(1));
  options->AddDouble("TranslationAveraging.function_tolerance",
                     &ta->function_tolerance,
                     "Ceres relative cost change to stop",
                     R::AtLeast(0));
  options->AddUint64("TranslationAveraging.random_seed",
                     &ta->random_seed,
                     "seeds the 1dSfM axes and the random initialisation");
  options->AddStructCheck([ta] { return ta->Check(); });
}

void AddTrackOptions(OptionManager* options, colmap::TrackOptions* tracks) {
  options->AddInt("Triangulation.min_track_length",
                  &tracks->min_track_length,
                  "images per track, at least",
                  R::AtLeast(2));
  options->AddInt("Triangulation.max_track_length",
                  &tracks->max_track_length,
                  "images per track, at most (0 = no cap; >= min_track_length)",
                  R::AtLeast(2).Or(0));
  options->AddStructCheck([tracks] { return tracks->Check(); });
}

void AddTriangulationOptions(OptionManager* options,
                             colmap::TriangulationOptions* triangulation) {
  options->AddDouble("Triangulation.max_reprojection_error_px",
                     &triangulation->max_reprojection_error_px,
                     "px, observations with a larger error are rejected",
                     R::GreaterThan(0));
  options->AddDouble(
      "Triangulation.min_triangulation_angle_deg",
      &triangulation->min_triangulation_angle_deg,
      "deg, points with a smaller maximum triangulation angle are dropped",
      R::AtLeast(0).AndLessThan(180));
  options->AddInt("Triangulation.num_refinement_iterations",
                  &triangulation->num_refinement_iterations,
                  "Levenberg-Marquardt iterations on the reprojection error",
                  R::AtLeast(0));
  options->AddInt("Triangulation.max_hypothesis_pairs",
                  &triangulation->max_hypothesis_pairs,
                  "pair hypotheses of the robust triangulation",
                  R::AtLeast(1));
  options->AddStructCheck([triangulation] { return triangulation->Check(); });
}

void AddTrackCompletionOptions(OptionManager* options, colmap::TrackCompletionOptions* completion) {
  options->AddBool("TrackCompletion.complete",
                   &completion->complete,
                   "after each refinement round, add to every point the observations its "
                   "matches link to that reproject within complete_max_reprojection_error_px");
  options->AddDouble("TrackCompletion.complete_max_reprojection_error_px",
                     &completion->complete_max_reprojection_error_px,
                     "px, largest reprojection error of an observation added by completion",
                     R::GreaterThan(0));
  options->AddInt("TrackCompletion.complete_max_transitivity",
                  &completion->complete_max_transitivity,
                  "match links followed from a point's observations by completion",
                  R::AtLeast(1));
  options->AddBool("TrackCompletion.merge",
                   &completion->merge,
                   "after each refinement round, merge two points linked by a match when the "
                   "re-triangulated point reprojects within merge_max_reprojection_error_px in "
                   "all their observations");
  options->AddDouble("TrackCompletion.merge_max_reprojection_error_px",
                     &completion->merge_max_reprojection_error_px,
                     "px, largest reprojection error of any observation of a merged point",
                     R::GreaterThan(0));
  options->AddStructCheck([completion] { return completion->Check(); });
}

void AddBundleAdjustmentOptions(
    OptionManager* options,
    colmap::BundleAdjustmentOptions* bundle_adjustment) {
  colmap::BundleAdjustmentOptions* ba = bundle_adjustment;
  options->AddBool("BundleAdjustment.refine_focal_length",
                   &ba->refine_focal_length,
                   "refine focal lengths");
  options->AddBool("BundleAdjustment.refine_principal_point",
                   &ba->refine_principal_point,
                   "refine principal points");
  options->AddBool("BundleAdjustment.refine_extra_params",
                   &ba->refine_extra_params,
                   "refine distortion parameters");
  options->AddBool("BundleAdjustment.refine_cam_from_rig",
                   &ba->refine_cam_from_rig,
                   "refine the camera-in-rig extrinsics (with a rig)");
  options->AddBool("BundleAdjustment.refine_frame_poses",
                   &ba->refine_frame_poses,
                   "refine the frame poses (0: structure only)");
  options->AddBool("BundleAdjustment.use_priors",
                   &ba->use_priors,
                   "frame position / rotation prior residuals");
  options->AddBool("BundleAdjustment.use_lidar_constraints",
                   &ba->use_lidar_constraints,
                   "LiDAR relative pose residuals");
  options->AddBool("BundleAdjustment.refine_prior_frame",
                   &ba->refine_prior_frame,
                   "refine one rigid transform rig_from_prior between the frame of the pose "
                   "priors / LiDAR constraints (lio's IMU frame) and the rig frame: absorbs the "
                   "LiDAR extrinsic calibration error (hand-eye; needs LiDAR constraints)");
  options->AddDouble("BundleAdjustment.prior_frame_max_rotation_sigma_deg",
                     &ba->prior_frame_max_rotation_sigma_deg,
                     "deg; refine_prior_frame refines the rotation only when the LiDAR "
                     "constraints predict its standard deviation (largest axis) below this",
                     R::AtLeast(0));
  options->AddDouble("BundleAdjustment.prior_frame_max_translation_sigma_m",
                     &ba->prior_frame_max_translation_sigma_m,
                     "m; refine_prior_frame refines the translation of rig_from_prior along "
                     "the directions whose predicted standard deviation is below this and holds "
                     "it along the others",
                     R::AtLeast(0));
  options->AddChoice("BundleAdjustment.loss_type",
                     &ba->loss_type,
                     {"trivial", "huber", "cauchy"},
                     "robust loss of the reprojection residuals");
  options->AddDouble("BundleAdjustment.loss_scale",
                     &ba->loss_scale,
                     "px, scale of the robust loss",
                     R::GreaterThan(0));
  options->AddInt(
      "BundleAdjustment.max_tracks_per_image",
      &ba->max_tracks_per_image,
      "adjust only each image's best N tracks (0 = all); the others are "
      "re-triangulated after each adjustment",
      R::AtLeast(0));
  options->AddDouble("BundleAdjustment.function_tolerance",
                     &ba->function_tolerance,
                     "relative cost change that stops the adjustment",
                     R::AtLeast(0));
  options->AddDouble("BundleAdjustment.gradient_tolerance",
                     &ba->gradient_tolerance,
                     "Ceres gradient tolerance",
                     R::AtLeast(0));
  options->AddDouble("BundleAdjustment.parameter_tolerance",
                     &ba->parameter_tolerance,
                     "relative step size that stops the adjustment",
                     R::AtLeast(0));
  options->AddInt("BundleAdjustment.max_num_iterations",
                  &ba->max_num_iterations,
                  "Levenberg-Marquardt iterations",
                  R::AtLeast(0));
  options->AddInt("BundleAdjustment.ceres_num_threads",
                  &ba->ceres_num_threads,
                  "Ceres threads (solver ceres; 1: the same result bit for bit from run to run)",
                  R::AtLeast(1));
  options->AddInt("BundleAdjustment.dense_schur_max_frames",
                  &ba->dense_schur_max_frames,
                  "up to this many frames: the dense-Schur solvers",
                  R::AtLeast(0));
  options->AddChoice(
      "BundleAdjustment.solver",
      &ba->solver,
      {"auto", "ceres", "schur"},
      "auto: lisfm's dense-Schur LM up to dense_schur_max_frames frames (no "
      "cam_from_rig refinement), Ceres otherwise");
  options->AddStructCheck([ba] { return ba->Check(); });
}

}  // namespace lisfm
