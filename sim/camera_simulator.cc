#include "sim/camera_simulator.h"

#include <cmath>
#include <random>

#include <tbb/parallel_for.h>

#include "core/errors.h"

namespace lisfm {
namespace sim {

CameraRenderer::CameraRenderer(const Scene& scene,
                               const CameraModel& model,
                               const TextureOptions& texture,
                               const CameraSimOptions& options)
    : scene_(scene), model_(model), texture_(texture), options_(options) {
  THROW_CHECK_GE(options_.supersampling, 1);
  THROW_CHECK_GT(model_.width, 0);
  THROW_CHECK_GT(model_.height, 0);
  const int n = options_.supersampling;
  samples_ = n * n;
  const int w = model_.width, h = model_.height;
  rays_.resize(static_cast<size_t>(w) * h * samples_);
  vignette_.resize(static_cast<size_t>(w) * h);
  const double half_diag = 0.5 * std::hypot(w, h);
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      for (int sy = 0; sy < n; ++sy) {
        for (int sx = 0; sx < n; ++sx) {
          // Pixel centres at integer coordinates (OpenCV/Kalibr convention).
          const Vec2 pixel(x + (sx + 0.5) / n - 0.5, y + (sy + 0.5) / n - 0.5);
          rays_[(static_cast<size_t>(y) * w + x) * samples_ + sy * n + sx] =
              model_.Unproject(pixel).cast<float>();
        }
      }
      const double r = std::hypot(x - model_.cx, y - model_.cy) / half_diag;
      vignette_[static_cast<size_t>(y) * w + x] =
          static_cast<float>(1.0 - options_.vignetting * r * r);
    }
  });
}

cv::Mat CameraRenderer::Render(const SE3& world_from_cam, uint64_t noise_seed) const {
  const int w = model_.width, h = model_.height;
  cv::Mat image(h, w, options_.color ? CV_8UC3 : CV_8UC1);
  const Eigen::Matrix3f rot = world_from_cam.RotationMatrix().cast<float>();
  const Eigen::Vector3f origin = world_from_cam.translation().cast<float>();
  const float origin_arr[3] = {origin.x(), origin.y(), origin.z()};
  const Eigen::Vector3f light = Eigen::Vector3f(0.3f, 0.5f, 0.81f).normalized();
  const float max_range = static_cast<float>(options_.max_range);
  const float gain = static_cast<float>(options_.exposure) * 255.f;
  const float sigma = static_cast<float>(options_.noise_sigma * options_.noise_scale);
  tbb::parallel_for(0, h, [&](int y) {
    std::mt19937 rng(static_cast<uint32_t>(noise_seed * 0x9E3779B1u + y * 0x85EBCA77u + 1u));
    std::normal_distribution<float> normal(0.f, 1.f);
    const size_t total = static_cast<size_t>(w) * samples_;
    std::vector<Eigen::Vector3f> radiance(w, Eigen::Vector3f::Zero());
    for (size_t base = 0; base < total; base += 8) {
      int valid[8];
      float dirs[8][3];
      for (int k = 0; k < 8; ++k) {
        const size_t idx = base + k;
        valid[k] = idx < total;
        const Eigen::Vector3f d =
            valid[k] ? Eigen::Vector3f(rot * rays_[static_cast<size_t>(y) * total + idx])
                     : Eigen::Vector3f::UnitZ();
        dirs[k][0] = d.x();
        dirs[k][1] = d.y();
        dirs[k][2] = d.z();
      }
      RayHit hits[8];
      scene_.Intersect8(valid, origin_arr, dirs, max_range, hits);
      for (int k = 0; k < 8; ++k) {
        if (!valid[k] || !hits[k].hit) continue;
        const Eigen::Vector3f d(dirs[k][0], dirs[k][1], dirs[k][2]);
        const Eigen::Vector3f p = origin + hits[k].distance * d;
        const float albedo = Albedo(texture_, hits[k].surface_id, p);
        const float shade = 0.55f + 0.45f * std::fabs(hits[k].normal.dot(light));
        Eigen::Vector3f value = Eigen::Vector3f::Constant(albedo * shade);
        if (options_.color) value = value.cwiseProduct(SurfaceTint(texture_, hits[k].surface_id));
        radiance[(base + k) / samples_] += value;
      }
    }
    for (int x = 0; x < w; ++x) {
      const float scale = gain * vignette_[static_cast<size_t>(y) * w + x] / samples_;
      if (options_.color) {
        cv::Vec3b& px = image.at<cv::Vec3b>(y, x);
        for (int c = 0; c < 3; ++c) {
          float v = radiance[x][2 - c] * scale;  // BGR
          if (sigma > 0) v += sigma * normal(rng);
          px[c] = cv::saturate_cast<uint8_t>(v);
        }
      } else {
        float v = radiance[x].x() * scale;
        if (sigma > 0) v += sigma * normal(rng);
        image.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(v);
      }
    }
  });
  return image;
}

cv::Mat CameraRenderer::RenderDepth(const SE3& world_from_cam) const {
  const int w = model_.width, h = model_.height;
  cv::Mat depth(h, w, CV_32FC1, cv::Scalar(0));
  const Mat3 rot = world_from_cam.RotationMatrix();
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      const Vec3 ray_cam = model_.Unproject(Vec2(x, y));
      const RayHit hit = scene_.Intersect(world_from_cam.translation(), rot * ray_cam, 0.0,
                                          options_.max_range);
      if (hit.hit) depth.at<float>(y, x) = static_cast<float>(hit.distance * ray_cam.z());
    }
  });
  return depth;
}

}  // namespace sim
}  // namespace lisfm
