// FAST-LIO2-style LiDAR-inertial odometry (Xu et al., "FAST-LIO2", T-RO 2022):
// IMU forward propagation of an error-state Kalman filter, per-point de-skew by
// backward interpolation of the propagated poses, and an iterated update in
// information form against an incremental iVox map (lio/voxel_map.h).
//
// State x = (R, p, v, bg, ba, g): world_from_imu rotation and position, world
// velocity, gyro and accelerometer biases (body frame), gravity (world). The
// 18-dim error state is [dθ, dp, dv, dbg, dba, dg]; rotation is perturbed on the
// right, R = R̂·Exp(dθ) (DESIGN.md). Units: rad, m, s.
//
// The iterated update is the Gauss-Newton form of the IEKF (FAST-LIO2 Eq. 18,
// with the boxminus Jacobian taken as identity): at iterate x_k with
// d = x_k ⊟ x̂, solve (P⁻¹ + HᵀR⁻¹H) δ = −P⁻¹ d − HᵀR⁻¹ z, x_{k+1} = x_k ⊞ δ.
// H has only the 6 pose columns non-zero, so the cost per iteration is one pass
// over the points to accumulate the 6x6 HᵀH, then an 18x18 solve: it grows with
// the state size, not the number of points.
//
// Online calibration (options estimate_extrinsic / estimate_time_offset): the
// error state grows by a block per LiDAR k, [dθ_e, dt_e] (imu_from_lidar, rotation
// on the right, translation in the IMU frame; FAST-LIO2's `extrinsic_est_en`)
// and/or dt_d (s, added to the rig's time offset: t_imu = t_lidar + offset + t_d).
// The calibration is constant (no process noise); its prior is the rig's value
// with the *_std options as 1-sigma. The measurement model and its Jacobian
// are in lio/point_to_plane.h; per point H gains the 7 columns of its LiDAR,
// accumulated as one 13x13 HᵀH per LiDAR. Points are de-skewed with the
// estimate of the previous frame; the map and keyframes get the updated one.
// Observability: the time offset shows in the motion distortion and the
// extrinsic rotation in the gyro rates; the extrinsic translation only through
// the lever-arm accelerations the IMU feels when the rig turns (a LiDAR-only
// fit moves the position instead), so it converges slowly at the inflated IMU
// noise, and the map built before convergence keeps the initial error
// (docs/BENCHMARKS.md).
//
// Gyroscope intrinsics (option estimate_gyro_scale, on by default): the rate
// model is measured = (I + E) true + bias, E the 3x3 scale-factor and
// cross-axis error matrix, so the propagation uses w = gyro - bg - E·gyro (to
// first order in E) and vec(E) (column-major) is a constant block of 9 states
// after the LiDAR calibration ones, with the transition coupling
// d dθ / d vec(E) = -J_r(w dt) dt [gyro_x I, gyro_y I, gyro_z I]. The LiDAR
// sees E only through the attitude it corrects after turns (no measurement
// columns); it shares the calibrated update above. With every estimation off
// the filter is the 18-state one above, bit for bit.
//
// Threading: AddImu/ProcessFrame are called from one thread; ProcessFrame uses
// TBB internally for de-skew and residuals. Results are bit-identical run to
// run and for any thread count: the per-point sums of the update are reduced
// over fixed chunks in a fixed order (tbb::parallel_deterministic_reduce).
#pragma once

#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "core/point_cloud.h"
#include "core/rig.h"
#include "core/sensor_data.h"
#include "lio/imu.h"
#include "lio/voxel_map.h"

