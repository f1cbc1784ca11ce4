// `lisfm model_evaluator`: scores the cameras of a COLMAP sparse model against
// reference cameras (colmap_ext/sfm_evaluation.h).
//
//   lisfm model_evaluator --model_path M --reference_path R
//       [--reference_format auto|colmap|strecha|bundler|sequence] [--alignment sim3|se3|none]
//       [--bundler_list_path list.txt] [--output_path metrics.json]
//
// M is a model folder, or a mapper output folder holding numbered models
// (0, 1, ...): then the model with the most images is scored. Prints a table
// on stdout; --output_path writes the metrics as JSON (atomically). With a
// simulated sequence folder as the reference (colmap_ext/sfm/sequence_reference.h)
// and a model with a rig, also the refined rig extrinsics against the truth.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "apps/summary_json.h"
#include "colmap_ext/io/model_io.h"
#include "colmap_ext/sfm/sequence_reference.h"
#include "colmap_ext/sfm/sfm_evaluation.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/logging.h"
#include "core/options.h"

namespace lisfm {
namespace {

std::string Cell(double v, int decimals) {
  return std::isfinite(v) ? fmt::format("{:>12.{}f}", v, decimals) : fmt::format("{:>12}", "-");
}

// `path` itself when it holds a model; else its numbered sub-model with the
// most images. Throws InputError when there is none.
std::string ResolveModelFolder(const std::string& path) {
  CheckDirExists(path, "model folder");
  if (colmap::HasModel(path, colmap::ModelFormat::kBinary) ||
      colmap::HasModel(path, colmap::ModelFormat::kText)) {
    return path;
  }
  std::string best;
  size_t best_images = 0;
  for (const auto& entry : std::filesystem::directory_iterator(path)) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_directory() || name.empty() ||
        name.find_first_not_of("0123456789") != std::string::npos) {
      continue;
    }
    const std::string sub = entry.path().string();
    if (!colmap::HasModel(sub, colmap::ModelFormat::kBinary) &&
        !colmap::HasModel(sub, colmap::ModelFormat::kText)) {
      continue;
    }
    const size_t num_images = colmap::ReadModel(sub).NumImages();
    if (best.empty() || num_images > best_images) {
      best = sub;
      best_images = num_images;
    }
  }
  if (best.empty()) {
    throw InputError(path, "", "expected a COLMAP model (cameras/images/points3D .bin or .txt) "
                               "or numbered model folders, found neither");
  }
  LogInfo("model_evaluator: {} holds several models; scoring {} ({} images)", path, best,
          best_images);
  return best;
}

}  // namespace

