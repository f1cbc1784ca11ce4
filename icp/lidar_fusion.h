// Point-based (surfel) fusion of spinning-LiDAR scans with given poses: each scan
// becomes a range image (icp/spherical_projection.h) with normals from its
// neighbours and is fused into a SurfelMap by the map's spherical Fuse (the same
// association, merge, addition and removal rules as RGB-D frames).
//
// Frames: scans are in the sensor (LiDAR) frame, poses are world_from_sensor (m).
//
// Range image of a scan (BuildRangeImage): a point p with range in
// [min_range_m, max_range_m] goes to the pixel of its azimuth column and of its
// ring's row (LidarImageLayout::row_of_ring; by its elevation for a scan without
// rings); of several points in one pixel the nearest is kept. A pixel's normal is
// n = t_u x t_v, oriented towards the sensor, from the differences to its
// neighbours along the row (columns u +- k, wrapping, k = round(de / da) >= 1: as
// many columns as one row spans, so that both baselines span similar angles and the
// range noise tilts the normal alike along both) and the column (rows v +- 1):
// the central difference when both neighbours are valid and within
// max_range_jump * r of the pixel's range r, else the one-sided difference to the
// one that is; a pixel with neither along a direction has no normal. Pixels seen
// more obliquely than max_incidence_deg (angle between normal and ray) are dropped.
// Colour: grey from the point's intensity, 255 * intensity / intensity_full_scale
// clamped to [0, 255] (128 when the layout has no intensity scale).
//
// Threads: TBB inside the map's stages; results do not depend on the thread count.
// Not thread-safe itself.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/geometry.h"
#include "core/point_cloud.h"
#include "icp/projective_icp.h"
#include "icp/spherical_projection.h"
#include "icp/surfel_map.h"

namespace lisfm {

struct LidarFusionOptions {
  // Column width of the range image (deg); the width is round(360 / this) columns
  // (XT-32 at 10 Hz: 2000 columns of 0.18 deg).
  double azimuth_resolution_deg = 0.18;
  // Row spacing (deg). 0: one row per ring of the scan, spaced by the rings' mean
  // elevations (1 deg for a scan without rings).
  double elevation_resolution_deg = 0;
  double min_range_m = 0.5;         // closer returns are dropped (m; the operator, the rig)
  double max_range_m = 60.0;        // farther returns are dropped (m)
  double max_range_jump = 0.15;     // no difference to a neighbour whose range differs more (x r)
  double max_incidence_deg = 80.0;  // drop pixels seen more obliquely (normal vs ray, deg)
  bool Check() const;
};

// How scans of one sensor map to range-image pixels.
struct LidarImageLayout {
  SphericalProjection projection;
  // Row of each ring index (-1: not a row; elevation rows are used). Empty: the
  // scans have no ring field, rows come from the elevation.
  std::vector<int> row_of_ring;
  float intensity_full_scale = 0;  // intensity shown white; 0 = no intensity (grey)
};

// The layout from one scan in the sensor frame: rows from its rings (their mean
// elevations, top ring first) or, with elevation_resolution_deg > 0 or without
// rings, evenly spaced from its highest to its lowest elevation in range; the
// intensity scale is the scan's 99th-percentile intensity. Throws InputError
// (naming `what`) when the scan has no point in range.
LidarImageLayout FitLidarImageLayout(const PointCloud& scan,
                                     const LidarFusionOptions& options,
                                     const std::string& what);

struct LidarFrameResult {
  FuseStats fuse;
  size_t points_in_range = 0;             // scan points within the range limits
  size_t pixels_with_points = 0;          // range-image pixels that received a point
  double preprocess_ms = 0, fuse_ms = 0;  // wall-clock per stage (ms)
};

class LidarFusion {
 public:
  // Throws InternalError for bad options.
  LidarFusion(const LidarImageLayout& layout,
              const LidarFusionOptions& options,
              const SurfelFusionOptions& fusion_options);

  // The range image (vertices and normals in the sensor frame) and per-pixel
  // colours of `scan`; returns the number of points within the range limits.
  size_t BuildRangeImage(const PointCloud& scan,
                         VertexNormalMap* image,
                         std::vector<std::array<uint8_t, 3>>* colors) const;

  // Fuses one scan (sensor frame) at world_from_sensor as the next frame.
  LidarFrameResult AddScan(const PointCloud& scan, const SE3& world_from_sensor);

  const SurfelMap& map() const { return map_; }
  const LidarImageLayout& layout() const { return layout_; }
  int num_frames() const { return num_frames_; }
  // Valid pixels (vertex + normal) over all frames so far.
  size_t num_input_points() const { return num_input_points_; }
  // Scan points within the range limits over all frames so far.
  size_t num_scan_points() const { return num_scan_points_; }

 private:
  LidarImageLayout layout_;
  LidarFusionOptions options_;
  SurfelMap map_;
  VertexNormalMap image_;
  std::vector<std::array<uint8_t, 3>> colors_;
  mutable std::vector<float> best_range_;
  mutable std::vector<float> intensity_;
  int num_frames_ = 0;
  size_t num_input_points_ = 0;
  size_t num_scan_points_ = 0;
};

}  // namespace lisfm
