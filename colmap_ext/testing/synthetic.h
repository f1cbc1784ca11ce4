// Synthetic COLMAP models with exact geometry, for tests and benchmarks
// (in the spirit of COLMAP's SynthesizeDataset): cameras on a ring around the
// origin looking at it, points in a cube at the origin, each point observed
// by `track_length` distinct random images at its exact projection plus
// Gaussian pixel noise; point errors are the true mean reprojection errors.
// Deterministic for a given seed.
#pragma once

#include <cstdint>

#include "colmap_ext/io/reconstruction.h"

namespace lisfm {
namespace colmap {

struct SyntheticModelOptions {
  int num_cameras = 2;          // alternating PINHOLE / OPENCV_FISHEYE / OPENCV ...
  int num_images = 10;
  int num_points = 200;
  int track_length = 3;         // observations per point (<= num_images)
  int unobserved_per_image = 5; // extra 2D points without a 3D point
  double pixel_noise = 0.5;     // px, standard deviation
  uint32_t seed = 42;
  bool Check() const;
};

Reconstruction SynthesizeModel(const SyntheticModelOptions& options);

}  // namespace colmap
}  // namespace lisfm
