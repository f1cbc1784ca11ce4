#include "icp/rgbd_fusion.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <utility>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

namespace {

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

bool RgbdFusionOptions::Check() const {
  CHECK_OPTION_MSG(
      downsample_factor, downsample_factor >= 1 && downsample_factor <= 8, "in [1, 8]");
  CHECK_OPTION_GE(min_depth_m, 0.0);
  CHECK_OPTION_GT(max_depth_m, min_depth_m);
  CHECK_OPTION_GT(max_depth_jump, 0.0);
  CHECK_OPTION_MSG(normal_window_px, normal_window_px >= 1 && normal_window_px <= 5, "in [1, 5]");
  CHECK_OPTION_GE(crease_rejection_sigma, 0.0);
  CHECK_OPTION_MSG(
      max_incidence_deg, max_incidence_deg > 0 && max_incidence_deg <= 90, "in (0, 90]");
  CHECK_OPTION_GT(bilateral_sigma_px, 0.0);
  CHECK_OPTION_GT(bilateral_sigma_depth_m, 0.0);
  CHECK_OPTION_MSG(model_splat_px, model_splat_px >= 0 && model_splat_px <= 3, "in [0, 3]");
  return true;
}

RgbdFusion::RgbdFusion(const PinholeIntrinsics& full_intrinsics,
                       const RgbdFusionOptions& options,
                       const ProjectiveIcpOptions& icp_options,
                       const SurfelFusionOptions& fusion_options)
    : full_(full_intrinsics), options_(options), icp_options_(icp_options), map_(fusion_options) {
  THROW_CHECK_OPTIONS(options_);
  THROW_CHECK_OPTIONS(icp_options_);
  const int k = options_.downsample_factor;
  if (!(full_.fx > 0 && full_.fy > 0) || full_.width < 3 * k || full_.height < 3 * k) {
    throw InputError("RGB-D intrinsics",
                     "",
                     fmt::format("expected fx, fy > 0 and at least {}x{} pixels (downsample "
                                 "factor {}), found fx={} fy={} {}x{}",
                                 3 * k,
                                 3 * k,
                                 k,
                                 full_.fx,
                                 full_.fy,
                                 full_.width,
                                 full_.height));
  }
  // Pixel (u', v') of the downsampled image is pixel (k u', k v') of the input:
  // u = fx x/z + cx  =>  u' = (fx/k) x/z + cx/k.
  intrinsics_ = full_;
  intrinsics_.fx = full_.fx / k;
  intrinsics_.fy = full_.fy / k;
  intrinsics_.cx = full_.cx / k;
  intrinsics_.cy = full_.cy / k;
  intrinsics_.width = full_.width / k;
  intrinsics_.height = full_.height / k;
  frame_.intrinsics = intrinsics_;
}

void RgbdFusion::Preprocess(const std::vector<float>& depth_m, const std::vector<uint8_t>& rgb) {
  const size_t full_pixels = static_cast<size_t>(full_.width) * full_.height;
  if (depth_m.size() != full_pixels || (!rgb.empty() && rgb.size() != 3 * full_pixels)) {
    throw InputError("RGB-D frame",
                     fmt::format("frame {}", num_frames_),
                     fmt::format("expected a {}x{} depth image ({} pixels) and an RGB image of "
                                 "the same size, found {} depth pixels and {} RGB bytes",
                                 full_.width,
                                 full_.height,
                                 full_pixels,
                                 depth_m.size(),
                                 rgb.size()));
  }
  const int k = options_.downsample_factor;
  const int w = intrinsics_.width, h = intrinsics_.height;
  const size_t n = static_cast<size_t>(w) * h;
  depth_.resize(n);
  frame_.colors.resize(rgb.empty() ? 0 : n);
  tbb::parallel_for(0, h, [&](int v) {
    for (int u = 0; u < w; ++u) {
      const size_t src = static_cast<size_t>(v * k) * full_.width + static_cast<size_t>(u * k);
      const size_t dst = static_cast<size_t>(v) * w + u;
      const float z = depth_m[src];
      depth_[dst] = std::isfinite(z) && z > 0 ? z : 0.f;
      if (!rgb.empty()) frame_.colors[dst] = {rgb[3 * src], rgb[3 * src + 1], rgb[3 * src + 2]};
    }
  });
  const std::vector<float>* depth = &depth_;
  if (options_.bilateral_filter) {
    // Bilateral filter over valid neighbours within 2 sigma (pixels):
    // z' = sum w z_j / sum w, w = exp(-d^2 / 2 s^2 - (z_j - z)^2 / 2 s_z^2).
    filtered_.resize(n);
    const int reach = static_cast<int>(std::ceil(2.0 * options_.bilateral_sigma_px));
    const float inv_s2 =
        static_cast<float>(0.5 / (options_.bilateral_sigma_px * options_.bilateral_sigma_px));
    const float inv_z2 = static_cast<float>(
        0.5 / (options_.bilateral_sigma_depth_m * options_.bilateral_sigma_depth_m));
    tbb::parallel_for(0, h, [&](int v) {
      for (int u = 0; u < w; ++u) {
        const size_t i = static_cast<size_t>(v) * w + u;
        const float z = depth_[i];
        if (!(z > 0)) {
          filtered_[i] = 0.f;
          continue;
        }
        float sum = 0.f, sum_w = 0.f;
        for (int dv = -reach; dv <= reach; ++dv) {
          const int vv = v + dv;
          if (vv < 0 || vv >= h) continue;
          for (int du = -reach; du <= reach; ++du) {
            const int uu = u + du;
            if (uu < 0 || uu >= w) continue;
            const float zj = depth_[static_cast<size_t>(vv) * w + uu];
            if (!(zj > 0)) continue;
            const float wt = std::exp(-static_cast<float>(du * du + dv * dv) * inv_s2 -
                                      (zj - z) * (zj - z) * inv_z2);
            sum += wt * zj;
            sum_w += wt;
          }
        }
        filtered_[i] = sum / sum_w;
      }
    });
    depth = &filtered_;
  }
  ComputeVertexNormalMap(*depth,
                         intrinsics_,
                         options_.min_depth_m,
                         options_.max_depth_m,
                         options_.max_depth_jump,
                         &frame_.map,
                         options_.normal_window_px,
                         options_.crease_rejection_sigma);
  // Oblique observations: |n . q| / |q| = cos of the angle between normal and ray.
  const float min_cos = static_cast<float>(std::cos(options_.max_incidence_deg * M_PI / 180.0));
  tbb::parallel_for(size_t{0}, n, [&](size_t i) {
    if (!frame_.map.Valid(i)) return;
    const Eigen::Vector3f& q = frame_.map.vertices[i];
    if (std::abs(frame_.map.normals[i].dot(q)) < min_cos * q.norm())
      frame_.map.normals[i].setZero();
  });
}

RgbdFrameResult RgbdFusion::AddFrame(const std::vector<float>& depth_m,
                                     const std::vector<uint8_t>& rgb,
                                     const std::optional<SE3>& world_from_camera) {
  RgbdFrameResult result;
  auto t0 = std::chrono::steady_clock::now();
  Preprocess(depth_m, rgb);

  // Intensity pyramid of this frame: the photometric source now, the target next.
  const bool tracking_next = !world_from_camera || num_frames_ == 0;
  const bool photometric = icp_options_.photometric_weight > 0 && !rgb.empty();
  if (photometric && tracking_next) {
    intensity_.resize(frame_.colors.size());
    tbb::parallel_for(size_t{0}, frame_.colors.size(), [&](size_t i) {
      const std::array<uint8_t, 3>& c = frame_.colors[i];
      intensity_[i] = (0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2]) * (1.f / 255.f);
    });
    BuildIntensityPyramid(intensity_,
                          intrinsics_.width,
                          intrinsics_.height,
                          icp_options_.num_levels,
                          &intensity_pyramid_);
  } else {
    intensity_pyramid_.levels.clear();
  }
  result.preprocess_ms = MsSince(t0);

