// Reader of the sequence folder (DESIGN.md "Formats", docs/FORMATS.md):
//   rig.yaml, imu0/data.csv, lidarK/data.csv + lidarK/data/<ns>.pcd,
//   camK/data.csv + camK/data/<ns>.png, groundtruth.txt / groundtruth.csv.
// CSV files are EuRoC/ASL style: a '#' header line, then comma-separated rows;
// imu0/data.csv rows are `t_ns, wx, wy, wz, ax, ay, az` (rad/s, m/s^2);
// lidarK/data.csv and camK/data.csv rows are `t_ns, filename`.
// Every malformed row, non-increasing time stamp or missing referenced file is
// an InputError naming the file and line.
#pragma once

#include <string>
#include <vector>

#include "core/io/sensor_index_io.h"  // SensorFile, ReadSensorIndex
#include "core/point_cloud.h"
#include "core/rig.h"
#include "core/sensor_data.h"

namespace lisfm {

struct Sequence {
  std::string root;
  Rig rig;
  std::vector<ImuSample> imu;
  std::vector<std::vector<SensorFile>> lidar_scans;    // [lidar k][scan]
  std::vector<std::vector<SensorFile>> camera_frames;  // [camera k][frame]
  std::string groundtruth_path;  // "" when absent
};

// Reads rig.yaml, the whole IMU file and the LiDAR/camera indexes (not the
// scans themselves). Throws InputError naming file and line on bad input.
Sequence ReadSequence(const std::string& root);

// Reads imu0/data.csv style files.
std::vector<ImuSample> ReadImuCsv(const std::string& path);

}  // namespace lisfm
