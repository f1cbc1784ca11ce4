// People walking through a scene (error source `dynamics`): the analytic
// body intersection against ray marching, the walking motion, and what the
// LiDAR and the cameras see of them at the time of each ray.
#include "sim/people.h"

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <random>

#include "sim/camera_simulator.h"
#include "sim/lidar_simulator.h"
#include "sim/scene.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

constexpr TimestampNs kStart = 1000 * kNsPerSecond;

// Distance from p to the surface of a body part (negative inside).
double PartDistance(const BodyPart& part, const Vec3& p) {
  const Vec3 a = part.a.cast<double>(), b = part.b.cast<double>();
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm() - part.radius;
}

double BodyDistance(const PersonPose& pose, const Vec3& p) {
  double best = 1e9;
  for (const BodyPart& part : pose.parts) best = std::min(best, PartDistance(part, p));
  return best;
}

// A closed box room x in [-10, 10], y in [-5, 5], z in [0, 3], inward faces;
// surface id per face.
std::unique_ptr<Scene> Room() {
  std::vector<Triangle> t;
  auto quad =
      [&](Eigen::Vector3f a, Eigen::Vector3f b, Eigen::Vector3f c, Eigen::Vector3f d, uint32_t id) {
        t.push_back({a, b, c, id});
        t.push_back({a, c, d, id});
      };
  const float x0 = -10, x1 = 10, y0 = -5, y1 = 5, z0 = 0, z1 = 3;
  quad({x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0}, 0);  // floor
  quad({x0, y0, z1}, {x0, y1, z1}, {x1, y1, z1}, {x1, y0, z1}, 1);  // ceiling
  quad({x0, y0, z0}, {x0, y1, z0}, {x0, y1, z1}, {x0, y0, z1}, 2);
  quad({x1, y0, z0}, {x1, y0, z1}, {x1, y1, z1}, {x1, y1, z0}, 3);
  quad({x0, y0, z0}, {x0, y0, z1}, {x1, y0, z1}, {x1, y0, z0}, 4);
  quad({x0, y1, z0}, {x1, y1, z0}, {x1, y1, z1}, {x0, y1, z1}, 5);
  return Scene::FromTriangles(std::move(t));
}

double RoomDistance(const Vec3& p) {
  return std::min({p.x() + 10, 10 - p.x(), p.y() + 5, 5 - p.y(), p.z(), 3 - p.z()});
}

// A rectangular loop x in [-6, 6], y in [-2, 2] on the floor, sampled every 0.1 m.
std::vector<Vec3> Loop() {
  std::vector<Vec3> corners = {{-6, -2, 0}, {6, -2, 0}, {6, 2, 0}, {-6, 2, 0}};
  std::vector<Vec3> path;
  for (size_t i = 0; i < corners.size(); ++i) {
    const Vec3 a = corners[i], b = corners[(i + 1) % corners.size()];
    const int n = static_cast<int>(std::lround((b - a).norm() / 0.1));
    for (int k = 0; k < n; ++k) path.push_back(a + (b - a) * (double(k) / n));
  }
  return path;
}

// A person starting at (-3, -2) walking +x along the loop's south side at 1.3 m/s.
WalkingPerson Walker() { return WalkingPerson(Loop(), 0.1, 3.0, 1.3, kStart); }

