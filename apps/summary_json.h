// JSON documents that commands write beside their outputs, built from the
// typed results the libraries return (the libraries know no JSON).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "colmap_ext/sfm/global_mapper.h"
#include "colmap_ext/sfm/sequence_reference.h"
#include "colmap_ext/sfm/sfm_evaluation.h"

namespace lisfm {

// global_mapper_summary.json: counts and timings (s) of every stage, per
// component (keys sorted, as nlohmann::json orders them). A skipped stage is
// an object {"skipped": true, ...} in place of its statistics.
nlohmann::json GlobalMapperSummaryToJson(
    const colmap::GlobalMapperSummary& summary);

// The metrics of lisfm model_evaluator as JSON text (NaN -> null), with
// `extra` key/value strings (paths, formats) at the top and, when `rig` is
// not empty, "rig": one object per rig camera (camera_id, camera_index,
// is_reference, rotation_error_deg, translation_error_mm of the refined
// extrinsics and believed_* of rig.yaml's, both against the truth).
std::string SfmEvaluationToJson(
    const colmap::SfmEvaluation& evaluation,
    const std::vector<std::pair<std::string, std::string>>& extra,
    const std::vector<colmap::RigCameraEvaluation>& rig = {});

}  // namespace lisfm
