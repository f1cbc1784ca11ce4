#include "sim/lidar_simulator.h"

#include <cmath>
#include <random>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {
namespace sim {
namespace {

float Intensity(const Texture& texture, const RayHit& hit,
                const Eigen::Vector3f& point, const Eigen::Vector3f& direction) {
  const float cos_incidence = std::fabs(hit.normal.dot(direction));
  const float albedo = texture.FootprintAlbedo(hit.surface_id, point, TextureAxis(hit.normal));
  return std::fmin(255.f, 255.f * albedo * (0.2f + 0.8f * cos_incidence));
}

}  // namespace

bool LidarSimOptions::Check() const {
  CHECK_OPTION_GE(noise_scale, 0.0);
  CHECK_OPTION_GE(range_sigma, 0.0);
  CHECK_OPTION_GE(azimuth_steps, 1);
  CHECK_OPTION_GT(livox_rate, 0.0);
  CHECK_OPTION_MSG(livox_fov_deg, livox_fov_deg > 0 && livox_fov_deg <= 180, "in (0, 180]");
  return true;
}

LidarSimulator::LidarSimulator(const Scene& scene,
                               const SplineTrajectory& trajectory,
                               const RigLidar& lidar,
                               const TextureOptions& texture,
                               const LidarSimOptions& options)
    : scene_(scene), trajectory_(trajectory), lidar_(lidar), texture_(texture),
      options_(options) {
  THROW_CHECK_GT(lidar_.scan_rate, 0.0);
  THROW_CHECK_OPTIONS(options_);
}

double LidarSimulator::RingElevation(int ring) const {
  return (-16.0 + ring) * M_PI / 180.0;
}

PointCloud LidarSimulator::SimulateScan(TimestampNs scan_start_ns, int64_t scan_index) const {
  std::mt19937_64 rng(options_.seed * 0x9E3779B97F4A7C15ULL +
                      static_cast<uint64_t>(scan_index) * 0xBF58476D1CE4E5B9ULL + 5);
  std::normal_distribution<double> normal(0.0, options_.range_sigma * options_.noise_scale);
  const bool noisy = options_.noise_scale > 0;
  const double period_s = 1.0 / lidar_.scan_rate;
  struct Raw {
    LidarPoint point;
    double t_s;  // since scan_start_ns
  };
  std::vector<Raw> raw;
  const float min_range = static_cast<float>(lidar_.min_range);
  const float max_range = static_cast<float>(lidar_.max_range);
  auto add_point = [&](const RayHit& hit, const SE3& world_from_lidar, const Vec3& dir_lidar,
                       const Vec3& dir_world, double t_s, int ring) {
    if (!hit.hit) return;
    double range = hit.distance;
    const Eigen::Vector3f hit_world =
        (world_from_lidar.translation() + range * dir_world).cast<float>();
    if (noisy) range += normal(rng);
    if (range < min_range || range > max_range) return;
    Raw r;
    const Vec3 p = dir_lidar * range;
    r.point.x = static_cast<float>(p.x());
    r.point.y = static_cast<float>(p.y());
    r.point.z = static_cast<float>(p.z());
    r.point.intensity = Intensity(texture_, hit, hit_world, dir_world.cast<float>());
    r.point.ring = static_cast<uint16_t>(ring);
    r.t_s = t_s;
    raw.push_back(r);
  };
  if (lidar_.type == LidarType::kSpinning) {
    THROW_CHECK_GT(lidar_.rings, 0);
    const int columns = options_.azimuth_steps;
    raw.reserve(static_cast<size_t>(columns) * lidar_.rings);
    std::vector<double> cos_el(lidar_.rings), sin_el(lidar_.rings);
    for (int r = 0; r < lidar_.rings; ++r) {
      cos_el[r] = std::cos(RingElevation(r));
      sin_el[r] = std::sin(RingElevation(r));
    }
    for (int c = 0; c < columns; ++c) {
      const double t_s = period_s * c / columns;
      const TimestampNs t_ns = scan_start_ns + SecondsToNs(t_s);
      const SE3 world_from_lidar = trajectory_.Pose(t_ns) * lidar_.imu_from_lidar;
      const double az = 2 * M_PI * c / columns;
      const double cos_az = std::cos(az), sin_az = std::sin(az);
      const float origin[3] = {static_cast<float>(world_from_lidar.translation().x()),
                               static_cast<float>(world_from_lidar.translation().y()),
                               static_cast<float>(world_from_lidar.translation().z())};
      const Mat3 rot = world_from_lidar.RotationMatrix();
      for (int r0 = 0; r0 < lidar_.rings; r0 += 16) {
        int valid[16];
        float dirs[16][3];
        Vec3 dirs_lidar[16], dirs_world[16];
        for (int k = 0; k < 16; ++k) {
          const int r = r0 + k;
          valid[k] = r < lidar_.rings;
          dirs_lidar[k] = valid[k] ? Vec3(cos_el[r] * cos_az, cos_el[r] * sin_az, sin_el[r])
                                   : Vec3::UnitX();
          dirs_world[k] = rot * dirs_lidar[k];
          for (int j = 0; j < 3; ++j) dirs[k][j] = static_cast<float>(dirs_world[k][j]);
        }
        RayHit hits[16];
        scene_.Intersect16At(t_ns, valid, origin, dirs, max_range + 1.f, /*coherent=*/false,
                             hits);
        for (int k = 0; k < 16; ++k) {
          if (!valid[k]) continue;
          add_point(hits[k], world_from_lidar, dirs_lidar[k], dirs_world[k], t_s, r0 + k);
        }
      }
    }
  } else {
    const int n = static_cast<int>(std::floor(options_.livox_rate * period_s));
    raw.reserve(n);
    const double half_fov = 0.5 * options_.livox_fov_deg * M_PI / 180.0;
    // Rosette frequencies (Hz), incommensurate so the pattern never repeats.
    const double f1 = 97.31, f2 = 163.87;
    const double scan_start_s = NsToSeconds(scan_start_ns - trajectory_.start_ns());
    for (int i = 0; i < n; ++i) {
      const double t_s = i / options_.livox_rate;
      const double tau = scan_start_s + t_s;
      const double r1 = 2 * M_PI * f1 * tau, r2 = 2 * M_PI * f2 * tau;
      const double a = 0.5 * half_fov * (std::cos(r1) + std::cos(r2));
      const double b = 0.5 * half_fov * (std::sin(r1) - std::sin(r2));
      const double theta = std::hypot(a, b), phi = std::atan2(b, a);
      const Vec3 dir_lidar(std::cos(theta), std::sin(theta) * std::cos(phi),
                           std::sin(theta) * std::sin(phi));
      const TimestampNs t_ns = scan_start_ns + SecondsToNs(t_s);
      const SE3 world_from_lidar = trajectory_.Pose(t_ns) * lidar_.imu_from_lidar;
      const Vec3 dir_world = world_from_lidar.rotation() * dir_lidar;
      const RayHit hit = scene_.IntersectAt(t_ns, world_from_lidar.translation(), dir_world, 0.0,
                                            lidar_.max_range + 1.0);
      add_point(hit, world_from_lidar, dir_lidar, dir_world, t_s, 0);
    }
  }
  PointCloud cloud;
  if (raw.empty()) {
    cloud.stamp_ns = scan_start_ns;
    return cloud;
  }
  const double first_s = raw.front().t_s;
  cloud.stamp_ns = scan_start_ns + SecondsToNs(first_s);
  cloud.points.reserve(raw.size());
  for (Raw& r : raw) {
    r.point.t = static_cast<float>(r.t_s - first_s);
    cloud.points.push_back(r.point);
  }
  return cloud;
}

}  // namespace sim
}  // namespace lisfm
