// Check() of every simulator options struct rejects an out-of-range value of
// each field it guards, naming that field (table-driven).
#include <gtest/gtest.h>

#include "core/errors.h"
#include "sim/camera_simulator.h"
#include "sim/imu_simulator.h"
#include "sim/lidar_simulator.h"
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
          {"error_sources", [](S* o) { o->error_sources = "dynamics,rain"; }},
          {"error_sources", [](S* o) { o->error_sources = "none,dynamics"; }},
          {"error_sources", [](S* o) { o->error_sources = ""; }},
          {"walk.num_stops", [](S* o) { o->walk.num_stops = 1; }},
          {"dynamics.people_per_100m", [](S* o) { o->dynamics.people_per_100m = -1.0; }},
      },
      valid);
  valid.error_sources = "dynamics";
  EXPECT_TRUE(valid.Check());
  EXPECT_TRUE(valid.HasErrorSource("dynamics"));
  valid.noise_scale = 0;  // turns every error source off
  EXPECT_FALSE(valid.HasErrorSource("dynamics"));
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
