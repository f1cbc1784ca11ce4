#include "lio/lio_odometry.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"
#include "lio/point_to_plane.h"

namespace lisfm {

namespace {

using Mat18 = Eigen::Matrix<double, 18, 18>;
using Vec18 = Eigen::Matrix<double, 18, 1>;
constexpr int kTheta = 0, kPos = 3, kVel = 6, kBg = 9, kBa = 12, kGrav = 15;
constexpr int64_t kMaxImuGapNs = 100000000;  // 0.1 s

// A plane n·x + d = 0 with |n| = 1 fitted to k points by least squares on
// A n' = -1 (FAST-LIO2's esti_plane), then checked against max_residual.
bool FitPlane(const std::vector<Eigen::Vector3f>& pts, double max_residual, Vec4* plane) {
  // Normal equations of A n' = -1 (3x3, fixed size: no allocation per point).
  Mat3 AtA = Mat3::Zero();
  Vec3 Atb = Vec3::Zero();
  for (const auto& p : pts) {
    const Vec3 q = p.cast<double>();
    AtA.noalias() += q * q.transpose();
    Atb -= q;
  }
  const Eigen::LDLT<Mat3> ldlt(AtA);
  if (ldlt.info() != Eigen::Success) return false;
  const Vec3 n = ldlt.solve(Atb);
  const double norm = n.norm();
  if (!(norm > 1e-9) || !std::isfinite(norm)) return false;
  const Vec3 unit = n / norm;
  const double d = 1.0 / norm;
  for (const auto& p : pts) {
    if (std::abs(unit.dot(p.cast<double>()) + d) > max_residual) return false;
  }
  *plane << unit, d;
  return true;
}

// Normal equations of one iteration with the calibration in the state: per
// LiDAR, HᵀH and Hᵀz over the 13 columns of lio/point_to_plane.h.
struct NormalCalibrated {
  using Mat13 = Eigen::Matrix<double, 13, 13>;
  using Vec13 = Eigen::Matrix<double, 13, 1>;
  std::vector<Mat13> HtH;
  std::vector<Vec13> Htz;
  int count = 0;
  double sum_sq = 0;
  explicit NormalCalibrated(size_t num_lidars = 0)
      : HtH(num_lidars, Mat13::Zero()), Htz(num_lidars, Vec13::Zero()) {}
  void Join(const NormalCalibrated& o) {
    for (size_t k = 0; k < HtH.size(); ++k) {
      HtH[k] += o.HtH[k];
      Htz[k] += o.Htz[k];
    }
    count += o.count;
    sum_sq += o.sum_sq;
  }
};

struct Normal6 {
  Mat6 HtH = Mat6::Zero();
  Vec6 Htz = Vec6::Zero();
  int count = 0;
  double sum_sq = 0;
  void Join(const Normal6& o) {
    HtH += o.HtH;
    Htz += o.Htz;
    count += o.count;
    sum_sq += o.sum_sq;
  }
};

}  // namespace

bool LioOptions::Check() const {
  CHECK_OPTION_GT(imu_noise_inflation, 0.0);
  CHECK_OPTION_GE(point_stride, 1);
  CHECK_OPTION_GE(scan_voxel_size, 0.0);
  CHECK_OPTION_GE(min_range, 0.0);
  CHECK_OPTION_GT(max_range, min_range);
  CHECK_OPTION_GE(num_neighbours, 3);
  CHECK_OPTION_GT(max_neighbour_distance, 0.0);
  CHECK_OPTION_GT(max_plane_residual, 0.0);
  CHECK_OPTION_GT(max_point_residual, 0.0);
  CHECK_OPTION_GT(point_noise_std, 0.0);
  CHECK_OPTION_GE(max_iterations, 1);
  CHECK_OPTION_GT(convergence_rotation, 0.0);
  CHECK_OPTION_GT(convergence_translation, 0.0);
  CHECK_OPTION_GE(reassociate_translation, 0.0);
  CHECK_OPTION_GE(reassociate_rotation, 0.0);
  CHECK_OPTION_GE(degeneracy_threshold, 0.0);
  CHECK_OPTION_NESTED(map);
  CHECK_OPTION_GT(keyframe_distance, 0.0);
  CHECK_OPTION_GT(keyframe_angle_deg, 0.0);
  CHECK_OPTION_NESTED(init);
  CHECK_OPTION_GT(extrinsic_rotation_std_deg, 0.0);
  CHECK_OPTION_GT(extrinsic_translation_std, 0.0);
  CHECK_OPTION_GT(time_offset_std_ms, 0.0);
  CHECK_OPTION_GT(gyro_scale_std, 0.0);
  return true;
}

LioOdometry::LioOdometry(const LioOptions& options,
                         const ImuNoise& imu_noise,
                         std::vector<SE3> imu_from_lidar,
                         std::vector<double> lidar_time_offsets_s)
    : options_(options),
      imu_noise_(imu_noise),
      imu_from_lidar_(std::move(imu_from_lidar)),
      lidar_time_offsets_s_(std::move(lidar_time_offsets_s)),
      map_(std::make_unique<VoxelMap>(options.map)) {
  if (!options_.Check()) {
    throw InputError("lio: invalid options: " + LastOptionCheckFailure().ToString());
  }
  THROW_CHECK_EQ(imu_from_lidar_.size(), lidar_time_offsets_s_.size());
  if (imu_from_lidar_.empty()) throw InputError("lio: no LiDAR extrinsics given");
  P_.setZero();
  const int num_lidars = static_cast<int>(imu_from_lidar_.size());
  calibration_block_ =
      (options_.estimate_extrinsic ? 6 : 0) + (options_.estimate_time_offset ? 1 : 0);
  time_offset_change_s_.assign(num_lidars, 0.0);
  int num_calib = num_lidars * calibration_block_;
  if (options_.estimate_gyro_scale) {
    gyro_scale_index_ = num_calib;
    num_calib += 9;
  }
  P_core_calib_ = Eigen::MatrixXd::Zero(18, num_calib);
  P_calib_ = Eigen::MatrixXd::Zero(num_calib, num_calib);
  if (gyro_scale_index_ >= 0) {
    P_calib_.diagonal()
        .segment<9>(gyro_scale_index_)
        .setConstant(options_.gyro_scale_std * options_.gyro_scale_std);
  }
  const double rot_var = std::pow(options_.extrinsic_rotation_std_deg * M_PI / 180.0, 2);
  const double trans_var = std::pow(options_.extrinsic_translation_std, 2);
  const double time_var = std::pow(options_.time_offset_std_ms * 1e-3, 2);
  for (int k = 0; k < num_lidars; ++k) {
    const int base = k * calibration_block_;
    if (options_.estimate_extrinsic) {
      P_calib_.diagonal().segment<3>(base).setConstant(rot_var);
      P_calib_.diagonal().segment<3>(base + 3).setConstant(trans_var);
    }
    if (options_.estimate_time_offset) {
      const int i = base + calibration_block_ - 1;
      P_calib_(i, i) = time_var;
    }
  }
}

LioOdometry::~LioOdometry() = default;

TimestampNs LioOdometry::LatestImuTime() const { return last_imu_time_; }

std::vector<LidarCalibrationEstimate> LioOdometry::LidarCalibration() const {
  std::vector<LidarCalibrationEstimate> out(imu_from_lidar_.size());
  for (size_t k = 0; k < out.size(); ++k) {
    LidarCalibrationEstimate& c = out[k];
    c.imu_from_lidar = imu_from_lidar_[k];
    c.time_offset_s = lidar_time_offsets_s_[k] + time_offset_change_s_[k];
    c.extrinsic_estimated = options_.estimate_extrinsic;
    c.time_offset_estimated = options_.estimate_time_offset;
    const int base = static_cast<int>(k) * calibration_block_;
    if (options_.estimate_extrinsic) {
      c.rotation_std_rad = P_calib_.diagonal().segment<3>(base).cwiseSqrt();
      c.translation_std_m = P_calib_.diagonal().segment<3>(base + 3).cwiseSqrt();
    }
    if (options_.estimate_time_offset) {
      const int i = base + calibration_block_ - 1;
      c.time_offset_std_s = std::sqrt(P_calib_(i, i));
    }
  }
  return out;
}

TimestampNs LioOdometry::TimeOffsetLookaheadNs() const {
  TimestampNs lookahead = 0;
  for (size_t k = 0; k < time_offset_change_s_.size(); ++k) {
    const TimestampNs shift = SecondsToNs(lidar_time_offsets_s_[k] + time_offset_change_s_[k]) -
                              SecondsToNs(lidar_time_offsets_s_[k]);
    lookahead = std::max(lookahead, shift);
  }
  return lookahead;
}

void LioOdometry::AddImu(const ImuSample& sample) {
  if (sample.t_ns <= last_imu_time_) {
    throw InputError(fmt::format("IMU time stamps not increasing: {} after {} ns", sample.t_ns,
                                 last_imu_time_));
  }
  if (!sample.gyro.allFinite() || !sample.accel.allFinite()) {
    throw InputError(fmt::format("IMU sample at {} ns is not finite", sample.t_ns));
  }
  if (last_imu_time_ != INT64_MIN && sample.t_ns - last_imu_time_ > kMaxImuGapNs) {
    LogWarning("IMU gap of {:.3f} s before t = {} ns; frames spanning it are not updated",
               NsToSeconds(sample.t_ns - last_imu_time_), sample.t_ns);
  }
  last_imu_time_ = sample.t_ns;
  if (!initialized_) {
    init_samples_.push_back(sample);
    TryInitialize();
    return;
  }
  imu_buffer_.push_back(sample);
}

bool LioOdometry::TryInitialize() {
  const TimestampNs span = init_samples_.back().t_ns - init_samples_.front().t_ns;
  if (span < SecondsToNs(options_.init.min_duration_s)) return false;
  init_ = InitializeFromStaticImu(init_samples_, options_.init);
  if (!init_.success) {
    // Not static at the start: initialise anyway from the mean specific force,
    // as FAST-LIO2 does, and say so.
    ImuInitializerOptions relaxed = options_.init;
    relaxed.max_accel_std = relaxed.max_gyro_std = 1e9;
    const std::string why = init_.message;
    init_ = InitializeFromStaticImu(init_samples_, relaxed);
    if (!init_.success) return false;
    init_.gyro_bias.setZero();
    LogWarning("lio: {}; initialised without a static period (gyro bias 0)", why);
  }
  LogInfo("lio: {}", init_.message);
  initialized_ = true;
  state_t_ns_ = init_.t_ns;
  R_ = init_.world_from_imu;
  p_.setZero();
  v_.setZero();
  bg_ = init_.gyro_bias;
  ba_.setZero();
  g_ = init_.gravity_world;
  // Initial uncertainty: tilt from the static average, yaw/position define the
  // world frame (gauge, tiny), biases from their typical ranges.
  P_.setZero();
  P_.block<2, 2>(kTheta, kTheta) = Eigen::Matrix2d::Identity() * 1e-4;
  P_(kTheta + 2, kTheta + 2) = 1e-6;
  P_.block<3, 3>(kPos, kPos) = Mat3::Identity() * 1e-6;
  P_.block<3, 3>(kVel, kVel) = Mat3::Identity() * 1e-4;
  P_.block<3, 3>(kBg, kBg) = Mat3::Identity() * 1e-6;
  P_.block<3, 3>(kBa, kBa) = Mat3::Identity() * 1e-2;
  P_.block<3, 3>(kGrav, kGrav) = Mat3::Identity() * 1e-6;
  for (const auto& s : init_samples_) {
    if (s.t_ns == init_.t_ns) {
      last_imu_ = s;
      have_last_imu_ = true;
    } else if (s.t_ns > init_.t_ns) {
      imu_buffer_.push_back(s);
    }
  }
  init_samples_.clear();
  return true;
}

void LioOdometry::PropagateStep(const Vec3& gyro, const Vec3& accel, double dt) {
  const Vec3 w = gyro - bg_ - gyro_scale_ * gyro;
  const Vec3 a = accel * init_.accel_scale - ba_;
  const Mat3 R = R_.toRotationMatrix();
  const Vec3 a_world = R * a + g_;
  // Mean.
  p_ += v_ * dt + 0.5 * a_world * dt * dt;
  v_ += a_world * dt;
  R_ = (R_ * so3::Exp(w * dt)).normalized();
  // Covariance: P = F P Fᵀ + Q (right-perturbation error dynamics).
  Mat18 F = Mat18::Identity();
  F.block<3, 3>(kTheta, kTheta) = so3::ExpMatrix(-w * dt);
  F.block<3, 3>(kTheta, kBg) = -so3::RightJacobian(w * dt) * dt;
  F.block<3, 3>(kPos, kVel) = Mat3::Identity() * dt;
  F.block<3, 3>(kVel, kTheta) = -R * Hat(a) * dt;
  F.block<3, 3>(kVel, kBa) = -R * dt;
  F.block<3, 3>(kVel, kGrav) = Mat3::Identity() * dt;
  const double k = options_.imu_noise_inflation;
  const double sg = imu_noise_.gyroscope_noise_density * k;
  const double sa = imu_noise_.accelerometer_noise_density * k;
  const double sbg = imu_noise_.gyroscope_random_walk * k;
  const double sba = imu_noise_.accelerometer_random_walk * k;
  P_ = F * P_ * F.transpose();
  // The calibration is constant: only its cross-covariance moves. (A
  // coefficient-wise product: 18 x K·block is too small for a blocked GEMM.)
  if (P_core_calib_.cols() > 0) P_core_calib_ = F.lazyProduct(P_core_calib_);
  if (gyro_scale_index_ >= 0) {
    // The augmented transition [[F, G], [0, I]], G = d dθ / d vec(E) =
    // -J_r(w dt) dt [gyro_x I, gyro_y I, gyro_z I] in the θ rows (w = gyro - bg - E gyro):
    // P_core += A Gᵀ + G Aᵀ + G P_EE Gᵀ and P_core_E = A + G P_EE, with A = F P_core_E.
    Eigen::Matrix<double, 3, 9> G;
    const Mat3 J = -so3::RightJacobian(w * dt) * dt;
    for (int j = 0; j < 3; ++j) G.middleCols<3>(3 * j) = J * gyro(j);
    const int e = gyro_scale_index_;
    const Eigen::Matrix<double, 18, 3> AGt = P_core_calib_.middleCols<9>(e) * G.transpose();
    const Mat3 GPGt = G * P_calib_.block<9, 9>(e, e) * G.transpose();
    P_.middleCols<3>(kTheta) += AGt;
    P_.middleRows<3>(kTheta) += AGt.transpose();
    P_.block<3, 3>(kTheta, kTheta) += GPGt;
    P_core_calib_.middleRows<3>(kTheta) += G * P_calib_.middleRows<9>(e);
  }
  P_.block<3, 3>(kTheta, kTheta).diagonal().array() += sg * sg * dt;
  P_.block<3, 3>(kVel, kVel).diagonal().array() += sa * sa * dt;
  P_.block<3, 3>(kBg, kBg).diagonal().array() += sbg * sbg * dt;
  P_.block<3, 3>(kBa, kBa).diagonal().array() += sba * sba * dt;
}

bool LioOdometry::PropagateTo(TimestampNs t_ns, std::vector<PoseSample>* history) {
  if (last_imu_time_ < t_ns || !have_last_imu_) return false;
  auto record = [&](const Vec3& gyro_mean, const Vec3& acc_mean) {
    PoseSample s;
    s.t_ns = state_t_ns_;
    s.R = R_;
    s.p = p_;
    s.v = v_;
    s.omega = gyro_mean - bg_ - gyro_scale_ * gyro_mean;
    s.acc_world = R_ * (acc_mean * init_.accel_scale - ba_) + g_;
    history->push_back(s);
  };
  while (state_t_ns_ < t_ns) {
    THROW_CHECK(!imu_buffer_.empty());
    const ImuSample& next = imu_buffer_.front();
    const Vec3 gyro = 0.5 * (last_imu_.gyro + next.gyro);
    const Vec3 acc = 0.5 * (last_imu_.accel + next.accel);
    const TimestampNs seg_end = std::min(next.t_ns, t_ns);
    const double dt = NsToSeconds(seg_end - state_t_ns_);
    record(gyro, acc);
    if (dt > 0) PropagateStep(gyro, acc, dt);
    state_t_ns_ = seg_end;
    if (seg_end == next.t_ns) {
      last_imu_ = next;
      imu_buffer_.pop_front();
    }
  }
  // Closing sample at t_ns (zero-length segment, rates of the last segment).
  if (!history->empty()) {
    PoseSample end = history->back();
    end.t_ns = state_t_ns_;
    end.R = R_;
    end.p = p_;
    end.v = v_;
    history->push_back(end);
  }
  return true;
}

std::optional<SE3> LioOdometry::Predict(TimestampNs t_ns) {
  if (!initialized_ || t_ns < state_t_ns_) return std::nullopt;
  std::vector<PoseSample> history;
  if (!PropagateTo(t_ns, &history)) return std::nullopt;
  return SE3(R_, p_);
}

std::vector<Keyframe> LioOdometry::TakeKeyframes() {
  std::vector<Keyframe> out;
  out.swap(keyframes_);
  return out;
}

LioFrameResult LioOdometry::ProcessFrame(const std::vector<LidarScanInput>& scans) {
  const auto wall_start = std::chrono::steady_clock::now();
  LioFrameResult result;
  // Absolute IMU-clock time of every point; the frame ends at the latest one.
  // Each LiDAR's time offset: the given one plus the current estimate's change.
  std::vector<TimestampNs> offsets_ns(imu_from_lidar_.size());
  for (size_t k = 0; k < offsets_ns.size(); ++k) {
    offsets_ns[k] = SecondsToNs(lidar_time_offsets_s_[k] + time_offset_change_s_[k]);
  }
  TimestampNs t_begin = INT64_MAX, t_end = INT64_MIN;
  for (const auto& s : scans) {
    THROW_CHECK(s.cloud != nullptr);
    if (s.sensor_id < 0 || s.sensor_id >= static_cast<int>(imu_from_lidar_.size())) {
      throw InputError(fmt::format("lio: scan from unknown LiDAR {} (the rig has {})", s.sensor_id,
                                   imu_from_lidar_.size()));
    }
    result.num_raw_points += static_cast<int>(s.cloud->size());
    const TimestampNs offset = offsets_ns[s.sensor_id];
    for (const auto& p : s.cloud->points) {
      const TimestampNs t = s.cloud->stamp_ns + offset + SecondsToNs(p.t);
      t_begin = std::min(t_begin, t);
      t_end = std::max(t_end, t);
    }
  }
  result.t_ns = t_end;
  if (result.num_raw_points == 0) {
    result.message = "empty scan";
    return result;
  }
  if (!initialized_) {
    result.message = "waiting for the IMU initialisation";
    return result;
  }
  if (t_end <= state_t_ns_) {
    result.message = "scan ends before the current filter time";
    return result;
  }
  if (last_imu_time_ < t_end) {
    result.message = fmt::format("scan outside IMU coverage (ends {:.3f} s after the last IMU sample)",
                                 NsToSeconds(t_end - last_imu_time_));
    return result;
  }
  // IMU gap inside the frame interval?
  bool gap = false;
  {
    TimestampNs prev = last_imu_.t_ns;
    // Up to and including the first sample after t_end (it bounds the last segment).
    for (const auto& s : imu_buffer_) {
      if (s.t_ns - prev > kMaxImuGapNs) gap = true;
      if (s.t_ns > t_end) break;
      prev = s.t_ns;
    }
  }

  // 1. Propagate to the frame end, keeping the poses for de-skew.
  std::vector<PoseSample> history;
  history.reserve(64);
  PropagateTo(t_end, &history);
  const SE3 world_from_imu_pred(R_, p_);
  const SE3 imu_end_from_world = world_from_imu_pred.Inverse();
  if (gap) {
    result.message = "IMU gap > 0.1 s inside the frame: prediction only";
    result.world_from_imu = world_from_imu_pred;
    result.velocity = v_;
    return result;
  }

  // 2. De-skew to the frame end, in the IMU frame. The pose at a point's time
  // is the propagated pose of its IMU segment moved forward by that segment's
  // rates (FAST-LIO2's backward propagation). Points sharing a time stamp (a
  // spinning LiDAR fires its rings together) share one transform.
  struct SegmentLookup {
    const std::vector<PoseSample>& history;
    const SE3& imu_end_from_world;
    // imu_end_from_lidar at absolute time t for extrinsic T_il.
    Eigen::Matrix<double, 3, 4> At(TimestampNs t, const SE3& T_il) const {
      auto it = std::upper_bound(history.begin(), history.end(), t,
                                 [](TimestampNs v, const PoseSample& ps) { return v < ps.t_ns; });
      const PoseSample& seg = (it == history.begin()) ? history.front() : *(it - 1);
      const double dt = NsToSeconds(t - seg.t_ns);
      const SE3 world_from_imu_t(seg.R * so3::Exp(seg.omega * dt),
                                 seg.p + seg.v * dt + 0.5 * seg.acc_world * dt * dt);
      return (imu_end_from_world * world_from_imu_t * T_il).Matrix3x4();
    }
  };
  const SegmentLookup lookup{history, imu_end_from_world};
  const double min_r2 = options_.min_range * options_.min_range;
  const double max_r2 = options_.max_range * options_.max_range;
  // De-skews `in` (sensor frame) into `out` (appended), dropping out-of-range points.
  auto deskew = [&](const LidarScanInput& s, const std::vector<LidarPoint>& in, PointCloud* out) {
    const SE3& T_il = imu_from_lidar_[s.sensor_id];
    const TimestampNs offset = offsets_ns[s.sensor_id];
    const size_t base = out->points.size();
    out->points.resize(base + in.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, in.size(), 2048),
                      [&](const tbb::blocked_range<size_t>& r) {
      float cached_t = std::numeric_limits<float>::quiet_NaN();
      Eigen::Matrix<double, 3, 4> A = Eigen::Matrix<double, 3, 4>::Zero();
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const LidarPoint& p_in = in[i];
        LidarPoint& p_out = out->points[base + i];
        p_out = p_in;
        const Vec3 x_l = p_in.xyzd();
        const double r2 = x_l.squaredNorm();
        if (!x_l.allFinite() || r2 < min_r2 || r2 > max_r2) {
          p_out.x = p_out.y = p_out.z = std::numeric_limits<float>::quiet_NaN();
          continue;
        }
        const TimestampNs t = s.cloud->stamp_ns + offset + SecondsToNs(p_in.t);
        if (!(p_in.t == cached_t)) {
          A = lookup.At(t, T_il);
          cached_t = p_in.t;
        }
        const Vec3 x_end = A.leftCols<3>() * x_l + A.col(3);
        p_out.x = static_cast<float>(x_end.x());
        p_out.y = static_cast<float>(x_end.y());
        p_out.z = static_cast<float>(x_end.z());
        p_out.t = static_cast<float>(NsToSeconds(t - t_end));
        p_out.sensor_id = static_cast<uint8_t>(s.sensor_id);
      }
    });
  };
  // Down-sample in the sensor frame first (the distortion within one voxel is
  // a few cm at walking speed), so only the kept points need de-skewing.
  PointCloud down;
  down.stamp_ns = t_end;
  for (const auto& s : scans) {
    PointCloud strided;
    const PointCloud* input = s.cloud;
    if (options_.point_stride > 1) {  // FAST-LIO2's point_filter_num
      strided.points.reserve(s.cloud->size() / options_.point_stride + 1);
      for (size_t i = 0; i < s.cloud->size(); i += options_.point_stride) {
        strided.points.push_back(s.cloud->points[i]);
      }
      input = &strided;
    }
    const PointCloud kept = VoxelDownsample(*input, options_.scan_voxel_size);
    deskew(s, kept.points, &down);
  }
  RemoveNonFinite(&down);
  result.num_downsampled = static_cast<int>(down.size());
  std::vector<Eigen::Vector3f> body(down.size());
  std::vector<MapPointAttributes> attributes(down.size());
  for (size_t i = 0; i < down.size(); ++i) {
    body[i] = down.points[i].xyz();
    attributes[i] = {down.points[i].intensity, down.points[i].sensor_id};
  }
  // The full de-skewed cloud, computed only when a keyframe needs it.
  auto full_deskewed = [&]() {
    PointCloud full;
    full.stamp_ns = t_end;
    for (const auto& s : scans) deskew(s, s.cloud->points, &full);
    RemoveNonFinite(&full);
    return full;
  };

  auto insert_into_map = [&](const SE3& pose) {
    std::vector<Eigen::Vector3f> world(body.size());
    const Eigen::Matrix3f R = pose.RotationMatrix().cast<float>();
    const Eigen::Vector3f t = pose.translation().cast<float>();
    for (size_t i = 0; i < body.size(); ++i) world[i] = R * body[i] + t;
    map_->Insert(world, &attributes);
  };

  auto finish = [&](const SE3& pose) {
    result.world_from_imu = pose;
    result.velocity = v_;
    result.processed = true;
    const bool kf = !have_keyframe_ ||
                    (pose.translation() - last_keyframe_pose_.translation()).norm() >=
                        options_.keyframe_distance ||
                    so3::AngularDistance(pose.rotation(), last_keyframe_pose_.rotation()) >=
                        options_.keyframe_angle_deg * M_PI / 180.0;
    if (kf) {
      Keyframe k;
      k.t_ns = t_end;
      k.world_from_imu = pose;
      // De-skewed with the predicted motion inside the scan; the update moves the
      // end pose, which the keyframe stores separately.
      k.cloud_in_imu = full_deskewed();
      keyframes_.push_back(std::move(k));
      last_keyframe_pose_ = pose;
      have_keyframe_ = true;
      result.is_keyframe = true;
    }
    result.time_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall_start)
            .count();
  };

  if (!map_initialized_) {
    if (body.size() < 50) {
      result.message = "too few points to start the map";
      return result;
    }
    insert_into_map(world_from_imu_pred);
    map_initialized_ = true;
    result.message = "first scan: map initialised";
    finish(world_from_imu_pred);
    return result;
  }

  // 3. Iterated update (information form).
  const Quat R_pred = R_;
  const Vec3 p_pred = p_, v_pred = v_, bg_pred = bg_, ba_pred = ba_, g_pred = g_;
  const Mat3 gyro_scale_pred = gyro_scale_;
  const double inv_var = 1.0 / (options_.point_noise_std * options_.point_noise_std);
  std::vector<Vec4> planes(body.size());
  std::vector<char> plane_ok(body.size(), 0);

  // With the calibration in the state (lio/point_to_plane.h): the prior is the
  // calibration the frame was de-skewed with; the iterate of LiDAR k is
  // (q_e[k], t_e[k]) and the time-offset change dt_d[k] since the prior.
  // The gyro intrinsics have no measurement columns: with them alone the
  // points give the 6x6 pose information of the 18-state filter, solved with
  // the extra states (`extra_states`).
  const bool calibrate = calibration_block_ > 0;
  const bool extra_states = P_calib_.rows() > 0;
  const size_t num_lidars = imu_from_lidar_.size();
  const int num_states = 18 + static_cast<int>(P_calib_.rows());
  std::vector<Quat> q_e(num_lidars);
  std::vector<Vec3> t_e(num_lidars);
  std::vector<double> dt_d(num_lidars, 0.0);
  std::vector<Vec3> x_lidar;  // body points in their LiDAR's frame at t_end
  BodyRates rates;
  Eigen::MatrixXd P_inv_full;
  Mat18 P_inv;
  if (calibrate) {
    rates.angular_velocity = history.back().omega;
    rates.velocity = v_pred;
    std::vector<SE3> lidar_from_imu(num_lidars);
    for (size_t k = 0; k < num_lidars; ++k) {
      q_e[k] = imu_from_lidar_[k].rotation();
      t_e[k] = imu_from_lidar_[k].translation();
      lidar_from_imu[k] = imu_from_lidar_[k].Inverse();
    }
    x_lidar.resize(body.size());
    for (size_t i = 0; i < body.size(); ++i) {
      x_lidar[i] = lidar_from_imu[attributes[i].sensor_id] * body[i].cast<double>();
    }
  }
  if (extra_states) {
    Eigen::MatrixXd P_full(num_states, num_states);
    P_full << P_, P_core_calib_, P_core_calib_.transpose(), P_calib_;
    P_inv_full = P_full.ldlt().solve(Eigen::MatrixXd::Identity(num_states, num_states));
  } else {
    P_inv = P_.ldlt().solve(Mat18::Identity());
  }
  // The measurement state of each LiDAR at pose (R, t) and the current iterate.
  auto calibrated_poses = [&](const Mat3& R, const Vec3& t) {
    std::vector<CalibratedPose> poses(num_lidars);
    for (size_t k = 0; k < num_lidars; ++k) {
      poses[k].world_R_imu = R;
      poses[k].world_p_imu = t;
      poses[k].imu_R_lidar = q_e[k].toRotationMatrix();
      poses[k].imu_p_lidar = t_e[k];
      poses[k].time_offset_change_s = dt_d[k];
    }
    return poses;
  };

  auto associate = [&](const Mat3& R, const Vec3& t) {
    const std::vector<CalibratedPose> poses = calibrate ? calibrated_poses(R, t)
                                                        : std::vector<CalibratedPose>();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, body.size(), 256),
                      [&](const tbb::blocked_range<size_t>& r) {
      std::vector<Eigen::Vector3f> nbrs;
      std::vector<float> d2;
      nbrs.reserve(options_.num_neighbours);
      d2.reserve(options_.num_neighbours);
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const Vec3 pw = calibrate ? CalibratedPointInWorld(poses[attributes[i].sensor_id], rates,
                                                           x_lidar[i])
                                  : Vec3(R * body[i].cast<double>() + t);
        plane_ok[i] = 0;
        const int n = map_->KnnSearch(pw.cast<float>(), options_.num_neighbours,
                                      options_.max_neighbour_distance, &nbrs, &d2);
        if (n < options_.num_neighbours) continue;
        if (FitPlane(nbrs, options_.max_plane_residual, &planes[i])) plane_ok[i] = 1;
      }
    });
  };

  // FAST-LIO2's gate (closer points must fit tighter) and an absolute one:
  // across a 0.17 m stair riser, or at a step edge where the 5 neighbours span
  // a tread and a riser, the range-relative gate alone admits biased matches
  // that pull the pose down the stairs. `range`: the point's distance from the IMU.
  auto keep_match = [&](double res, double range) {
    if (1.0 - 0.9 * std::abs(res) / std::sqrt(range) <= 0.9) return false;
    return !(std::abs(res) > options_.max_point_residual);
  };

  // Deterministic: fixed 512-point chunks summed in a fixed tree, so the
  // floating-point sum does not depend on the thread schedule or count.
  auto accumulate = [&](const Mat3& R, const Vec3& t) {
    return tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, body.size(), 512), Normal6(),
        [&](const tbb::blocked_range<size_t>& r, Normal6 acc) {
          for (size_t i = r.begin(); i < r.end(); ++i) {
            if (!plane_ok[i]) continue;
            const Vec3 pb = body[i].cast<double>();
            const Vec3 pw = R * pb + t;
            const Vec3 n = planes[i].head<3>();
            const double res = n.dot(pw) + planes[i](3);
            if (!keep_match(res, pb.norm())) continue;
            Vec6 h;
            h.head<3>() = -(R * Hat(pb)).transpose() * n;  // d res / d θ (right perturbation)
            h.tail<3>() = n;                               // d res / d p
            acc.HtH.noalias() += h * h.transpose();
            acc.Htz.noalias() += h * res;
            acc.count += 1;
            acc.sum_sq += res * res;
          }
          return acc;
        },
        [](Normal6 a, const Normal6& b) {
          a.Join(b);
          return a;
        });
  };
  auto accumulate_calibrated = [&](const Mat3& R, const Vec3& t) {
    const std::vector<CalibratedPose> poses = calibrated_poses(R, t);
    return tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, body.size(), 512), NormalCalibrated(num_lidars),
        [&](const tbb::blocked_range<size_t>& r, NormalCalibrated acc) {
          CalibratedPointJacobian h;
          Vec3 q;
          for (size_t i = r.begin(); i < r.end(); ++i) {
            if (!plane_ok[i]) continue;
            const int k = attributes[i].sensor_id;
            const double res =
                CalibratedPointToPlaneResidual(poses[k], rates, x_lidar[i], planes[i], &h, &q);
            if (!keep_match(res, q.norm())) continue;
            acc.HtH[k].noalias() += h * h.transpose();
            acc.Htz[k].noalias() += h * res;
            acc.count += 1;
            acc.sum_sq += res * res;
          }
          return acc;
        },
        [](NormalCalibrated a, const NormalCalibrated& b) {
          a.Join(b);
          return a;
        });
  };
  // Adds each LiDAR's HᵀR⁻¹H to the information matrix `A` over the full
  // error state and, optionally, −HᵀR⁻¹z to `b`.
  auto add_calibrated_information = [&](const NormalCalibrated& nc, Eigen::MatrixXd* A,
                                        Eigen::VectorXd* b) {
    for (size_t k = 0; k < num_lidars; ++k) {
      const int base = 18 + static_cast<int>(k) * calibration_block_;
      // Column j of the 13 of lio/point_to_plane.h -> index in the error state (-1: not estimated).
      int index[13];
      for (int j = 0; j < 13; ++j) {
        if (j < 6) {
          index[j] = j;  // kTheta = 0, kPos = 3: the same order
        } else if (j < 12) {
          index[j] = options_.estimate_extrinsic ? base + j - 6 : -1;
        } else {
          index[j] = options_.estimate_time_offset ? base + calibration_block_ - 1 : -1;
        }
      }
      const NormalCalibrated::Mat13& HtH = nc.HtH[k];
      for (int i = 0; i < 13; ++i) {
        if (index[i] < 0) continue;
        for (int j = 0; j < 13; ++j) {
          if (index[j] >= 0) (*A)(index[i], index[j]) += HtH(i, j) * inv_var;
        }
        if (b != nullptr) (*b)(index[i]) -= nc.Htz[k](i) * inv_var;
      }
    }
  };
  // The pose block of the calibrated normal equations (count, degeneracy).
  auto pose_block = [&](const NormalCalibrated& nc) {
    Normal6 n;
    for (size_t k = 0; k < num_lidars; ++k) {
      n.HtH += nc.HtH[k].topLeftCorner<6, 6>();
      n.Htz += nc.Htz[k].head<6>();
    }
    n.count = nc.count;
    n.sum_sq = nc.sum_sq;
    return n;
  };

  // One Gauss-Newton step at the current iterate: fills `normal` and returns
  // false when fewer than 6 points match; `delta_calib` gets the calibration
  // states' step.
  Normal6 normal;
  NormalCalibrated normal_calib;
  auto solve_step = [&](Vec18* delta, Eigen::VectorXd* delta_calib) {
    Vec18 d;
    d.segment<3>(kTheta) = so3::Log(R_pred.conjugate() * R_);
    d.segment<3>(kPos) = p_ - p_pred;
    d.segment<3>(kVel) = v_ - v_pred;
    d.segment<3>(kBg) = bg_ - bg_pred;
    d.segment<3>(kBa) = ba_ - ba_pred;
    d.segment<3>(kGrav) = g_ - g_pred;
    if (!extra_states) {
      normal = accumulate(R_.toRotationMatrix(), p_);
      if (normal.count < 6) return false;
      Mat18 A = P_inv;
      A.topLeftCorner<6, 6>() += normal.HtH * inv_var;
      Vec18 b = -P_inv * d;
      b.head<6>() -= normal.Htz * inv_var;
      *delta = A.ldlt().solve(b);
      return true;
    }
    if (calibrate) {
      normal_calib = accumulate_calibrated(R_.toRotationMatrix(), p_);
      normal = pose_block(normal_calib);
    } else {
      normal = accumulate(R_.toRotationMatrix(), p_);
    }
    if (normal.count < 6) return false;
    Eigen::VectorXd d_full = Eigen::VectorXd::Zero(num_states);
    d_full.head<18>() = d;
    for (size_t k = 0; k < num_lidars; ++k) {
      const int base = 18 + static_cast<int>(k) * calibration_block_;
      if (options_.estimate_extrinsic) {
        d_full.segment<3>(base) = so3::Log(imu_from_lidar_[k].rotation().conjugate() * q_e[k]);
        d_full.segment<3>(base + 3) = t_e[k] - imu_from_lidar_[k].translation();
      }
      if (options_.estimate_time_offset) d_full(base + calibration_block_ - 1) = dt_d[k];
    }
    if (gyro_scale_index_ >= 0) {
      const Mat3 dE = gyro_scale_ - gyro_scale_pred;
      d_full.segment<9>(18 + gyro_scale_index_) =
          Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dE.data());
    }
    Eigen::MatrixXd A = P_inv_full;
    Eigen::VectorXd b = -P_inv_full * d_full;
    if (calibrate) {
      add_calibrated_information(normal_calib, &A, &b);
    } else {
      A.topLeftCorner<6, 6>() += normal.HtH * inv_var;
      b.head<6>() -= normal.Htz * inv_var;
    }
    const Eigen::VectorXd step = A.ldlt().solve(b);
    *delta = step.head<18>();
    *delta_calib = step.tail(num_states - 18);
    return true;
  };

  bool converged = false;
  bool searched_after_convergence = false;
  associate(R_.toRotationMatrix(), p_);
  Quat R_assoc = R_;
  Vec3 p_assoc = p_;
  int it = 0;
  for (; it < options_.max_iterations; ++it) {
    Vec18 delta;
    Eigen::VectorXd delta_calib;
    if (!solve_step(&delta, &delta_calib)) break;
    if (!delta.allFinite() || !delta_calib.allFinite()) break;
    R_ = (R_ * so3::Exp(delta.segment<3>(kTheta))).normalized();
    p_ += delta.segment<3>(kPos);
    v_ += delta.segment<3>(kVel);
    bg_ += delta.segment<3>(kBg);
    ba_ += delta.segment<3>(kBa);
    g_ += delta.segment<3>(kGrav);
    for (size_t k = 0; calibrate && k < num_lidars; ++k) {
      const int base = static_cast<int>(k) * calibration_block_;
      if (options_.estimate_extrinsic) {
        q_e[k] = (q_e[k] * so3::Exp(delta_calib.segment<3>(base))).normalized();
        t_e[k] += delta_calib.segment<3>(base + 3);
      }
      if (options_.estimate_time_offset) dt_d[k] += delta_calib(base + calibration_block_ - 1);
    }
    if (gyro_scale_index_ >= 0) {
      gyro_scale_ += Eigen::Map<const Mat3>(delta_calib.segment<9>(gyro_scale_index_).data());
    }
    const bool small = delta.segment<3>(kTheta).norm() < options_.convergence_rotation &&
                       delta.segment<3>(kPos).norm() < options_.convergence_translation;
    if (small) {
      if (searched_after_convergence) {
        converged = true;
        ++it;
        break;
      }
      // Re-associate once at the converged pose, then iterate again (FAST-LIO2),
      // unless the pose barely moved since the last association: then the
      // same neighbours would be found and the result is already converged.
      if ((p_ - p_assoc).norm() < options_.reassociate_translation &&
          so3::AngularDistance(R_, R_assoc) < options_.reassociate_rotation) {
        converged = true;
        ++it;
        break;
      }
      associate(R_.toRotationMatrix(), p_);
      R_assoc = R_;
      p_assoc = p_;
      searched_after_convergence = true;
    }
  }
  result.iterations = it;
  if (normal.count < 6) {
    // No usable planes: keep the IMU prediction (degenerate / feature-less)
    // and the calibration.
    R_ = R_pred;
    p_ = p_pred;
    v_ = v_pred;
    bg_ = bg_pred;
    ba_ = ba_pred;
    g_ = g_pred;
    gyro_scale_ = gyro_scale_pred;
    result.message = "no valid point-to-plane matches: IMU prediction only";
    result.degeneracy.num_weak = 6;
    const SE3 pose(R_, p_);
    insert_into_map(pose);
    finish(pose);
    result.processed = false;
    return result;
  }
  // Posterior covariance at the final linearisation.
  if (!extra_states) {
    normal = accumulate(R_.toRotationMatrix(), p_);
    Mat18 A = P_inv;
    A.topLeftCorner<6, 6>() += normal.HtH * inv_var;
    P_ = A.ldlt().solve(Mat18::Identity());
    P_ = 0.5 * (P_ + P_.transpose()).eval();
  } else {
    Eigen::MatrixXd A = P_inv_full;
    if (calibrate) {
      normal_calib = accumulate_calibrated(R_.toRotationMatrix(), p_);
      normal = pose_block(normal_calib);
      add_calibrated_information(normal_calib, &A, nullptr);
    } else {
      normal = accumulate(R_.toRotationMatrix(), p_);
      A.topLeftCorner<6, 6>() += normal.HtH * inv_var;
    }
    Eigen::MatrixXd P_full = A.ldlt().solve(Eigen::MatrixXd::Identity(num_states, num_states));
    P_full = 0.5 * (P_full + P_full.transpose()).eval();
    P_ = P_full.topLeftCorner<18, 18>();
    P_core_calib_ = P_full.topRightCorner(18, num_states - 18);
    P_calib_ = P_full.bottomRightCorner(num_states - 18, num_states - 18);
  }
  result.num_matched = normal.count;

  // Degeneracy: eigenvalues of the information the points gave.
  Eigen::SelfAdjointEigenSolver<Mat6> eig(normal.HtH / static_cast<double>(normal.count));
  result.degeneracy.eigenvalues = eig.eigenvalues();
  result.degeneracy.weakest_direction = eig.eigenvectors().col(0);
  for (int i = 0; i < 6; ++i) {
    if (eig.eigenvalues()(i) < options_.degeneracy_threshold) ++result.degeneracy.num_weak;
  }
  if (!converged) result.message = "iteration limit reached";

  const SE3 pose(R_, p_);
  if (!pose.translation().allFinite() || !pose.rotation().coeffs().allFinite()) {
    throw InternalError("lio: non-finite pose after the update");
  }
  if (calibrate) {
    // The map gets the points at the updated calibration; later frames (and
    // this frame's keyframe cloud) are de-skewed with it.
    const std::vector<CalibratedPose> poses =
        calibrated_poses(pose.RotationMatrix(), pose.translation());
    std::vector<Eigen::Vector3f> world(body.size());
    for (size_t i = 0; i < body.size(); ++i) {
      world[i] = CalibratedPointInWorld(poses[attributes[i].sensor_id], rates, x_lidar[i])
                     .cast<float>();
    }
    map_->Insert(world, &attributes);
    for (size_t k = 0; k < num_lidars; ++k) {
      if (options_.estimate_extrinsic) imu_from_lidar_[k] = SE3(q_e[k], t_e[k]);
      time_offset_change_s_[k] += dt_d[k];
    }
  } else {
    insert_into_map(pose);
  }
  finish(pose);
  return result;
}

}  // namespace lisfm