  t0 = std::chrono::steady_clock::now();
  if (world_from_camera || num_frames_ == 0) {
    result.world_from_camera = world_from_camera ? *world_from_camera : SE3();
  } else {
    // model_ holds the model at previous_ (rendered after the last fusion).
    // previous_from_current: the last motion (constant velocity) or none.
    const SE3 initial = options_.constant_velocity ? previous_motion_ : SE3();
    result.icp = RegisterProjective(frame_.map,
                                    model_,
                                    intrinsics_,
                                    initial,
                                    icp_options_,
                                    &intensity_pyramid_,
                                    &previous_intensity_pyramid_);
    result.tracked = result.icp.num_inliers >= static_cast<size_t>(icp_options_.min_inliers) &&
                     result.icp.target_from_source.translation().allFinite();
    result.world_from_camera =
        previous_ * (result.tracked ? result.icp.target_from_source : initial);
  }
  result.track_ms = MsSince(t0);

  t0 = std::chrono::steady_clock::now();
  result.fuse = map_.Fuse(frame_, result.world_from_camera, num_frames_);
  num_input_points_ += result.fuse.valid_pixels;
  result.fuse_ms = MsSince(t0);

  t0 = std::chrono::steady_clock::now();
  if (!world_from_camera || num_frames_ == 0) {
    // The next frame's tracking target; only needed while tracking.
    // One render gives the geometric target and the index map of the colour target.
    std::vector<uint32_t>& index = model_index_;
    map_.RenderVertexNormalMap(
        result.world_from_camera, intrinsics_, 0.0, options_.model_splat_px, &model_, &index);
    if (!intensity_pyramid_.empty() && !frame_.colors.empty()) {
      // The photometric target: the model's colour rendered at this pose (world-anchored
      // texture), this frame's intensity where no surfel is seen.
      const std::vector<Surfel>& surfels = map_.surfels();
      tbb::parallel_for(size_t{0}, index.size(), [&](size_t i) {
        if (index[i] == SurfelMap::kNoSurfel) return;
        const std::array<uint8_t, 3>& c = surfels[index[i]].color;
        intensity_[i] = (0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2]) * (1.f / 255.f);
      });
      BuildIntensityPyramid(intensity_,
                            intrinsics_.width,
                            intrinsics_.height,
                            icp_options_.num_levels,
                            &intensity_pyramid_);
    }
  }
  result.track_ms += MsSince(t0);
  previous_motion_ = num_frames_ == 0 ? SE3() : previous_.Inverse() * result.world_from_camera;
  previous_ = result.world_from_camera;
  std::swap(intensity_pyramid_, previous_intensity_pyramid_);
  ++num_frames_;
  return result;
}

}  // namespace lisfm
