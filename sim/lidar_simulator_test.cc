#include "sim/lidar_simulator.h"

#include <gtest/gtest.h>

#include "sim/motion.h"
#include "tests/common/sim_walks.h"
#include "tests/common/point_triangle_distance.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

using test::PointTriangleDistance;

double SurfaceDistance(const Scene& scene, const Vec3& p) {
  double best = 1e9;
  for (const Triangle& t : scene.triangles()) {
    best = std::min(best, PointTriangleDistance(p, t.a.cast<double>(), t.b.cast<double>(),
                                                t.c.cast<double>()));
  }
  return best;
}

RigLidar Spinning() {
  RigLidar l;
  l.type = LidarType::kSpinning;
  l.imu_from_lidar = SE3(Quat(0.0, 0.7071068, -0.7071068, 0.0).normalized(),
                         Vec3(-0.001, -0.00855, 0.055));
  l.rings = 32;
  l.min_range = 0.05;
  return l;
}

class LidarSimulatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scene_ = Scene::Generate(DefaultSceneOptions("office"));
    walk_ = GenerateWalking(scene_->route(), 30.0, 0, 2, ThreeStopWalk(), nullptr);
  }
  std::unique_ptr<Scene> scene_;
  SplineTrajectory walk_;
};

// Noise-free points, each transformed to the world with the pose at its own
// time, lie on the scene surfaces. 1 mm bound: float32 coordinates (< 40 m
// ranges, 4 um) and float32 `t` (< 1e-8 s, 1e-8 m at 1 m/s) are far below it.
// Using the scan-start pose for all points instead (no de-skew) must be
// visibly wrong (> 2 cm somewhere): the distortion is real and matches the
// trajectory.
TEST_F(LidarSimulatorTest, NoiseFreePointsLieOnSurfacesWithPerPointPoses) {
  LidarSimOptions options;
  options.noise_scale = 0;
  const RigLidar lidar = Spinning();
  const LidarSimulator sim(*scene_, walk_, lidar, TextureOptions(), options);
  const TimestampNs start = SecondsToNs(8.0);  // walking at ~1 m/s
  const PointCloud cloud = sim.SimulateScan(start, 0);
  ASSERT_GT(cloud.size(), 30000u);
  double max_err = 0, max_err_rigid = 0;
  const SE3 stamp_pose = walk_.Pose(cloud.stamp_ns) * lidar.imu_from_lidar;
  for (size_t i = 0; i < cloud.size(); i += 97) {
    const LidarPoint& pt = cloud.points[i];
    const TimestampNs t = cloud.stamp_ns + SecondsToNs(pt.t);
    const Vec3 x_world = walk_.Pose(t) * lidar.imu_from_lidar * pt.xyzd();
    max_err = std::max(max_err, SurfaceDistance(*scene_, x_world));
    max_err_rigid = std::max(max_err_rigid, SurfaceDistance(*scene_, stamp_pose * pt.xyzd()));
  }
  EXPECT_LT(max_err, 1e-3);
  EXPECT_GT(max_err_rigid, 0.02);
}

TEST_F(LidarSimulatorTest, TimesInsidePeriodAndMonotonicInAzimuth) {
  const RigLidar lidar = Spinning();
  const LidarSimulator sim(*scene_, walk_, lidar, TextureOptions(), LidarSimOptions());
  const PointCloud cloud = sim.SimulateScan(SecondsToNs(8.0), 3);
  ASSERT_FALSE(cloud.empty());
  EXPECT_EQ(cloud.points.front().t, 0.f);  // the stamp is the first point's time
  std::vector<float> last_t(32, -1.f), last_az(32, -1.f);
  std::vector<int> ring_count(32, 0);
  for (const LidarPoint& p : cloud.points) {
    EXPECT_GE(p.t, 0.f);
    EXPECT_LT(p.t, 0.1f);
    ASSERT_LT(p.ring, 32);
    float az = std::atan2(p.y, p.x);
    if (az < 0) az += 2 * static_cast<float>(M_PI);
    if (last_t[p.ring] >= 0) {
      EXPECT_GE(p.t, last_t[p.ring]);
      // Azimuth grows with time within a ring (allow float rounding at 0.18 deg steps).
      EXPECT_GT(az, last_az[p.ring] - 1e-4f);
    }
    last_t[p.ring] = p.t;
    last_az[p.ring] = az;
    ++ring_count[p.ring];
    // Ring elevation matches -16 + ring degrees (noise is along the ray only).
    const double el = std::atan2(p.z, std::hypot(p.x, p.y)) * 180 / M_PI;
    EXPECT_NEAR(el, -16.0 + p.ring, 1e-3);
  }
  for (int r = 0; r < 32; ++r) EXPECT_GT(ring_count[r], 500) << "ring " << r;
}

TEST_F(LidarSimulatorTest, LivoxRosetteInsideFovOnSurfaces) {
  RigLidar lidar;
  lidar.type = LidarType::kLivox;
  lidar.rings = 0;
  lidar.imu_from_lidar = SE3(Mat3(Vec3(1, -1, -1).asDiagonal()), Vec3(0.12, 0, -0.06));
  LidarSimOptions options;
  options.noise_scale = 0;
  const LidarSimulator sim(*scene_, walk_, lidar, TextureOptions(), options);
  const PointCloud a = sim.SimulateScan(SecondsToNs(8.0), 0);
  const PointCloud b = sim.SimulateScan(SecondsToNs(8.1), 1);
  EXPECT_GT(a.size(), 9000u);  // 100k pts/s, closed scene: (almost) all return
  float last_t = -1;
  for (size_t i = 0; i < a.size(); ++i) {
    const LidarPoint& p = a.points[i];
    EXPECT_GT(p.t, last_t);
    last_t = p.t;
    EXPECT_LT(p.t, 0.1f);
    const double off_axis = std::acos(p.x / p.xyzd().norm()) * 180 / M_PI;
    EXPECT_LE(off_axis, 35.2 + 1e-3);
    if (i % 53 == 0) {
      const Vec3 x_world = walk_.Pose(a.stamp_ns + SecondsToNs(p.t)) * lidar.imu_from_lidar *
                           p.xyzd();
      EXPECT_LT(SurfaceDistance(*scene_, x_world), 1e-3);
    }
  }
  // Non-repetitive: the next scan's pattern differs.
  ASSERT_GT(b.size(), 100u);
  const Vec3 da = a.points[50].xyzd().normalized(), db = b.points[50].xyzd().normalized();
  EXPECT_GT((da - db).norm(), 1e-3);
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
