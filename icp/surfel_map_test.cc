#include "icp/surfel_map.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/errors.h"
#include "icp/rgbd_fusion.h"
#include "icp/testing/scenes.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

// A 5x5 frame whose only valid pixel is the centre (2, 2), on the optical axis.
FusionFrame CentreFrame(const Eigen::Vector3f& vertex, const Eigen::Vector3f& normal) {
  FusionFrame frame;
  frame.intrinsics = PinholeIntrinsics{10, 10, 2, 2, 5, 5};
  frame.map.Resize(5, 5);
  for (size_t i = 0; i < 25; ++i) {
    frame.map.vertices[i] = Eigen::Vector3f(0, 0, 0);
    frame.map.normals[i].setZero();
  }
  frame.map.vertices[12] = vertex;
  frame.map.normals[12] = normal.normalized();
  frame.colors.assign(25, {0, 0, 0});
  frame.colors[12] = {200, 100, 0};
  return frame;
}

// The write-up's merge rule: p_new = (w p + R q + t) / (w + 1), normals averaged
// with the same weights and normalised, confidence w + 1.
TEST(SurfelMap, MergeIsConfidenceWeightedAverage) {
  SurfelMap map;
  const SE3 world_from_camera(Quat::Identity(), Vec3(1, 2, 3));
  const Eigen::Vector3f t(1, 2, 3);
  const Eigen::Vector3f n1(0, 0, -1), n2 = Eigen::Vector3f(0.1f, 0, -1).normalized();
  map.Fuse(CentreFrame({0, 0, 1.0f}, n1), world_from_camera, 0);
  ASSERT_EQ(map.size(), 1u);
  FuseStats stats = map.Fuse(CentreFrame({0, 0, 1.01f}, n2), world_from_camera, 1);
  EXPECT_EQ(stats.merged, 1u);
  EXPECT_EQ(stats.added, 0u);
  ASSERT_EQ(map.size(), 1u);
  Surfel s = map.surfels()[0];
  EXPECT_TRUE(s.position.isApprox(t + Eigen::Vector3f(0, 0, 1.005f), 1e-6f)) << s.position;
  EXPECT_TRUE(s.normal.isApprox((n1 + n2).normalized(), 1e-6f)) << s.normal;
  EXPECT_EQ(s.confidence, 2.f);
  EXPECT_EQ(s.first_seen, 0);
  EXPECT_EQ(s.last_seen, 1);
  EXPECT_EQ(s.color[0], 200);
  // A third observation has weight 1 against 2.
  map.Fuse(CentreFrame({0, 0, 0.995f}, n1), world_from_camera, 2);
  s = map.surfels()[0];
  EXPECT_NEAR(s.position.z(), 3.f + (2 * 1.005f + 0.995f) / 3, 1e-6f);
  EXPECT_TRUE(s.normal.isApprox((2 * (n1 + n2).normalized() + n1).normalized(), 1e-6f));
  EXPECT_EQ(s.confidence, 3.f);
  // Too far (3 cm > 2 cm): a new surfel.
  stats = map.Fuse(CentreFrame({0, 0, 1.03f}, n1), world_from_camera, 3);
  EXPECT_EQ(stats.added, 1u);
  // Normals 60 deg apart (> 45 deg): a new surfel.
  const Eigen::Vector3f tilted(std::sin(1.05f), 0, -std::cos(1.05f));
  stats = map.Fuse(CentreFrame({0, 0, 1.0f}, tilted), world_from_camera, 4);
  EXPECT_EQ(stats.added, 1u);
}

// A surfel observed once is removed once it is older than unstable_age_frames
// with confidence below unstable_min_confidence; a surfel observed every frame stays.
TEST(SurfelMap, UnstableSurfelIsRemoved) {
  SurfelFusionOptions options;
  options.unstable_age_frames = 5;
  options.unstable_min_confidence = 3;
  SurfelMap map(options);
  // Frame 0: the centre pixel at 1 m; a second surfel far away, seen once.
  map.Fuse(CentreFrame({0, 0, 1.0f}, {0, 0, -1}), SE3(), 0);
  map.Fuse(CentreFrame({0, 0, 1.0f}, {0, 0, -1}), SE3(Quat::Identity(), Vec3(10, 0, 0)), 0);
  ASSERT_EQ(map.size(), 2u);
  for (int k = 1; k <= 5; ++k) map.Fuse(CentreFrame({0, 0, 1.0f}, {0, 0, -1}), SE3(), k);
  EXPECT_EQ(map.size(), 2u);  // 5 frames old: not yet
  const FuseStats stats = map.Fuse(CentreFrame({0, 0, 1.0f}, {0, 0, -1}), SE3(), 6);
  EXPECT_EQ(stats.removed, 1u);
  ASSERT_EQ(map.size(), 1u);
  EXPECT_EQ(map.surfels()[0].confidence, 7.f);
  EXPECT_TRUE(map.Stable(map.surfels()[0]));
}

