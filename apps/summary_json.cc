#include "apps/summary_json.h"

#include <cmath>
#include <sstream>

namespace lisfm {
namespace {

using colmap::MapperComponentSummary;
using colmap::MapperModelCounts;
using colmap::MapperRoundSummary;

nlohmann::json ModelCountsToJson(const MapperModelCounts& m) {
  return {{"registered_frames", m.registered_frames},
          {"registered_images", m.registered_images},
          {"points", m.points},
          {"observations", m.observations},
          {"mean_reprojection_error_px", m.mean_reprojection_error_px}};
}

nlohmann::json RoundToJson(const MapperRoundSummary& r) {
  nlohmann::json j;
  if (r.bundle_adjustment_skipped) {
    j["bundle_adjustment"] = {{"skipped", true}};
  } else {
    const colmap::BundleAdjustmentStats& ba = r.bundle_adjustment;
    j["bundle_adjustment"] = {
        {"residuals", ba.num_reprojection_residuals},
        {"prior_residuals",
         ba.num_position_prior_residuals + ba.num_rotation_prior_residuals},
        {"lidar_residuals", ba.num_lidar_residuals},
        {"gauge", ba.gauge},
        {"iterations", ba.num_iterations},
        {"initial_error_px", ba.initial_mean_reprojection_error_px},
        {"final_error_px", ba.final_mean_reprojection_error_px},
        {"termination", ba.termination},
        {"usable", ba.usable},
        {"solver", ba.linear_solver},
        {"initial_cost", ba.initial_cost},
        {"final_cost", ba.final_cost},
        {"setup_seconds", ba.setup_seconds},
        {"ceres_seconds", ba.ceres_seconds},
        {"linear_solver_seconds", ba.linear_solver_seconds},
        {"evaluation_seconds", ba.evaluation_seconds},
        {"seconds", r.bundle_adjustment_seconds}};
    if (ba.prior_frame_used) {
      j["bundle_adjustment"]["prior_frame"] = {
          {"rotation_refined", ba.prior_frame_rotation_refined},
          {"translation_refined", ba.prior_frame_translation_refined},
          {"translation_directions_refined", ba.prior_frame_translation_directions_refined},
          {"predicted_rotation_sigma_deg", ba.prior_frame_rotation_sigma_deg},
          {"predicted_translation_sigma_m", ba.prior_frame_translation_sigma_m},
          {"predicted_translation_sigmas_m",
           {ba.prior_frame_translation_sigmas_m.x(),
            ba.prior_frame_translation_sigmas_m.y(),
            ba.prior_frame_translation_sigmas_m.z()}},
          {"note", ba.prior_frame_note}};
    }
  }
  j["filtered_observations"] = r.filtered_observations;
  j["reset_bogus_cameras"] = r.reset_bogus_cameras;
  if (r.retriangulation_skipped) {
    j["retriangulation_skipped"] = true;
  } else if (!r.final_round) {
    j["retriangulated_observations"] = r.retriangulated_observations;
  }
  if (r.track_completion_run) {
    const colmap::TrackCompletionStats& tc = r.track_completion;
    j["track_completion"] = {{"correspondences", tc.num_correspondences},
                             {"tracks_completed", tc.num_tracks_completed},
                             {"observations_completed", tc.num_observations_completed},
                             {"observations_taken", tc.num_observations_taken},
                             {"merge_candidates", tc.num_merge_candidates},
                             {"merges", tc.num_merges},
                             {"observations_merged", tc.num_observations_merged},
                             {"seconds", tc.seconds}};
  }
  j["filter_retriangulate_seconds"] = r.filter_retriangulate_seconds;
  j["model"] = ModelCountsToJson(r.model);
  return j;
}

nlohmann::json ComponentToJson(const MapperComponentSummary& c) {
  nlohmann::json j;
  j["frames"] = c.frames;
  const colmap::RotationAveragingStats& ra = c.rotation_averaging;
  if (c.rotation_averaging_skipped) {
    j["rotation_averaging"] = {{"skipped", true},
                               {"registered_frames", ra.num_registered_frames},
                               {"prior_frames", ra.num_prior_frames},
                               {"initialization", ra.initialization},
                               {"seconds", c.rotation_averaging_seconds}};
  } else {
    j["rotation_averaging"] = {{"registered_frames", ra.num_registered_frames},
                               {"edges", ra.num_edge_measurements},
                               {"lidar_constraints", ra.num_lidar_measurements},
                               {"prior_frames", ra.num_prior_frames},
                               {"rejected_edges", ra.num_rejected_edges},
                               {"iterations", ra.num_iterations},
                               {"initialization", ra.initialization},
                               {"mean_residual_deg", ra.mean_residual_deg},
                               {"seconds", c.rotation_averaging_seconds}};
  }
  const colmap::TranslationAveragingStats& ta = c.translation_averaging;
  if (c.translation_averaging_skipped) {
    j["translation_averaging"] = {
        {"skipped", true},
        {"registered_frames", c.translation_averaging_registered_frames},
        {"seconds", c.translation_averaging_seconds}};
  } else {
    j["translation_averaging"] = {
        {"registered_frames", c.translation_averaging_registered_frames},
        {"edges", ta.num_edges_input},
        {"rejected_1dsfm", ta.num_rejected_1dsfm},
        {"rejected_residual", ta.num_rejected_residual},
        {"prior_residuals", ta.num_prior_residuals},
        {"lidar_residuals", ta.num_lidar_residuals},
        {"metric", ta.metric},
        {"gauge", ta.gauge},
        {"seconds_1dsfm", ta.seconds_1dsfm},
        {"seconds", c.translation_averaging_seconds}};
  }
  if (c.lost_frames_in_averaging) return j;
  j["tracks"] = {
      {"tracks", c.tracks.num_tracks},
      {"inconsistent", c.tracks.num_tracks_inconsistent},
      {"mean_track_length", c.tracks.mean_track_length},
      {"triangulated", c.triangulation.num_tracks_triangulated},
      {"failed_angle", c.triangulation.num_tracks_failed_angle},
      {"failed_reprojection", c.triangulation.num_tracks_failed_reprojection},
      {"failed_depth", c.triangulation.num_tracks_failed_depth},
      {"observations", c.triangulation.num_observations},
      {"mean_reprojection_error_px",
       c.triangulation.mean_reprojection_error_px},
      {"seconds", c.tracks_seconds}};
  nlohmann::json rounds = nlohmann::json::array();
  for (const MapperRoundSummary& r : c.refinement)
    rounds.push_back(RoundToJson(r));
  j["refinement"] = rounds;
  // X = rig_from_prior after the last adjustment (refine_prior_frame).
  if (!c.refinement.empty() && c.refinement.back().bundle_adjustment.prior_frame_used) {
    const colmap::BundleAdjustmentStats& ba = c.refinement.back().bundle_adjustment;
    const Vec3 omega_deg = so3::Log(ba.rig_from_prior.rotation()) * 180.0 / M_PI;
    const Vec3 t_mm = ba.rig_from_prior.translation() * 1e3;
    j["rig_from_prior"] = {
        {"rotation_vector_deg", {omega_deg.x(), omega_deg.y(), omega_deg.z()}},
        {"rotation_deg", omega_deg.norm()},
        {"translation_mm", {t_mm.x(), t_mm.y(), t_mm.z()}},
        {"rotation_refined", ba.prior_frame_rotation_refined},
        {"translation_refined", ba.prior_frame_translation_refined},
        {"translation_directions_refined", ba.prior_frame_translation_directions_refined}};
  }
  j["dropped_weak_frames"] = c.dropped_weak_frames;
  j["model"] = ModelCountsToJson(c.model);
  j["to_model_seconds"] = c.to_model_seconds;
  return j;
}

using ordered_json = nlohmann::ordered_json;

// NaN (undefined statistic) becomes JSON null.
ordered_json Number(double v) {
  return std::isfinite(v) ? ordered_json(v) : ordered_json(nullptr);
}

ordered_json StatsToJson(const ErrorStats& s) {
  return ordered_json{{"mean", Number(s.mean)},
                      {"median", Number(s.median)},
                      {"max", Number(s.max)},
                      {"rmse", Number(s.rmse)},
                      {"count", s.count}};
}

}  // namespace

nlohmann::json GlobalMapperSummaryToJson(const colmap::GlobalMapperSummary& s) {
  nlohmann::json j;
  j["load"] = {{"cameras", s.num_cameras},
               {"images", s.num_images},
               {"frames", s.num_frames},
               {"keypoints", s.num_keypoints},
               {"rig", s.has_rig},
               {"seconds", s.load_seconds}};
  if (s.has_lidar_constraints) {
    j["lidar_constraints"] = {{"read", s.num_lidar_constraints_read},
                              {"attached", s.num_lidar_constraints_attached}};
  }
  const colmap::ViewGraphStats& vg = s.view_graph;
  j["view_graph"] = {{"pairs_in_database", vg.num_pairs_in_database},
                     {"edges", vg.num_edges},
                     {"intra_frame_edges", vg.num_intra_frame_edges},
                     {"skipped_config", vg.num_skipped_config},
                     {"rejected_few_inliers", vg.num_rejected_few_inliers},
                     {"rejected_reestimation", vg.num_rejected_reestimation},
                     {"inlier_matches", vg.num_inlier_matches},
                     {"seconds", s.view_graph_seconds}};
  j["components"] = nlohmann::json::array();
  for (const MapperComponentSummary& c : s.components)
    j["components"].push_back(ComponentToJson(c));
  j["num_components"] = s.num_components;
  j["num_frames_in_small_components"] = s.num_frames_in_small_components;
  j["num_models"] = s.num_models;
  j["total_seconds"] = s.total_seconds;
  return j;
}

std::string SfmEvaluationToJson(
    const colmap::SfmEvaluation& ev,
    const std::vector<std::pair<std::string, std::string>>& extra,
    const std::vector<colmap::RigCameraEvaluation>& rig) {
  ordered_json j;
  for (const auto& [key, value] : extra) j[key] = value;
  j["num_reference_images"] = ev.num_reference_images;
  j["num_estimated_images"] = ev.num_estimated_images;
  j["num_registered"] = ev.num_registered;
  j["num_unmatched_estimated"] = ev.num_unmatched_estimated;
  j["alignment"] = ev.alignment;
  const Quat& q = ev.reference_from_estimate.pose.rotation();
  const Vec3& t = ev.reference_from_estimate.pose.translation();
  j["reference_from_estimate"] = {
      {"scale", ev.reference_from_estimate.scale},
      {"rotation_xyzw", {q.x(), q.y(), q.z(), q.w()}},
      {"translation", {t.x(), t.y(), t.z()}}};
  j["rotation_error_deg"] = StatsToJson(ev.rotation_error_deg);
  j["position_error"] = StatsToJson(ev.position_error);
  j["num_pairs"] = ev.num_pairs;
  j["relative_rotation_error_deg"] =
      StatsToJson(ev.relative_rotation_error_deg);
  j["relative_translation_error_deg"] =
      StatsToJson(ev.relative_translation_error_deg);
  ordered_json auc = ordered_json::object();
  for (size_t i = 0; i < ev.auc.size(); ++i) {
    std::ostringstream key;
    key << ev.auc_thresholds_deg[i];
    auc[key.str()] = ev.auc[i];
  }
  j["auc"] = auc;
  ordered_json images = ordered_json::array();
  for (const colmap::ImageEvaluation& image : ev.images) {
    images.push_back({{"name", image.name},
                      {"registered", image.registered},
                      {"rotation_error_deg", Number(image.rotation_error_deg)},
                      {"position_error", Number(image.position_error)}});
  }
  j["images"] = images;
  if (!rig.empty()) {
    ordered_json cameras = ordered_json::array();
    for (const colmap::RigCameraEvaluation& c : rig) {
      cameras.push_back({{"camera_id", c.camera_id},
                         {"camera_index", c.camera_index},
                         {"is_reference", c.is_reference},
                         {"rotation_error_deg", Number(c.rotation_error_deg)},
                         {"translation_error_mm", Number(c.translation_error_m * 1000)},
                         {"believed_rotation_error_deg", Number(c.believed_rotation_error_deg)},
                         {"believed_translation_error_mm",
                          Number(c.believed_translation_error_m * 1000)}});
    }
    j["rig"] = cameras;
  }
  return j.dump(2) + "\n";
}

}  // namespace lisfm
