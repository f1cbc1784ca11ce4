// COLMAP file commands: `lisfm model_converter`, `lisfm model_analyzer`,
// `lisfm database_info` (colmap_ext/ I/O, COLMAP 3.8 formats).
#include <chrono>
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>

#include "apps/commands.h"
#include "colmap_ext/io/database.h"
#include "colmap_ext/io/model_io.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/logging.h"
#include "core/options.h"

namespace lisfm {
namespace {

double SecondsSince(const std::chrono::steady_clock::time_point& start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string Printf(const char* format, double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, value);
  return buf;
}

}  // namespace

int RunModelConverter(int argc, char** argv) {
  std::string input_path, output_path, output_type = "BIN";
  bool overwrite = false;
  OptionManager options("lisfm model_converter",
                        "convert a COLMAP sparse model (BIN or TXT folder) to BIN, TXT or PLY");
  options.AddRequiredString("input_path", &input_path, "model folder (.bin or .txt files)");
  options.AddRequiredString("output_path", &output_path,
                            "output folder (BIN, TXT) or .ply file (PLY)");
  options.AddChoice("output_type", &output_type, {"BIN", "TXT", "PLY", "bin", "txt", "ply"},
                    "output format");
  options.AddBool("overwrite", &overwrite,
                  "replace an earlier lisfm output folder at --output_path (BIN, TXT)");
  if (!options.Parse(argc, argv)) return 0;
  std::string type = output_type;
  for (char& c : type) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  // Checked before the work: a folder for BIN/TXT, a writable file for PLY.
  std::optional<OutputFolder> output;
  if (type == "PLY") {
    CheckOutputFileWritable(output_path, "--output_path");
  } else {
    output.emplace(output_path, overwrite);
  }
  const auto start = std::chrono::steady_clock::now();
  colmap::ModelFormat input_format;
  const colmap::Reconstruction model = colmap::ReadModel(input_path, &input_format);
  const double read_s = SecondsSince(start);
  if (type == "PLY") {
    colmap::WritePly(model, output_path);
  } else {
    colmap::WriteModel(model, output->path(),
                       type == "BIN" ? colmap::ModelFormat::kBinary : colmap::ModelFormat::kText);
    output->Commit();
  }
  LogInfo("model_converter: read {} model ({} cameras, {} images, {} points, {} observations) "
          "from {} in {:.3f} s; wrote {} to {} in {:.3f} s.",
          input_format == colmap::ModelFormat::kBinary ? "BIN" : "TXT", model.NumCameras(),
          model.NumImages(), model.NumPoints3D(), model.ComputeNumObservations(), input_path,
          read_s, type, output_path, SecondsSince(start) - read_s);
  return 0;
}

int RunModelAnalyzer(int argc, char** argv) {
  std::string path;
  OptionManager options("lisfm model_analyzer",
                        "print the statistics of a COLMAP sparse model (as colmap model_analyzer)");
  options.AddRequiredString("path", &path, "model folder (.bin or .txt files)");
  if (!options.Parse(argc, argv)) return 0;
  const auto start = std::chrono::steady_clock::now();
  const colmap::Reconstruction model = colmap::ReadModel(path);
  // The same lines and formats as COLMAP 3.8's model_analyzer.
  std::cout << "Cameras: " << model.NumCameras() << "\n"
            << "Images: " << model.NumImages() << "\n"
            << "Registered images: " << model.NumImages() << "\n"
            << "Points: " << model.NumPoints3D() << "\n"
            << "Observations: " << model.ComputeNumObservations() << "\n"
            << "Mean track length: " << Printf("%f", model.ComputeMeanTrackLength()) << "\n"
            << "Mean observations per image: "
            << Printf("%f", model.ComputeMeanObservationsPerRegImage()) << "\n"
            << "Mean reprojection error: " << Printf("%f", model.ComputeMeanReprojectionError())
            << "px\n";
  size_t num_rig_sensors = 0;
  for (const auto& rig : model.Rigs()) num_rig_sensors += rig.sensors.size() + 1;
  LogInfo("model_analyzer: {} has {} cameras, {} images, {} points, {} observations, {} rigs "
          "({} sensors), {} frames; analysed in {:.3f} s.",
          path, model.NumCameras(), model.NumImages(), model.NumPoints3D(),
          model.ComputeNumObservations(), model.Rigs().size(), num_rig_sensors,
          model.Frames().size(), SecondsSince(start));
  return 0;
}

int RunDatabaseInfo(int argc, char** argv) {
  std::string database_path;
  OptionManager options("lisfm database_info",
                        "COLMAP database summary: schema, rows per table, pose priors");
  options.AddRequiredString("database_path", &database_path, "COLMAP database file");
  if (!options.Parse(argc, argv)) return 0;
  const auto start = std::chrono::steady_clock::now();
  const colmap::Database db(database_path, colmap::Database::OpenMode::kReadOnly);
  const colmap::DatabaseSchema& schema = db.schema();
  std::string tables;
  for (const auto& t : schema.tables) tables += (tables.empty() ? "" : ", ") + t;
  std::cout << "Database: " << database_path << "\n"
            << "Schema: user_version " << schema.user_version
            << ", images prior columns: " << (schema.images_have_prior_columns ? "yes" : "no")
            << ", pose_priors layout: " << schema.pose_priors_layout
            << ", rigs/frames tables: " << (schema.has_rigs ? "yes" : "no") << "\n"
            << "Tables: " << tables << "\n";
  for (const std::string& table : schema.tables) {
    std::cout << "  " << table << ": " << db.CountRows(table) << " rows";
    if (table == "keypoints" || table == "descriptors" || table == "matches" ||
        table == "two_view_geometries") {
      std::cout << ", " << db.SumRowsColumn(table) << " entries";
    }
    std::cout << "\n";
  }
  size_t with_rotation = 0, with_position = 0, with_covariance = 0;
  for (const colmap::DbImage& image : db.ReadAllImages()) {
    with_rotation += image.has_prior_rotation ? 1 : 0;
    with_position += image.has_prior_position ? 1 : 0;
    with_covariance += image.prior_position_covariance.allFinite() ? 1 : 0;
  }
  size_t calibrated = 0;
  const auto cameras = db.ReadAllCameras();
  for (const auto& camera : cameras) calibrated += camera.has_prior_focal_length ? 1 : 0;
  std::cout << "Cameras with prior_focal_length: " << calibrated << " of " << cameras.size()
            << "\n"
            << "Images with prior rotation: " << with_rotation << ", prior position: "
            << with_position << ", position covariance: " << with_covariance << "\n";
  LogInfo("database_info: {} has {} cameras, {} images ({} with position priors), {} keypoint "
          "rows, {} matched pairs, {} two-view geometries; read in {:.3f} s.",
          database_path, db.NumCameras(), db.NumImages(), with_position,
          db.CountRows("keypoints"), db.CountRows("matches"),
          db.CountRows("two_view_geometries"), SecondsSince(start));
  return 0;
}

}  // namespace lisfm
