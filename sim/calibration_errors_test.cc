// The calibration error source against its definition (sim/calibration_errors.h):
// the spread of the drawn errors over many seeds, their scaling and
// independence, and the true rig they make.
#include "sim/calibration_errors.h"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

// Sample mean and standard deviation of values drawn around 0.
struct Spread {
  double mean = 0, std = 0;
};
Spread SpreadOf(const std::vector<double>& v) {
  Spread s;
  for (double x : v) s.mean += x;
  s.mean /= static_cast<double>(v.size());
  for (double x : v) s.std += (x - s.mean) * (x - s.mean);
  s.std = std::sqrt(s.std / static_cast<double>(v.size() - 1));
  return s;
}

// Over n independent draws the sample std of N(0, sigma^2) has a relative
// standard error of 1 / sqrt(2 n) (1.1 % at n = 4000) and the mean a standard
// error of sigma / sqrt(n): 5 % and 4.5 sigma / sqrt(n) are > 4 standard errors.
void ExpectSpread(const std::vector<double>& v, double sigma, const std::string& what) {
  const Spread s = SpreadOf(v);
  const double n = static_cast<double>(v.size());
  EXPECT_NEAR(s.std, sigma, 0.05 * sigma) << what;
  EXPECT_LT(std::abs(s.mean), 4.5 * sigma / std::sqrt(n)) << what;
}

TEST(CalibrationErrors, SpreadOverSeedsIsTheConfiguredSigma) {
  CalibrationErrorOptions options;  // the defaults
  constexpr int kSeeds = 4000;
  std::vector<std::vector<double>> lidar_rot(3), lidar_trans(3), cam_rot(3), cam_trans(3);
  std::vector<double> lidar_dt, cam_dt, cam_pair_dt, cross;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const CalibrationErrors e = DrawCalibrationErrors(options, 1.0, seed, 2, 3);
    ASSERT_EQ(e.lidars.size(), 2u);
    ASSERT_EQ(e.cameras.size(), 3u);
    for (int a = 0; a < 3; ++a) {
      lidar_rot[a].push_back(e.lidars[0].rotation_rad[a]);
      lidar_trans[a].push_back(e.lidars[0].translation_m[a]);
      cam_rot[a].push_back(e.cameras[1].rotation_rad[a]);
      cam_trans[a].push_back(e.cameras[1].translation_m[a]);
    }
    lidar_dt.push_back(1e-9 * static_cast<double>(e.lidars[1].time_offset_ns));
    cam_dt.push_back(1e-9 * static_cast<double>(e.cameras[0].time_offset_ns));
    // Two cameras differ only by their own spread terms.
    cam_pair_dt.push_back(
        1e-9 * static_cast<double>(e.cameras[2].time_offset_ns - e.cameras[0].time_offset_ns));
    cross.push_back(e.lidars[0].rotation_rad.x() * e.lidars[1].rotation_rad.x());
  }
  const double deg = M_PI / 180;
  for (int a = 0; a < 3; ++a) {
    ExpectSpread(lidar_rot[a], options.lidar_rotation_sigma_deg * deg, "lidar rotation");
    ExpectSpread(lidar_trans[a], options.lidar_translation_sigma_m, "lidar translation");
    ExpectSpread(cam_rot[a], options.camera_rotation_sigma_deg * deg, "camera rotation");
    ExpectSpread(cam_trans[a], options.camera_translation_sigma_m, "camera translation");
  }
  ExpectSpread(lidar_dt, options.lidar_time_offset_sigma_s, "lidar time offset");
  ExpectSpread(cam_dt,
               std::hypot(options.camera_time_offset_sigma_s, options.camera_time_offset_spread_s),
               "camera time offset");
  ExpectSpread(cam_pair_dt,
               std::sqrt(2.0) * options.camera_time_offset_spread_s,
               "difference of two cameras' time offsets");
  // Two LiDARs are independent: E[x0 x1] = 0, its estimate has standard error
  // sigma^2 / sqrt(n).
  const double s2 = std::pow(options.lidar_rotation_sigma_deg * deg, 2);
  EXPECT_LT(std::abs(SpreadOf(cross).mean), 4.5 * s2 / std::sqrt(double{kSeeds}));
}

