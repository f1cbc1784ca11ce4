// ROS1 bags in and out without a ROS installation (rosbag_storage only):
// a bag -> a sequence folder (DESIGN.md "Formats", docs/FORMATS.md) that
// `lisfm lio` reads unchanged, and a sequence folder -> a bag in the message
// layouts of a topic preset (configs/bags/<preset>.yaml).
//
// Messages: sensor_msgs/Imu (header.stamp, angular_velocity rad/s,
// linear_acceleration m/s^2) -> imu0/data.csv; sensor_msgs/PointCloud2 ->
// lidarK/data/<ns>.pcd in the LiDAR frame (importers/point_cloud2.h: any field
// layout, both byte orders, the preset's per-point time field; non-finite points
// dropped; stamp = first point); livox_ros_driver/CustomMsg -> the same, decoded
// from the message definition stored in the bag (importers/bag_message.h); sensor_msgs/Image mono8
// -> 8-bit grey PNG, bgr8 / rgb8 -> BGR PNG -> camK/data/<ns>.png. LiDAR k and camera k of the
// preset are the rig's lidars[k] and cameras[k] (folder names from the rig).
// Camera stamps are moved to the IMU clock once, here (DESIGN.md "Time"):
// t_ns = header.stamp + rig.cameras[k].timeshift_cam_imu, so the rig.yaml
// written beside them must carry zero camera time shifts. IMU and LiDAR stamps
// are copied (lio applies the LiDAR time_offset of rig.yaml itself).
//
// The bag is read with rosbag::View in receive-time order, one chunk at a time
// (memory: the chunk being read plus the IMU samples and per-topic stamps), each
// scan and image written as soon as it is decoded.
//
// Errors: a file that is not a readable bag, a chunk that cannot be read
// (corrupted; named by the message read before it), a missing IMU or LiDAR topic, a topic
// of the wrong message type, a message that does not deserialize, a PointCloud2
// without the time field, an unsupported image encoding, non-increasing stamps on
// a topic: one InputError "<bag>: topic <topic> message <i>: ..." (i counts from 0
// per topic). The caller writes into a temporary folder (OutputFolder).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/rig.h"
#include "core/time.h"
#include "importers/point_cloud2.h"
#include "importers/sequence.h"

namespace lisfm {

// The topics and point layout of one recording setup (configs/bags/*.yaml).
struct BagPreset {
  std::string name;
  std::string imu_topic;                  // required on import
  std::vector<std::string> lidar_topics;  // [k] -> rig lidar k; each required on import
  // [k]: message type of lidar_topics[k] written by the exporter:
  // sensor_msgs/PointCloud2 (default) or livox_ros_driver/CustomMsg. The
  // importer takes either, by the type the bag gives the topic.
  std::vector<std::string> lidar_types;
  PointCloud2Mapping
      lidar_fields;  // per-point time / intensity / ring fields of PointCloud2 topics
  std::vector<std::string> camera_topics;  // [k] -> rig camera k; absent topics are skipped
};

// Reads a preset YAML:
//   imu_topic: /alphasense/imu
//   lidar_topics: [/hesai/pandar]
//   lidar_fields: {time: timestamp, time_type: float64, time_unit: s,
//                  time_reference: absolute, intensity: intensity, ring: ring}
//   camera_topics: [/alphasense/cam0/image_raw, ...]
//   lidar_types: [sensor_msgs/PointCloud2, livox_ros_driver/CustomMsg]  (optional)
// time_type: float32|float64|uint32|int32; time_unit: s|ns; time_reference:
// stamp (since header.stamp) | absolute. Throws InputError naming file and key.
BagPreset ReadBagPreset(const std::string& path);

struct BagImportOptions {
  double camera_rate_hz = 0;  // keep camera frames at most this often per camera (Hz); 0 = all
  bool Check() const;
};

struct BagTopicSummary {
  std::string topic;
  std::string type;
  size_t num_messages = 0;                // read
  size_t num_kept = 0;                    // written to the folder
  TimestampNs first_ns = 0, last_ns = 0;  // header stamps
  double rate_hz = 0;                     // (messages - 1) / span
  size_t num_gaps = 0;                    // intervals > 1.5 x median interval
  double max_gap_s = 0;                   // largest interval
};

struct BagImportSummary {
  std::vector<BagTopicSummary> topics;  // preset order: IMU, LiDARs, cameras present
  uint64_t bag_bytes = 0;
  double seconds = 0;
};

// The bag files of `input`: a comma list whose items are a bag file, a folder
// (every *.bag in it) or a glob pattern (`rec_*.bag`); each item's files in
// name order, items in the given order. Throws InputError for an item that
// matches nothing, a missing file or a file given twice.
std::vector<std::string> ExpandBagPaths(const std::string& input);

// Reads `bag_path` (one bag, or a bag split in several files: ExpandBagPaths;
// the files are read as one, messages in receive-time order) into the sequence
// folder `output_dir` (existing, empty). Errors name `bag_path` as given, or the
// file that cannot be opened.
// `rig` names the LiDAR and camera folders and gives the camera time shifts;
// `rig_yaml` is written as rig.yaml verbatim (the calibration file as given when
// its camera time shifts are 0, so that it is read exactly as before;
// FolderRigYaml).
BagImportSummary ImportBag(const std::string& bag_path,
                           const Rig& rig,
                           const std::string& rig_yaml,
                           const BagPreset& preset,
                           const BagImportOptions& options,
                           const std::string& output_dir);

struct BagExportSummary {
  size_t num_imu = 0, num_scans = 0, num_images = 0;
  uint64_t bag_bytes = 0;
};

// Writes the sequence folder `seq_root` as a bag at `bag_path` (temporary name,
// renamed when complete): IMU, every rig LiDAR that has a preset topic (scan
// stamp = header.stamp, received at the scan's last point), every camera with a
// preset topic (mono8 for grey PNGs, bgr8 for colour; header.stamp = stamp minus
// the folder rig's timeshift_cam_imu). Throws InputError when
// the sequence has more LiDARs than the preset has topics.
// `compression`: "none", "lz4" or "bz2" (rosbag chunk compression; the
// importer reads all three).
BagExportSummary ExportBag(const std::string& seq_root,
                           const BagPreset& preset,
                           const std::string& bag_path,
                           const std::string& compression = "none");

// The rig.yaml text of an imported folder: `rig_file_text` unchanged when every
// camera time shift of `rig` is 0, else `rig` with those shifts set to 0 (they
// are applied to the camera stamps by ImportBag).
std::string FolderRigYaml(const Rig& rig, const std::string& rig_file_text);

std::string FormatBagSummary(const BagImportSummary& summary);

}  // namespace lisfm
