// The camera error sources (sim/camera_errors.h) and the materials' camera
// appearance against their definitions: motion blur, sensor noise, auto
// exposure, scene lighting, texture-poor surfaces.
#include "sim/camera_errors.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "sim/camera_simulator.h"
#include "sim/materials.h"
#include "sim/motion.h"
#include "sim/scene.h"

namespace lisfm {
namespace sim {
namespace {

// 640 x 480 pinhole, f = 400 px, no distortion.
CameraModel Pinhole() {
  CameraModel m;
  m.width = 640;
  m.height = 480;
  m.fx = m.fy = 400;
  m.cx = 319.5;
  m.cy = 239.5;
  m.distortion = DistortionModel::kNone;
  return m;
}

// The plane z = 2 (x, y in [-20, 20]) facing a camera at the origin that
// looks along +z: surface 0 (x < 0) and surface 1 (x >= 0) with the given
// materials; the edge between them projects between columns 319 and 320.
std::unique_ptr<Scene> TwoMaterialPlane(const std::string& left, const std::string& right) {
  std::vector<Triangle> tris;
  auto quad = [&](float x0, float x1, uint32_t id) {
    const Eigen::Vector3f a(x0, -20, 2), b(x1, -20, 2), c(x1, 20, 2), d(x0, 20, 2);
    tris.push_back({a, b, c, id});
    tris.push_back({a, c, d, id});
  };
  quad(-20, 0, 0);
  quad(0, 20, 1);
  auto scene = Scene::FromTriangles(std::move(tris));
  scene->SetMaterials({*FindMaterial(left), *FindMaterial(right)});
  return scene;
}

CameraSimOptions ErrorOptions() {
  CameraSimOptions o;
  o.errors_enabled = true;
  o.vignetting = 0;
  return o;
}

// 10 %-90 % width (px) of the rising edge in the mean of rows [y0, y1).
double EdgeWidth(const cv::Mat& image, int y0, int y1) {
  std::vector<double> profile(image.cols, 0.0);
  for (int y = y0; y < y1; ++y) {
    for (int x = 0; x < image.cols; ++x) profile[x] += image.at<uint8_t>(y, x) / double(y1 - y0);
  }
  double lo = 0, hi = 0;
  for (int x = 200; x < 260; ++x) lo += profile[x] / 60;
  for (int x = 380; x < 440; ++x) hi += profile[x] / 60;
  auto crossing = [&](double level) {
    for (int x = 260; x < 380; ++x) {
      if (profile[x] < level && profile[x + 1] >= level) {
        return x + (level - profile[x]) / (profile[x + 1] - profile[x]);
      }
    }
    return -1.0;
  };
  return crossing(lo + 0.9 * (hi - lo)) - crossing(lo + 0.1 * (hi - lo));
}

// A box blur of length L turns a step into a ramp of length L: 10-90 % width
// 0.8 L. The camera moves during a 30 ms exposure so that the edge moves L =
// 12 px across the image: by translation (L = f v t / Z, v = 2 m/s, Z = 2 m)
// and by rotation about the camera's y axis (L = f w t at the image centre,
// w = 1 rad/s). The sharp edge is under 1.2 px wide; the blurred one 0.8 L
// within 0.8 px (pixel sampling of the step and the midpoint samples of the
// blur); blur off leaves it sharp.
TEST(CameraErrors, MotionBlurWidensAnEdgeByExposureTimesImageSpeed) {
  const auto scene = TwoMaterialPlane("bare_concrete", "painted_plaster");
  CameraSimOptions options = ErrorOptions();
  options.noise_scale = 0;
  options.errors.reference_exposure_ms = 60.0;  // keeps 30 ms exposures below 255 DN
  const CameraRenderer renderer(*scene, Pinhole(), TextureOptions(), options);
  const double exposure_s = 0.03, f = 400;
  CameraExposure exposure;
  exposure.setting.exposure_s = exposure_s;
  const SE3 mid;
  exposure.world_from_cam_start = mid;
  exposure.world_from_cam_end = mid;
  const double sharp = EdgeWidth(renderer.Render(mid, exposure, 1), 160, 320);
  EXPECT_LT(sharp, 1.2);

  const double v = 2.0, z = 2.0;
  exposure.world_from_cam_start = SE3(Quat::Identity(), Vec3(-0.5 * v * exposure_s, 0, 0));
  exposure.world_from_cam_end = SE3(Quat::Identity(), Vec3(0.5 * v * exposure_s, 0, 0));
  const double length_translation = f * v * exposure_s / z;
  EXPECT_NEAR(EdgeWidth(renderer.Render(mid, exposure, 1), 160, 320),
              0.8 * length_translation, 0.8);

  const double w = 1.0;
  exposure.world_from_cam_start =
      SE3(Quat(Eigen::AngleAxisd(-0.5 * w * exposure_s, Vec3::UnitY())), Vec3::Zero());
  exposure.world_from_cam_end =
      SE3(Quat(Eigen::AngleAxisd(0.5 * w * exposure_s, Vec3::UnitY())), Vec3::Zero());
  const double length_rotation = f * w * exposure_s;
  EXPECT_NEAR(EdgeWidth(renderer.Render(mid, exposure, 1), 200, 280), 0.8 * length_rotation,
              0.8);

  CameraSimOptions no_blur = options;
  no_blur.errors.motion_blur = false;
  const CameraRenderer sharp_renderer(*scene, Pinhole(), TextureOptions(), no_blur);
  EXPECT_LT(EdgeWidth(sharp_renderer.Render(mid, exposure, 1), 200, 280), 1.2);
}

// Noise variance in DN^2 = K g DN + (K g read_noise)^2, K = 255 / full_well:
// the difference of two renders of the same view with different noise seeds
// has variance 2 sigma^2 + 2/12 (rounding); the texture cancels. Checked at
// two brightness levels (shot noise) and with shot noise off and a large read
// noise; each within 3 % (3e5 pixels: the estimate's spread is ~0.3 %).
TEST(CameraErrors, SensorNoiseStdMatchesShotAndReadNoise) {
  const auto scene = TwoMaterialPlane("painted_plaster", "painted_plaster");
  struct Case {
    double dn_target;
    bool shot;
    double read_e;
  };
  for (const Case& c : {Case{120, true, 7}, Case{60, true, 7}, Case{100, false, 100}}) {
    CameraSimOptions options = ErrorOptions();
    options.errors.shot_noise = c.shot;
    options.errors.read_noise_e = c.read_e;
    const CameraRenderer renderer(*scene, Pinhole(), TextureOptions(), options);
    CameraExposure exposure;
    exposure.setting.gain = 4.0;
    // Exposure putting the median at dn_target: DN = 256 / t_ref * t * g * radiance.
    const double radiance = renderer.MeterRadiance(SE3(), 0.0);
    exposure.setting.exposure_s =
        c.dn_target * options.errors.reference_exposure_s() / (256.0 * 4.0 * radiance);
    const cv::Mat a = renderer.Render(SE3(), exposure, 11), b = renderer.Render(SE3(), exposure, 12);
    double mean_dn = 0, diff2 = 0, diff = 0;
    const int n = a.rows * a.cols;
    for (int y = 0; y < a.rows; ++y) {
      for (int x = 0; x < a.cols; ++x) {
        const double d = double(a.at<uint8_t>(y, x)) - b.at<uint8_t>(y, x);
        mean_dn += (a.at<uint8_t>(y, x) + b.at<uint8_t>(y, x)) / (2.0 * n);
        diff += d / n;
        diff2 += d * d / n;
      }
    }
    const double measured = (diff2 - diff * diff - 2.0 / 12.0) / 2.0;
    const double k = 255.0 / options.errors.full_well_e * 4.0;
    const double expected = (c.shot ? k * mean_dn : 0.0) + std::pow(k * c.read_e, 2);
    EXPECT_NEAR(mean_dn, c.dn_target, 0.05 * c.dn_target);
    EXPECT_NEAR(measured / expected, 1.0, 0.03)
        << "DN " << mean_dn << " measured " << measured << " expected " << expected;
  }
}

// The controller's log exposure follows the wanted one with a first-order
// lag: after a 4x brightness step the median DN error in log shrinks by
// exp(-dt / tau) per update once the median is unclipped, and is below 0.5 DN
// after 2 s (6.7 tau); in a scene too dark for the limits the exposure and
// gain sit at their maxima.
TEST(CameraErrors, AutoExposureConvergesAfterAStep) {
  CameraErrorOptions options;
  AutoExposure ae(options);
  ae.Reset(0.2);
  EXPECT_NEAR(ae.MedianDn(0.2), options.ae_target_median_dn, 1e-9);
  const double dt = 1.0 / options.ae_rate_hz;
  const double decay = std::exp(-dt / options.ae_time_constant_s);
  double previous_error = std::log(ae.MedianDn(0.8) / options.ae_target_median_dn);
  EXPECT_EQ(ae.MedianDn(0.8), 255.0);  // the step: 4 x 70 DN clips
  for (int k = 1; k <= 20; ++k) {
    ae.Update(0.8, dt);
    const double error = std::log(ae.MedianDn(0.8) / options.ae_target_median_dn);
    if (k >= 2) {
      EXPECT_NEAR(error / previous_error, decay, 1e-9) << "update " << k;
    }
    previous_error = error;
  }
  EXPECT_NEAR(ae.MedianDn(0.8), options.ae_target_median_dn, 0.5);
  EXPECT_LT(ae.setting().exposure_s, 1e-3 * options.max_exposure_ms);
  EXPECT_EQ(ae.setting().gain, 1.0);

  for (int k = 0; k < 40; ++k) ae.Update(1e-3, dt);
  EXPECT_DOUBLE_EQ(ae.setting().exposure_s, 1e-3 * options.max_exposure_ms);
  EXPECT_DOUBLE_EQ(ae.setting().gain, options.max_gain);
  EXPECT_LT(ae.MedianDn(1e-3), options.ae_target_median_dn);

  options.auto_exposure = false;
  AutoExposure fixed(options);
  fixed.Reset(0.8);
  fixed.Update(0.1, dt);
  EXPECT_DOUBLE_EQ(fixed.setting().exposure_s, options.reference_exposure_s());
  EXPECT_DOUBLE_EQ(fixed.setting().gain, 1.0);
}

// The metered median predicts the rendered image's median: an office view
// rendered at the converged setting has its median within 8 DN of the target
// (the meter samples every 32nd pixel).
TEST(CameraErrors, RenderedMedianMeetsTheAutoExposureTarget) {
  const auto scene = Scene::Generate(DefaultSceneOptions("office"));
  WalkingOptions walk_options;
  walk_options.num_stops = 3;  // the walk this bound was set on
  const SplineTrajectory walk = GenerateWalking(scene->route(), 20.0, 0, 2, walk_options, nullptr);
  const SceneLighting lighting(scene->Bounds(), 1, CameraErrorOptions());
  const CameraRenderer renderer(*scene, Pinhole(), TextureOptions(), ErrorOptions(), &lighting);
  // Camera looking along the walking direction (imu x forward, camera z = imu x).
  const SE3 cam_in_imu(Quat((Mat3() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished()), Vec3::Zero());
  for (const double t : {6.0, 12.0}) {
    const SE3 world_from_cam = walk.Pose(SecondsToNs(t)) * cam_in_imu;
    AutoExposure ae{CameraErrorOptions()};
    ae.Reset(renderer.MeterRadiance(world_from_cam, t));
    CameraExposure exposure;
    exposure.time_s = t;
    exposure.setting = ae.setting();
    exposure.world_from_cam_start = exposure.world_from_cam_end = world_from_cam;
    cv::Mat image = renderer.Render(world_from_cam, exposure, 3).reshape(1, 1).clone();
    std::vector<uint8_t> values(image.begin<uint8_t>(), image.end<uint8_t>());
    std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
    EXPECT_NEAR(values[values.size() / 2], CameraErrorOptions().ae_target_median_dn, 8.0)
        << "t " << t;
  }
}

// Light levels: at a lattice node the level over one period swings by
// (1 + a) / (1 - a), around a base inside [ratio^-1/2, ratio^1/2]; bases
// differ between nodes (log spread of a log-uniform level: ln(ratio)/sqrt(12));
// ratio 1 and amplitude 0 give a uniform level 1.
TEST(CameraErrors, LightingVariesBetweenAreasAndOverTime) {
  CameraErrorOptions options;
  const Eigen::AlignedBox3d bounds(Vec3(0, 0, 0), Vec3(40, 24, 3));
  const SceneLighting lighting(bounds, 7, options);
  const double a = options.light_change_amplitude;
  std::vector<double> log_bases;
  for (int i = 0; i <= 6; ++i) {
    for (int j = 0; j <= 4; ++j) {
      const Eigen::Vector3f node(6.0f * i, 6.0f * j, 0.0f);
      double lo = 1e9, hi = 0;
      for (double t = 0; t < options.light_change_period_s; t += 0.25) {
        const double level = lighting.At(t).Level(node);
        lo = std::min(lo, level);
        hi = std::max(hi, level);
      }
      EXPECT_NEAR(hi / lo, (1 + a) / (1 - a), 0.01);
      const double base = std::sqrt(hi * lo / (1 - a * a));
      EXPECT_GE(base, 1.0 / std::sqrt(options.light_level_ratio) - 1e-3);
      EXPECT_LE(base, std::sqrt(options.light_level_ratio) + 1e-3);
      log_bases.push_back(std::log(base));
    }
  }
  double mean = 0, var = 0;
  for (double l : log_bases) mean += l / log_bases.size();
  for (double l : log_bases) var += (l - mean) * (l - mean) / (log_bases.size() - 1);
  EXPECT_GT(std::sqrt(var), 0.3);  // expected 0.66 for ratio 10

  options.light_level_ratio = 1.0;
  options.light_change_amplitude = 0.0;
  const SceneLighting uniform(bounds, 7, options);
  EXPECT_FLOAT_EQ(uniform.At(13.0).Level(Eigen::Vector3f(17.3f, 5.1f, 1.2f)), 1.0f);
}

// Texture-poor materials render with low gradient energy: on the same view
// (noise off) the mean squared horizontal gradient of plaster is under 1 %
// and of bare concrete under 5 % of a textured panel's (contrast 0.04 and 0.10
// against 1: energy ratios 0.002 and 0.01 at equal brightness).
TEST(CameraErrors, TexturePoorSurfacesHaveLowGradientEnergy) {
  auto energy = [](const std::string& material) {
    const auto scene = TwoMaterialPlane(material, material);
    CameraSimOptions options = ErrorOptions();
    options.noise_scale = 0;
    const CameraRenderer renderer(*scene, Pinhole(), TextureOptions(), options);
    CameraExposure exposure;
    exposure.setting.exposure_s = options.errors.reference_exposure_s();
    const cv::Mat image = renderer.Render(SE3(), exposure, 1);
    double sum = 0;
    int n = 0;
    for (int y = 0; y < image.rows; ++y) {
      for (int x = 1; x + 1 < image.cols; ++x) {
        if (x == 319 || x == 320) continue;  // the seam between the two surfaces
        const double g = 0.5 * (double(image.at<uint8_t>(y, x + 1)) - image.at<uint8_t>(y, x - 1));
        sum += g * g;
        ++n;
      }
    }
    return sum / n;
  };
  const double panel = energy("textured_panel");
  EXPECT_GT(panel, 20.0);
  EXPECT_LT(energy("painted_plaster"), 0.01 * panel);
  EXPECT_LT(energy("bare_concrete"), 0.05 * panel);
}

// Walls and ceilings of the office draw texture-poor materials with the
// configured probability (binomial, 4 sigma), floors are concrete floor, and
// the draw is deterministic for the seed.
TEST(Materials, TexturePoorFractionOfWallsAndCeilings) {
  auto scene = Scene::Generate(DefaultSceneOptions("office"));
  for (const double fraction : {0.0, 0.25, 0.6, 1.0}) {
    scene->AssignMaterials(fraction);
    int walls = 0, poor = 0;
    for (int s = 0; s < scene->num_surfaces(); ++s) {
      const SurfaceClass c = scene->surface_class(s);
      if (c == SurfaceClass::kFloor) {
        EXPECT_STREQ(scene->material(s).name, "concrete_floor");
      }
      if (c != SurfaceClass::kWall && c != SurfaceClass::kCeiling) continue;
      ++walls;
      poor += scene->material(s).texture_poor ? 1 : 0;
    }
    ASSERT_GT(walls, 200);
    EXPECT_NEAR(double(poor) / walls, fraction,
                4.0 * std::sqrt(fraction * (1 - fraction) / walls) + 1e-12);
  }
  scene->AssignMaterials(0.6);
  std::vector<MaterialId> first;
  for (int s = 0; s < scene->num_surfaces(); ++s) first.push_back(scene->material_id(s));
  scene->AssignMaterials(1.0);
  scene->AssignMaterials(0.6);
  for (int s = 0; s < scene->num_surfaces(); ++s) EXPECT_EQ(scene->material_id(s), first[s]);
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
