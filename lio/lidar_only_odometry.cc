#include "lio/lidar_only_odometry.h"

#include <chrono>

#include <Eigen/Cholesky>

#include "icp/icp.h"

namespace lisfm {

namespace {

// Point-to-plane matches against the iVox map: the k nearest map points must
// fit a plane (the LIO's test); the match is the nearest one with that normal.
class VoxelMapTarget : public IcpTarget {
 public:
  VoxelMapTarget(const VoxelMap& map, const LioOptions& options) : map_(map), options_(options) {}

  bool Match(const Eigen::Vector3f& point,
             const Eigen::Vector3f& /*normal*/,
             const MatchCriteria& criteria,  // only max_distance_m: the planes are fitted here
             Eigen::Vector3f* target_point,
             Eigen::Vector3f* target_normal) const override {
    thread_local std::vector<Eigen::Vector3f> nbrs;
    thread_local std::vector<float> d2;
    const int n = map_.KnnSearch(point, options_.num_neighbours,
                                 std::min<double>(criteria.max_distance_m, options_.max_neighbour_distance),
                                 &nbrs, &d2);
    if (n < options_.num_neighbours) return false;
    Mat3 AtA = Mat3::Zero();
    Vec3 Atb = Vec3::Zero();
    for (const auto& q : nbrs) {
      AtA.noalias() += q.cast<double>() * q.cast<double>().transpose();
      Atb -= q.cast<double>();
    }
    const Vec3 nn = AtA.ldlt().solve(Atb);
    const double norm = nn.norm();
    if (!(norm > 1e-9) || !std::isfinite(norm)) return false;
    const Vec3 unit = nn / norm;
    for (const auto& q : nbrs) {
      if (std::abs(unit.dot(q.cast<double>()) + 1.0 / norm) > options_.max_plane_residual) return false;
    }
    *target_point = nbrs[0];
    *target_normal = unit.cast<float>();
    return true;
  }
  size_t size() const override { return map_.NumPoints(); }

 private:
  const VoxelMap& map_;
  const LioOptions& options_;
};

}  // namespace

LidarOnlyOdometry::LidarOnlyOdometry(const LioOptions& options,
                                     const SE3& imu_from_lidar,
                                     double time_offset_s)
    : options_(options),
      imu_from_lidar_(imu_from_lidar),
      time_offset_ns_(SecondsToNs(time_offset_s)),
      map_(std::make_unique<VoxelMap>(options.map)) {}

LidarOnlyOdometry::~LidarOnlyOdometry() = default;

LioFrameResult LidarOnlyOdometry::ProcessScan(const PointCloud& scan) {
  const auto start = std::chrono::steady_clock::now();
  LioFrameResult result;
  result.num_raw_points = static_cast<int>(scan.size());
  float tmax = 0;
  for (const auto& p : scan.points) tmax = std::max(tmax, p.t);
  const TimestampNs t_end = scan.stamp_ns + time_offset_ns_ + SecondsToNs(tmax);
  result.t_ns = t_end;
  if (scan.empty()) {
    result.message = "empty scan";
    return result;
  }
  // Constant-velocity prediction of the end pose and de-skew with the same twist.
  const double dt = have_previous_ ? NsToSeconds(t_end - previous_t_ns_) : 0.0;
  const SE3 predicted = previous_pose_ * SE3::Exp(velocity_ * dt);
  const PointCloud kept = VoxelDownsample(scan, options_.scan_voxel_size);
  PointSet body;
  body.reserve(kept.size());
  std::vector<MapPointAttributes> attributes;
  attributes.reserve(kept.size());
  const double min_r2 = options_.min_range * options_.min_range;
  const double max_r2 = options_.max_range * options_.max_range;
  for (const auto& p : kept.points) {
    const double r2 = p.xyzd().squaredNorm();
    if (r2 < min_r2 || r2 > max_r2) continue;
    const double dt_p = NsToSeconds(scan.stamp_ns + time_offset_ns_ + SecondsToNs(p.t) - t_end);
    const Vec3 x = SE3::Exp(velocity_ * dt_p) * (imu_from_lidar_ * p.xyzd());
    body.push_back(x.cast<float>());
    attributes.push_back({p.intensity, p.sensor_id});
  }
  result.num_downsampled = static_cast<int>(body.size());
  SE3 pose = predicted;
  if (map_->NumPoints() > 0 && body.size() >= 50) {
    IcpOptions icp;
    icp.max_correspondence_distance_m = 1.0;
    icp.kernel = "huber";
    icp.kernel_scale_m = 0.1;
    icp.max_iterations = 30;
    icp.coarse_stride = 1;
    const VoxelMapTarget target(*map_, options_);
    const IcpResult r = RegisterPointToPlane(body, target, predicted, icp);
    result.iterations = r.iterations;
    result.num_matched = static_cast<int>(r.num_inliers);
    if (r.num_inliers >= 50) pose = r.target_from_source;
    result.message = r.converged ? "" : r.message;
  }
  if (have_previous_ && dt > 0) velocity_ = (previous_pose_.Inverse() * pose).Log() / dt;
  previous_pose_ = pose;
  previous_t_ns_ = t_end;
  have_previous_ = true;
  std::vector<Eigen::Vector3f> world(body.size());
  for (size_t i = 0; i < body.size(); ++i) world[i] = (pose * body[i].cast<double>()).cast<float>();
  map_->Insert(world, &attributes);
  result.world_from_imu = pose;
  result.processed = true;
  result.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace lisfm
