// `lisfm database_importer`: a COLMAP database with pose priors, the rig and a
// LiDAR-proxy co-visibility pair list (importers/database_importer.h) from a
// sequence folder, the pose_slam output and lio's keyframe scans; or from the
// HILTI 2022 extract that GTSFM ships (--input_type hilti_gtsfm).
// Under `mpirun -np N` the co-visibility work is split across the ranks
// (core/mpi); rank 0 writes every output, byte for byte as one process does.
#include <optional>
#include <string>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/logging.h"
#include "core/mpi/mpi_world.h"
#include "core/options.h"
#include "importers/database_importer.h"

namespace lisfm {

int RunDatabaseImporter(int argc, char** argv) {
  DatabaseImporterInput input;
  std::string output_path;
  bool overwrite = false;
  DatabaseImporterOptions importer;
  OptionManager options(
      "lisfm database_importer",
      "COLMAP database (cameras from the rig, one image per camera frame, pose priors from the "
      "pose_slam trajectory), image_list.txt, a LiDAR-proxy co-visibility pairs.txt, the rig "
      "and the LiDAR constraints between rig frames");
  options.AddRequiredString("input_path",
                            &input.input_path,
                            "sequence folder (rig.yaml, camK/data.csv + camK/data/<ns>.png); with "
                            "--input_type hilti_gtsfm the GTSFM HILTI folder (calibration/, "
                            "images/k.jpg, lidar/)");
  options.AddString("image_path",
                    &input.image_path,
                    "image root the names camK/data/<ns>.png are relative to (default: "
                    "--input_path)");
  options.AddString("pose_slam_path",
                    &input.pose_slam_path,
                    "pose_slam output folder: trajectory.txt, keyframes.txt, "
                    "keyframe_covariances.txt, constraints.txt (sequence input)");
  options.AddString("lio_path",
                    &input.lio_path,
                    "lio output folder whose keyframes/<t_ns>.pcd are the scans of the "
                    "constraints (sequence input)");
  options.AddRequiredString("output_path",
                            &output_path,
                            "output folder: database.db, image_list.txt, pairs.txt, rig.yaml, "
                            "rig_config.json, constraints.txt, covisibility.csv, "
                            "importer_summary.json");
  options.AddChoice("input_type",
                    &input.input_type,
                    {"sequence", "hilti_gtsfm"},
                    "sequence folder + pose_slam + lio, or the GTSFM HILTI 2022 extract "
                    "(priors from its FAST-LIO2 poses, no co-visibility)");
  options.AddBool("overwrite", &overwrite, "replace an earlier lisfm output at --output_path");
  AddDatabaseImporterOptions(&options, &importer);
  if (!options.Parse(argc, argv)) return 0;
  options.ThrowUnlessValid(importer.Check());
  if (input.input_type == "sequence") {
    if (input.pose_slam_path.empty()) throw UsageError("--pose_slam_path is required");
    if (input.lio_path.empty()) throw UsageError("--lio_path is required");
    // Read only when there are constraints; checked always, so that a wrong
    // folder is reported whatever the constraints hold.
    CheckDirExists(input.lio_path, "--lio_path folder");
    CheckDirExists(JoinPaths(input.lio_path, "keyframes"), "lio keyframes folder");
  }
  if (!mpi::IsRoot()) SetLogLevel(LogLevel::kError);          // rank 0 reports
  std::optional<OutputFolder> output;                         // rank 0 writes
  if (mpi::IsRoot()) output.emplace(output_path, overwrite);  // checked before the work

  LogStage("database_importer: " + input.input_path);
  const DatabaseImporterSummary s = RunDatabaseImporter(
      input,
      importer,
      output ? output->path() : std::string(),
      mpi::Active() ? WorkListRunner(mpi::RunWorkList) : WorkListRunner(),
      mpi::Active() ? SharedWorkListRunner(mpi::RunSharedWorkList) : SharedWorkListRunner());
  if (s.share_only || !output) return 0;  // this rank's share went to rank 0
  options.WriteConfig(output->File("database_importer_config.yaml"));
  output->Commit();
  LogInfo(
      "database_importer: {} cameras, {} images ({} left out), {} rig frames; {} pairs "
      "({} co-visibility{}, {} rig, {} temporal, {} priors); {} of {} constraints written; "
      "{:.2f} s (read {:.2f}, co-visibility {:.2f}, write {:.2f}); outputs in {}",
      s.num_cameras,
      s.num_images,
      s.num_images_skipped,
      s.num_frames,
      s.num_pairs,
      s.num_pairs_covisibility,
      s.priors_fallback ? ", fallback to priors" : "",
      s.num_pairs_rig,
      s.num_pairs_temporal,
      s.num_pairs_priors,
      s.num_constraints_written,
      s.num_constraints_read,
      s.seconds_total,
      s.seconds_read,
      s.seconds_covisibility,
      s.seconds_write,
      output_path);
  return 0;
}

}  // namespace lisfm
