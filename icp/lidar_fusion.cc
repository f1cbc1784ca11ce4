#include "icp/lidar_fusion.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <string>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

namespace {

constexpr double kDegToRad = M_PI / 180.0;

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

bool LidarFusionOptions::Check() const {
  CHECK_OPTION_MSG(azimuth_resolution_deg,
                   azimuth_resolution_deg >= 0.01 && azimuth_resolution_deg <= 10,
                   "in [0.01, 10]");
  CHECK_OPTION_MSG(elevation_resolution_deg,
                   elevation_resolution_deg == 0 ||
                       (elevation_resolution_deg >= 0.01 && elevation_resolution_deg <= 10),
                   "0 or in [0.01, 10]");
  CHECK_OPTION_GE(min_range_m, 0.0);
  CHECK_OPTION_GT(max_range_m, min_range_m);
  CHECK_OPTION_GT(max_range_jump, 0.0);
  CHECK_OPTION_MSG(
      max_incidence_deg, max_incidence_deg > 0 && max_incidence_deg <= 90, "in (0, 90]");
  return true;
}

LidarImageLayout FitLidarImageLayout(const PointCloud& scan,
                                     const LidarFusionOptions& options,
                                     const std::string& what) {
  THROW_CHECK_OPTIONS(options);
  const int width =
      std::max(1, static_cast<int>(std::lround(360.0 / options.azimuth_resolution_deg)));
  // Per ring: sum and count of elevations (rad) of the points in range.
  std::map<int, std::pair<double, size_t>> rings;
  double e_min = std::numeric_limits<double>::infinity(), e_max = -e_min;
  std::vector<float> intensities;
  intensities.reserve(scan.size());
  for (const LidarPoint& p : scan.points) {
    const double r = std::sqrt(double{p.x} * p.x + double{p.y} * p.y + double{p.z} * p.z);
    if (!std::isfinite(r) || r < options.min_range_m || r > options.max_range_m) continue;
    const double e = std::atan2(p.z, std::hypot(p.x, p.y));
    e_min = std::min(e_min, e);
    e_max = std::max(e_max, e);
    auto& ring = rings[p.ring];
    ring.first += e;
    ++ring.second;
    intensities.push_back(p.intensity);
  }
  if (intensities.empty()) {
    throw InputError(what,
                     "",
                     fmt::format("expected LiDAR points within {} to {} m of the sensor, found "
                                 "none among {} points",
                                 options.min_range_m,
                                 options.max_range_m,
                                 scan.size()));
  }
  LidarImageLayout layout;
  const size_t k = intensities.size() * 99 / 100;
  std::nth_element(intensities.begin(), intensities.begin() + k, intensities.end());
  layout.intensity_full_scale = intensities[k] > 0 ? intensities[k] : 0.f;
  if (options.elevation_resolution_deg == 0 && rings.size() >= 2) {
    // One row per ring, top ring first, spaced by the mean elevations of the extreme rings.
    std::vector<std::pair<double, int>> by_elevation;  // (-mean elevation, ring)
    int max_ring = 0;
    for (const auto& [ring, sum] : rings) {
      by_elevation.emplace_back(-sum.first / sum.second, ring);
      max_ring = std::max(max_ring, ring);
    }
    std::sort(by_elevation.begin(), by_elevation.end());
    const double top = -by_elevation.front().first, bottom = -by_elevation.back().first;
    const int height = static_cast<int>(by_elevation.size());
    const double step = std::max((top - bottom) / (height - 1), 1e-4);
    layout.row_of_ring.assign(max_ring + 1, -1);
    for (int row = 0; row < height; ++row) layout.row_of_ring[by_elevation[row].second] = row;
    layout.projection = SphericalProjection(width, height, top, step);
    return layout;
  }
  const double step =
      (options.elevation_resolution_deg > 0 ? options.elevation_resolution_deg : 1.0) * kDegToRad;
  const int height = std::max(1, static_cast<int>(std::ceil((e_max - e_min) / step - 1e-9)) + 1);
  layout.projection = SphericalProjection(width, height, e_max, step);
  return layout;
}

LidarFusion::LidarFusion(const LidarImageLayout& layout,
                         const LidarFusionOptions& options,
                         const SurfelFusionOptions& fusion_options)
    : layout_(layout), options_(options), map_(fusion_options) {
  THROW_CHECK_OPTIONS(options_);
  THROW_CHECK(layout_.projection.num_pixels() > 0);
}

size_t LidarFusion::BuildRangeImage(const PointCloud& scan,
                                    VertexNormalMap* image,
                                    std::vector<std::array<uint8_t, 3>>* colors) const {
  const SphericalProjection& proj = layout_.projection;
  const int w = proj.width(), h = proj.height();
  const size_t n = proj.num_pixels();
  image->Resize(w, h);
  best_range_.assign(n, std::numeric_limits<float>::infinity());
  intensity_.resize(n);
  const float min_r = static_cast<float>(options_.min_range_m);
  const float max_r = static_cast<float>(options_.max_range_m);
  const std::vector<int>& row_of_ring = layout_.row_of_ring;
  size_t in_range = 0;
  // Nearest point per pixel (in file order; ties keep the earlier point).
  for (const LidarPoint& lp : scan.points) {
    const Eigen::Vector3f p(lp.x, lp.y, lp.z);
    int u, v;
    float r;
    if (!row_of_ring.empty()) {
      r = p.norm();
      if (!(r >= min_r && r <= max_r)) continue;
      ++in_range;
      if (lp.ring >= row_of_ring.size() || row_of_ring[lp.ring] < 0) continue;
      if (p.x() == 0.f && p.y() == 0.f) continue;
      v = row_of_ring[lp.ring];
      u = proj.Column(p);
    } else {
      r = p.norm();
      if (!(r >= min_r && r <= max_r)) continue;
      ++in_range;
      if (!proj.Project(p, &u, &v, &r)) continue;
    }
    const size_t i = static_cast<size_t>(v) * w + u;
    if (r < best_range_[i]) {
      best_range_[i] = r;
      image->vertices[i] = p;
      intensity_[i] = lp.intensity;
    }
  }
  const float jump = static_cast<float>(options_.max_range_jump);
  const float min_cos = static_cast<float>(std::cos(options_.max_incidence_deg * kDegToRad));
  const float scale = layout_.intensity_full_scale > 0 ? 255.f / layout_.intensity_full_scale : 0.f;
  // Row neighbours as many columns away as one row is high (XT-32: 6 x 0.18 deg for 1
  // deg), so that both differences span similar angles.
  const int column_step =
      static_cast<int>(std::clamp(std::lround(proj.elevation_step_rad() / proj.azimuth_step_rad()),
                                  1L,
                                  static_cast<long>(w / 4 + 1)));
  colors->resize(n);
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      Eigen::Vector3f& normal = image->normals[i];
      normal.setZero();
      const float r = best_range_[i];
      if (!std::isfinite(r)) {
        image->vertices[i].setZero();
        continue;
      }
      const Eigen::Vector3f& q = image->vertices[i];
      const float max_jump = jump * r;
      auto usable = [&](size_t j) {
        return std::isfinite(best_range_[j]) && std::abs(best_range_[j] - r) <= max_jump;
      };
      // The difference across the pixel along one direction (a, b: the neighbours
      // before and after it, or n for none); false when neither is usable.
      auto difference = [&](size_t a, size_t b, Eigen::Vector3f* d) {
        const bool ua = a < n && usable(a), ub = b < n && usable(b);
        if (ua && ub) {
          *d = image->vertices[b] - image->vertices[a];
        } else if (ub) {
          *d = image->vertices[b] - q;
        } else if (ua) {
          *d = q - image->vertices[a];
        } else {
          return false;
        }
        return true;
      };
      const size_t left = static_cast<size_t>(v) * w + proj.WrapColumn(u - column_step);
      const size_t right = static_cast<size_t>(v) * w + proj.WrapColumn(u + column_step);
      const size_t up = v > 0 ? i - w : n, down = v + 1 < h ? i + w : n;
      Eigen::Vector3f du, dv;
      if (!difference(left, right, &du) || !difference(up, down, &dv)) continue;
      Eigen::Vector3f m = du.cross(dv);
      const float norm = m.norm();
      if (!(norm > 0.f)) continue;
      m /= norm;
      if (m.dot(q) > 0) m = -m;  // towards the sensor
      if (-m.dot(q) < min_cos * r) continue;
      normal = m;
      const uint8_t grey =
          scale > 0 ? static_cast<uint8_t>(std::clamp(std::lround(intensity_[i] * scale), 0L, 255L))
                    : uint8_t{128};
      (*colors)[i] = {grey, grey, grey};
    }
  });
  return in_range;
}

LidarFrameResult LidarFusion::AddScan(const PointCloud& scan, const SE3& world_from_sensor) {
  LidarFrameResult result;
  auto t0 = std::chrono::steady_clock::now();
  result.points_in_range = BuildRangeImage(scan, &image_, &colors_);
  for (float r : best_range_) result.pixels_with_points += std::isfinite(r) ? 1 : 0;
  result.preprocess_ms = MsSince(t0);
  t0 = std::chrono::steady_clock::now();
  result.fuse = map_.Fuse(image_, colors_, layout_.projection, world_from_sensor, num_frames_);
  result.fuse_ms = MsSince(t0);
  num_input_points_ += result.fuse.valid_pixels;
  num_scan_points_ += result.points_in_range;
  ++num_frames_;
  return result;
}

}  // namespace lisfm
