// `lisfm simulate`: a HILTI-style recording with exact ground truth (sim/).
//
//   lisfm simulate --output_path DIR [--scene office|staircase|hall|site|sim_x.yaml]
//                  [--trajectory_path TUM] [--duration s] [--camera_rate Hz]
//                  [--lidars spinning[,livox]] [--noise_scale k] [--seed n]
//                  [--rig_path rig.yaml] [--rgbd 0|1] [--supersampling n] [--color 0|1]
//
// The default rig is configs/hilti2022.yaml (the real HILTI 2022 rig), else the
// HILTI calibration folder in ../shared/data.
#include <string>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/rig_io.h"
#include "core/logging.h"
#include "core/options.h"
#include "sim/simulator.h"

#ifndef LISFM_DEFAULT_RIG_PATH
#define LISFM_DEFAULT_RIG_PATH ""
#endif
#ifndef LISFM_DEFAULT_HILTI_CALIBRATION
#define LISFM_DEFAULT_HILTI_CALIBRATION ""
#endif

namespace lisfm {

int RunSimulate(int argc, char** argv) {
  OptionManager options("lisfm simulate",
                        "simulate a HILTI-style recording with exact ground truth");
  sim::SimulatorOptions sim_options;
  std::string rig_path;
  AddSimulatorOptions(&options, &sim_options);
  options.AddString("rig_path", &rig_path,
                    "rig YAML (default: configs/hilti2022.yaml, the HILTI 2022 rig)");
  if (!options.Parse(argc, argv)) return 0;

  Rig rig;
  if (!rig_path.empty()) {
    rig = ReadRigYaml(rig_path);
  } else if (FileExists(LISFM_DEFAULT_RIG_PATH)) {
    rig = ReadRigYaml(LISFM_DEFAULT_RIG_PATH);
  } else if (DirExists(LISFM_DEFAULT_HILTI_CALIBRATION)) {
    rig = LoadHiltiCalibration(LISFM_DEFAULT_HILTI_CALIBRATION);
  } else {
    throw InputError(std::string(LISFM_DEFAULT_RIG_PATH), "file",
                     "default rig not found; pass --rig_path");
  }
  const sim::SimulationSummary s = sim::Simulate(
      sim_options, rig, [&](const std::string& dir) {
        options.WriteConfig(JoinPaths(dir, "simulate_config.yaml"));
      });
  std::string lidar_text;
  for (size_t k = 0; k < s.num_scans.size(); ++k) {
    lidar_text += fmt::format("lidar{}: {} scans, {} points; ", k, s.num_scans[k],
                              s.num_points[k]);
  }
  LogInfo(
      "simulate: {} scene ({} triangles), {:.1f} s, path {:.1f} m; {} IMU samples; {}{} images "
      "from {} cameras; {} RGB-D frames; {} control points; {} people. Time {:.1f} s (scene "
      "{:.1f}, IMU {:.1f}, LiDAR {:.1f}, cameras {:.1f}). Output: {}",
      s.scene_type, s.num_triangles, s.duration_s, s.path_length_m, s.num_imu, lidar_text,
      s.num_images, rig.cameras.size(), s.num_rgbd, s.num_control_points, s.num_people,
      s.seconds_total,
      s.seconds_scene, s.seconds_imu, s.seconds_lidar, s.seconds_cameras,
      sim_options.output_path);
  return 0;
}

}  // namespace lisfm
