#include "icp/surfel_map.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr uint64_t kEmptyKey = ~uint64_t{0};

// z-buffer key: a splat flag (bit 63), the depth's bits (bits 32-62: positive
// floats order like their bit patterns and have a zero sign bit) and the surfel
// index, so that the atomic minimum keeps a surfel whose centre falls into the
// pixel over any splatted disc, then the nearest, then the lower index.
uint64_t Key(float z, uint32_t index, bool splatted) {
  uint32_t bits;
  std::memcpy(&bits, &z, sizeof(bits));
  return (static_cast<uint64_t>(splatted) << 63) | (static_cast<uint64_t>(bits) << 32) | index;
}

void AtomicMin(std::atomic<uint64_t>* a, uint64_t value) {
  uint64_t current = a->load(std::memory_order_relaxed);
  while (value < current && !a->compare_exchange_weak(current, value, std::memory_order_relaxed)) {
  }
}

}  // namespace

bool SurfelFusionOptions::Check() const {
  CHECK_OPTION_GT(max_merge_distance_m, 0.0);
  CHECK_OPTION_MSG(
      max_merge_angle_deg, max_merge_angle_deg > 0 && max_merge_angle_deg <= 180, "in (0, 180]");
  CHECK_OPTION_MSG(
      association_radius_px, association_radius_px >= 0 && association_radius_px <= 3, "in [0, 3]");
  CHECK_OPTION_GE(unstable_age_frames, 0);
  CHECK_OPTION_GE(unstable_min_confidence, 0.0);
  CHECK_OPTION_GE(output_min_confidence, 0.0);
  return true;
}

SurfelMap::SurfelMap(const SurfelFusionOptions& options) : options_(options) {
  THROW_CHECK_OPTIONS(options_);
}

size_t SurfelMap::NumStable() const {
  size_t n = 0;
  for (const Surfel& s : surfels_) n += Stable(s) ? 1 : 0;
  return n;
}

std::atomic<uint64_t>* SurfelMap::ClearedZBuffer(size_t num_pixels) const {
  if (zbuffer_size_ < num_pixels) {
    zbuffer_.reset(new std::atomic<uint64_t>[num_pixels]);
    zbuffer_size_ = num_pixels;
  }
  std::atomic<uint64_t>* zb = zbuffer_.get();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, num_pixels, 4096),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t i = r.begin(); i != r.end(); ++i) {
                        zb[i].store(kEmptyKey, std::memory_order_relaxed);
                      }
                    });
  return zb;
}

