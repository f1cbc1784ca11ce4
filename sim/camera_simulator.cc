#include "sim/camera_simulator.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"
#include "core/option_check.h"
#include "sim/hash_random.h"

namespace lisfm {
namespace sim {

bool CameraSimOptions::Check() const {
  CHECK_OPTION_MSG(supersampling, supersampling >= 1 && supersampling <= 8, "in [1, 8]");
  CHECK_OPTION_GT(exposure, 0.0);
  CHECK_OPTION_GE(noise_sigma, 0.0);
  CHECK_OPTION_GE(noise_scale, 0.0);
  CHECK_OPTION_MSG(vignetting, vignetting >= 0 && vignetting <= 1, "in [0, 1]");
  CHECK_OPTION_GT(max_range, 0.0);
  CHECK_OPTION_NESTED(errors);
  return true;
}

namespace {

// Casts `samples` rays per pixel (rays[pixel * samples + s], camera frame,
// rotated by `rot` from `origin`) at time t_ns, in 16-ray packets of 4x4 pixels,
// TBB-parallel over rows of packets. Per pixel an accumulator starts at zero;
// on_hit(acc, index, s, hit, point) is called for each hit of sample s, in
// sample order, then on_pixel(index, x, y, acc) once. index = y * width + x.
template <typename OnHit, typename OnPixel>
void TracePixelPackets(const Scene& scene,
                       const std::vector<Eigen::Vector3f>& rays,
                       int samples,
                       int width,
                       int height,
                       const Eigen::Matrix3f& rot,
                       const Eigen::Vector3f& origin,
                       TimestampNs t_ns,
                       float max_range,
                       const OnHit& on_hit,
                       const OnPixel& on_pixel) {
  const float origin_arr[3] = {origin.x(), origin.y(), origin.z()};
  constexpr int kBlock = 4;  // 4x4 pixel blocks: one 16-ray packet per sample
  const int block_rows = (height + kBlock - 1) / kBlock;
  tbb::parallel_for(
      tbb::blocked_range<int>(0, block_rows, 2), [&](const tbb::blocked_range<int>& r) {
        for (int by = r.begin(); by != r.end(); ++by) {
          const int y0 = by * kBlock;
          for (int x0 = 0; x0 < width; x0 += kBlock) {
            int pixel_x[16], pixel_y[16], valid[16];
            size_t index[16];
            for (int k = 0; k < 16; ++k) {
              pixel_x[k] = x0 + (k & 3);
              pixel_y[k] = y0 + (k >> 2);
              valid[k] = pixel_x[k] < width && pixel_y[k] < height;
              index[k] = static_cast<size_t>(pixel_y[k]) * width + pixel_x[k];
            }
            Eigen::Vector3f acc[16];
            for (int k = 0; k < 16; ++k) acc[k].setZero();
            for (int s = 0; s < samples; ++s) {
              float dirs[16][3];
              for (int k = 0; k < 16; ++k) {
                const Eigen::Vector3f d = valid[k]
                                              ? Eigen::Vector3f(rot * rays[index[k] * samples + s])
                                              : Eigen::Vector3f::UnitZ();
                dirs[k][0] = d.x();
                dirs[k][1] = d.y();
                dirs[k][2] = d.z();
              }
              RayHit hits[16];
              scene.Intersect16At(
                  t_ns, valid, origin_arr, dirs, max_range, /*coherent=*/true, hits);
              for (int k = 0; k < 16; ++k) {
                if (!valid[k] || !hits[k].hit) continue;
                const Eigen::Vector3f p =
                    origin + hits[k].distance * Eigen::Vector3f(dirs[k][0], dirs[k][1], dirs[k][2]);
                on_hit(acc[k], index[k], s, hits[k], p);
              }
            }
            for (int k = 0; k < 16; ++k) {
              if (valid[k]) on_pixel(index[k], pixel_x[k], pixel_y[k], acc[k]);
            }
          }
        }
      });
}

}  // namespace

CameraRenderer::CameraRenderer(const Scene& scene,
                               const CameraModel& model,
                               const TextureOptions& texture,
                               const CameraSimOptions& options,
                               const SceneLighting* lighting)
    : scene_(scene), model_(model), texture_(texture), options_(options), lighting_(lighting) {
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
  if (options_.errors_enabled && options_.errors.motion_blur) {
    // Central differences of the projection around the unit ray of each
    // block's centre (step 1e-4: the truncation error is ~1e-8 of the
    // Jacobian; across a block the Jacobian changes by ~1 %).
    const int gw = (w + kJacobianBlock - 1) / kJacobianBlock;
    const int gh = (h + kJacobianBlock - 1) / kJacobianBlock;
    jacobians_.resize(static_cast<size_t>(gw) * gh);
    constexpr double kStep = 1e-4;
    tbb::parallel_for(0, gh, [&](int by) {
      for (int bx = 0; bx < gw; ++bx) {
        const Vec2 centre(std::min(bx * kJacobianBlock + 0.5 * (kJacobianBlock - 1), w - 1.0),
                          std::min(by * kJacobianBlock + 0.5 * (kJacobianBlock - 1), h - 1.0));
        const Vec3 d = model_.Unproject(centre);
        Eigen::Matrix<float, 2, 3>& jac = jacobians_[static_cast<size_t>(by) * gw + bx];
        jac.setZero();
        for (int a = 0; a < 3; ++a) {
          Vec2 plus, minus;
          if (!model_.Project(d + kStep * Vec3::Unit(a), &plus, false) ||
              !model_.Project(d - kStep * Vec3::Unit(a), &minus, false)) {
            jac.setZero();
            break;
          }
          jac.col(a) = ((plus - minus) / (2 * kStep)).cast<float>();
        }
      }
    });
  }
}

cv::Mat CameraRenderer::Render(const SE3& world_from_cam,
                               uint64_t noise_seed,
                               TimestampNs t_ns) const {
  const int w = model_.width, h = model_.height;
  cv::Mat image(h, w, options_.color ? CV_8UC3 : CV_8UC1);
  const Eigen::Matrix3f rot = world_from_cam.RotationMatrix().cast<float>();
  const Eigen::Vector3f origin = world_from_cam.translation().cast<float>();
  const Eigen::Vector3f light = Eigen::Vector3f(0.3f, 0.5f, 0.81f).normalized();
  const float max_range = static_cast<float>(options_.max_range);
  const float gain = static_cast<float>(options_.exposure) * 255.f;
  const float sigma = static_cast<float>(options_.noise_sigma * options_.noise_scale);
  const bool color = options_.color;
  const uint64_t noise_key = Mix64(noise_seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL);
  TracePixelPackets(
      scene_,
      rays_,
      samples_,
      w,
      h,
      rot,
      origin,
      t_ns,
      max_range,
      [&](Eigen::Vector3f& radiance, size_t, int, const RayHit& hit, const Eigen::Vector3f& p) {
        const float albedo = texture_.Albedo(hit.surface_id, p, TextureAxis(hit.normal));
        const float shade = 0.55f + 0.45f * std::fabs(hit.normal.dot(light));
        if (color) {
          radiance += (albedo * shade) * texture_.Tint(hit.surface_id);
        } else {
          radiance.x() += albedo * shade;
        }
      },
      [&](size_t index, int x, int y, const Eigen::Vector3f& radiance) {
        const float scale = gain * vignette_[index] / samples_;
        if (color) {
          cv::Vec3b& px = image.at<cv::Vec3b>(y, x);
          for (int c = 0; c < 3; ++c) {
            float v = radiance[2 - c] * scale;  // BGR
            if (sigma > 0) v += sigma * HashGaussian(Mix64(noise_key + 3 * index + c));
            px[c] = cv::saturate_cast<uint8_t>(v);
          }
        } else {
          float v = radiance.x() * scale;
          if (sigma > 0) v += sigma * HashGaussian(Mix64(noise_key + index));
          image.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(v);
        }
      });
  return image;
}

cv::Mat CameraRenderer::Render(const SE3& world_from_cam,
                               const CameraExposure& exposure,
                               uint64_t noise_seed,
                               TimestampNs t_ns) const {
  THROW_CHECK(options_.errors_enabled);
  const CameraErrorOptions& e = options_.errors;
  const int w = model_.width, h = model_.height;
  const bool color = options_.color;
  const int channels = color ? 3 : 1;
  const LightField light = lighting_ != nullptr ? lighting_->At(exposure.time_s) : LightField();
  const Eigen::Matrix3f rot = world_from_cam.RotationMatrix().cast<float>();
  const Eigen::Vector3f origin = world_from_cam.translation().cast<float>();
  const Eigen::Vector3f sun = Eigen::Vector3f(0.3f, 0.5f, 0.81f).normalized();
  const float max_range = static_cast<float>(options_.max_range);
  const size_t num_pixels = static_cast<size_t>(w) * h;
  // Radiance (before the exposure) per pixel and channel, and the hit
  // distance of each pixel's first ray (0: no hit).
  std::vector<float> radiance(num_pixels * channels, 0.f), distance(num_pixels, 0.f);
  TracePixelPackets(
      scene_,
      rays_,
      samples_,
      w,
      h,
      rot,
      origin,
      t_ns,
      max_range,
      [&](Eigen::Vector3f& sum, size_t index, int s, const RayHit& hit, const Eigen::Vector3f& p) {
        const float albedo =
            MaterialAlbedo(scene_.material(hit.surface_id),
                           texture_.Albedo(hit.surface_id, p, TextureAxis(hit.normal)));
        const float shade = 0.55f + 0.45f * std::fabs(hit.normal.dot(sun));
        const float value = albedo * shade * light.Level(p);
        if (color) {
          sum += value * texture_.Tint(hit.surface_id);
        } else {
          sum.x() += value;
        }
        if (s == 0) distance[index] = hit.distance;
      },
      [&](size_t index, int, int, const Eigen::Vector3f& sum) {
        const float scale = vignette_[index] / samples_;
        for (int c = 0; c < channels; ++c) {
          radiance[index * channels + c] = sum[color ? 2 - c : 0] * scale;  // BGR
        }
      });

  // Exposure and sensor noise, in DN.
  const double product = exposure.setting.exposure_s * exposure.setting.gain;
  const float to_dn = static_cast<float>(256.0 / e.reference_exposure_s() * product);
  const float k_gain = static_cast<float>(255.0 / e.full_well_e * exposure.setting.gain);
  const float shot = e.shot_noise ? k_gain : 0.f;
  const float read = k_gain * static_cast<float>(e.read_noise_e);
  const float read2 = read * read;
  const float noise_scale = static_cast<float>(options_.noise_scale);
  const uint64_t noise_key = Mix64(noise_seed * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL);

  // Motion blur: the pixel's image motion over the exposure, from the hit
  // point X = s ray in the middle camera frame moved to the start and end
  // camera frames: dX / s = (R_em - R_sm) ray + (t_em - t_sm) / s.
  const bool blur = e.motion_blur && !jacobians_.empty() && exposure.setting.exposure_s > 0;
  const SE3 end_from_mid = exposure.world_from_cam_end.Inverse() * world_from_cam;
  const SE3 start_from_mid = exposure.world_from_cam_start.Inverse() * world_from_cam;
  const Eigen::Matrix3f d_rot =
      (end_from_mid.RotationMatrix() - start_from_mid.RotationMatrix()).cast<float>();
  const Eigen::Vector3f d_trans =
      (end_from_mid.translation() - start_from_mid.translation()).cast<float>();
  const int blocks_per_row = (w + kJacobianBlock - 1) / kJacobianBlock;
  // Bilinear radiance of channel c at (x, y) in [0, w - 1) x [0, h - 1).
  auto sample = [&](float x, float y, int c) {
    const int ix = static_cast<int>(x), iy = static_cast<int>(y);
    const float fx = x - ix, fy = y - iy;
    const float* row0 = radiance.data() + (static_cast<size_t>(iy) * w + ix) * channels + c;
    const float* row1 = row0 + static_cast<size_t>(w) * channels;
    const float a = row0[0] + (row0[channels] - row0[0]) * fx;
    const float b = row1[0] + (row1[channels] - row1[0]) * fx;
    return a + (b - a) * fy;
  };
  const float x_max = std::nextafter(static_cast<float>(w - 1), 0.f);
  const float y_max = std::nextafter(static_cast<float>(h - 1), 0.f);
  cv::Mat image(h, w, color ? CV_8UC3 : CV_8UC1);
  tbb::parallel_for(0, h, [&](int y) {
    uint8_t* row = image.ptr<uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      const size_t index = static_cast<size_t>(y) * w + x;
      float value[3];
      for (int c = 0; c < channels; ++c) value[c] = radiance[index * channels + c];
      const float s = distance[index];
      if (blur && s > 0) {
        const Eigen::Vector3f ray = rays_[index * samples_];
        const size_t block =
            static_cast<size_t>(y / kJacobianBlock) * blocks_per_row + x / kJacobianBlock;
        const Eigen::Vector2f motion = jacobians_[block] * (d_rot * ray + d_trans / s);
        const float length = motion.norm();
        if (length >= 0.5f) {  // under half a pixel (or not finite): sharp
          // Midpoint rule over the motion segment, samples <= 1 px apart.
          const int n = std::min(64, std::max(2, static_cast<int>(std::ceil(length))));
          // The samples clamped to the image (a segment leaving the image
          // repeats its border).
          float sx[64], sy[64];
          for (int k = 0; k < n; ++k) {
            const float a = (static_cast<float>(k) + 0.5f) / n - 0.5f;
            sx[k] = std::min(std::max(x + a * motion.x(), 0.f), x_max);
            sy[k] = std::min(std::max(y + a * motion.y(), 0.f), y_max);
          }
          for (int c = 0; c < channels; ++c) {
            float acc = 0;
            for (int k = 0; k < n; ++k) acc += sample(sx[k], sy[k], c);
            value[c] = acc / n;
          }
        }
      }
      for (int c = 0; c < channels; ++c) {
        float v = to_dn * value[c];
        if (noise_scale > 0) {
          const float sigma = std::sqrt(shot * v + read2);
          v += noise_scale * sigma * HashGaussian(Mix64(noise_key + index * channels + c));
        }
        row[x * channels + c] = cv::saturate_cast<uint8_t>(v);
      }
    }
  });
  return image;
}

double CameraRenderer::MeterRadiance(const SE3& world_from_cam,
                                     double time_s,
                                     TimestampNs t_ns) const {
  constexpr int kStride = 32;
  const int w = model_.width, h = model_.height;
  const LightField light = lighting_ != nullptr ? lighting_->At(time_s) : LightField();
  const Eigen::Matrix3f rot = world_from_cam.RotationMatrix().cast<float>();
  const Eigen::Vector3f origin = world_from_cam.translation().cast<float>();
  const float origin_arr[3] = {origin.x(), origin.y(), origin.z()};
  const Eigen::Vector3f sun = Eigen::Vector3f(0.3f, 0.5f, 0.81f).normalized();
  std::vector<size_t> pixels;
  for (int y = kStride / 2; y < h; y += kStride) {
    for (int x = kStride / 2; x < w; x += kStride) pixels.push_back(static_cast<size_t>(y) * w + x);
  }
  std::vector<float> values(pixels.size(), 0.f);
  for (size_t i0 = 0; i0 < pixels.size(); i0 += 16) {
    int valid[16];
    float dirs[16][3];
    for (int k = 0; k < 16; ++k) {
      valid[k] = i0 + k < pixels.size();
      const Eigen::Vector3f d =
          valid[k] ? Eigen::Vector3f(rot * rays_[pixels[i0 + k] * samples_]) : Eigen::Vector3f::UnitZ();
      dirs[k][0] = d.x();
      dirs[k][1] = d.y();
      dirs[k][2] = d.z();
    }
    RayHit hits[16];
    scene_.Intersect16At(t_ns, valid, origin_arr, dirs, static_cast<float>(options_.max_range),
                         /*coherent=*/false, hits);
    for (int k = 0; k < 16; ++k) {
      if (!valid[k] || !hits[k].hit) continue;
      const Eigen::Vector3f p =
          origin + hits[k].distance * Eigen::Vector3f(dirs[k][0], dirs[k][1], dirs[k][2]);
      const float albedo = MaterialAlbedo(
          scene_.material(hits[k].surface_id),
          texture_.Albedo(hits[k].surface_id, p, TextureAxis(hits[k].normal)));
      const float shade = 0.55f + 0.45f * std::fabs(hits[k].normal.dot(sun));
      values[i0 + k] = albedo * shade * light.Level(p) * vignette_[pixels[i0 + k]];
    }
  }
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
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