int RunModelEvaluator(int argc, char** argv) {
  std::string model_path, reference_path, output_path, bundler_list_path;
  std::string reference_format_name = "auto";
  colmap::SfmEvaluationOptions eval_options;
  OptionManager options("lisfm model_evaluator",
                        "score a COLMAP model's cameras against reference cameras: rotation and "
                        "position errors after alignment, relative-pose AUC");
  options.AddRequiredString("model_path", &model_path,
                            "estimated COLMAP model folder (or mapper output with 0, 1, ...)");
  options.AddRequiredString("reference_path", &reference_path,
                            "reference: COLMAP model folder, Strecha gt_dense_cameras folder, "
                            "Bundler .out file or simulated sequence folder (true camera poses)");
  options.AddChoice("reference_format", &reference_format_name,
                    {"auto", "colmap", "strecha", "bundler", "sequence"},
                    "format of --reference_path");
  AddSfmEvaluationOptions(&options, &eval_options);
  options.AddString("bundler_list_path", &bundler_list_path,
                    "Bundler image list (one name per camera); default list.txt or images/ "
                    "beside the .out file");
  options.AddString("output_path", &output_path, "metrics JSON file (optional)");
  if (!options.Parse(argc, argv)) return 0;
  if (!output_path.empty()) CheckOutputFileWritable(output_path, "--output_path");
  const auto start = std::chrono::steady_clock::now();

  colmap::ReferenceFormat reference_format = colmap::ReferenceFormat::kAuto;
  THROW_CHECK(colmap::ParseReferenceFormat(reference_format_name, &reference_format));
  if (reference_format == colmap::ReferenceFormat::kAuto) {
    reference_format = colmap::DetectReferenceFormat(reference_path);
  }

  const std::string model_folder = ResolveModelFolder(model_path);
  const colmap::Reconstruction model = colmap::ReadModel(model_folder);
  const std::vector<colmap::NamedPose> estimate = colmap::PosesFromReconstruction(model);
  std::vector<colmap::NamedPose> reference;
  std::optional<colmap::SequenceReference> sequence;
  if (reference_format == colmap::ReferenceFormat::kSequence) {
    sequence = colmap::ReadSequenceReference(reference_path);
    reference = sequence->poses;
  } else {
    reference = colmap::ReadReferencePoses(reference_path, reference_format, bundler_list_path);
  }
  colmap::SfmEvaluation ev;
  try {
    ev = colmap::EvaluatePoses(estimate, reference, eval_options);
  } catch (const InputError& e) {
    throw InputError(model_folder, "", std::string(e.what()) + " (reference " + reference_path + ")");
  }

  std::cout << fmt::format(
      "model     {} ({} images)\nreference {} ({}, {} images)\nregistered {} / {} reference "
      "images ({} estimated images not in the reference), alignment {}",
      model_folder, ev.num_estimated_images, reference_path,
      colmap::ReferenceFormatName(reference_format), ev.num_reference_images, ev.num_registered,
      ev.num_reference_images, ev.num_unmatched_estimated, ev.alignment);
  if (ev.alignment == "sim3") {
    std::cout << fmt::format(", scale {:.6g}", ev.reference_from_estimate.scale);
  }
  std::cout << "\n\n"
            << fmt::format("{:<34}{:>12}{:>12}{:>12}{:>8}\n", "", "mean", "median", "max", "count");
  const auto row = [](const std::string& name, const ErrorStats& s, int decimals) {
    return fmt::format("{:<34}{}{}{}{:>8}\n", name, Cell(s.mean, decimals),
                       Cell(s.median, decimals), Cell(s.max, decimals), s.count);
  };
  std::cout << row("rotation error [deg]", ev.rotation_error_deg, 4)
            << row(sequence ? "position error [m]" : "position error [reference units]",
                   ev.position_error, 5)
            << row("relative rotation error [deg]", ev.relative_rotation_error_deg, 4)
            << row("relative translation angle [deg]", ev.relative_translation_error_deg, 4);
  std::string auc_line = "relative pose AUC over " + std::to_string(ev.num_pairs) + " pairs:";
  for (size_t i = 0; i < ev.auc.size(); ++i) {
    auc_line += fmt::format("  @{:g} deg {:.4f}", ev.auc_thresholds_deg[i], ev.auc[i]);
  }
  std::cout << "\n" << auc_line << "\n";

  std::vector<colmap::RigCameraEvaluation> rig_evaluation;
  if (sequence) {
    rig_evaluation = colmap::EvaluateModelRig(model, sequence->believed_rig, sequence->truth_rig,
                                              ev.reference_from_estimate.scale, model_folder);
  }
  if (!rig_evaluation.empty()) {
    std::cout << fmt::format(
        "\nrig extrinsics cam_from_{} against {} (refined = the model's rig, calibration = "
        "rig.yaml)\n{:<10}{:>16}{:>16}{:>20}{:>20}\n",
        sequence->believed_rig.cameras[rig_evaluation.front().camera_index].name,
        sequence->has_truth_rig_file ? "truth/rig.yaml" : "rig.yaml (no truth/rig.yaml)",
        "camera", "refined [deg]", "refined [mm]", "calibration [deg]", "calibration [mm]");
    for (const colmap::RigCameraEvaluation& c : rig_evaluation) {
      const std::string name = sequence->believed_rig.cameras[c.camera_index].name;
      if (c.is_reference) {
        std::cout << fmt::format("{:<10}{:>72}\n", name, "(reference camera)");
        continue;
      }
      std::cout << fmt::format("{:<10}{:>16.4f}{:>16.3f}{:>20.4f}{:>20.3f}\n", name,
                               c.rotation_error_deg, c.translation_error_m * 1000,
                               c.believed_rotation_error_deg, c.believed_translation_error_m * 1000);
    }
  }

  if (!output_path.empty()) {
    WriteFileAtomically(output_path,
                        SfmEvaluationToJson(
                            ev,
                            {{"model_path", model_folder},
                             {"reference_path", reference_path},
                             {"reference_format", colmap::ReferenceFormatName(reference_format)}},
                            rig_evaluation));
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  LogInfo("model_evaluator: scored {} ({} images) against {} ({} reference images, {}): {} "
          "registered, {} alignment, rotation error mean {:.4f} deg, position error mean {:.4g}, "
          "AUC@{:g}deg {:.4f}; {} in {:.3f} s.",
          model_folder, ev.num_estimated_images, reference_path, ev.num_reference_images,
          colmap::ReferenceFormatName(reference_format), ev.num_registered, ev.alignment,
          ev.rotation_error_deg.mean, ev.position_error.mean, ev.auc_thresholds_deg.front(),
          ev.auc.front(), output_path.empty() ? "no JSON written" : "metrics in " + output_path,
          seconds);
  return 0;
}

}  // namespace lisfm
