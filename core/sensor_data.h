// Plain sensor-data records that readers produce and estimators consume
// (DESIGN.md "Time", "Frames"): an IMU sample and a LiDAR frame (the scans of
// one or several LiDARs processed as one update). No file formats, no logic
// beyond views: readers live in importers/, estimators in lio/.
#pragma once

#include <vector>

#include "core/geometry.h"
#include "core/point_cloud.h"
#include "core/time.h"

namespace lisfm {

struct ImuSample {
  TimestampNs t_ns = 0;       // IMU clock
  Vec3 gyro = Vec3::Zero();   // rad/s, body (IMU) frame
  Vec3 accel = Vec3::Zero();  // specific force, m/s^2 (or g, see ImuInitializerOptions), body frame
};

// One scan of a frame: a non-owning view of a cloud in its sensor frame
// (stamp = time of the first point, `t` per point) and the rig LiDAR index.
struct LidarScanInput {
  int sensor_id = 0;                  // rig LiDAR index
  const PointCloud* cloud = nullptr;  // not owned
};

// The scans of one LiDAR update: clouds in their sensor frames, the rig LiDAR
// index of each, and the latest point time on the IMU clock.
struct LidarFrame {
  std::vector<PointCloud> clouds;  // sensor frames; stamp_ns = first point
  std::vector<int> sensor_ids;     // rig LiDAR index of each cloud
  TimestampNs end_ns = 0;          // latest point time on the IMU clock (ns)

  // Views of the clouds (valid while this frame lives and is not modified).
  std::vector<LidarScanInput> Inputs() const {
    std::vector<LidarScanInput> inputs;
    inputs.reserve(clouds.size());
    for (size_t c = 0; c < clouds.size(); ++c) inputs.push_back({sensor_ids[c], &clouds[c]});
    return inputs;
  }
};

}  // namespace lisfm