void SurfelMap::RenderIndexMap(const SE3& world_from_camera,
                               const PinholeIntrinsics& K,
                               double min_confidence,
                               int splat,
                               std::vector<uint32_t>* index_map) const {
  THROW_CHECK(K.width > 0 && K.height > 0 && K.fx > 0 && K.fy > 0);
  THROW_CHECK(splat >= 0);
  const size_t num_pixels = static_cast<size_t>(K.width) * static_cast<size_t>(K.height);
  std::atomic<uint64_t>* zb = ClearedZBuffer(num_pixels);
  const SE3 camera_from_world = world_from_camera.Inverse();
  const Eigen::Matrix3f R = camera_from_world.RotationMatrix().cast<float>();
  const Eigen::Vector3f t = camera_from_world.translation().cast<float>();
  const float fx = static_cast<float>(K.fx), fy = static_cast<float>(K.fy);
  const float cx = static_cast<float>(K.cx), cy = static_cast<float>(K.cy);
  const float min_conf = static_cast<float>(min_confidence);
  const Eigen::Vector3f centre = world_from_camera.translation().cast<float>();
  const int w = K.width, h = K.height;
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, surfels_.size(), 8192),
      [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const Surfel& s = surfels_[i];
          if (s.confidence < min_conf) continue;
          const Eigen::Vector3f p = R * s.position + t;
          if (!(p.z() > 0)) continue;
          if (s.normal.dot(s.position - centre) > 0) continue;  // facing away from the camera
          const float inv_z = 1.f / p.z();
          // Nearest pixel: floor(x + 0.5); far outside the image is skipped before the cast.
          const float uf = fx * p.x() * inv_z + cx + 0.5f, vf = fy * p.y() * inv_z + cy + 0.5f;
          if (!(uf >= -splat && vf >= -splat && uf < w + splat && vf < h + splat)) continue;
          const int u = static_cast<int>(std::floor(uf)), v = static_cast<int>(std::floor(vf));
          const uint64_t key = Key(p.z(), static_cast<uint32_t>(i), false);
          if (splat == 0) {
            if (u < 0 || v < 0 || u >= w || v >= h) continue;
            AtomicMin(&zb[static_cast<size_t>(v) * w + u], key);
            continue;
          }
          const float radius_px = s.radius_m * fx * inv_z;
          const int reach = std::min(splat, static_cast<int>(radius_px));
          const float r2 = std::max(radius_px * radius_px, 0.25f);
          const Eigen::Vector3f n = R * s.normal;
          const float n_dot_p = n.dot(p);
          for (int dv = -reach; dv <= reach; ++dv) {
            const int vv = v + dv;
            if (vv < 0 || vv >= h) continue;
            for (int du = -reach; du <= reach; ++du) {
              const int uu = u + du;
              if (uu < 0 || uu >= w) continue;
              if (static_cast<float>(du * du + dv * dv) > r2 && (du != 0 || dv != 0)) continue;
              if (du == 0 && dv == 0) {
                AtomicMin(&zb[static_cast<size_t>(vv) * w + uu], key);
                continue;
              }
              // The depth where the pixel's ray meets the surfel's disc (its plane);
              // the centre's depth when the ray is nearly parallel to it.
              float z = p.z();
              const Eigen::Vector3f ray((uu - cx) / fx, (vv - cy) / fy, 1.f);
              const float n_dot_ray = n.dot(ray);
              if (n_dot_ray < -1e-3f) {
                const float zi = n_dot_p / n_dot_ray;
                if (zi > 0 && std::abs(zi - p.z()) < 4.f * s.radius_m) z = zi;
              }
              AtomicMin(&zb[static_cast<size_t>(vv) * w + uu],
                        Key(z, static_cast<uint32_t>(i), true));
            }
          }
        }
      });
  index_map->resize(num_pixels);
  uint32_t* out = index_map->data();
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, num_pixels, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const uint64_t key = zb[i].load(std::memory_order_relaxed);
          out[i] = key == kEmptyKey ? kNoSurfel : static_cast<uint32_t>(key & 0xffffffffu);
        }
      });
}

void SurfelMap::RenderVertexNormalMap(const SE3& world_from_camera,
                                      const PinholeIntrinsics& K,
                                      double min_confidence,
                                      int splat,
                                      VertexNormalMap* out,
                                      std::vector<uint32_t>* index_map_out) const {
  std::vector<uint32_t> temporary;
  std::vector<uint32_t>& index_map = index_map_out != nullptr ? *index_map_out : temporary;
  RenderIndexMap(world_from_camera, K, min_confidence, splat, &index_map);
  out->Resize(K.width, K.height);
  const SE3 camera_from_world = world_from_camera.Inverse();
  const Eigen::Matrix3f R = camera_from_world.RotationMatrix().cast<float>();
  const Eigen::Vector3f t = camera_from_world.translation().cast<float>();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  tbb::parallel_for(size_t{0}, index_map.size(), [&](size_t i) {
    const uint32_t s = index_map[i];
    if (s == kNoSurfel) {
      out->vertices[i] = Eigen::Vector3f(nan, nan, 0.f);
      out->normals[i].setZero();
    } else {
      // The point where the pixel's ray meets the surfel's plane (so that the
      // vertex lies on the ray, like a measured one), or the surfel centre when the
      // ray is nearly parallel to the plane or meets it beyond the disc's reach.
      const Eigen::Vector3f p = R * surfels_[s].position + t;
      const Eigen::Vector3f n = R * surfels_[s].normal;
      const int u = static_cast<int>(i % K.width), v = static_cast<int>(i / K.width);
      const Eigen::Vector3f ray(
          static_cast<float>((u - K.cx) / K.fx), static_cast<float>((v - K.cy) / K.fy), 1.f);
      const float n_dot_ray = n.dot(ray);
      Eigen::Vector3f q = p;
      if (n_dot_ray < -1e-3f) {
        const Eigen::Vector3f qi = ray * (n.dot(p) / n_dot_ray);
        if (qi.z() > 0 &&
            (qi - p).squaredNorm() < 16.f * surfels_[s].radius_m * surfels_[s].radius_m) {
          q = qi;
        }
      }
      out->vertices[i] = q;
      out->normals[i] = n;
    }
  });
}

