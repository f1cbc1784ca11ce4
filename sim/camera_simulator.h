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
// Thread safety: Render() is const and may run concurrently.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera_model.h"
#include "core/geometry.h"
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
  bool Check() const;
};

class CameraRenderer {
 public:
  CameraRenderer(const Scene& scene,
                 const CameraModel& model,
                 const TextureOptions& texture,
                 const CameraSimOptions& options);

  // Renders the view of a camera at `world_from_cam` (z forward) at time
  // `t_ns` (where the scene's people are; irrelevant without people).
  // `noise_seed` makes the pixel noise deterministic.
  cv::Mat Render(const SE3& world_from_cam, uint64_t noise_seed, TimestampNs t_ns = 0) const;

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
};

}  // namespace sim
}  // namespace lisfm
