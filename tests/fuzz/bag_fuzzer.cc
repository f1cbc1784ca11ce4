// Fuzz target bag: a ROS1 bag file through ImportBag with a Velodyne-style
// preset (IMU /imu/data, PointCloud2 /velodyne_points with a float32 `time`
// field since header.stamp, camera /cam0/image_raw) and a rig of one camera
// and one LiDAR; the sequence folder goes to a scratch folder that is removed
// after each input.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include "core/errors.h"
#include "core/io/rig_io.h"
#include "importers/bag.h"
#include "tests/fuzz/fuzz_util.h"

namespace {

const char kRigYaml[] = R"(cam0:
  camera_model: pinhole
  intrinsics: [100, 100, 32, 24]
  distortion_model: none
  resolution: [64, 48]
  T_cam_imu: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
lidars:
  - type: spinning
    T_imu_lidar: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.1], [0, 0, 0, 1]]
    rings: 16
)";

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const lisfm::Rig rig = lisfm::ParseRigYaml(kRigYaml, "rig.yaml");
  static const lisfm::BagPreset preset = [] {
    lisfm::BagPreset p;
    p.name = "velodyne";
    p.imu_topic = "/imu/data";
    p.lidar_topics = {"/velodyne_points"};
    p.lidar_fields.time.name = "time";
    p.lidar_fields.time.datatype = 7;
    p.camera_topics = {"/cam0/image_raw"};
    return p;
  }();
  const std::string path = lisfm::fuzz::WriteScratchFile("input.bag", data, size);
  lisfm::fuzz::RemoveScratch("sequence");
  const std::string output_dir = lisfm::fuzz::ScratchDir() + "/sequence";
  std::filesystem::create_directory(output_dir);
  try {
    lisfm::ImportBag(path, rig, kRigYaml, preset, lisfm::BagImportOptions{}, output_dir);
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  lisfm::fuzz::RemoveScratch("sequence");
  return 0;
}