namespace {

// The projection-specific parts of a fusion step (FuseImpl): the index map, the
// column wrap of the association window and the radius of an observation.
struct PinholeFuseCamera {
  static constexpr bool kWrapsColumns = false;
  const PinholeIntrinsics& K;
  float f;  // mean focal length (pixels)
  int width() const { return K.width; }
  int height() const { return K.height; }
  int WrapColumn(int u) const { return u; }
  void Render(const SurfelMap& map, const SE3& pose, std::vector<uint32_t>* index_map) const {
    map.RenderIndexMap(pose, K, 0.0, 0, index_map);
  }
  // sqrt(2) z / (f |cos a|) / 2.
  float ObservedRadius(const Eigen::Vector3f& q, const Eigen::Vector3f& n) const {
    const float cos_a = std::max(std::abs(n.dot(q)) / q.norm(), 0.2f);
    return 0.70710678f * q.z() / (f * cos_a);
  }
};

struct SphericalFuseCamera {
  static constexpr bool kWrapsColumns = true;
  const SphericalProjection& projection;
  float half_diagonal_rad;  // sqrt(da^2 + de^2) / 2
  int width() const { return projection.width(); }
  int height() const { return projection.height(); }
  int WrapColumn(int u) const { return projection.WrapColumn(u); }
  void Render(const SurfelMap& map, const SE3& pose, std::vector<uint32_t>* index_map) const {
    map.RenderIndexMap(pose, projection, 0.0, 0, index_map);
  }
  // r sqrt(da^2 + de^2) / (2 |cos a|).
  float ObservedRadius(const Eigen::Vector3f& q, const Eigen::Vector3f& n) const {
    const float r = q.norm();
    const float cos_a = std::max(std::abs(n.dot(q)) / r, 0.2f);
    return half_diagonal_rad * r / cos_a;
  }
};

}  // namespace

void SurfelMap::RenderIndexMap(const SE3& world_from_sensor,
                               const SphericalProjection& projection,
                               double min_confidence,
                               int splat,
                               std::vector<uint32_t>* index_map) const {
  THROW_CHECK(projection.width() > 0 && projection.height() > 0);
  THROW_CHECK(splat >= 0);
  const size_t num_pixels = projection.num_pixels();
  std::atomic<uint64_t>* zb = ClearedZBuffer(num_pixels);
  const SE3 sensor_from_world = world_from_sensor.Inverse();
  const Eigen::Matrix3f R = sensor_from_world.RotationMatrix().cast<float>();
  const Eigen::Vector3f t = sensor_from_world.translation().cast<float>();
  const float min_conf = static_cast<float>(min_confidence);
  const Eigen::Vector3f centre = world_from_sensor.translation().cast<float>();
  const int w = projection.width(), h = projection.height();
  const float inv_da = static_cast<float>(1.0 / projection.azimuth_step_rad());
  const float inv_de = static_cast<float>(1.0 / projection.elevation_step_rad());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, surfels_.size(), 8192),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t i = r.begin(); i != r.end(); ++i) {
                        const Surfel& s = surfels_[i];
                        if (s.confidence < min_conf) continue;
                        if (s.normal.dot(s.position - centre) > 0)
                          continue;  // facing away from the sensor
                        const Eigen::Vector3f p = R * s.position + t;
                        int u, v;
                        float range;
                        if (!projection.Project(p, &u, &v, &range)) continue;
                        const uint64_t key = Key(range, static_cast<uint32_t>(i), false);
                        AtomicMin(&zb[static_cast<size_t>(v) * w + u], key);
                        if (splat == 0) continue;
                        // The disc's half extents in pixels: r / (range cos e da) across, r /
                        // (range de) along the rows.
                        const float horizontal = std::max(std::hypot(p.x(), p.y()), 1e-6f);
                        const float ru = s.radius_m * inv_da / horizontal,
                                    rv = s.radius_m * inv_de / range;
                        const int reach_u = std::min(splat, static_cast<int>(ru));
                        const int reach_v = std::min(splat, static_cast<int>(rv));
                        if (reach_u == 0 && reach_v == 0) continue;
                        const float inv_ru2 = 1.f / std::max(ru * ru, 0.25f);
                        const float inv_rv2 = 1.f / std::max(rv * rv, 0.25f);
                        const Eigen::Vector3f n = R * s.normal;
                        const float n_dot_p = n.dot(p);
                        for (int dv = -reach_v; dv <= reach_v; ++dv) {
                          const int vv = v + dv;
                          if (vv < 0 || vv >= h) continue;
                          for (int du = -reach_u; du <= reach_u; ++du) {
                            if (du == 0 && dv == 0) continue;
                            if (du * du * inv_ru2 + dv * dv * inv_rv2 > 1.f) continue;
                            const int uu = projection.WrapColumn(u + du);
                            // The range where the pixel's ray meets the surfel's plane; the
                            // centre's range when the ray is nearly parallel to it.
                            float z = range;
                            const float n_dot_ray = n.dot(projection.Ray(uu, vv));
                            if (n_dot_ray < -1e-3f) {
                              const float zi = n_dot_p / n_dot_ray;
                              if (zi > 0 && std::abs(zi - range) < 4.f * s.radius_m) z = zi;
                            }
                            AtomicMin(&zb[static_cast<size_t>(vv) * w + uu],
                                      Key(z, static_cast<uint32_t>(i), true));
                          }
                        }
                      }
                    });
  index_map->resize(num_pixels);
  uint32_t* out = index_map->data();
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, num_pixels, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const uint64_t key = zb[i].load(std::memory_order_relaxed);
          out[i] = key == kEmptyKey ? kNoSurfel : static_cast<uint32_t>(key & 0xffffffffu);
        }
      });
}