namespace lisfm {

struct LioOptions {
  // IMU process noise: the rig's continuous-time densities times this factor
  // (absorbs discretisation and vibration; FAST-LIO2 uses far larger values).
  double imu_noise_inflation = 10.0;
  int point_stride = 2;             // keep every n-th raw point before down-sampling (1 = all)
  double scan_voxel_size = 0.4;     // m, down-sampling of each scan
  double min_range = 0.5;           // m, points closer to the sensor are dropped (blind)
  double max_range = 100.0;         // m
  int num_neighbours = 5;           // k of the plane fit
  double max_neighbour_distance = 2.2;  // m, the 5th neighbour must be closer (sqrt 5 m^2)
  // m, every neighbour must be this close to the plane. FAST-LIO2 uses 0.1,
  // which passes "planes" fitted across a step edge (tread + riser), tilted
  // and biased; 0.05 is still 5 sigma of the 1 cm range noise.
  double max_plane_residual = 0.05;
  // m, a point farther than this from its plane is not used, on top of
  // FAST-LIO2's range-relative gate |r| < sqrt(range)/9 (which admits
  // 0.2-0.3 m at 4-8 m): a point on a tread not yet in the map would otherwise
  // match the tread one 0.17 m riser below, always pulling the pose down the
  // stairs. 4 sigma of the range noise; office/hall accuracy is unchanged.
  double max_point_residual = 0.04;
  double point_noise_std = 0.03;    // m, point-to-plane measurement std (FAST-LIO2: sqrt(0.001))
  int max_iterations = 4;           // IEKF iterations per scan
  double convergence_rotation = 1e-4;     // rad, stop when the step is below both
  double convergence_translation = 1e-3;  // m
  // After convergence the neighbours are searched again only if the pose moved
  // more than this since the last search (0 = always, as FAST-LIO2 does).
  double reassociate_translation = 0.01;  // m
  double reassociate_rotation = 0.0035;   // rad (0.2 deg)
  // Degeneracy test on the geometry of one scan, independent of its point
  // count: eigenvalues of HᵀH/N over [θ; p] (N matched points). The
  // translation part is the spread of the plane normals: 1/3 each for a
  // perfect box, near 0 along a corridor axis. A direction is weak below this
  // value. Simulated office/hall scans: 10th percentile ~0.11; staircase: median ~0.02.
  double degeneracy_threshold = 0.05;
  VoxelMapOptions map;              // the incremental map
  double keyframe_distance = 1.0;   // m between keyframes
  double keyframe_angle_deg = 15.0; // or this much rotation
  ImuInitializerOptions init;
  // Online LiDAR–IMU calibration (see the header comment). Prior 1-sigma of
  // the rig's values: FAST-LIO2 starts its extrinsic at 0.18 deg / 3.2 mm.
  bool estimate_extrinsic = false;          // imu_from_lidar of every LiDAR
  bool estimate_time_offset = false;        // time offset of every LiDAR
  double extrinsic_rotation_std_deg = 0.5;  // deg
  double extrinsic_translation_std = 0.01;  // m
  double time_offset_std_ms = 5.0;          // ms
  // Online gyroscope intrinsics: the error matrix E of the rates, measured =
  // (I + E) true + bias (per-axis scale on the diagonal, cross-axis
  // sensitivity off it), as 9 constant states with the prior 1-sigma
  // gyro_scale_std per entry (Bosch BMI085 datasheet: sensitivity tolerance
  // and cross-axis sensitivity 1 % typ). Unmodelled, E tilts the attitude by
  // |E| x the turn angle on every turn (1-4 deg over a 180 deg turn at 1-2 %),
  // which the LiDAR must correct; where it constrains the attitude weakly
  // (narrow stairwells) the tilt leaks gravity into the velocity and the
  // filter diverges (docs/notes/lio_stairwell.md).
  bool estimate_gyro_scale = true;
  double gyro_scale_std = 0.01;  // fraction, 1-sigma per entry of E
  bool Check() const;
};

// The LiDAR–IMU calibration the filter holds for one LiDAR.
struct LidarCalibrationEstimate {
  SE3 imu_from_lidar;             // current estimate (the given value when not estimated)
  double time_offset_s = 0;       // t_imu = t_lidar + time_offset_s
  bool extrinsic_estimated = false;
  bool time_offset_estimated = false;
  // 1-sigma of the filter covariance; 0 when not estimated. Rotation about
  // the LiDAR axes (right perturbation, rad), translation in the IMU frame (m).
  Vec3 rotation_std_rad = Vec3::Zero();
  Vec3 translation_std_m = Vec3::Zero();
  double time_offset_std_s = 0;
};

// Which directions one update constrained weakly.
struct DegeneracyReport {
  Vec6 eigenvalues = Vec6::Zero();  // of HᵀH/N over [θ; p] (N matched points), ascending
  int num_weak = 0;                 // eigenvalues below the threshold
  Vec6 weakest_direction = Vec6::Zero();
};

struct LioFrameResult {
  bool processed = false;      // false: skipped (message says why)
  std::string message;
  TimestampNs t_ns = 0;        // frame end time: the pose's time stamp
  SE3 world_from_imu;
  Vec3 velocity = Vec3::Zero();
  int num_raw_points = 0;
  int num_downsampled = 0;
  int num_matched = 0;         // points with a valid plane in the last iteration
  int iterations = 0;
  double time_ms = 0;
  DegeneracyReport degeneracy;
  bool is_keyframe = false;
};

struct Keyframe {
  TimestampNs t_ns = 0;
  SE3 world_from_imu;
  PointCloud cloud_in_imu;  // de-skewed to t_ns, in the IMU (body) frame
};

class LioOdometry {
 public:
  // `imu_from_lidar[k]` and time offsets (t_imu = t_lidar + offset) per sensor.
  LioOdometry(const LioOptions& options,
              const ImuNoise& imu_noise,
              std::vector<SE3> imu_from_lidar,
              std::vector<double> lidar_time_offsets_s);
  ~LioOdometry();

