// LiDAR simulation by ray casting: every point is cast from the sensor pose at
// its own time (world_from_imu(t) * imu_from_lidar), so motion distortion is
// real, and it sees the scene's people where they are at that time
// (Scene::Intersect16At). Points are returned in the LiDAR frame with the DESIGN.md time
// convention: the scan stamp is the time of the first returned point and each
// point's `t` is seconds since that stamp, inside [0, 1 / scan_rate).
// Stamps are on the LiDAR's clock: a point stamped t was captured at IMU time
// t + lidar.time_offset_s (Kalibr sense), so a simulator given the true
// RigLidar of a recording makes data whose stamps carry its time offset.
//
// Spinning (HESAI PandarXT-32-like): `rings` lasers spread from -16 deg at 1
// deg spacing (32 rings: -16..+15 deg), 2000 azimuth steps per revolution
// (0.18 deg) fired at equal time steps, azimuth increasing counter-clockwise
// about the LiDAR z axis starting at +x; one column's rings fire together
// (as the XT-32 fires all lasers of an azimuth step), so the pose is
// evaluated once per column and its rays are traced as Embree packets of 16.
// Solid-state (Livox MID-70-like): 70.4 deg circular field of view around the
// LiDAR x axis, 100k points/s along a non-repetitive rosette (two
// incommensurate prism rotations, so successive scans fill the disc).
// Range noise: Gaussian, sigma = range_sigma * noise_scale; points outside
// [min_range, max_range] are dropped. Intensity in [0, 255] from the surface
// albedo averaged over the beam footprint (Texture::FootprintAlbedo) and the
// incidence angle.
//
// Error sources (LidarSimOptions::errors_enabled, LidarErrorOptions; the
// surfaces' materials come from Scene::material, sim/materials.h). For a beam
// hitting material (rho_d, rho_s) at incidence theta, with texture modulation
// m (MaterialAlbedo / albedo at the footprint's texture albedo):
// - apparent reflectivity rho = rho_d m cos(theta) + rho_s cos(theta)^20;
// - intensity = min(255, 100 rho) (the Hesai reflectivity scale: 0-100 is the
//   diffuse reflectivity in %);
// - maximum range R10 sqrt(rho / 0.1): a 10 % target is seen to R10
//   (range_at_10_percent_m, XT-32 datasheet 80 m), the received power falls
//   with range squared;
// - dropout probability 1 - (1 - p_m) (1 - 1 / (1 + (rho / rho_half)^2)),
//   p_m the material's own dropout (glass), rho_half = dropout_reflectivity;
// - range noise sigma = range_sigma noise_scale (1 + g (1 / cos(theta) - 1)),
//   1 / cos capped at 10 (g = incidence_noise_gain; range noise of a laser
//   footprint stretched by 1 / cos on an inclined surface, Soudarissanane et
//   al., ISPRS J. 2011);
// - mixed pixels: a beam of full divergence d (uniform profile) whose
//   neighbour (next column or ring; for the Livox the previous / next firing)
//   hits a point off the beam's own surface plane (> 2 cm: a depth edge or a
//   corner) straddles an edge placed uniformly at random in the angular gap
//   between the two beams (one draw per gap, shared by both beams). A fraction
//   f = clamp(1/2 - distance to the edge / d, 0, 1) of the footprint then lies
//   on the neighbour's surface. Echoes within mixed_pixel_max_separation_m of
//   the strongest echo (power f rho / r^2) merge into one return at their
//   power-weighted mean range, with reflectivity sum f rho: a point between
//   the two surfaces; a farther echo is lost. Only the azimuth / elevation
//   neighbours are modelled (a 1D footprint per direction).
// The random draws are counter-based hashes of (seed, scan, beam), so a scan
// is the same for any thread schedule.
//
// Thread safety: SimulateScan() is const and may run concurrently.
#pragma once

#include <cstdint>

#include "core/point_cloud.h"
#include "core/rig.h"
#include "sim/scene.h"
#include "sim/spline_trajectory.h"
#include "sim/texture.h"

namespace lisfm {
namespace sim {

// The LiDAR error sources (model above); each is off at its "off" value.
struct LidarErrorOptions {
  // g: the range noise grows as 1 + g (1 / cos(theta) - 1); 0 = off.
  double incidence_noise_gain = 1.0;
  // Full beam divergence (mrad) of the mixed-pixel model; 0 = off.
  double beam_divergence_mrad = 3.0;
  // Echoes closer than this (m) merge into one return between the surfaces.
  double mixed_pixel_max_separation_m = 1.0;
  // Intensity from the material's apparent reflectivity; 0 = from the albedo
  // as without error sources.
  bool material_intensity = true;
  // R10 (m): the range up to which a 10 % diffuse target is detected; 0 = off.
  double range_at_10_percent_m = 80.0;
  // rho_half: the apparent reflectivity at which half of the pulses return
  // nothing; 0 = no dropouts (also none from the materials' own dropout).
  double dropout_reflectivity = 0.01;
  bool Check() const;
};

struct LidarSimOptions {
  double noise_scale = 1.0;     // 0 = exact ranges
  double range_sigma = 0.01;    // m, 1-sigma range noise at noise_scale 1
  int azimuth_steps = 2000;     // spinning: columns per revolution
  double livox_rate = 100000;   // solid-state: points per second
  double livox_fov_deg = 70.4;  // solid-state: full circular field of view
  uint64_t seed = 1;
  bool errors_enabled = false;  // apply `errors`
  LidarErrorOptions errors;
  bool Check() const;
};

// The apparent reflectivity rho_d m cos(theta) + rho_s cos(theta)^20 of
// `material` at incidence cos(theta) = `cos_incidence` where the footprint's
// texture albedo is `texture_albedo` (model above).
float ApparentReflectivity(const Material& material, float texture_albedo, float cos_incidence);

class LidarSimulator {
 public:
  LidarSimulator(const Scene& scene,
                 const SplineTrajectory& trajectory,
                 const RigLidar& lidar,
                 const TextureOptions& texture,
                 const LidarSimOptions& options);

  // The scan that starts at `scan_start_ns` (first firing, LiDAR clock) and
  // covers one period 1 / lidar.scan_rate. `scan_index` seeds the noise
  // (deterministic).
  PointCloud SimulateScan(TimestampNs scan_start_ns, int64_t scan_index) const;

  // Elevation of ring r (rad).
  double RingElevation(int ring) const;

 private:
  PointCloud SimulateScanWithErrors(TimestampNs scan_start_ns, int64_t scan_index) const;

  // Number of beams CastBeams() visits per scan.
  size_t NumBeams() const;

  // Casts every beam of the scan that starts at `scan_start_ns` at its true
  // firing time (poses from lidar.time_offset_s on): a spinning LiDAR column
  // by column, 16 rings per Scene::Intersect16At packet, up to
  // `spinning_max_cast` m; a solid-state one along its rosette up to
  // `solid_state_max_cast` m. Calls visit(hit, world_from_lidar, dir_lidar,
  // dir_world, t_s, ring, beam) once per beam, with t_s the firing time since
  // scan_start_ns and beam = column * rings + ring (spinning) or the firing
  // index (solid state), in increasing beam order.
  template <typename Visit>
  void CastBeams(TimestampNs scan_start_ns, float spinning_max_cast, double solid_state_max_cast,
                 Visit&& visit) const;

  const Scene& scene_;
  const SplineTrajectory& trajectory_;
  RigLidar lidar_;
  Texture texture_;
  LidarSimOptions options_;
};

}  // namespace sim
}  // namespace lisfm