namespace {

// Throws InputError (what, frame `frame_index`) unless the map has width x height
// vertices and normals and `colors` is empty or has one per pixel.
void CheckFuseInput(const char* what,
                    int frame_index,
                    int width,
                    int height,
                    const VertexNormalMap& map,
                    const std::vector<std::array<uint8_t, 3>>& colors) {
  const size_t num_pixels = static_cast<size_t>(std::max(width, 0)) * std::max(height, 0);
  if (num_pixels == 0 || map.width != width || map.height != height ||
      map.vertices.size() != num_pixels || map.normals.size() != num_pixels ||
      (!colors.empty() && colors.size() != num_pixels)) {
    throw InputError(
        what,
        fmt::format("frame {}", frame_index),
        fmt::format("expected {}x{} vertices, normals and colours, found {}, {} and {}",
                    width,
                    height,
                    map.vertices.size(),
                    map.normals.size(),
                    colors.size()));
  }
}

}  // namespace

FuseStats SurfelMap::Fuse(const FusionFrame& frame, const SE3& world_from_camera, int frame_index) {
  const PinholeIntrinsics& K = frame.intrinsics;
  CheckFuseInput("fusion frame", frame_index, K.width, K.height, frame.map, frame.colors);
  const PinholeFuseCamera camera{K, static_cast<float>(0.5 * (K.fx + K.fy))};
  return FuseImpl(frame.map, frame.colors, camera, world_from_camera, frame_index);
}

FuseStats SurfelMap::Fuse(const VertexNormalMap& map,
                          const std::vector<std::array<uint8_t, 3>>& colors,
                          const SphericalProjection& projection,
                          const SE3& world_from_sensor,
                          int frame_index) {
  CheckFuseInput(
      "fusion range image", frame_index, projection.width(), projection.height(), map, colors);
  const double da = projection.azimuth_step_rad(), de = projection.elevation_step_rad();
  const SphericalFuseCamera camera{projection, static_cast<float>(0.5 * std::hypot(da, de))};
  return FuseImpl(map, colors, camera, world_from_sensor, frame_index);
}