// The entry distance and normal against ray marching of the capsule's
// distance function (bisection to 1e-6 m) for random capsules and rays.
TEST(People, BodyPartIntersectionMatchesRayMarching) {
  std::mt19937& rng = test::Rng();
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  int hits = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    BodyPart part;
    part.a = Eigen::Vector3f(u(rng), u(rng), u(rng)) * 0.5f;
    part.b = trial % 5 == 0 ? part.a : part.a + Eigen::Vector3f(u(rng), u(rng), u(rng)) * 0.6f;
    part.radius = 0.05f + 0.15f * (u(rng) + 1.f);
    const Eigen::Vector3f origin = Eigen::Vector3f(u(rng), u(rng), u(rng)).normalized() * 3.f;
    const Eigen::Vector3f target(u(rng) * 0.5f, u(rng) * 0.5f, u(rng) * 0.5f);
    const Eigen::Vector3f dir = (target - origin).normalized();
    Eigen::Vector3f normal;
    const float t = IntersectBodyPart(part, origin, dir, &normal);
    auto f = [&](double s) {
      return PartDistance(part, (origin + static_cast<float>(s) * dir).cast<double>());
    };
    double lo = 0, hi = -1;
    for (double s = 0; s < 6.0; s += 1e-3) {
      if (f(s) <= 0) {
        hi = s;
        break;
      }
      lo = s;
    }
    if (hi < 0) {
      EXPECT_TRUE(std::isinf(t)) << "trial " << trial << ": t " << t;
      continue;
    }
    while (hi - lo > 1e-6) (f(0.5 * (lo + hi)) > 0 ? lo : hi) = 0.5 * (lo + hi);
    ASSERT_FALSE(std::isinf(t)) << "trial " << trial;
    // The entry point is on the surface, where marching first reaches it
    // (float32 arithmetic: ~1e-6 m; near-tangent rays enter where the surface
    // is parallel to them, so there only the first condition is tight).
    EXPECT_LT(std::abs(f(t)), 3e-5) << "trial " << trial;
    EXPECT_TRUE(std::abs(t - hi) < 1e-4 || std::abs(f(hi) - f(t)) < 3e-5)
        << "trial " << trial << ": " << t << " vs " << hi;
    // The normal is the outward unit normal at the entry point.
    const Vec3 p = (origin + t * dir).cast<double>();
    const double e = 1e-4;
    Vec3 gradient;
    for (int j = 0; j < 3; ++j) {
      gradient[j] =
          (PartDistance(part, p + e * Vec3::Unit(j)) - PartDistance(part, p - e * Vec3::Unit(j))) /
          (2 * e);
    }
    EXPECT_LT((normal.cast<double>() - gradient.normalized()).norm(), 1e-3) << "trial " << trial;
    ++hits;
  }
  EXPECT_GT(hits, 200);
}

// On a straight stretch the feet advance by speed * dt along the path and the
// heading is the direction of travel; against the path the heading turns around.
TEST(People, WalkAlongTheirPathAtTheirSpeed) {
  const WalkingPerson walker = Walker();
  Vec3 p0, p1;
  double yaw0, yaw1;
  walker.Locate(kStart, &p0, &yaw0);
  walker.Locate(kStart + 2 * kNsPerSecond, &p1, &yaw1);
  EXPECT_TRUE(p0.isApprox(Vec3(-3, -2, 0), 1e-9)) << p0.transpose();
  EXPECT_TRUE(p1.isApprox(Vec3(-3 + 2.6, -2, 0), 1e-9)) << p1.transpose();
  EXPECT_NEAR(yaw0, 0.0, 1e-9);
  const WalkingPerson back(Loop(), 0.1, 3.0, -1.3, kStart);
  back.Locate(kStart + 2 * kNsPerSecond, &p1, &yaw1);
  EXPECT_TRUE(p1.isApprox(Vec3(-3 - 2.6, -2, 0), 1e-9)) << p1.transpose();
  EXPECT_NEAR(std::abs(yaw1), M_PI, 1e-9);
  // One loop (32 m) later the person is back.
  walker.Locate(kStart + SecondsToNs(32.0 / 1.3), &p1, &yaw1);
  EXPECT_LT((p1 - p0).norm(), 1e-6);
  // The body: 1.73 m tall, inside its bounding sphere, legs swinging.
  const PersonPose pose = walker.Pose(kStart + kNsPerSecond / 4);
  double top = 0;
  for (const BodyPart& part : pose.parts) {
    top = std::max({top, double(part.a.z() + part.radius), double(part.b.z() + part.radius)});
    for (const Eigen::Vector3f& e : {part.a, part.b}) {
      EXPECT_LE((e - pose.centre).norm() + part.radius, pose.radius) << part.surface;
    }
  }
  EXPECT_NEAR(top, 1.73, 1e-5);
}

