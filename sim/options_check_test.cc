// Check() of every simulator options struct rejects an out-of-range value of
// each field it guards, naming that field (table-driven).
#include <gtest/gtest.h>

#include "core/errors.h"
#include "sim/calibration_errors.h"
#include "sim/camera_errors.h"
#include "sim/camera_simulator.h"
#include "sim/imu_errors.h"
#include "sim/imu_simulator.h"
#include "sim/lidar_simulator.h"
#include "sim/materials.h"
#include "sim/motion.h"
#include "sim/scene.h"
#include "sim/simulator.h"
#include "sim/texture.h"
#include "tests/common/option_check_test.h"

namespace lisfm {
namespace sim {
namespace {

using test::ExpectCheckRejects;

TEST(SimOptionsCheck, Simulator) {
  using S = SimulatorOptions;
  S valid;
  valid.output_path = "out";
  ExpectCheckRejects<S>(
      {
          {"output_path", [](S* o) { o->output_path.clear(); }},
          {"duration", [](S* o) { o->duration = 2e5; }},
          {"duration",
           [](S* o) { o->duration = 0.5; }},  // without a trajectory_path
          {"camera_rate", [](S* o) { o->camera_rate = -1.0; }},
          {"camera_rate", [](S* o) { o->camera_rate = 101.0; }},
          {"noise_scale", [](S* o) { o->noise_scale = -0.1; }},
          {"supersampling", [](S* o) { o->supersampling = 0; }},
          {"supersampling", [](S* o) { o->supersampling = 9; }},
          {"rgbd_rate", [](S* o) { o->rgbd_rate = 0.0; }},
          {"lidars", [](S* o) { o->lidars = "spinning,velodyne"; }},
          {"error_sources", [](S* o) { o->error_sources = "imu,weather"; }},
          {"error_sources", [](S* o) { o->error_sources = "all,imu"; }},
          {"error_sources", [](S* o) { o->error_sources = ""; }},
          {"calibration_error.lidar_rotation_sigma_deg",
           [](S* o) { o->calibration_error.lidar_rotation_sigma_deg = -0.1; }},
          {"imu_error.temperature_sigma_k", [](S* o) { o->imu_error.temperature_sigma_k = -1.0; }},
          {"error_sources", [](S* o) { o->error_sources = "lidar,weather"; }},
          // A source named for a sensor the recording does not have.
          {"error_sources",
           [](S* o) {
             o->error_sources = "lidar";
             o->lidars = "none";
           }},
          {"error_sources",
           [](S* o) {
             o->error_sources = "camera";
             o->camera_rate = 0;
           }},
          {"lidar_errors.beam_divergence_mrad",
           [](S* o) { o->lidar_errors.beam_divergence_mrad = -1; }},
          {"camera_errors.read_noise_e", [](S* o) { o->camera_errors.read_noise_e = -1; }},
          {"materials.texture_poor_fraction",
           [](S* o) { o->materials.texture_poor_fraction = 1.5; }},
          {"error_sources", [](S* o) { o->error_sources = "dynamics,rain"; }},
          {"error_sources", [](S* o) { o->error_sources = "none,dynamics"; }},
          {"walk.num_stops", [](S* o) { o->walk.num_stops = 1; }},
          {"dynamics.people_per_100m", [](S* o) { o->dynamics.people_per_100m = -1.0; }},
      },
      valid);
  // "all" needs no particular sensor: it applies to the sensors there are.
  valid.lidars = "none";
  valid.camera_rate = 0;
  EXPECT_TRUE(valid.Check()) << LastOptionCheckFailure().ToString();
  valid.error_sources = "dynamics";
  EXPECT_TRUE(valid.Check());
  EXPECT_TRUE(ErrorSourceEnabled(valid.error_sources, "dynamics"));
  valid.error_sources = "all";
  valid.trajectory_path = "motion.txt";
  valid.duration = -1.0;  // all of the file
  EXPECT_TRUE(valid.Check());
}

TEST(SimOptionsCheck, Sensors) {
  using L = LidarSimOptions;
  ExpectCheckRejects<L>({
      {"noise_scale", [](L* o) { o->noise_scale = -1.0; }},
      {"range_sigma", [](L* o) { o->range_sigma = -0.01; }},
      {"azimuth_steps", [](L* o) { o->azimuth_steps = 0; }},
      {"livox_rate", [](L* o) { o->livox_rate = 0.0; }},
      {"livox_fov_deg", [](L* o) { o->livox_fov_deg = 181.0; }},
      {"errors.incidence_noise_gain", [](L* o) { o->errors.incidence_noise_gain = -0.1; }},
  });
  using LE = LidarErrorOptions;
  ExpectCheckRejects<LE>({
      {"incidence_noise_gain", [](LE* o) { o->incidence_noise_gain = -1.0; }},
      {"beam_divergence_mrad", [](LE* o) { o->beam_divergence_mrad = -1.0; }},
      {"mixed_pixel_max_separation_m", [](LE* o) { o->mixed_pixel_max_separation_m = -1.0; }},
      {"range_at_10_percent_m", [](LE* o) { o->range_at_10_percent_m = -1.0; }},
      {"dropout_reflectivity", [](LE* o) { o->dropout_reflectivity = -0.1; }},
      {"dropout_reflectivity", [](LE* o) { o->dropout_reflectivity = 1.5; }},
  });
  using CE = CameraErrorOptions;
  ExpectCheckRejects<CE>({
      {"ae_target_median_dn", [](CE* o) { o->ae_target_median_dn = 0.0; }},
      {"ae_target_median_dn", [](CE* o) { o->ae_target_median_dn = 255.0; }},
      {"ae_time_constant_s", [](CE* o) { o->ae_time_constant_s = -1.0; }},
      {"ae_rate_hz", [](CE* o) { o->ae_rate_hz = 0.0; }},
      {"min_exposure_ms", [](CE* o) { o->min_exposure_ms = 0.0; }},
      {"max_exposure_ms", [](CE* o) { o->max_exposure_ms = 0.01; }},  // < min_exposure_ms
      {"max_gain", [](CE* o) { o->max_gain = 0.5; }},
      {"reference_exposure_ms", [](CE* o) { o->reference_exposure_ms = 0.0; }},
      {"full_well_e", [](CE* o) { o->full_well_e = 0.0; }},
      {"read_noise_e", [](CE* o) { o->read_noise_e = -1.0; }},
      {"light_level_ratio", [](CE* o) { o->light_level_ratio = 0.5; }},
      {"light_cell_m", [](CE* o) { o->light_cell_m = 0.0; }},
      {"light_change_amplitude", [](CE* o) { o->light_change_amplitude = 1.0; }},
      {"light_change_period_s", [](CE* o) { o->light_change_period_s = 0.0; }},
  });
  using M = MaterialOptions;
  ExpectCheckRejects<M>({
      {"texture_poor_fraction", [](M* o) { o->texture_poor_fraction = -0.1; }},
  });
  using I = ImuSimOptions;
  ExpectCheckRejects<I>({
      {"noise_scale", [](I* o) { o->noise_scale = -1.0; }},
      {"initial_gyro_bias_sigma",
       [](I* o) { o->initial_gyro_bias_sigma = -1e-3; }},
      {"initial_accel_bias_sigma",
       [](I* o) { o->initial_accel_bias_sigma = -1e-3; }},
  });
  using C = CameraSimOptions;
  ExpectCheckRejects<C>({
      {"supersampling", [](C* o) { o->supersampling = 0; }},
      {"exposure", [](C* o) { o->exposure = 0.0; }},
      {"noise_sigma", [](C* o) { o->noise_sigma = -1.0; }},
      {"noise_scale", [](C* o) { o->noise_scale = -1.0; }},
      {"vignetting", [](C* o) { o->vignetting = 1.5; }},
      {"max_range", [](C* o) { o->max_range = 0.0; }},
      {"errors.max_gain", [](C* o) { o->errors.max_gain = 0.0; }},
  });
}

TEST(SimOptionsCheck, ErrorSources) {
  using C = CalibrationErrorOptions;
  ExpectCheckRejects<C>({
      {"lidar_translation_sigma_m", [](C* o) { o->lidar_translation_sigma_m = -1e-3; }},
      {"lidar_rotation_sigma_deg", [](C* o) { o->lidar_rotation_sigma_deg = 31.0; }},
      {"lidar_time_offset_sigma_s", [](C* o) { o->lidar_time_offset_sigma_s = -1e-3; }},
      {"camera_translation_sigma_m", [](C* o) { o->camera_translation_sigma_m = 2.0; }},
      {"camera_rotation_sigma_deg", [](C* o) { o->camera_rotation_sigma_deg = -1.0; }},
      {"camera_time_offset_sigma_s", [](C* o) { o->camera_time_offset_sigma_s = 1.5; }},
      {"camera_time_offset_spread_s", [](C* o) { o->camera_time_offset_spread_s = -1e-4; }},
  });
  using I = ImuErrorOptions;
  ExpectCheckRejects<I>({
      {"gyro_scale_sigma_percent", [](I* o) { o->gyro_scale_sigma_percent = -1.0; }},
      {"accel_scale_sigma_percent", [](I* o) { o->accel_scale_sigma_percent = 11.0; }},
      {"gyro_cross_axis_sigma_percent", [](I* o) { o->gyro_cross_axis_sigma_percent = -1.0; }},
      {"accel_cross_axis_sigma_percent", [](I* o) { o->accel_cross_axis_sigma_percent = 11.0; }},
      {"gyro_temperature_coefficient_dps_per_k",
       [](I* o) { o->gyro_temperature_coefficient_dps_per_k = -0.01; }},
      {"accel_temperature_coefficient_mg_per_k",
       [](I* o) { o->accel_temperature_coefficient_mg_per_k = -0.1; }},
      {"temperature_sigma_k", [](I* o) { o->temperature_sigma_k = 51.0; }},
      {"temperature_time_constant_s", [](I* o) { o->temperature_time_constant_s = 0.5; }},
  });
}

TEST(SimOptionsCheck, SceneMotionAndTexture) {
  using W = WalkingOptions;
  ExpectCheckRejects<W>({
      {"speed", [](W* o) { o->speed = 0.0; }},
      {"stationary_s", [](W* o) { o->stationary_s = -1.0; }},
      {"step_frequency", [](W* o) { o->step_frequency = 0.0; }},
      {"sway_scale", [](W* o) { o->sway_scale = -1.0; }},
      {"knot_spacing", [](W* o) { o->knot_spacing = 0.0; }},
      {"num_stops", [](W* o) { o->num_stops = 1; }},
      {"num_stops", [](W* o) { o->num_stops = 1001; }},
  });
  using D = DynamicsOptions;
  ExpectCheckRejects<D>({
      {"people_per_100m", [](D* o) { o->people_per_100m = -0.5; }},
      {"people_per_100m", [](D* o) { o->people_per_100m = 101.0; }},
      {"speed", [](D* o) { o->speed = 0.0; }},
      {"speed", [](D* o) { o->speed = 3.5; }},
  });
  using T = TextureOptions;
  ExpectCheckRejects<T>(
      {{"frequency_scale", [](T* o) { o->frequency_scale = 0.0f; }}});
  using S = SceneOptions;
  ExpectCheckRejects<S>({
      {"type", [](S* o) { o->type = "garage"; }},
      {"length", [](S* o) { o->length = 5.0; }},
      {"width", [](S* o) { o->width = 5.0; }},
      {"height", [](S* o) { o->height = 2.0; }},
      {"corridor_width", [](S* o) { o->corridor_width = 1.0; }},
      {"room_depth", [](S* o) { o->room_depth = 1.0; }},
      {"width",
       [](S* o) {
         o->room_depth = 10.0;
       }},  // rooms and corridors exceed the width
      {"furniture_per_room", [](S* o) { o->furniture_per_room = -1; }},
      {"pillar_spacing", [](S* o) { o->pillar_spacing = 3.0; }},
      {"car_density", [](S* o) { o->car_density = 1.5; }},
      {"texture_scale", [](S* o) { o->texture_scale = 0.1; }},
  });
  ExpectCheckRejects<S>(
      {
          {"length", [](S* o) { o->length = 50.0; }},
          {"width", [](S* o) { o->width = 30.0; }},
          {"height", [](S* o) { o->height = 2.5; }},
          {"corridor_width", [](S* o) { o->corridor_width = 2.0; }},
          {"room_depth", [](S* o) { o->room_depth = 9.0; }},
      },
      DefaultSceneOptions("site"));
  SceneOptions bad;
  bad.height = 30.0;
  try {
    bad.CheckOrThrow("sim_x.yaml");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("sim_x.yaml"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("field height"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("expected in [2.2, 20] m, found 30"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
