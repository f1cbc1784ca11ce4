// Check() of every LIO options struct rejects an out-of-range value of each
// field it guards, naming that field (table-driven).
#include <gtest/gtest.h>

#include "lio/imu.h"
#include "lio/lio_odometry.h"
#include "lio/voxel_map.h"
#include "tests/common/option_check_test.h"

namespace lisfm {
namespace {

using test::ExpectCheckRejects;

TEST(LioOptionsCheck, MapAndInitializer) {
  using M = VoxelMapOptions;
  ExpectCheckRejects<M>({
      {"voxel_size", [](M* o) { o->voxel_size = 0.0; }},
      {"resolution", [](M* o) { o->resolution = -0.1; }},
      {"resolution", [](M* o) { o->resolution = o->voxel_size; }},
      {"max_points_per_voxel", [](M* o) { o->max_points_per_voxel = 0; }},
      {"max_voxels", [](M* o) { o->max_voxels = 0; }},
  });
  using I = ImuInitializerOptions;
  ExpectCheckRejects<I>({
      {"min_duration_s", [](I* o) { o->min_duration_s = 0.0; }},
      {"min_samples", [](I* o) { o->min_samples = 9; }},
      {"max_gyro_std", [](I* o) { o->max_gyro_std = 0.0; }},
      {"max_accel_std", [](I* o) { o->max_accel_std = -1.0; }},
      {"gravity_magnitude", [](I* o) { o->gravity_magnitude = 0.0; }},
  });
}

TEST(LioOptionsCheck, Odometry) {
  using L = LioOptions;
  ExpectCheckRejects<L>({
      {"imu_noise_inflation", [](L* o) { o->imu_noise_inflation = 0.0; }},
      {"point_stride", [](L* o) { o->point_stride = 0; }},
      {"scan_voxel_size", [](L* o) { o->scan_voxel_size = -0.4; }},
      {"min_range", [](L* o) { o->min_range = -0.5; }},
      {"max_range", [](L* o) { o->max_range = o->min_range; }},
      {"num_neighbours", [](L* o) { o->num_neighbours = 2; }},
      {"max_neighbour_distance", [](L* o) { o->max_neighbour_distance = 0.0; }},
      {"max_plane_residual", [](L* o) { o->max_plane_residual = 0.0; }},
      {"max_point_residual", [](L* o) { o->max_point_residual = 0.0; }},
      {"point_noise_std", [](L* o) { o->point_noise_std = 0.0; }},
      {"max_iterations", [](L* o) { o->max_iterations = 0; }},
      {"convergence_rotation", [](L* o) { o->convergence_rotation = 0.0; }},
      {"convergence_translation",
       [](L* o) { o->convergence_translation = 0.0; }},
      {"reassociate_translation",
       [](L* o) { o->reassociate_translation = -0.01; }},
      {"reassociate_rotation", [](L* o) { o->reassociate_rotation = -0.01; }},
      {"degeneracy_threshold", [](L* o) { o->degeneracy_threshold = -0.05; }},
      {"map.voxel_size", [](L* o) { o->map.voxel_size = 0.0; }},
      {"keyframe_distance", [](L* o) { o->keyframe_distance = 0.0; }},
      {"keyframe_angle_deg", [](L* o) { o->keyframe_angle_deg = 0.0; }},
      {"init.min_samples", [](L* o) { o->init.min_samples = 0; }},
      {"extrinsic_rotation_std_deg", [](L* o) { o->extrinsic_rotation_std_deg = 0.0; }},
      {"extrinsic_translation_std", [](L* o) { o->extrinsic_translation_std = -0.01; }},
      {"time_offset_std_ms", [](L* o) { o->time_offset_std_ms = 0.0; }},
  });
}

}  // namespace
}  // namespace lisfm