// A ray aimed at the head hits it at the sphere's distance at that time; once
// the person has walked on, the same ray reaches the wall; the packet version
// agrees ray by ray.
TEST(People, RaysSeeThePersonWhereItIsAtTheirTime) {
  auto room = Room();
  room->SetPeople({Walker()});
  ASSERT_EQ(room->num_static_surfaces(), 6);
  EXPECT_EQ(room->num_surfaces(), 6 + kPersonSurfaces);
  const TimestampNs t = kStart + kNsPerSecond;
  const Vec3 head = room->people()[0].Pose(t).parts[0].a.cast<double>();
  const Vec3 origin(head.x() + 0.5, 2.0, 1.5);
  const Vec3 dir = (head - origin).normalized();
  const RayHit hit = room->IntersectAt(t, origin, dir);
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.distance, (head - origin).norm() - 0.11, 1e-4);
  EXPECT_EQ(hit.surface_id, 6u + 0u);  // the first person's head
  EXPECT_LT(hit.normal.cast<double>().dot(dir), 0.0);
  const RayHit later = room->IntersectAt(t + 3 * kNsPerSecond, origin, dir);
  const RayHit wall = room->Intersect(origin, dir);
  ASSERT_TRUE(later.hit);
  EXPECT_EQ(later.distance, wall.distance);
  EXPECT_EQ(later.surface_id, wall.surface_id);
  // Sixteen rays fanned across the body against one-by-one casts.
  int valid[16];
  float origin_f[3] = {float(origin.x()), float(origin.y()), float(origin.z())};
  float dirs[16][3];
  for (int k = 0; k < 16; ++k) {
    valid[k] = k != 7;
    const Vec3 d = (head + Vec3(0.05 * (k % 4) - 0.1, 0, -0.25 * (k / 4)) - origin).normalized();
    for (int j = 0; j < 3; ++j) dirs[k][j] = static_cast<float>(d[j]);
  }
  RayHit hits[16];
  room->Intersect16At(t, valid, origin_f, dirs, 100.f, true, hits);
  int on_person = 0;
  for (int k = 0; k < 16; ++k) {
    if (!valid[k]) continue;
    const Vec3 d = Eigen::Vector3f(dirs[k][0], dirs[k][1], dirs[k][2]).cast<double>();
    const RayHit single = room->IntersectAt(t, origin, d, 0.0, 100.0);
    EXPECT_EQ(hits[k].hit, single.hit);
    EXPECT_NEAR(hits[k].distance, single.distance, 1e-5) << k;
    EXPECT_EQ(hits[k].surface_id, single.surface_id) << k;
    on_person += hits[k].surface_id >= 6u;
  }
  EXPECT_GE(on_person, 8);
}

// A static spinning LiDAR in the room with a person walking past: every point
// off the room's surfaces lies on the person posed at the point's own time
// (not at the scan's start), and the person moves between scans by v * dt.
class PeopleInLidarScans : public ::testing::Test {
 protected:
  void SetUp() override {
    room_ = Room();
    room_->SetPeople({Walker()});
    const std::vector<Quat> q(8, Quat::Identity());
    const std::vector<Vec3> p(8, Vec3(0, 0, 1.4));
    still_ = SplineTrajectory(kStart, 0.5, q, p);
    lidar_.type = LidarType::kSpinning;
    lidar_.rings = 32;
    lidar_.min_range = 0.05;
    lidar_.max_range = 120.0;
    lidar_.scan_rate = 10.0;
    options_.noise_scale = 0;
  }
  std::unique_ptr<Scene> room_;
  SplineTrajectory still_;
  RigLidar lidar_;
  LidarSimOptions options_;
};

TEST_F(PeopleInLidarScans, PointsLieOnThePersonAtTheirTimeAndThePersonMoves) {
  const LidarSimulator sim(*room_, still_, lidar_, TextureOptions(), options_);
  Vec3 centroid[2];
  for (int s = 0; s < 2; ++s) {
    const TimestampNs scan_start = kStart + s * kNsPerSecond / 2;
    const PointCloud cloud = sim.SimulateScan(scan_start, s);
    int n = 0;
    double err_own = 0, err_start = 0;
    Vec3 sum = Vec3::Zero();
    for (const LidarPoint& p : cloud.points) {
      const Vec3 world = Vec3(p.x, p.y, p.z) + Vec3(0, 0, 1.4);
      if (RoomDistance(world) < 0.01) continue;
      const TimestampNs t = cloud.stamp_ns + SecondsToNs(p.t);
      err_own = std::max(err_own, std::abs(BodyDistance(room_->people()[0].Pose(t), world)));
      err_start += std::abs(BodyDistance(room_->people()[0].Pose(scan_start), world));
      sum += world;
      ++n;
    }
    std::printf(
        "scan %d: %d points on the person; max distance to the body at the point's "
        "time %.2e m, mean at the scan start %.3f m\n",
        s,
        n,
        err_own,
        err_start / std::max(n, 1));
    ASSERT_GT(n, 100);
    EXPECT_LT(err_own, 1e-3);  // float32 point coordinates at < 10 m
    EXPECT_GT(err_start / n, 0.02);
    centroid[s] = sum / n;
  }
  // 0.5 s at 1.3 m/s along +x (the visible side of the body changes little).
  EXPECT_NEAR(centroid[1].x() - centroid[0].x(), 0.65, 0.1);
  EXPECT_NEAR(centroid[1].y() - centroid[0].y(), 0.0, 0.1);
}

