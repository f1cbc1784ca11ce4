#include "colmap_ext/io/rig_config.h"

#include <nlohmann/json.hpp>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {
namespace colmap {

RigConfig RigConfigFromRig(const Rig& rig,
                           const std::vector<camera_t>& camera_ids,
                           std::vector<std::string> image_prefixes,
                           size_t ref_camera_index) {
  if (camera_ids.size() != rig.cameras.size()) {
    throw InputError("rig config", "camera_ids",
                     "expected " + std::to_string(rig.cameras.size()) + " camera ids, found " +
                         std::to_string(camera_ids.size()));
  }
  if (image_prefixes.empty()) {
    for (size_t i = 0; i < rig.cameras.size(); ++i) {
      image_prefixes.push_back("cam" + std::to_string(i) + "/data/");
    }
  }
  if (image_prefixes.size() != rig.cameras.size()) {
    throw InputError("rig config", "image_prefixes",
                     "expected " + std::to_string(rig.cameras.size()) + " prefixes, found " +
                         std::to_string(image_prefixes.size()));
  }
  if (ref_camera_index >= rig.cameras.size()) {
    throw InputError("rig config", "ref_camera_index",
                     "expected < " + std::to_string(rig.cameras.size()) + ", found " +
                         std::to_string(ref_camera_index));
  }
  RigConfig config;
  config.ref_camera_id = camera_ids[ref_camera_index];
  const SE3 imu_from_ref = rig.cameras[ref_camera_index].cam_from_imu.Inverse();
  for (size_t i = 0; i < rig.cameras.size(); ++i) {
    RigConfigCamera camera;
    camera.camera_id = camera_ids[i];
    camera.image_prefix = image_prefixes[i];
    camera.has_rel_pose = true;
    const SE3 cam_from_rig = i == ref_camera_index
                                 ? SE3::Identity()
                                 : rig.cameras[i].cam_from_imu * imu_from_ref;
    const Quat& q = cam_from_rig.rotation();
    camera.rel_qvec = Vec4(q.w(), q.x(), q.y(), q.z());
    camera.rel_tvec = cam_from_rig.translation();
    config.cameras.push_back(camera);
  }
  return config;
}

std::string RigConfigsToJson(const std::vector<RigConfig>& configs) {
  nlohmann::json root = nlohmann::json::array();
  for (const RigConfig& config : configs) {
    nlohmann::json rig;
    rig["ref_camera_id"] = config.ref_camera_id;
    rig["cameras"] = nlohmann::json::array();
    for (const RigConfigCamera& c : config.cameras) {
      nlohmann::json cam;
      cam["camera_id"] = c.camera_id;
      cam["image_prefix"] = c.image_prefix;
      if (c.has_rel_pose) {
        cam["rel_tvec"] = {c.rel_tvec(0), c.rel_tvec(1), c.rel_tvec(2)};
        cam["rel_qvec"] = {c.rel_qvec(0), c.rel_qvec(1), c.rel_qvec(2), c.rel_qvec(3)};
      }
      rig["cameras"].push_back(cam);
    }
    root.push_back(rig);
  }
  return root.dump(2) + "\n";
}

void WriteRigConfigs(const std::vector<RigConfig>& configs, const std::string& path) {
  WriteFileAtomically(path, RigConfigsToJson(configs));
}

std::vector<RigConfig> ReadRigConfigs(const std::string& path) {
  const std::string text = ReadFile(path);
  nlohmann::json root;
  try {
    root = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, "", std::string("expected JSON, found a parse error: ") + e.what());
  }
  if (!root.is_array()) throw InputError(path, "", "expected a JSON array of rigs");
  std::vector<RigConfig> configs;
  for (size_t r = 0; r < root.size(); ++r) {
    const std::string where = "rig " + std::to_string(r);
    try {
      RigConfig config;
      config.ref_camera_id = root[r].at("ref_camera_id").get<camera_t>();
      for (const auto& cam : root[r].at("cameras")) {
        RigConfigCamera c;
        c.camera_id = cam.at("camera_id").get<camera_t>();
        c.image_prefix = cam.at("image_prefix").get<std::string>();
        if (cam.contains("rel_tvec") && cam.contains("rel_qvec")) {
          c.has_rel_pose = true;
          for (int k = 0; k < 3; ++k) c.rel_tvec(k) = cam.at("rel_tvec").at(k).get<double>();
          for (int k = 0; k < 4; ++k) c.rel_qvec(k) = cam.at("rel_qvec").at(k).get<double>();
        }
        config.cameras.push_back(c);
      }
      configs.push_back(config);
    } catch (const nlohmann::json::exception& e) {
      throw InputError(path, where, std::string("malformed rig: ") + e.what());
    }
  }
  return configs;
}

}  // namespace colmap
}  // namespace lisfm
