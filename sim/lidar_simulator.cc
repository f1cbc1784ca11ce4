#include "sim/lidar_simulator.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "core/errors.h"
#include "core/option_check.h"
#include "sim/hash_random.h"

namespace lisfm {
namespace sim {
namespace {

float Intensity(const Texture& texture, const RayHit& hit,
                const Eigen::Vector3f& point, const Eigen::Vector3f& direction) {
  const float cos_incidence = std::fabs(hit.normal.dot(direction));
  const float albedo = texture.FootprintAlbedo(hit.surface_id, point, TextureAxis(hit.normal));
  return std::fmin(255.f, 255.f * albedo * (0.2f + 0.8f * cos_incidence));
}

// Solid-state direction (LiDAR frame, unit) at `tau` s since the trajectory
// start: two incommensurate prism rotations (97.31 and 163.87 Hz), so the
// rosette never repeats; `half_fov` in rad.
Vec3 RosetteDirection(double tau, double half_fov) {
  const double f1 = 97.31, f2 = 163.87;
  const double r1 = 2 * M_PI * f1 * tau, r2 = 2 * M_PI * f2 * tau;
  const double a = 0.5 * half_fov * (std::cos(r1) + std::cos(r2));
  const double b = 0.5 * half_fov * (std::sin(r1) - std::sin(r2));
  const double theta = std::hypot(a, b), phi = std::atan2(b, a);
  return Vec3(std::cos(theta), std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi));
}

// Streams of the counter-based draws of one beam.
enum Stream : uint64_t { kEdgeDraw = 1, kDropoutDraw = 2, kNoiseDraw = 3 };

// One cast beam of a scan (error-source path), before the error model.
struct Beam {
  Eigen::Vector3f direction;        // unit, LiDAR frame
  Eigen::Vector3f normal;           // unit surface normal facing the sensor, LiDAR frame
  double t_s = 0;                   // firing time since the scan start
  float range = 0;                  // m; 0 = no hit
  float cos_incidence = 1;
  float reflectivity = 0;           // apparent reflectivity
  float albedo_intensity = 0;       // the intensity without error sources
  MaterialId material = 0;
  uint16_t ring = 0;
};

// A surface seen within one beam footprint: its fraction of the footprint,
// range, apparent reflectivity, incidence and material.
struct Echo {
  float fraction, range, reflectivity, cos_incidence;
  MaterialId material;
};

constexpr float kEdgeMinOffset = 0.02f;  // m off the beam's own plane: a depth edge

}  // namespace

float ApparentReflectivity(const Material& material, float texture_albedo, float cos_incidence) {
  const float m = MaterialAlbedo(material, texture_albedo) / material.albedo;
  const float c2 = cos_incidence * cos_incidence, c4 = c2 * c2, c8 = c4 * c4, c16 = c8 * c8;
  return material.reflectivity * m * cos_incidence + material.specularity * c16 * c4;
}

bool LidarErrorOptions::Check() const {
  CHECK_OPTION_GE(incidence_noise_gain, 0.0);
  CHECK_OPTION_GE(beam_divergence_mrad, 0.0);
  CHECK_OPTION_GE(mixed_pixel_max_separation_m, 0.0);
  CHECK_OPTION_GE(range_at_10_percent_m, 0.0);
  CHECK_OPTION_MSG(dropout_reflectivity, dropout_reflectivity >= 0 && dropout_reflectivity <= 1,
                   "in [0, 1]");
  return true;
}

bool LidarSimOptions::Check() const {
  CHECK_OPTION_GE(noise_scale, 0.0);
  CHECK_OPTION_GE(range_sigma, 0.0);
  CHECK_OPTION_GE(azimuth_steps, 1);
  CHECK_OPTION_GT(livox_rate, 0.0);
  CHECK_OPTION_MSG(livox_fov_deg, livox_fov_deg > 0 && livox_fov_deg <= 180, "in (0, 180]");
  CHECK_OPTION_NESTED(errors);
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

size_t LidarSimulator::NumBeams() const {
  if (lidar_.type == LidarType::kSpinning) {
    return static_cast<size_t>(options_.azimuth_steps) * static_cast<size_t>(lidar_.rings);
  }
  return static_cast<size_t>(std::floor(options_.livox_rate * (1.0 / lidar_.scan_rate)));
}

template <typename Visit>
void LidarSimulator::CastBeams(TimestampNs scan_start_ns, float spinning_max_cast,
                               double solid_state_max_cast, Visit&& visit) const {
  const double period_s = 1.0 / lidar_.scan_rate;
  const TimestampNs capture_start_ns = scan_start_ns + SecondsToNs(lidar_.time_offset_s);
  if (lidar_.type == LidarType::kSpinning) {
    THROW_CHECK_GT(lidar_.rings, 0);
    const int columns = options_.azimuth_steps;
    const int rings = lidar_.rings;
    std::vector<double> cos_el(rings), sin_el(rings);
    for (int r = 0; r < rings; ++r) {
      cos_el[r] = std::cos(RingElevation(r));
      sin_el[r] = std::sin(RingElevation(r));
    }
    for (int c = 0; c < columns; ++c) {
      const double t_s = period_s * c / columns;
      const TimestampNs t_ns = capture_start_ns + SecondsToNs(t_s);
      const SE3 world_from_lidar = trajectory_.Pose(t_ns) * lidar_.imu_from_lidar;
      const double az = 2 * M_PI * c / columns;
      const double cos_az = std::cos(az), sin_az = std::sin(az);
      const float origin[3] = {static_cast<float>(world_from_lidar.translation().x()),
                               static_cast<float>(world_from_lidar.translation().y()),
                               static_cast<float>(world_from_lidar.translation().z())};
      const Mat3 rot = world_from_lidar.RotationMatrix();
      for (int r0 = 0; r0 < rings; r0 += 16) {
        int valid[16];
        float dirs[16][3];
        Vec3 dirs_lidar[16], dirs_world[16];
        for (int k = 0; k < 16; ++k) {
          const int r = r0 + k;
          valid[k] = r < rings;
          dirs_lidar[k] = valid[k] ? Vec3(cos_el[r] * cos_az, cos_el[r] * sin_az, sin_el[r])
                                   : Vec3::UnitX();
          dirs_world[k] = rot * dirs_lidar[k];
          for (int j = 0; j < 3; ++j) dirs[k][j] = static_cast<float>(dirs_world[k][j]);
        }
        RayHit hits[16];
        scene_.Intersect16At(t_ns, valid, origin, dirs, spinning_max_cast, /*coherent=*/false,
                             hits);
        for (int k = 0; k < 16 && r0 + k < rings; ++k) {
          visit(hits[k], world_from_lidar, dirs_lidar[k], dirs_world[k], t_s, r0 + k,
                static_cast<size_t>(c) * rings + r0 + k);
        }
      }
    }
  } else {
    const int n = static_cast<int>(std::floor(options_.livox_rate * period_s));
    const double half_fov = 0.5 * options_.livox_fov_deg * M_PI / 180.0;
    const double scan_start_s = NsToSeconds(scan_start_ns - trajectory_.start_ns());
    for (int i = 0; i < n; ++i) {
      const double t_s = i / options_.livox_rate;
      const Vec3 dir_lidar = RosetteDirection(scan_start_s + t_s, half_fov);
      const TimestampNs t_ns = capture_start_ns + SecondsToNs(t_s);
      const SE3 world_from_lidar = trajectory_.Pose(t_ns) * lidar_.imu_from_lidar;
      const Vec3 dir_world = world_from_lidar.rotation() * dir_lidar;
      const RayHit hit = scene_.IntersectAt(t_ns, world_from_lidar.translation(), dir_world, 0.0,
                                            solid_state_max_cast);
      visit(hit, world_from_lidar, dir_lidar, dir_world, t_s, 0, static_cast<size_t>(i));
    }
  }
}

PointCloud LidarSimulator::SimulateScan(TimestampNs scan_start_ns, int64_t scan_index) const {
  if (options_.errors_enabled) return SimulateScanWithErrors(scan_start_ns, scan_index);
  std::mt19937_64 rng(options_.seed * 0x9E3779B97F4A7C15ULL +
                      static_cast<uint64_t>(scan_index) * 0xBF58476D1CE4E5B9ULL + 5);
  std::normal_distribution<double> normal(0.0, options_.range_sigma * options_.noise_scale);
  const bool noisy = options_.noise_scale > 0;
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
  raw.reserve(NumBeams());
  CastBeams(scan_start_ns, max_range + 1.f, lidar_.max_range + 1.0,
            [&](const RayHit& hit, const SE3& world_from_lidar, const Vec3& dir_lidar,
                const Vec3& dir_world, double t_s, int ring, size_t /*beam*/) {
              add_point(hit, world_from_lidar, dir_lidar, dir_world, t_s, ring);
            });
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

PointCloud LidarSimulator::SimulateScanWithErrors(TimestampNs scan_start_ns,
                                                  int64_t scan_index) const {
  const LidarErrorOptions& e = options_.errors;
  const uint64_t scan_key =
      Mix64(Mix64(options_.seed * 0x9E3779B97F4A7C15ULL + 0x4c494441ULL) +
            static_cast<uint64_t>(scan_index) * 0xD6E8FEB86659FD93ULL);
  auto draw = [&](uint64_t index, Stream stream) {
    return Mix64(scan_key + Mix64(index * 4 + stream));
  };
  const float max_cast = static_cast<float>(lidar_.max_range) + 1.f;

  // ---- pass 1: cast every beam, keep what the error model needs ----
  std::vector<Beam> beams;
  auto record = [&](const RayHit& hit, const SE3& world_from_lidar, const Vec3& dir_lidar,
                    const Vec3& dir_world, double t_s, int ring, Beam* b) {
    b->direction = dir_lidar.cast<float>();
    b->t_s = t_s;
    b->ring = static_cast<uint16_t>(ring);
    if (!hit.hit) return;
    const Eigen::Vector3f hit_world =
        (world_from_lidar.translation() + static_cast<double>(hit.distance) * dir_world)
            .cast<float>();
    b->range = hit.distance;
    b->normal = (world_from_lidar.rotation().conjugate() * hit.normal.cast<double>()).cast<float>();
    b->cos_incidence = std::fabs(hit.normal.dot(dir_world.cast<float>()));
    b->material = scene_.material_id(hit.surface_id);
    const float albedo =
        texture_.FootprintAlbedo(hit.surface_id, hit_world, TextureAxis(hit.normal));
    b->reflectivity = ApparentReflectivity(Materials()[b->material], albedo, b->cos_incidence);
    // Intensity() of the path without error sources, from the same albedo.
    b->albedo_intensity = std::fmin(255.f, 255.f * albedo * (0.2f + 0.8f * b->cos_incidence));
  };
  const bool spinning = lidar_.type == LidarType::kSpinning;
  const int columns = spinning ? options_.azimuth_steps : 0;
  const int rings = spinning ? lidar_.rings : 0;
  beams.resize(NumBeams());
  CastBeams(scan_start_ns, max_cast, max_cast,
            [&](const RayHit& hit, const SE3& world_from_lidar, const Vec3& dir_lidar,
                const Vec3& dir_world, double t_s, int ring, size_t beam) {
              record(hit, world_from_lidar, dir_lidar, dir_world, t_s, ring, &beams[beam]);
            });

  // ---- pass 2: mixed pixels, dropouts, range limits, noise, intensity ----
  const double divergence = 1e-3 * e.beam_divergence_mrad;
  const double az_gap = spinning ? 2 * M_PI / columns : 0.0;
  const double el_gap = spinning ? RingElevation(1) - RingElevation(0) : 0.0;
  const double sigma0 = options_.range_sigma * options_.noise_scale;
  const float min_range = static_cast<float>(lidar_.min_range);
  const float max_range = static_cast<float>(lidar_.max_range);
  struct Raw {
    LidarPoint point;
    double t_s;
  };
  std::vector<Raw> raw;
  raw.reserve(beams.size());
  for (size_t i = 0; i < beams.size(); ++i) {
    const Beam& b = beams[i];
    if (b.range <= 0) continue;
    Echo echoes[5];
    int num_echoes = 1;
    echoes[0] = {1.f, b.range, b.reflectivity, b.cos_incidence, b.material};
    if (divergence > 0) {
      // Neighbours (index, angular gap) whose hit is off this beam's plane.
      size_t nb[4];
      double gap[4];
      int num_nb = 0;
      if (spinning) {
        const size_t c = i / rings, r = i % rings;
        if (c > 0) nb[num_nb] = i - rings, gap[num_nb++] = az_gap;
        if (c + 1 < static_cast<size_t>(columns)) nb[num_nb] = i + rings, gap[num_nb++] = az_gap;
        if (r > 0) nb[num_nb] = i - 1, gap[num_nb++] = el_gap;
        if (r + 1 < static_cast<size_t>(rings)) nb[num_nb] = i + 1, gap[num_nb++] = el_gap;
      } else {
        for (const size_t j : {i - 1, i + 1}) {
          if (i == 0 && j == i - 1) continue;
          if (j >= beams.size()) continue;
          nb[num_nb] = j;
          gap[num_nb++] = std::acos(std::min(1.f, b.direction.dot(beams[j].direction)));
        }
      }
      const Eigen::Vector3f p = b.range * b.direction;
      float total = 0;
      for (int k = 0; k < num_nb; ++k) {
        const Beam& n = beams[nb[k]];
        if (n.range <= 0) continue;  // open space: no echo from there
        if (std::fabs(b.normal.dot(n.range * n.direction - p)) < kEdgeMinOffset) continue;
        // The edge lies at u * gap from the lower-index beam of the pair; a
        // gap is keyed by that beam and whether the pair is adjacent in index
        // (ring / firing order) or a column apart.
        const size_t lo = std::min(i, nb[k]);
        const uint64_t gap_id = lo * 2 + (std::max(i, nb[k]) - lo == 1 ? 0 : 1);
        const double u = HashUniform(draw(gap_id, kEdgeDraw));
        const double distance = (i == lo ? u : 1.0 - u) * gap[k];
        const float f =
            static_cast<float>(std::clamp(0.5 - distance / divergence, 0.0, 1.0));
        if (f <= 0) continue;
        // The neighbour's surface along this beam: its plane through its hit.
        const float along = n.normal.dot(b.direction);
        const float range_there =
            std::fabs(along) > 0.05f ? n.normal.dot(n.range * n.direction) / along : n.range;
        echoes[num_echoes++] = {f, range_there, n.reflectivity, n.cos_incidence, n.material};
        total += f;
      }
      if (total > 1.f) {
        for (int k = 1; k < num_echoes; ++k) echoes[k].fraction /= total;
        total = 1.f;
      }
      echoes[0].fraction = 1.f - total;
    }
    // The strongest echo, and the echoes that merge with it.
    int strongest = 0;
    float best_power = -1;
    for (int k = 0; k < num_echoes; ++k) {
      const float power = echoes[k].fraction * echoes[k].reflectivity /
                          (echoes[k].range * echoes[k].range);
      if (power > best_power) best_power = power, strongest = k;
    }
    float weight_sum = 0, range_sum = 0, reflectivity = 0;
    for (int k = 0; k < num_echoes; ++k) {
      if (std::fabs(echoes[k].range - echoes[strongest].range) >
          e.mixed_pixel_max_separation_m) {
        continue;
      }
      const float w =
          echoes[k].fraction * echoes[k].reflectivity / (echoes[k].range * echoes[k].range);
      weight_sum += w;
      range_sum += w * echoes[k].range;
      reflectivity += echoes[k].fraction * echoes[k].reflectivity;
    }
    double range = weight_sum > 0 ? range_sum / weight_sum : echoes[strongest].range;
    const Echo& main = echoes[strongest];
    if (e.dropout_reflectivity > 0) {
      const double q = reflectivity / e.dropout_reflectivity;
      const double p_power = 1.0 / (1.0 + q * q);
      const double p_drop = 1.0 - (1.0 - Materials()[main.material].dropout) * (1.0 - p_power);
      if (HashUniform(draw(i, kDropoutDraw)) < p_drop) continue;
    }
    if (e.range_at_10_percent_m > 0 &&
        range > e.range_at_10_percent_m * std::sqrt(reflectivity / 0.1)) {
      continue;
    }
    if (sigma0 > 0) {
      const double inv_cos = 1.0 / std::max(static_cast<double>(main.cos_incidence), 0.1);
      const double sigma = sigma0 * (1.0 + e.incidence_noise_gain * (inv_cos - 1.0));
      range += sigma * HashNormal(draw(i, kNoiseDraw));
    }
    if (range < min_range || range > max_range) continue;
    Raw r;
    const Eigen::Vector3f x = static_cast<float>(range) * b.direction;
    r.point.x = x.x();
    r.point.y = x.y();
    r.point.z = x.z();
    r.point.intensity = e.material_intensity ? std::fmin(255.f, 100.f * reflectivity)
                                             : b.albedo_intensity;
    r.point.ring = b.ring;
    r.t_s = b.t_s;
    raw.push_back(r);
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
