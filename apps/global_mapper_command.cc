// `lisfm global_mapper`: global SfM on a COLMAP database (colmap_ext/global_mapper.h).
#include <chrono>
#include <memory>
#include <string>

#include "apps/commands.h"
#include "colmap_ext/io/database.h"
#include "colmap_ext/sfm/global_mapper.h"
#include "colmap_ext/sfm/lidar_constraints.h"
#include "core/io/lidar_constraints_io.h"
#include "colmap_ext/io/model_io.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/rig_io.h"
#include "core/logging.h"
#include "core/options.h"
#include "core/rig.h"

namespace lisfm {

int RunGlobalMapper(int argc, char** argv) {
  std::string database_path, image_path, output_path, rig_path, constraints_path;
  std::string output_type = "BIN";
  int num_threads = -1;
  bool overwrite = false;
  colmap::GlobalMapperOptions mapper;
  OptionManager options(
      "lisfm global_mapper",
      "global SfM on a COLMAP database after feature extraction and matching: view graph -> "
      "rotation averaging -> 1dSfM translation averaging -> tracks -> bundle adjustment with "
      "rig, pose priors and LiDAR constraints; writes COLMAP models OUT/0, OUT/1, ...");
  options.AddRequiredString("database_path", &database_path,
                            "COLMAP database with keypoints and two_view_geometries");
  options.AddString("image_path", &image_path,
                    "image folder (image names are relative to it); used for point colours");
  options.AddRequiredString("output_path", &output_path,
                            "output folder: one model per connected component in OUT/0, OUT/1, ...");
  options.AddBool("overwrite", &overwrite, "replace an earlier lisfm output at --output_path");
  options.AddString("rig_path", &rig_path,
                    "rig YAML (or a HILTI calibration folder); images camK/data/<ns>.png with "
                    "the same <ns> form one rig frame");
  options.AddString("lidar_constraints_path", &constraints_path,
                    "LiDAR relative-pose constraints (DESIGN.md format or GTSFM HILTI format)");
  options.AddChoice("output_type", &output_type, {"BIN", "TXT"}, "model file format");
  options.AddInt("num_threads", &num_threads, "threads (-1 = all cores)");
  // Mapper.
  options.AddInt("Mapper.num_refinement_rounds", &mapper.num_refinement_rounds,
                 "rounds of bundle adjustment -> filter -> retriangulate before the final BA");
  options.AddDouble("Mapper.refinement_function_tolerance", &mapper.refinement_function_tolerance,
                    "relative cost change that ends a refinement round's bundle adjustment");
  options.AddBool("Mapper.final_full_bundle_adjustment", &mapper.final_full_bundle_adjustment,
                  "the final bundle adjustment uses every point");
  options.AddInt("Mapper.final_max_num_iterations", &mapper.final_max_num_iterations,
                 "iteration cap of the final full bundle adjustment");
  options.AddInt("Mapper.min_component_frames", &mapper.min_component_frames,
                 "components with fewer frames are not reconstructed");
  options.AddBool("Mapper.reconstruct_all_components", &mapper.reconstruct_all_components,
                  "one model per component (false: only the largest)");
  options.AddInt("Mapper.min_frame_observations", &mapper.min_frame_observations,
                 "frames seeing fewer triangulated points are dropped");
  options.AddDouble("Mapper.lidar_constraint_tolerance_ms", &mapper.lidar_constraint_tolerance_ms,
                    "ms, constraint stamps attach to frames within this tolerance");
  options.AddBool("Mapper.read_colors", &mapper.read_colors, "read point colours from the images");
  // Priors.
  options.AddBool("Priors.use", &mapper.load.use_priors, "use the database's pose priors");
  options.AddDouble("Priors.position_sigma", &mapper.load.prior_position_sigma,
                    "m, prior position std where the database has no covariance");
  options.AddDouble("Priors.rotation_sigma", &mapper.load.prior_rotation_sigma,
                    "rad, prior rotation std");
  // View graph.
  options.AddInt("ViewGraph.min_num_inliers", &mapper.view_graph.min_num_inliers,
                 "pairs with fewer inlier matches are ignored");
  options.AddDouble("ViewGraph.min_inlier_ratio", &mapper.view_graph.min_inlier_ratio,
                    "pairs with a lower inlier ratio are ignored");
  options.AddDouble("ViewGraph.max_error_px", &mapper.view_graph.max_error_px,
                    "px, RANSAC threshold of the relative pose re-estimation");
  options.AddBool("ViewGraph.reestimate_relative_poses",
                  &mapper.view_graph.reestimate_relative_poses,
                  "re-estimate relative poses (5-point RANSAC) from the inlier matches");
  options.AddBool("ViewGraph.use_database_essential",
                  &mapper.view_graph.use_database_essential,
                  "CALIBRATED pairs: start from the database's E instead of a new RANSAC");
  // Rotation / translation averaging.
  options.AddDouble("RotationAveraging.max_rotation_error_deg",
                    &mapper.rotation_averaging.max_rotation_error_deg,
                    "deg, edges with a larger residual are removed and the average re-run");
  options.AddBool("TranslationAveraging.filter_1dsfm", &mapper.translation_averaging.filter_1dsfm,
                  "1dSfM outlier filtering of the relative directions");
  options.AddInt("TranslationAveraging.num_projections",
                 &mapper.translation_averaging.num_projections, "1dSfM random projections");
  options.AddDouble("TranslationAveraging.max_broken_ratio",
                    &mapper.translation_averaging.max_broken_ratio,
                    "1dSfM: edges inconsistent in more than this fraction of projections are removed");
  // Tracks and triangulation.
  options.AddInt("Triangulation.min_track_length", &mapper.tracks.min_track_length,
                 "images per track, at least");
  options.AddDouble("Triangulation.max_reprojection_error_px",
                    &mapper.triangulation.max_reprojection_error_px,
                    "px, observations with a larger error are rejected");
  options.AddDouble("Triangulation.min_triangulation_angle_deg",
                    &mapper.triangulation.min_triangulation_angle_deg,
                    "deg, points with a smaller maximum triangulation angle are dropped");
  // Bundle adjustment.
  options.AddBool("BundleAdjustment.refine_focal_length",
                  &mapper.bundle_adjustment.refine_focal_length, "refine focal lengths");
  options.AddBool("BundleAdjustment.refine_principal_point",
                  &mapper.bundle_adjustment.refine_principal_point, "refine principal points");
  options.AddBool("BundleAdjustment.refine_extra_params",
                  &mapper.bundle_adjustment.refine_extra_params, "refine distortion parameters");
  options.AddBool("BundleAdjustment.refine_cam_from_rig",
                  &mapper.bundle_adjustment.refine_cam_from_rig,
                  "refine the camera-in-rig extrinsics (with a rig)");
  options.AddChoice("BundleAdjustment.loss_type", &mapper.bundle_adjustment.loss_type,
                    {"trivial", "huber", "cauchy"}, "robust loss of the reprojection residuals");
  options.AddDouble("BundleAdjustment.loss_scale", &mapper.bundle_adjustment.loss_scale,
                    "px, scale of the robust loss");
  options.AddInt("BundleAdjustment.max_tracks_per_image",
                 &mapper.bundle_adjustment.max_tracks_per_image,
                 "adjust only each image's best N tracks (0 = all); the others are "
                 "re-triangulated after each adjustment");
  options.AddDouble("BundleAdjustment.function_tolerance",
                    &mapper.bundle_adjustment.function_tolerance,
                    "relative cost change that stops the adjustment");
  options.AddInt("BundleAdjustment.max_num_iterations",
                 &mapper.bundle_adjustment.max_num_iterations, "Levenberg-Marquardt iterations");
  options.AddChoice("BundleAdjustment.solver", &mapper.bundle_adjustment.solver,
                    {"auto", "ceres", "schur"},
                    "auto: lisfm's dense-Schur LM up to 50 frames (no cam_from_rig "
                    "refinement), Ceres otherwise");
  if (!options.Parse(argc, argv)) return 0;
  mapper.view_graph.num_threads = num_threads;
  mapper.translation_averaging.num_threads = num_threads;
  mapper.triangulation.num_threads = num_threads;
  mapper.bundle_adjustment.num_threads = num_threads;
  if (!mapper.view_graph.Check() || !mapper.rotation_averaging.Check() ||
      !mapper.translation_averaging.Check() || !mapper.tracks.Check() ||
      !mapper.triangulation.Check() || !mapper.bundle_adjustment.Check() ||
      mapper.num_refinement_rounds < 0 || !(mapper.refinement_function_tolerance >= 0.0) ||
      mapper.final_max_num_iterations < 0) {
    throw UsageError("lisfm global_mapper: invalid option values (see -h)");
  }

  OutputFolder output(output_path, overwrite);  // checked before the work

  const auto start = std::chrono::steady_clock::now();
  CheckFileExists(database_path, "database");
  if (!image_path.empty()) CheckDirExists(image_path, "image folder");
  std::unique_ptr<Rig> rig;
  if (!rig_path.empty()) {
    rig = std::make_unique<Rig>(DirExists(rig_path) ? LoadHiltiCalibration(rig_path)
                                                    : ReadRigYaml(rig_path));
    if (rig->cameras.empty()) throw InputError(rig_path, "cameras", "the rig has no camera");
  }
  std::vector<LidarConstraintRecord> constraints;
  if (!constraints_path.empty()) constraints = ReadLidarConstraints(constraints_path);

  LogStage("global_mapper: " + database_path);
  const colmap::Database database(database_path, colmap::Database::OpenMode::kReadOnly);
  colmap::GlobalMapperResult result =
      colmap::RunGlobalMapper(database, rig.get(), constraints, image_path, mapper);
  const double mapping_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // Outputs: one model per component, in the output's temporary folder.
  const colmap::ModelFormat format =
      output_type == "TXT" ? colmap::ModelFormat::kText : colmap::ModelFormat::kBinary;
  for (size_t k = 0; k < result.models.size(); ++k) {
    const std::string dir = output.File(std::to_string(k));
    CreateDirs(dir);
    colmap::WriteModel(result.models[k], dir, format);
  }
  result.summary["mapping_seconds_including_io"] = mapping_s;
  WriteFileAtomically(output.File("global_mapper_summary.json"), result.summary.dump(2) + "\n");
  options.WriteConfig(output.File("global_mapper_config.yaml"));
  output.Commit();

  size_t images = 0, points = 0, observations = 0;
  double error = 0.0;
  for (const auto& m : result.models) {
    images += m.NumImages();
    points += m.NumPoints3D();
    observations += m.ComputeNumObservations();
  }
  if (!result.models.empty()) error = result.models.front().ComputeMeanReprojectionError();
  LogInfo("global_mapper: {} model(s) in {}: {} of {} images registered, {} points, {} "
          "observations, mean reprojection error {:.3f} px (largest model); {:.2f} s; summary "
          "in {}/global_mapper_summary.json",
          result.models.size(), output_path, images, database.NumImages(), points, observations,
          error, mapping_s, output_path);
  if (result.models.empty()) {
    LogWarning("global_mapper: no model could be reconstructed (see the summary)");
    return 1;
  }
  return 0;
}

}  // namespace lisfm
