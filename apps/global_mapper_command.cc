// `lisfm global_mapper`: global SfM on a COLMAP database (colmap_ext/global_mapper.h).
#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "apps/summary_json.h"
#include "colmap_ext/io/database.h"
#include "colmap_ext/io/model_io.h"
#include "colmap_ext/sfm/global_mapper.h"
#include "colmap_ext/sfm/lidar_constraints.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/rig_io.h"
#include "core/logging.h"
#include "core/mpi/mpi_world.h"
#include "core/options.h"
#include "core/rig.h"
#include "core/work_list.h"

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
  options.AddInt("num_threads", &num_threads, "threads (-1 = all cores)",
                 OptionRange::AtLeast(1).Or(-1));
  AddGlobalMapperOptions(&options, &mapper);
  if (!options.Parse(argc, argv)) return 0;
  mapper.view_graph.num_threads = num_threads;
  mapper.translation_averaging.num_threads = num_threads;
  mapper.triangulation.num_threads = num_threads;
  mapper.bundle_adjustment.num_threads = num_threads;
  options.ThrowUnlessValid(mapper.Check());

  if (!mpi::IsRoot()) SetLogLevel(LogLevel::kError);                 // rank 0 reports
  std::optional<OutputFolder> output_folder;                         // rank 0 writes
  if (mpi::IsRoot()) output_folder.emplace(output_path, overwrite);  // checked before the work

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
  // Under mpirun the view graph's pairs are split across the ranks; rank 0
  // gets every pair's result and continues alone.
  colmap::GlobalMapperResult result =
      colmap::RunGlobalMapper(database,
                              rig.get(),
                              constraints,
                              image_path,
                              mapper,
                              mpi::Active() ? WorkListRunner(mpi::RunWorkList) : WorkListRunner());
  if (result.share_only || !mpi::IsRoot()) return 0;  // this rank's pairs went to rank 0
  OutputFolder& output = *output_folder;
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
  nlohmann::json summary = GlobalMapperSummaryToJson(result.summary);
  summary["mapping_seconds_including_io"] = mapping_s;
  WriteFileAtomically(output.File("global_mapper_summary.json"), summary.dump(2) + "\n");
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
