// LiDAR simulation by ray casting: every point is cast from the sensor pose at
// its own time (world_from_imu(t) * imu_from_lidar), so motion distortion is
// real, and it sees the scene's people where they are at that time
// (Scene::Intersect16At). Points are returned in the LiDAR frame with the DESIGN.md time
// convention: the scan stamp is the time of the first returned point and each
// point's `t` is seconds since that stamp, inside [0, 1 / scan_rate).
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

struct LidarSimOptions {
  double noise_scale = 1.0;     // 0 = exact ranges
  double range_sigma = 0.01;    // m, 1-sigma range noise at noise_scale 1
  int azimuth_steps = 2000;     // spinning: columns per revolution
  double livox_rate = 100000;   // solid-state: points per second
  double livox_fov_deg = 70.4;  // solid-state: full circular field of view
  uint64_t seed = 1;
  bool Check() const;
};

class LidarSimulator {
 public:
  LidarSimulator(const Scene& scene,
                 const SplineTrajectory& trajectory,
                 const RigLidar& lidar,
                 const TextureOptions& texture,
                 const LidarSimOptions& options);

  // The scan that starts at `scan_start_ns` (first firing) and covers one
  // period 1 / lidar.scan_rate. `scan_index` seeds the noise (deterministic).
  PointCloud SimulateScan(TimestampNs scan_start_ns, int64_t scan_index) const;

  // Elevation of ring r (rad).
  double RingElevation(int ring) const;

 private:
  const Scene& scene_;
  const SplineTrajectory& trajectory_;
  RigLidar lidar_;
  Texture texture_;
  LidarSimOptions options_;
};

}  // namespace sim
}  // namespace lisfm