// Frames with mismatched arrays are bad input.
TEST(SurfelMap, BadFrameThrows) {
  SurfelMap map;
  FusionFrame frame = CentreFrame({0, 0, 1}, {0, 0, -1});
  frame.colors.pop_back();
  EXPECT_THROW(map.Fuse(frame, SE3(), 0), InputError);
}

// Depth images of a box room from a moving camera.
const Eigen::Vector3d kRoom(3.0, 2.0, 4.0);
const PinholeIntrinsics kFull{300, 300, 159.5, 119.5, 320, 240};

std::vector<float> RenderDepth(const SE3& world_from_camera) {
  const PointSet vertices = test::RenderBoxRoom(kRoom, world_from_camera, kFull);
  std::vector<float> depth(vertices.size());
  for (size_t i = 0; i < vertices.size(); ++i) depth[i] = vertices[i].z();
  return depth;
}

// A slow arc (~1 cm and ~0.6 deg per frame) of a camera that looks down into a
// corner (walls and floor constrain all six degrees of freedom).
SE3 PoseAt(int k) {
  const double s = 0.01 * k;
  return SE3(so3::Exp(Vec3(0.35 + 0.05 * std::sin(3 * s), 0.6 + 0.6 * s, 0.1 * s)),
             Vec3(0.3 + 0.3 * s, -0.5 + 0.1 * std::sin(2 * s), 1.0 - 0.5 * s));
}

// Distance of a world point to the nearest wall of the room.
double WallDistance(const Eigen::Vector3f& p) {
  const Eigen::Vector3d a = p.cast<double>().cwiseAbs();
  return (kRoom - a).cwiseAbs().minCoeff();
}

// Fusion with the true poses puts the surfels on the walls (noise-free depth: float
// rounding, ~1 um at 4 m) and merges repeated views instead of adding. At the room's
// edges an average of observations on both walls within one pixel footprint (~2 cm)
// lies inside the room, less than 5 mm from the walls.
TEST(RgbdFusion, GivenPosesPutSurfelsOnTheWalls) {
  RgbdFusion fusion(kFull, RgbdFusionOptions(), ProjectiveIcpOptions(), SurfelFusionOptions());
  for (int k = 0; k < 10; ++k) {
    const RgbdFrameResult r = fusion.AddFrame(RenderDepth(PoseAt(k)), {}, PoseAt(k));
    EXPECT_FALSE(r.tracked);
  }
  const SurfelMap& map = fusion.map();
  ASSERT_GT(map.size(), 10000u);
  std::vector<double> distances;
  for (const Surfel& s : map.surfels()) distances.push_back(WallDistance(s.position));
  std::sort(distances.begin(), distances.end());
  EXPECT_LT(distances[distances.size() / 2], 1e-5);
  EXPECT_LT(distances[distances.size() * 95 / 100], 1e-4);
  EXPECT_LT(distances.back(), 5e-3);
  // 10 frames of 160x120: most pixels merge into existing surfels.
  EXPECT_LT(map.size(), fusion.num_input_points() / 3);
  EXPECT_GT(map.NumStable(), map.size() / 2);
}

// Frame-to-model tracking on the same noise-free sequence: the chained poses stay
// within 1 mm / 1 mrad of the truth after 20 frames; with the default crease
// rejection within 10 um / 10 urad (measured ~1 um: float rounding).
TEST(RgbdFusion, TracksKnownTrajectory) {
  RgbdFusion fusion(kFull, RgbdFusionOptions(), ProjectiveIcpOptions(), SurfelFusionOptions());
  for (int k = 0; k < 20; ++k) {
    const RgbdFrameResult r = fusion.AddFrame(
        RenderDepth(PoseAt(k)), {}, k == 0 ? std::optional<SE3>(PoseAt(0)) : std::nullopt);
    if (k > 0) {
      EXPECT_TRUE(r.tracked) << k << ": " << r.icp.message;
      EXPECT_TRUE(r.icp.converged) << k << ": " << r.icp.message;
    }
    EXPECT_TRUE(test::PosesNear(r.world_from_camera, PoseAt(k), 1e-5, 1e-5)) << "frame " << k;
  }
}

// Without crease rejection the normals of pixels whose window spans the room's
// edges mix two walls and bias each frame's estimate along the motion: the error
// after 20 frames is over 100 um (~1 mm measured) with the default window of 2
// pixels, so the rejection is what keeps the test above within 10 um.
TEST(RgbdFusion, CreaseNormalsBiasTracking) {
  RgbdFusionOptions options;
  options.crease_rejection_sigma = 0;
  RgbdFusion fusion(kFull, options, ProjectiveIcpOptions(), SurfelFusionOptions());
  double max_error_m = 0;
  for (int k = 0; k < 20; ++k) {
    const RgbdFrameResult r = fusion.AddFrame(
        RenderDepth(PoseAt(k)), {}, k == 0 ? std::optional<SE3>(PoseAt(0)) : std::nullopt);
    max_error_m =
        std::max(max_error_m, (r.world_from_camera.translation() - PoseAt(k).translation()).norm());
  }
  EXPECT_GT(max_error_m, 1e-4);
}

}  // namespace
}  // namespace lisfm
