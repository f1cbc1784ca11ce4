// Camera rig configuration JSON in the format that COLMAP 3.8's
// `rig_bundle_adjuster --rig_config_path` reads:
//   [ { "ref_camera_id": 1,
//       "cameras": [ { "camera_id": 1, "image_prefix": "cam0/data/",
//                      "rel_tvec": [tx, ty, tz], "rel_qvec": [qw, qx, qy, qz] }, ... ] } ]
// rel_qvec/rel_tvec are cam_from_rig, where the rig frame is the reference
// camera's frame (so the reference camera has the identity). COLMAP groups
// images into rig snapshots by the image name after the prefix, which for a
// sequence folder (`camK/data/<ns>.png`, DESIGN.md "Formats") is the stamp.
//
// Failures: mismatched sizes or a reference index out of range throw
// InputError; the reader throws InputError naming the file and field.
#pragma once

#include <string>
#include <vector>

#include "colmap_ext/io/camera_models.h"
#include "core/rig.h"

namespace lisfm {
namespace colmap {

struct RigConfigCamera {
  camera_t camera_id = kInvalidCameraId;
  std::string image_prefix;
  bool has_rel_pose = false;
  Vec4 rel_qvec = Vec4(1, 0, 0, 0);  // cam_from_rig (qw, qx, qy, qz)
  Vec3 rel_tvec = Vec3::Zero();      // cam_from_rig translation (m)
};

struct RigConfig {
  camera_t ref_camera_id = kInvalidCameraId;
  std::vector<RigConfigCamera> cameras;
};

// One rig from our rig calibration: camera i of `rig` gets `camera_ids[i]`
// and `image_prefixes[i]` (default "camK/data/" with K the index when empty);
// cam_from_rig = cam_i_from_imu * (cam_ref_from_imu)^-1.
RigConfig RigConfigFromRig(const Rig& rig,
                           const std::vector<camera_t>& camera_ids,
                           std::vector<std::string> image_prefixes = {},
                           size_t ref_camera_index = 0);

// JSON text (an array of rigs) and file I/O (atomic write).
std::string RigConfigsToJson(const std::vector<RigConfig>& configs);
void WriteRigConfigs(const std::vector<RigConfig>& configs, const std::string& path);
std::vector<RigConfig> ReadRigConfigs(const std::string& path);

}  // namespace colmap
}  // namespace lisfm