TEST(CalibrationErrors, ScaledByNoiseScaleAndOffWhenZero) {
  const CalibrationErrorOptions options;
  const CalibrationErrors one = DrawCalibrationErrors(options, 1.0, 5, 1, 2);
  const CalibrationErrors two = DrawCalibrationErrors(options, 2.0, 5, 1, 2);
  EXPECT_EQ(two.lidars[0].rotation_rad, 2.0 * one.lidars[0].rotation_rad);
  EXPECT_EQ(two.cameras[1].translation_m, 2.0 * one.cameras[1].translation_m);
  // Rounded to whole ns after scaling.
  EXPECT_NEAR(static_cast<double>(two.lidars[0].time_offset_ns),
              2.0 * static_cast<double>(one.lidars[0].time_offset_ns),
              1.0);
  EXPECT_GT(one.lidars[0].rotation_rad.norm(), 0.0);
  EXPECT_NE(one.lidars[0].time_offset_ns, 0);
  for (const CalibrationErrors& zero :
       {DrawCalibrationErrors(options, 0.0, 5, 1, 2),
        DrawCalibrationErrors(CalibrationErrorOptions{0, 0, 0, 0, 0, 0, 0}, 1.0, 5, 1, 2)}) {
    for (const auto* list : {&zero.lidars, &zero.cameras}) {
      for (const SensorCalibrationError& e : *list) {
        EXPECT_EQ(e.rotation_rad, Vec3::Zero());
        EXPECT_EQ(e.translation_m, Vec3::Zero());
        EXPECT_EQ(e.time_offset_ns, 0);
      }
    }
  }
}

// A sensor's errors depend on (seed, kind, index) only.
TEST(CalibrationErrors, EachSensorHasItsOwnStream) {
  const CalibrationErrorOptions options;
  const CalibrationErrors a = DrawCalibrationErrors(options, 1.0, 11, 1, 5);
  const CalibrationErrors b = DrawCalibrationErrors(options, 1.0, 11, 2, 3);
  EXPECT_EQ(a.lidars[0].rotation_rad, b.lidars[0].rotation_rad);
  EXPECT_EQ(a.lidars[0].time_offset_ns, b.lidars[0].time_offset_ns);
  EXPECT_EQ(a.cameras[2].translation_m, b.cameras[2].translation_m);
  EXPECT_EQ(a.cameras[2].time_offset_ns, b.cameras[2].time_offset_ns);
  EXPECT_NE(a.cameras[0].rotation_rad, a.cameras[1].rotation_rad);
  const CalibrationErrors c = DrawCalibrationErrors(options, 1.0, 12, 1, 5);
  EXPECT_NE(a.lidars[0].rotation_rad, c.lidars[0].rotation_rad);
}

// true imu_from_sensor = (R Exp(dtheta), t + dt); time offsets += d.
TEST(CalibrationErrors, TrueRigIsTheBelievedOnePerturbedByTheDraw) {
  Rig rig;
  RigLidar lidar;
  lidar.name = "lidar0";
  lidar.imu_from_lidar = SE3(so3::Exp(Vec3(0.3, -2.0, 0.5)), Vec3(0.01, -0.02, 0.05));
  lidar.time_offset_s = 0.001;
  rig.lidars.push_back(lidar);
  RigCamera cam;
  cam.name = "cam0";
  cam.cam_from_imu = SE3(so3::Exp(Vec3(1.5, 0.2, -0.1)), Vec3(-0.05, 0.01, 0.02));
  rig.cameras.push_back(cam);
  CalibrationErrorOptions options;
  options.lidar_rotation_sigma_deg = 2.0;
  options.camera_rotation_sigma_deg = 2.0;
  const CalibrationErrors e = DrawCalibrationErrors(options, 1.0, 3, 1, 1);
  const Rig truth = ApplyCalibrationErrors(rig, e);
  const SE3& believed_l = rig.lidars[0].imu_from_lidar;
  const SE3& true_l = truth.lidars[0].imu_from_lidar;
  EXPECT_LT(
      (so3::Log(believed_l.rotation().conjugate() * true_l.rotation()) - e.lidars[0].rotation_rad)
          .norm(),
      1e-12);
  EXPECT_LT((true_l.translation() - believed_l.translation() - e.lidars[0].translation_m).norm(),
            1e-15);
  EXPECT_EQ(SecondsToNs(truth.lidars[0].time_offset_s),
            SecondsToNs(0.001) + e.lidars[0].time_offset_ns);
  const SE3 believed_c = rig.cameras[0].cam_from_imu.Inverse();
  const SE3 true_c = truth.cameras[0].cam_from_imu.Inverse();
  EXPECT_LT(
      (so3::Log(believed_c.rotation().conjugate() * true_c.rotation()) - e.cameras[0].rotation_rad)
          .norm(),
      1e-12);
  EXPECT_LT((true_c.translation() - believed_c.translation() - e.cameras[0].translation_m).norm(),
            1e-12);
  EXPECT_EQ(SecondsToNs(truth.cameras[0].timeshift_cam_imu_s), e.cameras[0].time_offset_ns);
  EXPECT_GT(e.cameras[0].rotation_rad.norm(), 1e-3);  // the test sees a real perturbation
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
