// `lisfm bag_importer` (a ROS1 bag -> a sequence folder) and `lisfm
// bag_exporter` (a sequence folder -> a ROS1 bag), with the topics and point
// layout of a preset in configs/bags/ (importers/bag.h).
#include <fmt/format.h>

#include <sstream>
#include <string>

#include "apps/commands.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/rig_io.h"
#include "core/logging.h"
#include "core/options.h"
#include "importers/bag.h"

#ifndef LISFM_DEFAULT_RIG_PATH
#define LISFM_DEFAULT_RIG_PATH ""
#endif
#ifndef LISFM_BAG_PRESET_DIR
#define LISFM_BAG_PRESET_DIR ""
#endif

namespace lisfm {
namespace {

constexpr char kPresetHelp[] =
    "topic preset: a name in configs/bags/ (hilti2022, hilti2021, velodyne) or a preset YAML path";

// A preset name (configs/bags/<name>.yaml) or a path to a preset YAML.
BagPreset LoadPreset(const std::string& preset) {
  const bool yaml = preset.size() > 5 && preset.substr(preset.size() - 5) == ".yaml";
  if (yaml || preset.find('/') != std::string::npos) {
    return ReadBagPreset(preset);
  }
  const std::string path = JoinPaths(LISFM_BAG_PRESET_DIR, preset + ".yaml");
  if (!FileExists(path)) {
    throw UsageError(fmt::format("--preset {}: no preset {}", preset, path));
  }
  BagPreset p = ReadBagPreset(path);
  p.name = preset;
  return p;
}

// Applies `--topics role=topic,...` to a preset: role imu, lidarK or camK
// (K from 0; K equal to the preset's count appends a topic). An empty list
// leaves the preset as it is.
void ApplyTopicOverrides(const std::string& list, BagPreset* preset) {
  std::stringstream in(list);
  for (std::string item; std::getline(in, item, ',');) {
    if (item.empty()) continue;
    const size_t eq = item.find('=');
    const std::string role = item.substr(0, eq);
    const std::string topic = eq == std::string::npos ? "" : item.substr(eq + 1);
    if (topic.empty()) {
      throw UsageError(fmt::format("--topics: '{}' is not role=topic", item));
    }
    if (role == "imu") {
      preset->imu_topic = topic;
      continue;
    }
    std::vector<std::string>* topics = nullptr;
    std::string digits;
    if (role.rfind("lidar", 0) == 0) {
      topics = &preset->lidar_topics;
      digits = role.substr(5);
    } else if (role.rfind("cam", 0) == 0) {
      topics = &preset->camera_topics;
      digits = role.substr(3);
    }
    if (topics == nullptr || digits.empty() ||
        digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 3) {
      throw UsageError(
          fmt::format("--topics: unknown role '{}' (imu, lidarK or camK, K from 0)", role));
    }
    const size_t k = std::stoul(digits);
    if (k > topics->size()) {
      throw UsageError(fmt::format("--topics: {} skips an index: preset {} has {} such topics, "
                                   "so the next one is {}{}",
                                   role,
                                   preset->name,
                                   topics->size(),
                                   role[0] == 'l' ? "lidar" : "cam",
                                   topics->size()));
    }
    if (k == topics->size()) {
      topics->push_back(topic);
    } else {
      (*topics)[k] = topic;
    }
  }
}

}  // namespace

int RunBagImporter(int argc, char** argv) {
  std::string input_path, output_path, rig_path, preset = "hilti2022", topics;
  bool overwrite = false;
  BagImportOptions import;
  OptionManager options("lisfm bag_importer",
                        "a ROS1 bag (no ROS installation needed) -> a sequence folder that "
                        "`lisfm lio` reads: imu0/, lidarK/ (PCD, per-point t since the scan's "
                        "first point), camK/ (PNG), rig.yaml; prints a per-topic summary");
  options.AddRequiredString("input_path",
                            &input_path,
                            "ROS1 bag (.bag); a bag split in several files: a comma list "
                            "a.bag,b.bag, a folder (all its *.bag) or a quoted glob 'rec_*.bag'");
  options.AddRequiredString("output_path", &output_path, "sequence folder to write");
  options.AddString("rig_path",
                    &rig_path,
                    "rig YAML or HILTI/Kalibr calibration folder written as rig.yaml (default: "
                    "configs/hilti2021.yaml with --preset hilti2021, else configs/hilti2022.yaml)");
  options.AddString("preset", &preset, kPresetHelp);
  options.AddString("topics",
                    &topics,
                    "comma list role=topic replacing the preset's topics: imu, lidarK, camK (K "
                    "from 0; the next K appends), e.g. imu=/imu,cam0=/left/image_raw");
  options.AddDouble("camera_rate",
                    &import.camera_rate_hz,
                    "keep camera frames at most this often per camera (Hz; a frame is kept "
                    "when >= 0.9 / rate s after the last kept one); 0 keeps all",
                    OptionRange::AtLeast(0));
  options.AddBool("overwrite", &overwrite, "replace an earlier output at --output_path");
  if (!options.Parse(argc, argv)) return 0;
  BagPreset bag_preset = LoadPreset(preset);
  ApplyTopicOverrides(topics, &bag_preset);
  if (rig_path.empty()) {
    rig_path = preset == "hilti2021" ? JoinPaths(LISFM_BAG_PRESET_DIR, "../hilti2021.yaml")
                                     : std::string(LISFM_DEFAULT_RIG_PATH);
  }
  // A rig YAML is copied verbatim unless its camera time shifts are applied to
  // the stamps; a calibration folder is converted once.
  const bool folder = DirExists(rig_path);
  const Rig rig = folder ? LoadHiltiCalibration(rig_path) : ReadRigYaml(rig_path);
  const std::string rig_yaml = FolderRigYaml(rig, folder ? RigToYaml(rig) : ReadFile(rig_path));
  ExpandBagPaths(input_path);  // every file exists, before the output folder is made
  OutputFolder output(output_path, overwrite);

  LogStage("bag_importer: " + input_path);
  const BagImportSummary s =
      ImportBag(input_path, rig, rig_yaml, bag_preset, import, output.path());
  options.WriteConfig(output.File("bag_importer_config.yaml"));
  output.Commit();
  LogInfo("bag_importer: {:.1f} MB in {:.2f} s ({:.0f} MB/s) -> {}\n{}",
          static_cast<double>(s.bag_bytes) * 1e-6,
          s.seconds,
          static_cast<double>(s.bag_bytes) * 1e-6 / std::max(s.seconds, 1e-9),
          output_path,
          FormatBagSummary(s));
  return 0;
}

int RunBagExporter(int argc, char** argv) {
  std::string input_path, output_path, preset = "hilti2022", compression = "none";
  OptionManager options("lisfm bag_exporter",
                        "a sequence folder -> a ROS1 bag in the message layouts of a preset "
                        "(sensor_msgs/Imu, PointCloud2, Image)");
  options.AddRequiredString("input_path", &input_path, "sequence folder");
  options.AddRequiredString("output_path", &output_path, "ROS1 bag to write (.bag)");
  options.AddString("preset", &preset, kPresetHelp);
  options.AddChoice("compression",
                    &compression,
                    {"none", "lz4", "bz2"},
                    "chunk compression of the bag (rosbag's lz4 or bz2)");
  if (!options.Parse(argc, argv)) return 0;
  const BagPreset bag_preset = LoadPreset(preset);
  CheckDirExists(input_path, "sequence folder");
  CheckOutputFileWritable(output_path, "--output_path");
  LogStage("bag_exporter: " + input_path);
  const BagExportSummary s = ExportBag(input_path, bag_preset, output_path, compression);
  LogInfo("bag_exporter: {} IMU messages, {} scans, {} images -> {} ({:.1f} MB)",
          s.num_imu,
          s.num_scans,
          s.num_images,
          output_path,
          static_cast<double>(s.bag_bytes) * 1e-6);
  return 0;
}

}  // namespace lisfm
