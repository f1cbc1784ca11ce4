// `lisfm kitti_importer`: a KITTI odometry sequence -> a sequence folder
// (importers/kitti.h).
#include <string>

#include "apps/commands.h"
#include "core/file_utils.h"
#include "core/logging.h"
#include "core/options.h"
#include "importers/kitti.h"

namespace lisfm {

int RunKittiImporter(int argc, char** argv) {
  std::string input_path, output_path, poses_path;
  int64_t time_origin_ns = 0;
  bool overwrite = false;
  OptionManager options("lisfm kitti_importer",
                        "a KITTI odometry sequence (velodyne/*.bin, times.txt, calib.txt, "
                        "poses) -> a sequence folder: lidar0/ (PCD, t = 0), rig.yaml (body = "
                        "camera 0), groundtruth.txt; KITTI odometry has no IMU, so no imu0/");
  options.AddRequiredString(
      "input_path", &input_path, "KITTI sequence folder (dataset/sequences/NN)");
  options.AddRequiredString("output_path", &output_path, "sequence folder to write");
  options.AddString("poses_path",
                    &poses_path,
                    "KITTI poses file (dataset/poses/NN.txt); default: poses.txt in "
                    "--input_path if present, else no groundtruth.txt");
  options.AddInt64("time_origin_ns",
                   &time_origin_ns,
                   "ns added to times.txt (s since the sequence start) for the stamps",
                   OptionRange::AtLeast(0));
  options.AddBool("overwrite", &overwrite, "replace an earlier output at --output_path");
  if (!options.Parse(argc, argv)) return 0;
  CheckDirExists(input_path, "KITTI sequence folder");
  if (!poses_path.empty()) CheckFileExists(poses_path, "KITTI poses");
  OutputFolder output(output_path, overwrite);
  LogStage("kitti_importer: " + input_path);
  const KittiImportSummary s =
      ImportKittiOdometry(input_path, poses_path, time_origin_ns, output.path());
  options.WriteConfig(output.File("kitti_importer_config.yaml"));
  output.Commit();
  LogInfo("kitti_importer: {} scans, {} points, {} poses -> {}",
          s.num_scans,
          s.num_points,
          s.num_poses,
          output_path);
  return 0;
}

}  // namespace lisfm
