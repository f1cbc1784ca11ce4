// lisfm_sim_reference_model SEQ DATABASE OUTPUT: the ground-truth cameras of a
// simulated sequence as a COLMAP model (the database's cameras and image ids,
// no points), for `lisfm model_evaluator --reference_path` in
// scripts/bench_covisibility.sh. An image camK/data/<ns>.png gets
// world_from_cam = groundtruth.txt(<ns> + true timeshift_cam_imu) *
// T_cam_imu_true^-1 with truth/rig.yaml (docs/FORMATS.md "Error sources"; the
// rig.yaml of the sequence when there is no truth/).
#include <algorithm>
#include <exception>
#include <iostream>
#include <string>

#include "colmap_ext/io/database.h"
#include "colmap_ext/io/model_io.h"
#include "colmap_ext/io/reconstruction.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"

int main(int argc, char** argv) {
  using namespace lisfm;
  if (argc != 4) {
    std::cerr << "usage: lisfm_sim_reference_model SEQ DATABASE OUTPUT\n";
    return 2;
  }
  try {
    const std::string seq = argv[1];
    const std::string truth_path = JoinPaths(seq, "truth/rig.yaml");
    const Rig truth = ReadRigYaml(FileExists(truth_path) ? truth_path : JoinPaths(seq, "rig.yaml"));
    const Trajectory gt = ReadTum(JoinPaths(seq, "groundtruth.txt"));
    const colmap::Database db(argv[2], colmap::Database::OpenMode::kReadOnly);
    colmap::Reconstruction model;
    for (const colmap::Camera& camera : db.ReadAllCameras()) model.AddCamera(camera);
    size_t n = 0;
    for (const colmap::DbImage& row : db.ReadAllImages()) {
      const size_t cam = row.name.find("cam");
      const size_t slash = row.name.rfind('/');
      if (cam == std::string::npos || slash == std::string::npos) continue;
      const int k = std::stoi(row.name.substr(cam + 3));
      const TimestampNs stamp = std::stoll(row.name.substr(slash + 1));
      // Poses beyond the ground truth's ends are those at its ends.
      const auto pose =
          gt.Interpolate(std::clamp(stamp + SecondsToNs(truth.cameras.at(k).timeshift_cam_imu_s),
                                    gt.start_ns(),
                                    gt.end_ns()));
      if (!pose) continue;
      colmap::Image image;
      image.image_id = row.image_id;
      image.camera_id = row.camera_id;
      image.name = row.name;
      image.SetCamFromWorld(truth.cameras.at(k).cam_from_imu * pose->Inverse());
      model.AddImage(image);
      ++n;
    }
    CreateDirs(argv[3]);
    colmap::WriteModelBinary(model, argv[3]);
    std::cout << "reference model: " << n << " images in " << argv[3] << "\n";
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
