// `lisfm simulate` as a library call: scene + motion + IMU + LiDARs + cameras
// (+ optional RGB-D) written as a sequence folder (DESIGN.md "Formats";
// docs/FORMATS_sequence.md describes the folder as built).
//
// Frames and times: the world is the scene frame (z up, gravity -z); the body
// is the IMU frame; all stamps are int64 ns, read on the IMU clock with the
// written rig.yaml, whose camera and LiDAR time offsets are 0. Generated
// sequences start at kDefaultStartNs; sequences driven by a TUM file keep its
// stamps.
//
// Error sources (`error_sources`, each with its own sizes; all of them off
// with noise_scale 0, and "none" gives the clean recording: white noise and
// bias random walk only):
//  - calibration (sim/calibration_errors.h): the LiDARs and cameras are
//    simulated with true extrinsics and time offsets that differ from the
//    written rig.yaml; truth/rig.yaml holds the true calibration. A sensor
//    stamp t was captured at IMU time t + (truth offset - rig.yaml offset);
//    poses outside the trajectory are those at its ends (generated walks
//    start and end at rest).
//  - imu (sim/imu_errors.h): scale factor, misalignment and temperature bias
//    drift of the IMU; truth/imu_errors.yaml holds the drawn values.
//  - lidar (sim/lidar_simulator.h): incidence-dependent range noise, mixed
//    pixels at depth edges, material intensity, dropouts and maximum ranges,
//    acting on the points cast at the true time with the true extrinsic.
//  - camera (sim/camera_errors.h): auto-exposure and gain, sensor noise,
//    motion blur over the exposure (poses at the true capture times
//    with the true extrinsic), room and time lighting; texture-poor surfaces
//    through the materials (sim/materials.h).
//  - dynamics (sim/people.h): people walk the scene's route; every LiDAR ray
//    and camera frame sees them at its own (true) time; truth/people.csv has
//    their tracks.
// A source named explicitly for a sensor the recording does not have is an
// error.
//
// Output goes through core's OutputFolder: checked before the work, written
// into `<output_path>.tmp-<pid>` and renamed at the end, so a failed run never
// leaves a folder that looks complete; `overwrite` replaces only an earlier
// lisfm output (a folder holding the .lisfm_output marker). Deterministic for a
// given seed (TBB only changes the order of work, never the values).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/rig.h"
#include "core/time.h"
#include "sim/calibration_errors.h"
#include "sim/camera_errors.h"
#include "sim/imu_errors.h"
#include "sim/lidar_simulator.h"
#include "sim/materials.h"
#include "sim/motion.h"
#include "sim/people.h"

namespace lisfm {
namespace sim {

constexpr TimestampNs kDefaultStartNs = 1700000000LL * kNsPerSecond;

struct SimulatorOptions {
  std::string scene = "office";   // office | staircase | hall | site | configs/sim_*.yaml path
  std::string trajectory_path;    // optional TUM file of real motion (world_from_imu)
  double duration = 60.0;         // s; with a TUM file: at most its length (<= 0: all of it)
  double camera_rate = 2.0;       // Hz, rig frames per second (0 = no cameras)
  std::string lidars = "spinning";  // comma list of spinning, livox (or "none")
  double noise_scale = 1.0;         // multiplies every sensor noise, bias and error (0 = exact)
  int seed = 1;                   // scene layout, texture, motion and noise seed
  std::string output_path;        // the sequence folder to create
  int supersampling = 1;          // camera rays per pixel = n x n
  bool color = false;             // colour (BGR) instead of grayscale images
  bool rgbd = false;              // add an RGB-D camera (rgbd0/)
  double rgbd_rate = 5.0;         // Hz
  bool overwrite = false;         // replace an earlier lisfm output folder at output_path
  std::string error_sources = "all";          // comma list of ErrorSourceNames(), or all / none
  CalibrationErrorOptions calibration_error;  // sizes of the `calibration` source
  ImuErrorOptions imu_error;                  // sizes of the `imu` source
  LidarErrorOptions lidar_errors;    // the `lidar` source (sim/lidar_simulator.h)
  CameraErrorOptions camera_errors;  // the `camera` source (sim/camera_errors.h)
  MaterialOptions materials;         // surface materials (sim/materials.h)
  WalkingOptions walk;               // generated motion (not used with trajectory_path)
  DynamicsOptions dynamics;          // the `dynamics` source: people walking through the scene

  bool Check() const;
};

// The error source tokens of SimulatorOptions::error_sources.
const std::vector<std::string>& ErrorSourceNames();
// True when `source` (one of ErrorSourceNames()) is named in `error_sources`
// or it is "all". Throws InternalError for an unknown `source`.
bool ErrorSourceEnabled(const std::string& error_sources, const std::string& source);

// A HILTI-style control point: the pole tip world_from_imu * kPoleTipInImu
// (HILTI 2022 evaluation, REFERENCES.md sec. 7) at the middle of a rest.
inline const Vec3 kPoleTipInImu(0.059, -0.00855, 0.1964);
struct ControlPoint {
  TimestampNs t_ns = 0;
  Vec3 position = Vec3::Zero();  // scene frame, m
};
// One control point per stationary period inside [start_ns, end_ns], at its
// middle, in time order.
std::vector<ControlPoint> SurveyControlPoints(const SplineTrajectory& trajectory,
                                              const std::vector<StationaryPeriod>& stationary,
                                              TimestampNs start_ns,
                                              TimestampNs end_ns);

struct SimulationSummary {
  std::string scene_type;
  double duration_s = 0;
  double path_length_m = 0;
  size_t num_imu = 0;
  std::vector<size_t> num_scans;       // per LiDAR
  std::vector<size_t> num_points;      // per LiDAR, all scans
  size_t num_images = 0;               // all cameras
  size_t num_rgbd = 0;
  size_t num_control_points = 0;
  size_t num_triangles = 0;
  size_t num_people = 0;
  double seconds_scene = 0, seconds_imu = 0, seconds_lidar = 0, seconds_cameras = 0,
         seconds_total = 0;
  // Breakdown in CPU seconds summed over threads (thread CPU clocks, so other
  // load on the machine does not inflate them): LiDAR ray casting + point
  // generation, PCD writing, camera rendering, PNG encoding + writing.
  double cpu_lidar_cast = 0, cpu_lidar_write = 0, cpu_camera_render = 0, cpu_camera_write = 0;
};

// Adapts `rig` to the requested LiDAR list: keeps the rig's LiDAR of each
// requested type, adds a default one where the rig has none (spinning: the
// HILTI 2022 XT-32 mounting; livox: kLivoxImuFromLidar), drops the others,
// and sets all time offsets to 0 (the folder's stamps are on the IMU clock).
Rig PrepareRig(const Rig& rig, const std::string& lidars);

// Runs the simulation and writes the folder. `before_commit` (optional) is
// called with the temporary folder before the final rename (e.g. to write the
// effective config). Throws InputError/UsageError for bad input.
SimulationSummary Simulate(const SimulatorOptions& options,
                           const Rig& rig,
                           const std::function<void(const std::string&)>& before_commit = {});

}  // namespace sim
}  // namespace lisfm
