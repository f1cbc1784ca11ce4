#include "sim/camera_simulator.h"

#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {
namespace sim {

bool CameraSimOptions::Check() const {
  CHECK_OPTION_MSG(supersampling, supersampling >= 1 && supersampling <= 8, "in [1, 8]");
  CHECK_OPTION_GT(exposure, 0.0);
  CHECK_OPTION_GE(noise_sigma, 0.0);
  CHECK_OPTION_GE(noise_scale, 0.0);
  CHECK_OPTION_MSG(vignetting, vignetting >= 0 && vignetting <= 1, "in [0, 1]");
  CHECK_OPTION_GT(max_range, 0.0);
  return true;
}

CameraRenderer::CameraRenderer(const Scene& scene,
                               const CameraModel& model,
                               const TextureOptions& texture,
                               const CameraSimOptions& options)
    : scene_(scene), model_(model), texture_(texture), options_(options) {
  THROW_CHECK_OPTIONS(options_);
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

namespace {

inline uint64_t Mix64(uint64_t x) {  // splitmix64 finaliser
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  x ^= x >> 31;
  return x;
}

// Approximately standard normal from a 64-bit hash: the sum of four 16-bit
// uniforms (Irwin-Hall, variance 4/12) centred and scaled to unit variance.
inline float HashGaussian(uint64_t h) {
  const float sum = static_cast<float>((h & 0xffff) + ((h >> 16) & 0xffff) +
                                       ((h >> 32) & 0xffff) + (h >> 48));
  return (sum * (1.0f / 65536.0f) - 2.0f) * 1.7320508f;
}

}  // namespace

cv::Mat CameraRenderer::Render(const SE3& world_from_cam,
                               uint64_t noise_seed,
                               TimestampNs t_ns) const {
  const int w = model_.width, h = model_.height;
  cv::Mat image(h, w, options_.color ? CV_8UC3 : CV_8UC1);
  const Eigen::Matrix3f rot = world_from_cam.RotationMatrix().cast<float>();
  const Eigen::Vector3f origin = world_from_cam.translation().cast<float>();
  const float origin_arr[3] = {origin.x(), origin.y(), origin.z()};
  const Eigen::Vector3f light = Eigen::Vector3f(0.3f, 0.5f, 0.81f).normalized();
  const float max_range = static_cast<float>(options_.max_range);
  const float gain = static_cast<float>(options_.exposure) * 255.f;
  const float sigma = static_cast<float>(options_.noise_sigma * options_.noise_scale);
  const bool color = options_.color;
  const uint64_t noise_key = Mix64(noise_seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL);
  constexpr int kBlock = 4;  // 4x4 pixel blocks: one 16-ray packet per subsample
  const int block_rows = (h + kBlock - 1) / kBlock;
  const tbb::blocked_range<int> all_rows(0, block_rows, 2);
  tbb::parallel_for(all_rows, [&](const tbb::blocked_range<int>& r) {
    for (int by = r.begin(); by != r.end(); ++by) {
      const int y0 = by * kBlock;
      for (int x0 = 0; x0 < w; x0 += kBlock) {
        int pixel_x[16], pixel_y[16], valid[16];
        for (int k = 0; k < 16; ++k) {
          pixel_x[k] = x0 + (k & 3);
          pixel_y[k] = y0 + (k >> 2);
          valid[k] = pixel_x[k] < w && pixel_y[k] < h;
        }
        Eigen::Vector3f radiance[16];
        for (int k = 0; k < 16; ++k) radiance[k].setZero();
        for (int s = 0; s < samples_; ++s) {
          float dirs[16][3];
          for (int k = 0; k < 16; ++k) {
            const Eigen::Vector3f d =
                valid[k] ? Eigen::Vector3f(
                               rot * rays_[(static_cast<size_t>(pixel_y[k]) * w + pixel_x[k]) *
                                               samples_ + s])
                         : Eigen::Vector3f::UnitZ();
            dirs[k][0] = d.x();
            dirs[k][1] = d.y();
            dirs[k][2] = d.z();
          }
          RayHit hits[16];
          scene_.Intersect16At(t_ns, valid, origin_arr, dirs, max_range, /*coherent=*/true,
                               hits);
          for (int k = 0; k < 16; ++k) {
            if (!valid[k] || !hits[k].hit) continue;
            const Eigen::Vector3f p =
                origin + hits[k].distance * Eigen::Vector3f(dirs[k][0], dirs[k][1], dirs[k][2]);
            const float albedo =
                texture_.Albedo(hits[k].surface_id, p, TextureAxis(hits[k].normal));
            const float shade = 0.55f + 0.45f * std::fabs(hits[k].normal.dot(light));
            if (color) {
              radiance[k] += (albedo * shade) * texture_.Tint(hits[k].surface_id);
            } else {
              radiance[k].x() += albedo * shade;
            }
          }
        }
        for (int k = 0; k < 16; ++k) {
          if (!valid[k]) continue;
          const size_t index = static_cast<size_t>(pixel_y[k]) * w + pixel_x[k];
          const float scale = gain * vignette_[index] / samples_;
          if (color) {
            cv::Vec3b& px = image.at<cv::Vec3b>(pixel_y[k], pixel_x[k]);
            for (int c = 0; c < 3; ++c) {
              float v = radiance[k][2 - c] * scale;  // BGR
              if (sigma > 0) v += sigma * HashGaussian(Mix64(noise_key + 3 * index + c));
              px[c] = cv::saturate_cast<uint8_t>(v);
            }
          } else {
            float v = radiance[k].x() * scale;
            if (sigma > 0) v += sigma * HashGaussian(Mix64(noise_key + index));
            image.at<uint8_t>(pixel_y[k], pixel_x[k]) = cv::saturate_cast<uint8_t>(v);
          }
        }
      }
    }
  });
  return image;
}

cv::Mat CameraRenderer::RenderDepth(const SE3& world_from_cam, TimestampNs t_ns) const {
  const int w = model_.width, h = model_.height;
  cv::Mat depth(h, w, CV_32FC1, cv::Scalar(0));
  const Mat3 rot = world_from_cam.RotationMatrix();
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      const Vec3 ray_cam = model_.Unproject(Vec2(x, y));
      const RayHit hit = scene_.IntersectAt(t_ns, world_from_cam.translation(), rot * ray_cam,
                                            0.0, options_.max_range);
      if (hit.hit) depth.at<float>(y, x) = static_cast<float>(hit.distance * ray_cam.z());
    }
  });
  return depth;
}

}  // namespace sim
}  // namespace lisfm
