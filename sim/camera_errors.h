// Camera error sources of the simulator (the `camera` token of
// SimulatorOptions::error_sources): scene lighting that varies between areas
// and over time, an auto-exposure controller, the exposure's motion blur and
// sensor noise. The renderer (sim/camera_simulator.h) applies them per pixel:
//
//   radiance  = MaterialAlbedo(material, texture) * shading * light(p, t) * vignetting
//   blurred   = mean of the radiance along the pixel's image motion during the exposure
//   DN        = G * exposure_s * gain * blurred,   G = 256 / reference_exposure_s
//   DN noise  ~ N(0, K g DN + (K g read_noise_e)^2),   K = 255 / full_well_e  (DN / e-)
//
// so a surface of radiance 0.5 renders at 128 DN after reference_exposure_ms
// at gain 1. Sensor figures are the Alphasense Core's (HILTI 2022 rig): Sony
// IMX287 0.4 MP global shutter (`image_sensor_type IMX287`), image stamps at
// the middle of the exposure, auto exposure on the image median
// (sevensense-robotics/core_research_manual: sensor_settings.md, faq.md,
// ncamera_settings.yaml).
//
// Thread safety: SceneLighting and LightField are immutable after
// construction; AutoExposure is a sequential controller (one per camera).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace lisfm {
namespace sim {

struct CameraErrorOptions {
  // Auto exposure: a first-order lag in log exposure toward the exposure that
  // puts the image median at the target, updated at ae_rate_hz on the median
  // of the previous update's frame; exposure time first, then gain.
  bool auto_exposure = true;                 // 0 = fixed: reference_exposure_ms at gain 1
  double ae_target_median_dn = 70.0;         // Alphasense autoexp_target_median default 70
  double ae_time_constant_s = 0.3;           // lag of the exposure (log domain), s
  double ae_rate_hz = 10.0;                  // controller updates per second
  double min_exposure_ms = 0.05;             // Alphasense min_exp_time_us default 50
  double max_exposure_ms = 10.0;             // Alphasense max_exp_time_us default 10000
  double max_gain = 5.6;                     // Alphasense: gain 255 = x5.6 sensitivity
  double reference_exposure_ms = 8.0;        // radiance 0.5 -> 128 DN at gain 1 (see above)
  // Sensor noise (IMX287).
  bool shot_noise = true;                    // Poisson noise of the collected electrons
  double full_well_e = 22000.0;              // electrons at 255 DN and gain 1
  double read_noise_e = 7.0;                 // temporal dark noise, electrons; 0 = off
  // Motion blur from the exposure time and the true motion.
  bool motion_blur = true;
  // Scene lighting: a level per cell of a light_cell_m x light_cell_m x 3 m
  // lattice, log-uniform in [ratio^-1/2, ratio^1/2], interpolated
  // trilinearly; each node varies slowly over time as
  // 1 + amplitude sin(2 pi t / period + phase_node).
  double light_level_ratio = 10.0;           // brightest / darkest area; 1 = uniform
  double light_cell_m = 6.0;                 // lattice spacing (about a room), m
  double light_change_amplitude = 0.2;       // relative change over time; 0 = off
  double light_change_period_s = 60.0;       // s

  bool Check() const;
  double reference_exposure_s() const { return 1e-3 * reference_exposure_ms; }
};

// The light level at one time: a small lattice over the scene.
class LightField {
 public:
  // Level at scene point p (trilinear; clamped at the lattice border).
  float Level(const Eigen::Vector3f& p) const;

 private:
  friend class SceneLighting;
  Eigen::Vector3f origin_ = Eigen::Vector3f::Zero();  // node (0, 0, 0), scene frame
  Eigen::Vector3f inv_cell_ = Eigen::Vector3f::Ones();
  int nx_ = 1, ny_ = 1, nz_ = 1;
  std::vector<float> levels_ = {1.f};  // x fastest
};

class SceneLighting {
 public:
  // The lattice covers `bounds` (scene frame); levels and phases are hashes of
  // (seed, lattice index), so they do not depend on the bounds.
  SceneLighting(const Eigen::AlignedBox3d& bounds,
                uint32_t seed,
                const CameraErrorOptions& options);
  // The field at time t_s (s since the sequence start).
  LightField At(double t_s) const;

 private:
  CameraErrorOptions options_;
  Eigen::Vector3i lo_, size_;        // lattice index range covered
  Eigen::Vector3f cell_;             // lattice spacing per axis, m
  std::vector<float> base_, phase_;  // per node
};

// An exposure setting: exposure_s * gain is the exposure product.
struct ExposureSetting {
  double exposure_s = 0;
  double gain = 1;
};

class AutoExposure {
 public:
  explicit AutoExposure(const CameraErrorOptions& options);
  // Starts converged on a scene of median radiance `median_radiance`.
  void Reset(double median_radiance);
  // One update after a frame of median radiance `median_radiance` taken with
  // the current setting, `dt_s` after the previous update.
  void Update(double median_radiance, double dt_s);
  ExposureSetting setting() const;
  // The median DN (clamped to 255) of a frame of median radiance m now.
  double MedianDn(double median_radiance) const;

 private:
  // The exposure product that puts median radiance m at the target.
  double TargetProduct(double median_radiance) const;
  CameraErrorOptions options_;
  double product_;  // exposure_s * gain
};

}  // namespace sim
}  // namespace lisfm
