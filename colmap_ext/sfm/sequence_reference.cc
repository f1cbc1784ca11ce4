#include "colmap_ext/sfm/sequence_reference.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "colmap_ext/sfm/mapper_state.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/rig_io.h"
#include "core/io/sensor_index_io.h"
#include "core/io/trajectory_io.h"

namespace lisfm {
namespace colmap {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

double RotationAngleDeg(const Quat& a, const Quat& b) {
  return so3::AngularDistance(a, b) * kRadToDeg;
}

void CheckSameCameras(const Rig& believed, const Rig& truth, const std::string& source) {
  if (believed.cameras.size() != truth.cameras.size()) {
    throw InputError(source,
                     "",
                     fmt::format("rig.yaml has {} cameras but truth/rig.yaml has {}",
                                 believed.cameras.size(),
                                 truth.cameras.size()));
  }
}

}  // namespace

bool IsSequenceFolderWithGroundTruth(const std::string& path) {
  return DirExists(path) && FileExists(JoinPaths(path, "rig.yaml")) &&
         FileExists(JoinPaths(path, "groundtruth.txt"));
}

std::vector<NamedPose> SequenceReferencePoses(const Rig& believed,
                                              const Rig& truth,
                                              const Trajectory& groundtruth,
                                              const std::vector<SequenceImage>& images,
                                              const std::string& source) {
  CheckSameCameras(believed, truth, source);
  std::vector<NamedPose> poses;
  poses.reserve(images.size());
  for (const SequenceImage& image : images) {
    if (image.camera_index < 0 || image.camera_index >= static_cast<int>(truth.cameras.size())) {
      throw InputError(source,
                       image.name,
                       fmt::format("camera index {} is not a camera of the rig ({} cameras)",
                                   image.camera_index,
                                   truth.cameras.size()));
    }
    const RigCamera& true_camera = truth.cameras[image.camera_index];
    const double shift_s =
        true_camera.timeshift_cam_imu_s - believed.cameras[image.camera_index].timeshift_cam_imu_s;
    const TimestampNs t_true = std::clamp(
        image.stamp_ns + SecondsToNs(shift_s), groundtruth.start_ns(), groundtruth.end_ns());
    const SE3 world_from_cam =
        *groundtruth.Interpolate(t_true) * true_camera.cam_from_imu.Inverse();
    poses.push_back({image.name, world_from_cam.Inverse(), {}});
  }
  return poses;
}

SequenceReference ReadSequenceReference(const std::string& folder) {
  CheckDirExists(folder, "sequence folder");
  const std::string truth_dir = JoinPaths(folder, "truth");
  if (!DirExists(truth_dir)) {
    throw InputError(folder,
                     "",
                     "a sequence reference needs the simulator's ground truth: expected rig.yaml, "
                     "groundtruth.txt and truth/ (lisfm simulate), found no truth/ folder");
  }
  SequenceReference reference;
  reference.believed_rig = ReadRigYaml(JoinPaths(folder, "rig.yaml"));
  const std::string truth_rig = JoinPaths(truth_dir, "rig.yaml");
  reference.has_truth_rig_file = FileExists(truth_rig);
  reference.truth_rig =
      reference.has_truth_rig_file ? ReadRigYaml(truth_rig) : reference.believed_rig;
  const Trajectory groundtruth = ReadTum(JoinPaths(folder, "groundtruth.txt"));
  std::vector<SequenceImage> images;
  for (size_t k = 0; k < reference.believed_rig.cameras.size(); ++k) {
    const std::string name = reference.believed_rig.cameras[k].name;
    const std::string dir = JoinPaths(folder, name);
    if (!DirExists(dir)) continue;
    for (const SensorFile& file :
         ReadSensorIndex(JoinPaths(dir, "data.csv"), JoinPaths(dir, "data"))) {
      const std::string file_name = file.path.substr(file.path.find_last_of('/') + 1);
      images.push_back({static_cast<int>(k), file.t_ns, name + "/data/" + file_name});
    }
  }
  if (images.empty()) {
    throw InputError(folder, "", "no camera images (camK/data.csv of the rig's cameras)");
  }
  reference.poses = SequenceReferencePoses(
      reference.believed_rig, reference.truth_rig, groundtruth, images, folder);
  return reference;
}

std::vector<RigCameraEvaluation> EvaluateModelRig(const Reconstruction& model,
                                                  const Rig& believed,
                                                  const Rig& truth,
                                                  double scale,
                                                  const std::string& source) {
  std::vector<RigCameraEvaluation> result;
  if (model.Rigs().empty() || !model.Rigs().front().has_ref_sensor) return result;
  CheckSameCameras(believed, truth, source);
  std::map<camera_t, int> index_of_camera;
  for (const Image& image : model.Images()) {
    int k = -1;
    int64_t stamp = 0;
    if (ParseRigImageName(image.name, &k, &stamp)) index_of_camera.emplace(image.camera_id, k);
  }
  const auto camera_index = [&](camera_t camera_id) {
    const auto it = index_of_camera.find(camera_id);
    if (it == index_of_camera.end()) {
      throw InputError(source,
                       fmt::format("camera {}", camera_id),
                       "rig camera without an image named camK/data/<ns>.<ext>");
    }
    if (it->second >= static_cast<int>(truth.cameras.size())) {
      throw InputError(
          source,
          fmt::format("camera {}", camera_id),
          fmt::format(
              "images named cam{} but the rig has {} cameras", it->second, truth.cameras.size()));
    }
    return it->second;
  };
  const ModelRig& rig = model.Rigs().front();
  const int ref = camera_index(rig.ref_sensor.id);
  RigCameraEvaluation reference;
  reference.camera_id = rig.ref_sensor.id;
  reference.camera_index = ref;
  reference.is_reference = true;
  result.push_back(reference);
  const SE3 true_imu_from_ref = truth.cameras[ref].cam_from_imu.Inverse();
  const SE3 believed_imu_from_ref = believed.cameras[ref].cam_from_imu.Inverse();
  for (const RigSensor& sensor : rig.sensors) {
    if (sensor.sensor.type != SensorType::kCamera || !sensor.has_pose) continue;
    RigCameraEvaluation e;
    e.camera_id = sensor.sensor.id;
    e.camera_index = camera_index(sensor.sensor.id);
    const SE3 true_cam_from_ref = truth.cameras[e.camera_index].cam_from_imu * true_imu_from_ref;
    const SE3 believed_cam_from_ref =
        believed.cameras[e.camera_index].cam_from_imu * believed_imu_from_ref;
    const Quat refined_rotation =
        Quat(sensor.qvec(0), sensor.qvec(1), sensor.qvec(2), sensor.qvec(3)).normalized();
    e.rotation_error_deg = RotationAngleDeg(refined_rotation, true_cam_from_ref.rotation());
    e.translation_error_m = (scale * sensor.tvec - true_cam_from_ref.translation()).norm();
    e.believed_rotation_error_deg =
        RotationAngleDeg(believed_cam_from_ref.rotation(), true_cam_from_ref.rotation());
    e.believed_translation_error_m =
        (believed_cam_from_ref.translation() - true_cam_from_ref.translation()).norm();
    result.push_back(e);
  }
  std::sort(result.begin(), result.end(), [](const auto& a, const auto& b) {
    return a.camera_index < b.camera_index;
  });
  return result;
}

}  // namespace colmap
}  // namespace lisfm
