// The command-line registration of each library options struct, written once
// and shared by every command that exposes the struct (COLMAP's
// OptionManager::AddXxxOptions). Each function registers the struct's fields
// by pointer as `Section.field_name` (the section fixed per struct, given
// below), with the field's range (shown by -h, validated by Parse) and an
// OptionManager::AddStructCheck of the struct's Check() for the constraints
// between fields. Former names stay accepted as aliases.
//
// The ranges here and the CHECK_OPTION_* limits of the structs' Check() are the
// same by contract: apps/option_sections_test.cc sets every registered field
// just outside its range and expects Check() to reject exactly that field.
#pragma once

#include "colmap_ext/sfm/global_mapper.h"
#include "colmap_ext/sfm/sfm_evaluation.h"
#include "core/evaluation.h"
#include "core/options.h"
#include "icp/bayesian_icp.h"
#include "icp/icp.h"
#include "icp/lidar_fusion.h"
#include "icp/normals.h"
#include "icp/projective_icp.h"
#include "icp/rgbd_fusion.h"
#include "icp/surfel_map.h"
#include "importers/database_importer.h"
#include "lio/imu.h"
#include "lio/lio_odometry.h"
#include "lio/pose_slam/g2o_pose_graph.h"
#include "lio/pose_slam/pose_graph.h"
#include "lio/pose_slam/pose_slam.h"
#include "lio/voxel_map.h"
#include "sim/simulator.h"

