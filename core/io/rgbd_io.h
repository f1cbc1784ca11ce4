// RGB-D frame sequences: the frame list, intrinsics, depth scale and given poses of a
// folder, and loading one frame as metric depth + RGB bytes.
//
// Layouts (RgbdLayout; detected from the folder unless RgbdReadOptions::layout says):
//  - kLisfm: a sequence folder of `lisfm simulate --rgbd 1` (or its `rgbd0/` folder):
//      rgbd0/data.csv `#timestamp [ns],rgb,depth` (paths relative to rgbd0/),
//      rgbd0/camera.yaml `intrinsics: [fx, fy, cx, cy]`, `resolution: [w, h]`,
//      `depth_scale: <units per metre>`, `T_cam_imu:` 4x4 (cam_from_imu);
//      the given pose is groundtruth.txt (TUM, world_from_imu, beside rgbd0/) interpolated
//      at the frame stamp and composed: world_from_camera = world_from_imu(t) * T_cam_imu^-1.
//  - kTum: the TUM RGB-D benchmark layout: rgb.txt and depth.txt (`timestamp filename`,
//      seconds, `#` comments), optional groundtruth.txt (TUM, world_from_camera). Each
//      colour image is paired with the nearest depth image within association_max_dt_s
//      (greedy on |dt| with unique pairs, as the benchmark's associate.py); the frame time is
//      the colour stamp. Depth scale 5000 units per metre (the TUM spec). TUM folders carry no
//      intrinsics: RgbdReadOptions::intrinsics_path, else a camera.yaml in the folder (lisfm
//      format above; T_cam_imu ignored; its depth_scale, if any, replaces 5000), else the
//      benchmark's ROS default for registered depth (fx = fy = 525, cx = 319.5, cy = 239.5,
//      640x480); intrinsics_source says which.
//  - kSevenScenes: Microsoft 7-Scenes: frame-XXXXXX.{color.png|color.jpg, depth.png,
//      pose.txt} in the folder or its `frames/` subfolder, camera-intrinsics.txt (3x3 K) in
//      the folder, beside the frames or in their parent; depth uint16 mm (0 and 65535 =
//      invalid); pose.txt a 4x4 world_from_camera matrix; 30 Hz, frame time = index / 30 s.
//      The colour camera is not registered to depth in 7-Scenes: colour is an approximation.
//
// Frames: camera frame x right, y down, z forward (optical axis); depth is z (not ray
// length); pixel (u, v) has its centre at column u, row v; u = fx x / z + cx.
//
// Failures (InputError naming the file and the line or field): a folder that matches no
// layout; a missing list file, frame file or intrinsics; a malformed line, pose or
// intrinsics; a zero, negative or unknown depth scale; stamps that are not strictly
// increasing; an empty sequence. Every frame file is checked to exist when the sequence is
// read, so a command fails before any work. LoadRgbdFrame: an unreadable image, a depth
// image that is not 16-bit single channel, colour/depth size mismatch, or a size other than
// the intrinsics' resolution. Thread safety: all functions are reentrant; LoadRgbdFrame may
// run concurrently on one sequence.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "core/time.h"
#include "core/trajectory.h"

namespace lisfm {

enum class RgbdLayout { kAuto, kLisfm, kTum, kSevenScenes };

// "auto", "lisfm", "tum", "7scenes".
std::string RgbdLayoutName(RgbdLayout layout);
// Throws UsageError for an unknown name (message lists the valid names).
RgbdLayout ParseRgbdLayout(const std::string& name);

// Pinhole intrinsics of the depth image (colour is registered to it, except 7-Scenes).
struct RgbdIntrinsics {
  double fx = 0, fy = 0;      // focal lengths, pixels
  double cx = 0, cy = 0;      // principal point, pixels (centre of the top-left pixel = (0, 0))
  int width = 0, height = 0;  // pixels
};

// The intrinsics of every `factor`-th pixel (row and column 0, factor, 2 factor, ...), the
// grid LoadRgbdFrame returns for that factor: f / factor, c / factor, ceil(size / factor).
RgbdIntrinsics DownsampleIntrinsics(const RgbdIntrinsics& intrinsics, int factor);

struct RgbdFrameInfo {
  TimestampNs t_ns = 0;    // frame time (see the layouts), ns
  std::string color_path;  // full path of the colour image
  std::string depth_path;  // full path of the depth image
  // The data set's pose of this frame (world_from_camera, metres), when it has one.
  std::optional<SE3> world_from_camera;
};

struct RgbdSequence {
  RgbdLayout layout = RgbdLayout::kAuto;  // the layout that was read (never kAuto)
  std::string path;                       // the folder given to ReadRgbdSequence
  RgbdIntrinsics intrinsics;
  std::string intrinsics_source;      // file the intrinsics came from, or "TUM ROS default"
  double depth_m_per_unit = 0;        // metres per depth-image unit (0.001 = mm), > 0
  std::vector<RgbdFrameInfo> frames;  // strictly increasing t_ns, at least one
  std::string pose_source;            // file(s) the given poses came from; empty if none

  // Number of frames with a given pose.
  size_t NumGivenPoses() const;
  // The given poses (world_from_camera) of the frames that have one, at the frame times.
  Trajectory GivenTrajectory() const;
};

struct RgbdReadOptions {
  RgbdLayout layout = RgbdLayout::kAuto;  // kAuto: detect from the folder
  // Intrinsics file overriding the layout's: a lisfm camera.yaml (fields above) or a 3x3
  // K text file (7-Scenes camera-intrinsics.txt; then the resolution is the first depth
  // image's). Empty: the layout's own.
  std::string intrinsics_path;
  double depth_units_per_m = 0;        // overrides the layout's depth scale when > 0
  double association_max_dt_s = 0.02;  // TUM colour/depth pairing tolerance, s
  double pose_max_gap_s = 0.1;         // TUM / lisfm groundtruth: longest gap bridged when
                                       // interpolating a pose, s; frames in a longer gap have none
  bool Check() const;
};

// Reads the frame list, intrinsics, depth scale and given poses of `path` (no pixels).
RgbdSequence ReadRgbdSequence(const std::string& path, const RgbdReadOptions& options = {});

// One frame in metric units, row-major, on the grid of DownsampleIntrinsics(factor).
struct RgbdImage {
  int width = 0, height = 0;   // pixels
  std::vector<float> depth_m;  // width * height; z in metres, 0 = invalid
  std::vector<uint8_t> rgb;    // width * height * 3; R, G, B per pixel
};

// Loads frame `index` of `sequence`: depth unit * depth_m_per_unit (0 and, for 7-Scenes,
// 65535 stay 0), colour converted to RGB order. With factor > 1 both images are sampled at
// every factor-th pixel (no averaging across depth edges). Throws InputError (see above).
RgbdImage LoadRgbdFrame(const RgbdSequence& sequence, size_t index, int factor = 1);

}  // namespace lisfm