template <class Camera>
FuseStats SurfelMap::FuseImpl(const VertexNormalMap& map,
                              const std::vector<std::array<uint8_t, 3>>& colors,
                              const Camera& camera,
                              const SE3& world_from_camera,
                              int frame_index) {
  const size_t num_pixels = static_cast<size_t>(camera.width()) * camera.height();
  FuseStats stats;
  camera.Render(*this, world_from_camera, &index_map_);
  match_.resize(num_pixels);
  const Eigen::Matrix3f R = world_from_camera.RotationMatrix().cast<float>();
  const Eigen::Vector3f t = world_from_camera.translation().cast<float>();
  const float max_sq =
      static_cast<float>(options_.max_merge_distance_m * options_.max_merge_distance_m);
  const float min_cos = static_cast<float>(std::cos(options_.max_merge_angle_deg * kDegToRad));
  const int radius = options_.association_radius_px;
  const int w = camera.width(), h = camera.height();
  // Radius of the observation of pixel i (header comment).
  auto observed_radius = [&](size_t i) {
    return camera.ObservedRadius(map.vertices[i], map.normals[i]);
  };
  // The rendered surfels in pixel order (one gather), so that the window search
  // below reads neighbouring pixels instead of scattered surfels.
  rendered_.resize(num_pixels);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, num_pixels, 4096),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t i = r.begin(); i != r.end(); ++i) {
                        const uint32_t s = index_map_[i];
                        RenderedSurfel& out = rendered_[i];
                        out.index = s;
                        if (s == kNoSurfel) continue;
                        out.position = surfels_[s].position;
                        out.normal = surfels_[s].normal;
                        out.radius_m = surfels_[s].radius_m;
                      }
                    });
  // 2. Association (parallel over rows; each pixel reads the rendered surfels only).
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      match_[i] = kNoSurfel;
      if (!map.Valid(i)) continue;
      const Eigen::Vector3f q = R * map.vertices[i] + t;
      const Eigen::Vector3f n = R * map.normals[i];
      const float r_obs = observed_radius(i);
      auto compatible = [&](const RenderedSurfel& surfel, float* d2) {
        if (surfel.index == kNoSurfel) return false;
        const Eigen::Vector3f d = surfel.position - q;
        const float along = surfel.normal.dot(d);
        *d2 = d.squaredNorm();
        const float reach = surfel.radius_m + r_obs;
        return along * along < max_sq && *d2 - along * along < reach * reach &&
               surfel.normal.dot(n) >= min_cos;
      };
      float best_d2;
      if (compatible(rendered_[i], &best_d2)) {
        match_[i] = rendered_[i].index;
        continue;
      }
      best_d2 = std::numeric_limits<float>::infinity();
      for (int dv = -radius; dv <= radius; ++dv) {
        const int vv = v + dv;
        if (vv < 0 || vv >= h) continue;
        for (int du = -radius; du <= radius; ++du) {
          int uu = u + du;
          if (Camera::kWrapsColumns) uu = camera.WrapColumn(uu);
          if (uu < 0 || uu >= w || (du == 0 && dv == 0)) continue;
          const RenderedSurfel& candidate = rendered_[static_cast<size_t>(vv) * w + uu];
          float d2;
          if (compatible(candidate, &d2) && d2 < best_d2) {
            best_d2 = d2;
            match_[i] = candidate.index;
          }
        }
      }
    }
  });
  // 3.-4. Merge and add, in pixel order.
  for (size_t i = 0; i < num_pixels; ++i) {
    if (!map.Valid(i)) continue;
    ++stats.valid_pixels;
    const Eigen::Vector3f& qc = map.vertices[i];
    const Eigen::Vector3f& nc = map.normals[i];
    const float radius_m = observed_radius(i);
    const std::array<uint8_t, 3> color =
        colors.empty() ? std::array<uint8_t, 3>{128, 128, 128} : colors[i];
    const uint32_t m = match_[i];
    if (m != kNoSurfel) {
      Surfel& s = surfels_[m];
      if (s.last_seen == frame_index) {
        ++stats.skipped;
        continue;
      }
      const float wgt = s.confidence, inv = 1.f / (wgt + 1.f);
      s.position = (wgt * s.position + (R * qc + t)) * inv;
      const Eigen::Vector3f n = wgt * s.normal + R * nc;
      const float nn = n.norm();
      if (nn > 0) s.normal = n / nn;
      s.radius_m = (wgt * s.radius_m + radius_m) * inv;
      for (int c = 0; c < 3; ++c) {
        s.color[c] = static_cast<uint8_t>(std::lround((wgt * s.color[c] + color[c]) * inv));
      }
      s.confidence = wgt + 1.f;
      s.last_seen = frame_index;
      ++stats.merged;
      continue;
    }
    Surfel s;
    s.position = R * qc + t;
    s.normal = R * nc;
    s.radius_m = radius_m;
    s.confidence = 1.f;
    s.first_seen = s.last_seen = frame_index;
    s.color = color;
    surfels_.push_back(s);
    ++stats.added;
  }
  // 5. Removal.
  stats.removed = RemoveUnstable(frame_index);
  return stats;
}

size_t SurfelMap::RemoveUnstable(int frame_index) {
  if (options_.unstable_min_confidence <= 0) return 0;
  const float min_conf = static_cast<float>(options_.unstable_min_confidence);
  const int age = options_.unstable_age_frames;
  const size_t before = surfels_.size();
  surfels_.erase(std::remove_if(surfels_.begin(),
                                surfels_.end(),
                                [&](const Surfel& s) {
                                  return frame_index - s.first_seen > age &&
                                         s.confidence < min_conf;
                                }),
                 surfels_.end());
  return before - surfels_.size();
}

}  // namespace lisfm