namespace lisfm {

// DatabaseImporter.*: co-visibility pair selection and pose priors of lisfm
// database_importer (importers/database_importer.h).
void AddDatabaseImporterOptions(OptionManager* options, DatabaseImporterOptions* importer);

// Icp.*: point-to-plane ICP.
void AddIcpOptions(OptionManager* options, IcpOptions* icp);
// Icp.num_neighbors, Icp.max_radius_m: the target's PCA normals.
void AddNormalOptions(OptionManager* options, NormalOptions* normals);
// Bayesian.*: the SGLD chain.
void AddSgldOptions(OptionManager* options, SgldOptions* sgld);
// Bayesian.*: the likelihood, the chain (AddSgldOptions) and the calibrated
// association of Bayesian ICP: of bayes->icp only kernel, kernel_scale_m,
// min_planarity, field_of_view_gate and visibility_gate_m are registered
// (the command takes the other bayes->icp fields from its Icp.* options).
void AddBayesianIcpOptions(OptionManager* options, BayesianIcpOptions* bayes);

// ProjectiveIcp.*: frame-to-model tracking of lisfm fusion (icp/projective_icp.h).
void AddProjectiveIcpOptions(OptionManager* options, ProjectiveIcpOptions* icp);
// Fusion.*: surfel merging, removal and output (icp/surfel_map.h).
void AddSurfelFusionOptions(OptionManager* options, SurfelFusionOptions* fusion);
// Fusion.*: RGB-D preprocessing and the tracking target (icp/rgbd_fusion.h).
void AddRgbdFusionOptions(OptionManager* options, RgbdFusionOptions* rgbd);
// LidarFusion.*: the range images of `lisfm fusion --mode lidar`.
void AddLidarFusionOptions(OptionManager* options, LidarFusionOptions* lidar);

// Lio.*, plus Map.* (AddVoxelMapOptions) and Init.* (AddImuInitializerOptions).
void AddLioOptions(OptionManager* options, LioOptions* lio);
void AddVoxelMapOptions(OptionManager* options, VoxelMapOptions* map);
void AddImuInitializerOptions(OptionManager* options,
                              ImuInitializerOptions* init);

// Solver.*: Levenberg-Marquardt of the pose graph (lisfm pose_graph, pose_slam).
void AddPoseGraphSolverOptions(OptionManager* options, PoseGraphSolverOptions* solver);
// PoseGraph.initialization and Solver.* (AddPoseGraphSolverOptions): lisfm pose_graph.
void AddPoseGraphOptions(OptionManager* options, G2oOptimizationOptions* pose_graph);
// PoseSlam.*, Stationary.*, ZeroVelocity.*, plus Bayesian.* / Sgld.*
// (AddBayesianIcpOptions) and Solver.* (AddPoseGraphSolverOptions): lisfm pose_slam.
void AddPoseSlamOptions(OptionManager* options, PoseSlamOptions* pose_slam);

// `alignment` (alias `align`); no section (lisfm evaluate). The association
// tolerance is the command's --max_dt (seconds; its default depends on the
// reference type).
void AddTrajectoryEvaluationOptions(OptionManager* options,
                                    TrajectoryEvaluationOptions* eval);
// `alignment`; no section (lisfm model_evaluator).
void AddSfmEvaluationOptions(OptionManager* options,
                             colmap::SfmEvaluationOptions* eval);

// No section (lisfm simulate); `output_path` is required. Also registers the
// error source sizes, materials and walk for sim's members: CalibrationError.*,
// ImuError.*, LidarErrors.*, CameraErrors.*, Materials.*, Walk.* and
// Dynamics.* (below).
void AddSimulatorOptions(OptionManager* options, sim::SimulatorOptions* sim);
// CalibrationError.*: the `calibration` error source of lisfm simulate.
void AddCalibrationErrorOptions(OptionManager* options, sim::CalibrationErrorOptions* calibration);
// ImuError.*: the `imu` error source of lisfm simulate.
void AddImuErrorOptions(OptionManager* options, sim::ImuErrorOptions* imu);
// LidarErrors.*: the `lidar` error source of lisfm simulate.
void AddLidarErrorOptions(OptionManager* options, sim::LidarErrorOptions* errors);
// CameraErrors.*: the `camera` error source of lisfm simulate.
void AddCameraErrorOptions(OptionManager* options, sim::CameraErrorOptions* errors);
// Materials.*: surface materials of the simulated scenes.
void AddMaterialOptions(OptionManager* options, sim::MaterialOptions* materials);
// Walk.* (AddWalkingOptions) and Dynamics.* (AddDynamicsOptions).
void AddSimulatorOptions(OptionManager* options, sim::SimulatorOptions* sim);
// Walk.*: the generated walk of lisfm simulate.
void AddWalkingOptions(OptionManager* options, sim::WalkingOptions* walk);
// Dynamics.*: the people of error source `dynamics`.
void AddDynamicsOptions(OptionManager* options, sim::DynamicsOptions* dynamics);

// Mapper.* and the stages: Priors.*, ViewGraph.*, RotationAveraging.*,
// TranslationAveraging.*, Triangulation.* (tracks and triangulation),
// BundleAdjustment.*. The stages' num_threads are not registered (the command
// sets them from its --num_threads).
void AddGlobalMapperOptions(OptionManager* options,
                            colmap::GlobalMapperOptions* mapper);
void AddLoadMapperStateOptions(OptionManager* options,
                               colmap::LoadMapperStateOptions* load);
void AddViewGraphOptions(OptionManager* options,
                         colmap::ViewGraphOptions* view_graph);
void AddRotationAveragingOptions(
    OptionManager* options,
    colmap::RotationAveragingOptions* rotation_averaging);
void AddTranslationAveragingOptions(
    OptionManager* options,
    colmap::TranslationAveragingOptions* translation_averaging);
void AddTrackOptions(OptionManager* options, colmap::TrackOptions* tracks);
void AddTriangulationOptions(OptionManager* options,
                             colmap::TriangulationOptions* triangulation);
void AddTrackCompletionOptions(OptionManager* options, colmap::TrackCompletionOptions* completion);
void AddBundleAdjustmentOptions(
    OptionManager* options, colmap::BundleAdjustmentOptions* bundle_adjustment);

}  // namespace lisfm
