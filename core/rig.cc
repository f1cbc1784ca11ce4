#include "core/rig.h"

#include "core/errors.h"

namespace lisfm {

std::string LidarTypeName(LidarType type) {
  switch (type) {
    case LidarType::kSpinning:
      return "spinning";
    case LidarType::kLivox:
      return "livox";
  }
  return "unknown";
}

LidarType ParseLidarType(const std::string& name) {
  if (name == "spinning") return LidarType::kSpinning;
  if (name == "livox") return LidarType::kLivox;
  throw InputError("unknown lidar type '" + name + "' (expected spinning or livox)");
}

const RigCamera* Rig::FindCamera(const std::string& name) const {
  for (const RigCamera& camera : cameras) {
    if (camera.name == name) return &camera;
  }
  return nullptr;
}

const RigLidar* Rig::FindLidar(const std::string& name) const {
  for (const RigLidar& lidar : lidars) {
    if (lidar.name == name) return &lidar;
  }
  return nullptr;
}

}  // namespace lisfm