// The same scans in parallel (any thread, any order) and one by one are
// identical, as are repeated casts at alternating times on one thread.
TEST_F(PeopleInLidarScans, DeterministicAcrossThreadsAndOrder) {
  const LidarSimulator sim(*room_, still_, lidar_, TextureOptions(), options_);
  const int n = 8;
  std::vector<PointCloud> serial(n), parallel(n);
  for (int i = n - 1; i >= 0; --i) serial[i] = sim.SimulateScan(kStart + i * kNsPerSecond / 10, i);
  tbb::parallel_for(
      0, n, [&](int i) { parallel[i] = sim.SimulateScan(kStart + i * kNsPerSecond / 10, i); });
  for (int i = 0; i < n; ++i) {
    ASSERT_EQ(serial[i].stamp_ns, parallel[i].stamp_ns);
    ASSERT_EQ(serial[i].size(), parallel[i].size());
    for (size_t k = 0; k < serial[i].size(); ++k) {
      const LidarPoint &a = serial[i].points[k], &b = parallel[i].points[k];
      ASSERT_TRUE(a.x == b.x && a.y == b.y && a.z == b.z && a.intensity == b.intensity &&
                  a.t == b.t)
          << "scan " << i << " point " << k;
    }
  }
  const Vec3 origin(0, 0, 1.4);
  const Vec3 dir = (Vec3(-2.0, -2.0, 1.0) - origin).normalized();
  const RayHit first = room_->IntersectAt(kStart + kNsPerSecond, origin, dir);
  room_->IntersectAt(kStart + 5 * kNsPerSecond, origin, dir);
  const RayHit again = room_->IntersectAt(kStart + kNsPerSecond, origin, dir);
  EXPECT_EQ(first.distance, again.distance);
  EXPECT_EQ(first.surface_id, again.surface_id);
}

// A camera looking at the walker: the person covers pixels at its time (closer
// than the wall there, nowhere farther), and none once it has walked out of view.
TEST(People, CamerasSeeThePersonAtTheFrameTime) {
  auto room = Room();
  const auto empty = Room();
  room->SetPeople({Walker()});
  CameraModel model;
  model.width = 160;
  model.height = 120;
  model.fx = model.fy = 100;
  model.cx = 79.5;
  model.cy = 59.5;
  model.distortion = DistortionModel::kNone;
  CameraSimOptions options;
  options.noise_scale = 0;
  const CameraRenderer with(*room, model, TextureOptions(), options);
  const CameraRenderer without(*empty, model, TextureOptions(), options);
  // At (-1.7, 0, 1.2) looking -y (z_cam = -y, x_cam = -x, y_cam = -z); the
  // walker passes x = -1.7, 2 m in front, at t = 1 s.
  const Mat3 world_from_cam_rot = (Mat3() << -1, 0, 0, 0, 0, -1, 0, -1, 0).finished();
  const SE3 world_from_cam(world_from_cam_rot, Vec3(-1.7, 0.0, 1.2));
  const TimestampNs t = kStart + kNsPerSecond;
  const cv::Mat depth_with = with.RenderDepth(world_from_cam, t);
  const cv::Mat depth_without = without.RenderDepth(world_from_cam, t);
  int closer = 0, farther = 0;
  for (int y = 0; y < model.height; ++y) {
    for (int x = 0; x < model.width; ++x) {
      const float a = depth_with.at<float>(y, x), b = depth_without.at<float>(y, x);
      closer += a < b - 1e-4f;
      farther += a > b + 1e-4f;
    }
  }
  EXPECT_GT(closer, 500);  // ~0.6 m^2 of body at 2 m: ~1500 pixels of 2 cm
  EXPECT_EQ(farther, 0);
  const cv::Mat image_with = with.Render(world_from_cam, 1, t);
  const cv::Mat image_without = without.Render(world_from_cam, 1, t);
  EXPECT_GT(cv::countNonZero(image_with != image_without), 500);
  const cv::Mat gone = with.Render(world_from_cam, 1, t + 6 * kNsPerSecond);
  EXPECT_EQ(cv::countNonZero(gone != image_without), 0);
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