  // IMU samples must arrive in strictly increasing time; throws InputError otherwise.
  void AddImu(const ImuSample& sample);
  TimestampNs LatestImuTime() const;

  // IMU-only prediction: propagates the state (mean and covariance) to t_ns
  // without a LiDAR update and returns world_from_imu; nullopt before the
  // initialisation or when the IMU does not cover t_ns yet.
  std::optional<SE3> Predict(TimestampNs t_ns);

  // Processes one frame (LidarFrame::Inputs(); sensor_id indexes the
  // extrinsics given to the constructor). Every point's absolute time must be
  // covered by IMU data already added (otherwise the frame is skipped with a
  // message).
  LioFrameResult ProcessFrame(const std::vector<LidarScanInput>& scans);

  bool initialized() const { return initialized_; }
  const ImuInitialization& initialization() const { return init_; }
  const VoxelMap& map() const { return *map_; }
  // Keyframes produced since the last call (moved out).
  std::vector<Keyframe> TakeKeyframes();
  // 18x18 covariance of the error state after the last update.
  const Eigen::Matrix<double, 18, 18>& covariance() const { return P_; }
  const Vec3& gyro_bias() const { return bg_; }
  const Vec3& accel_bias() const { return ba_; }
  // The gyroscope error matrix E (zero unless estimate_gyro_scale).
  const Mat3& gyro_scale_error() const { return gyro_scale_; }
  // Per LiDAR given to the constructor (estimated or not).
  std::vector<LidarCalibrationEstimate> LidarCalibration() const;
  // ns by which the estimated time offsets move points later than the given
  // ones (>= 0; 0 when not estimated): a frame needs IMU data up to its end
  // computed with the given offsets plus this (lio/imu_feeder.h adds it).
  TimestampNs TimeOffsetLookaheadNs() const;

 private:
  struct PoseSample {
    TimestampNs t_ns;
    Quat R;
    Vec3 p, v, acc_world, omega;  // omega: bias-corrected body rate over the segment
  };
  bool TryInitialize();
  // Propagates mean and covariance to t_ns using buffered IMU samples,
  // appending pose samples for de-skew. Returns false if IMU does not cover t_ns.
  bool PropagateTo(TimestampNs t_ns, std::vector<PoseSample>* history);
  void PropagateStep(const Vec3& gyro, const Vec3& accel, double dt);

  LioOptions options_;
  ImuNoise imu_noise_;
  std::vector<SE3> imu_from_lidar_;           // current estimate
  std::vector<double> lidar_time_offsets_s_;  // as given
  // Online calibration: states per LiDAR in the error state after the 18 core
  // ones (6 extrinsic, then 1 time offset; 0 = off), the time-offset estimate
  // minus the given offset (s), and the covariance blocks: core x calibration
  // (18 x K·block) and calibration x calibration.
  int calibration_block_ = 0;
  std::vector<double> time_offset_change_s_;
  Eigen::MatrixXd P_core_calib_;
  Eigen::MatrixXd P_calib_;
  // With estimate_gyro_scale, E's 9 states (column-major vec(E)) follow the
  // LiDAR calibration states: index into the calibration blocks above, or -1.
  int gyro_scale_index_ = -1;
  Mat3 gyro_scale_ = Mat3::Zero();
  std::deque<ImuSample> imu_buffer_;   // samples not yet consumed by propagation
  std::vector<ImuSample> init_samples_;
  ImuSample last_imu_;                 // last sample consumed (for mid-point integration)
  bool have_last_imu_ = false;
  TimestampNs last_imu_time_ = INT64_MIN;
  bool initialized_ = false;
  ImuInitialization init_;

  // State.
  TimestampNs state_t_ns_ = 0;
  Quat R_ = Quat::Identity();
  Vec3 p_ = Vec3::Zero(), v_ = Vec3::Zero(), bg_ = Vec3::Zero(), ba_ = Vec3::Zero();
  Vec3 g_ = Vec3(0, 0, -9.81);
  Eigen::Matrix<double, 18, 18> P_;

  std::unique_ptr<VoxelMap> map_;
  bool map_initialized_ = false;
  SE3 last_keyframe_pose_;
  bool have_keyframe_ = false;
  std::vector<Keyframe> keyframes_;
};

}  // namespace lisfm
