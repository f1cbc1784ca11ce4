// Camera rendering by ray casting through the scene (global shutter).
// The ray of every (sub)pixel is precomputed once per camera with
// CameraModel::Unproject (any Kalibr model: equidistant fisheye, radtan,
// none). Pixel value = exposure * albedo(hit) * shading * vignetting + noise,
// with view-independent shading (ambient + one fixed directional light in the
// scene frame, so a surface point looks the same from every view), 8-bit
// grayscale (default) or BGR colour (albedo tinted per surface).
//
// Rays are traced as Embree packets of 16 (4x4 pixel blocks, one packet per
// subsample), blocks of rows run in parallel with TBB. Pixel noise is a
// counter-based approximate Gaussian (sum of 4 uniforms from a hash of the
// seed and the pixel index, so it is deterministic and independent of the
// thread schedule; bounded at +-3.46 sigma).
//
// With error sources (CameraSimOptions::errors_enabled, sim/camera_errors.h)
// Render(world_from_cam, exposure, seed) renders one exposure instead: the
// material albedo (sim/materials.h) lit by the scene lighting at the hit
// point, the exposure time and gain of the auto exposure, motion blur along
// each pixel's image motion between the exposure's start and end poses (the
// pixel's hit point moved with the projection Jacobian at its 4x4 block's
// centre ray, a first-order model of the motion), and shot + read noise. The radiance is
// blurred before the noise, as on a real sensor.
//
// Thread safety: Render() is const and may run concurrently.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera_model.h"
#include "core/geometry.h"
#include "sim/camera_errors.h"
#include "sim/scene.h"
#include "sim/texture.h"

namespace lisfm {
namespace sim {

struct CameraSimOptions {
  int supersampling = 1;        // n x n rays per pixel (1 = pixel centre only)
  bool color = false;           // BGR 8-bit instead of 8-bit grayscale
  double exposure = 1.0;        // gain on the rendered radiance
  double noise_sigma = 2.0;     // Gaussian pixel noise, DN at noise_scale 1
  double noise_scale = 1.0;     // 0 = noise-free
  double vignetting = 0.15;     // relative darkening at the image corner
  double max_range = 200.0;     // m; rays that hit nothing render black
  bool errors_enabled = false;  // Render(pose, exposure, seed) applies `errors`
  CameraErrorOptions errors;
  bool Check() const;
};

// One exposure of a camera (error-source rendering).
struct CameraExposure {
  double time_s = 0;         // middle of the exposure, s since the sequence start (lighting)
  ExposureSetting setting;   // exposure time and gain
  SE3 world_from_cam_start;  // camera pose at the start of the exposure
  SE3 world_from_cam_end;    // and at its end (motion blur)
};

class CameraRenderer {
 public:
  // `lighting` (may be null: a uniform level 1) is used by the error-source
  // rendering and must outlive the renderer.
  CameraRenderer(const Scene& scene,
                 const CameraModel& model,
                 const TextureOptions& texture,
                 const CameraSimOptions& options,
                 const SceneLighting* lighting = nullptr);

  // Renders the view of a camera at `world_from_cam` (z forward) at time
  // `t_ns` (where the scene's people are; irrelevant without people).
  // `noise_seed` makes the pixel noise deterministic. No error sources.
  cv::Mat Render(const SE3& world_from_cam, uint64_t noise_seed, TimestampNs t_ns = 0) const;

  // Renders one exposure with the error sources (options.errors_enabled must
  // be set): `world_from_cam` is the pose at the middle of the exposure.
  // People are where they are at `t_ns` (the middle of the exposure).
  cv::Mat Render(const SE3& world_from_cam,
                 const CameraExposure& exposure,
                 uint64_t noise_seed,
                 TimestampNs t_ns = 0) const;

  // The median radiance (albedo x shading x light x vignetting, before the
  // exposure) over a grid of every 32nd pixel: what the auto exposure meters.
  // People are where they are at `t_ns`.
  double MeterRadiance(const SE3& world_from_cam, double time_s, TimestampNs t_ns = 0) const;

  // Depth along the optical axis (z in the camera frame, m) per pixel centre
  // at time `t_ns`; 0 where nothing was hit. Used by the RGB-D simulation and
  // tests.
  cv::Mat RenderDepth(const SE3& world_from_cam, TimestampNs t_ns = 0) const;

  const CameraModel& model() const { return model_; }

 private:
  const Scene& scene_;
  CameraModel model_;
  Texture texture_;
  CameraSimOptions options_;
  int samples_ = 1;                     // rays per pixel
  std::vector<Eigen::Vector3f> rays_;   // per pixel, samples_ unit rays (camera frame)
  std::vector<float> vignette_;         // per pixel gain
  const SceneLighting* lighting_ = nullptr;
  // Per block of kJacobianBlock^2 pixels (row-major), the 2x3 Jacobian of the
  // projection at the unit ray through the block's centre: pixel motion =
  // J (dX / s) for a point X = s ray moving by dX. Only with errors_enabled
  // and motion blur.
  static constexpr int kJacobianBlock = 4;
  std::vector<Eigen::Matrix<float, 2, 3>> jacobians_;
};

}  // namespace sim
}  // namespace lisfm
