#include "importers/database_importer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "colmap_ext/sfm/lidar_constraints.h"
#include "core/file_utils.h"
#include "sim/motion.h"
#include "sim/scene.h"
#include "tests/common/sim_walks.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Pinhole camera, 640 x 480, f = 300 px, looking along +x (forward = true) or
// -x of the IMU frame.
RigCamera MakeCamera(const std::string& name, bool forward) {
  RigCamera c;
  c.name = name;
  c.model.width = 640;
  c.model.height = 480;
  c.model.fx = c.model.fy = 300;
  c.model.cx = 319.5;
  c.model.cy = 239.5;
  Mat3 R;
  if (forward) {
    R << 0, -1, 0, 0, 0, -1, 1, 0, 0;  // z_cam = x_imu
  } else {
    R << 0, 1, 0, 0, 0, -1, -1, 0, 0;  // z_cam = -x_imu
  }
  c.cam_from_imu = SE3(R, Vec3::Zero());
  return c;
}

// Points of the plane x = x0 over y in [-3, 3], z in [-2, 2] (5 cm grid), world frame.
std::vector<Eigen::Vector3f> Wall(double x0) {
  std::vector<Eigen::Vector3f> points;
  for (double y = -3; y <= 3; y += 0.05) {
    for (double z = -2; z <= 2; z += 0.05) points.emplace_back(x0, y, z);
  }
  return points;
}

KeyframeScan MakeScan(TimestampNs t,
                      const SE3& world_from_imu,
                      const std::vector<Eigen::Vector3f>& world_points) {
  KeyframeScan s;
  s.t_ns = t;
  s.world_from_imu = world_from_imu;
  const SE3 imu_from_world = world_from_imu.Inverse();
  for (const auto& p : world_points) {
    s.points_in_imu.push_back((imu_from_world * p.cast<double>()).cast<float>());
  }
  return s;
}

struct TwoScanCase {
  Rig rig;
  std::vector<ImporterImage> images;  // cam0@0, cam1@0, cam0@1, cam1@1
  std::vector<KeyframeScan> scans;
};

TwoScanCase MakeTwoScanCase(bool occluder) {
  TwoScanCase c;
  c.rig.cameras = {MakeCamera("cam0", true), MakeCamera("cam1", false)};
  const SE3 pose0 = SE3::Identity();
  const SE3 pose1(Quat(Eigen::AngleAxisd(0.1, Vec3::UnitZ())), Vec3(0.3, 0.5, 0.0));
  const TimestampNs t0 = 1000000000, t1 = 2000000000;
  for (const auto& [t, pose] : {std::make_pair(t0, pose0), std::make_pair(t1, pose1)}) {
    for (int k = 0; k < 2; ++k) {
      ImporterImage image;
      image.camera_index = k;
      image.stamp_ns = image.t_imu_ns = t;
      image.name = "cam" + std::to_string(k) + "/data/" + std::to_string(t) + ".png";
      image.world_from_cam = pose * c.rig.cameras[k].cam_from_imu.Inverse();
      image.frame = t == t0 ? 0 : 1;
      c.images.push_back(image);
    }
  }
  std::vector<Eigen::Vector3f> scene_i = Wall(5.0);
  if (occluder) {
    const auto front = Wall(2.0);
    scene_i.insert(scene_i.end(), front.begin(), front.end());
  }
  c.scans.push_back(MakeScan(t0, pose0, scene_i));
  c.scans.push_back(MakeScan(t1, pose1, Wall(5.0)));
  return c;
}

TEST(Covisibility, WallSeenByFacingCamerasOnly) {
  const TwoScanCase c = MakeTwoScanCase(/*occluder=*/false);
  const auto votes = ComputeCovisibility(c.rig, c.images, c.scans, {{0, 1}}, CovisibilityOptions());
  // Only cam0 at t0 (image 0) and cam0 at t1 (image 2) face the wall.
  ASSERT_EQ(votes.size(), 1u);
  const auto& [pair, v] = *votes.begin();
  EXPECT_EQ(pair, std::make_pair(0, 2));
  // The wall in cam0's view at 5 m: about 2 x 5 tan(46.8 deg) by 2 x 5 tan(38.7 deg) m,
  // 10.6 x 8 m, clipped to the 6 x 4 m wall: the whole wall, 60 x 40 voxels of 10 cm.
  EXPECT_GT(v.count, 1500);
  ASSERT_EQ(v.voters.size(), 1u);
  EXPECT_EQ(v.voters[0].first, std::make_pair(0, 1));
  EXPECT_EQ(v.voters[0].second, v.count);
  // The selection lists it; the rig pair (cam0, cam1) never overlaps.
  const auto pairs = SelectPairs(c.rig, c.images, votes, false, CovisibilityOptions());
  bool found = false;
  for (const SelectedPair& p : pairs) {
    if (p.a == 0 && p.b == 2) {
      found = true;
      EXPECT_EQ(p.source, PairSource::kCovisibility);
    }
    EXPECT_NE(p.source, PairSource::kRig);
  }
  EXPECT_TRUE(found);
  EXPECT_TRUE(OverlappingRigCameras(c.rig, CovisibilityOptions()).empty());
}

TEST(Covisibility, OccludingWallHidesTheMatchedPoints) {
  const TwoScanCase c = MakeTwoScanCase(/*occluder=*/true);
  const auto votes = ComputeCovisibility(c.rig, c.images, c.scans, {{0, 1}}, CovisibilityOptions());
  // The far wall's points match, but from cam0 at t0 the near wall (2 m) is
  // the first surface along every ray: no vote.
  EXPECT_TRUE(votes.empty());
}

TEST(Covisibility, DeterministicAcrossThreadCounts) {
  const TwoScanCase c = MakeTwoScanCase(false);
  CovisibilityOptions one;
  one.num_threads = 1;
  const auto a = ComputeCovisibility(c.rig, c.images, c.scans, {{0, 1}, {1, 0}}, one);
  const auto b =
      ComputeCovisibility(c.rig, c.images, c.scans, {{0, 1}, {1, 0}}, CovisibilityOptions());
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [pair, v] : a) {
    EXPECT_EQ(b.at(pair).count, v.count);
    EXPECT_EQ(b.at(pair).voters, v.voters);
  }
}

TEST(MapCovisibility, WallSeenByFacingCamerasOnly) {
  const TwoScanCase c = MakeTwoScanCase(/*occluder=*/false);
  const auto votes = ComputeMapCovisibility(c.rig, c.images, c.scans, CovisibilityOptions());
  // Only cam0 at t0 (image 0) and cam0 at t1 (image 2) face the wall; both see
  // all of it (60 x 40 voxels of 10 cm, the two scans' points share the voxels).
  ASSERT_EQ(votes.size(), 1u);
  const auto& [pair, v] = *votes.begin();
  EXPECT_EQ(pair, std::make_pair(0, 2));
  EXPECT_GT(v.count, 1500);
  EXPECT_LE(v.count, 61 * 41);
  EXPECT_TRUE(v.voters.empty());
  // Area score: the wall's solid angle seen from ~5 m, at most its 6 x 4 m^2 / (5 m)^2.
  EXPECT_GT(v.score, 0.5);
  EXPECT_LT(v.score, 24.0 / 25.0);
  CovisibilityOptions count;
  count.score = "count";
  EXPECT_EQ(ComputeMapCovisibility(c.rig, c.images, c.scans, count).begin()->second.score,
            static_cast<double>(v.count));
  CovisibilityOptions fraction;
  fraction.score = "fraction";
  const auto f = ComputeMapCovisibility(c.rig, c.images, c.scans, fraction);
  ASSERT_EQ(f.size(), 1u);
  EXPECT_GT(f.begin()->second.score, 0.9);
  EXPECT_LE(f.begin()->second.score, 1.0);
  // The rays from the two centres are at least 2.95 degrees apart at every
  // wall point: no vote below that.
  CovisibilityOptions narrow;
  narrow.max_view_angle_deg = 2.5;
  EXPECT_TRUE(ComputeMapCovisibility(c.rig, c.images, c.scans, narrow).empty());
}

// Camera A at the origin and camera B at x = 3.5, both looking along +x; a
// far wall at x = 5 that B sees. With a wall at x = 2 in the map (scanned from
// both places), A sees only that wall: the pair gets no vote.
TEST(MapCovisibility, WallBetweenTheCamerasHidesTheFarWall) {
  for (const bool occluder : {false, true}) {
    SCOPED_TRACE(occluder ? "occluder" : "open");
    Rig rig;
    rig.cameras = {MakeCamera("cam0", true)};
    std::vector<ImporterImage> images;
    std::vector<KeyframeScan> scans;
    const std::vector<SE3> poses = {SE3::Identity(), SE3(Quat::Identity(), Vec3(3.5, 0.0, 0.0))};
    for (size_t k = 0; k < poses.size(); ++k) {
      const TimestampNs t = static_cast<TimestampNs>(k + 1) * 1000000000;
      ImporterImage image;
      image.stamp_ns = image.t_imu_ns = t;
      image.name = "cam0/data/" + std::to_string(t) + ".png";
      image.world_from_cam = poses[k] * rig.cameras[0].cam_from_imu.Inverse();
      image.frame = static_cast<int>(k);
      images.push_back(image);
      std::vector<Eigen::Vector3f> scene = Wall(k == 0 && occluder ? 2.0 : 5.0);
      if (k == 1 && occluder) {
        const auto near = Wall(2.0);
        scene.insert(scene.end(), near.begin(), near.end());
      }
      scans.push_back(MakeScan(t, poses[k], scene));
    }
    const auto votes = ComputeMapCovisibility(rig, images, scans, CovisibilityOptions());
    if (occluder) {
      EXPECT_TRUE(votes.empty());
    } else {
      ASSERT_EQ(votes.size(), 1u);
      // B at 1.5 m sees +-1.6 m x +-1.2 m of the wall: ~32 x 24 voxels.
      EXPECT_GT(votes.begin()->second.count, 500);
    }
  }
}

TEST(MapCovisibility, DeterministicAcrossThreadCounts) {
  const TwoScanCase c = MakeTwoScanCase(true);
  CovisibilityOptions one;
  one.num_threads = 1;
  const auto a = ComputeMapCovisibility(c.rig, c.images, c.scans, one);
  const auto b = ComputeMapCovisibility(c.rig, c.images, c.scans, CovisibilityOptions());
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [pair, v] : a) {
    EXPECT_EQ(b.at(pair).count, v.count);
    EXPECT_EQ(b.at(pair).score, v.score);
  }
}

// Rig pairing (header comment of database_importer.h): the images of one rig
// frame are paired when their cameras' views overlap (intra_rig_pairs), never
// otherwise without votes; images of different frames only through votes or
// as temporal neighbours of the same camera.
TEST(SelectPairs, RigFramesPairOverlappingCamerasOnly) {
  Rig rig;
  RigCamera left = MakeCamera("cam0", true);
  RigCamera right = MakeCamera("cam1", true);
  right.cam_from_imu = SE3(right.cam_from_imu.rotation(), Vec3(-0.1, 0.0, 0.0));  // 10 cm base
  rig.cameras = {left, right, MakeCamera("cam2", false)};
  std::vector<ImporterImage> images;
  for (int f = 0; f < 3; ++f) {
    for (int k = 0; k < 3; ++k) {
      ImporterImage image;
      image.camera_index = k;
      image.stamp_ns = image.t_imu_ns = (f + 1) * TimestampNs{1000000000};
      image.name = "cam" + std::to_string(k) + "/data/" + std::to_string(image.stamp_ns) + ".png";
      image.world_from_cam =
          SE3(Quat::Identity(), Vec3(f, 0, 0)) * rig.cameras[k].cam_from_imu.Inverse();
      image.frame = f;
      images.push_back(image);
    }
  }
  const auto overlapping = OverlappingRigCameras(rig, CovisibilityOptions());
  ASSERT_EQ(overlapping, (std::vector<std::pair<int, int>>{{0, 1}}));
  CovisibilityOptions options;
  options.num_temporal_neighbors = 0;
  const std::map<std::pair<int, int>, PairVotes> no_votes;
  auto pairs = SelectPairs(rig, images, no_votes, false, options);
  ASSERT_EQ(pairs.size(), 3u);
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(pairs[f].a, 3 * f);
    EXPECT_EQ(pairs[f].b, 3 * f + 1);
    EXPECT_EQ(pairs[f].source, PairSource::kRig);
  }
  options.intra_rig_pairs = false;
  EXPECT_TRUE(SelectPairs(rig, images, no_votes, false, options).empty());
  // One temporal neighbour: each camera's successive frames, nothing across cameras.
  options.num_temporal_neighbors = 1;
  pairs = SelectPairs(rig, images, no_votes, false, options);
  ASSERT_EQ(pairs.size(), 6u);
  for (const SelectedPair& p : pairs) {
    EXPECT_EQ(p.source, PairSource::kTemporal);
    EXPECT_EQ(images[p.a].camera_index, images[p.b].camera_index);
    EXPECT_EQ(images[p.b].frame, images[p.a].frame + 1);
  }
  // Votes between the front and back cameras of one frame list the pair (as
  // co-visibility); the rig rule alone never does.
  std::map<std::pair<int, int>, PairVotes> votes;
  votes[{0, 2}].count = 50;
  votes[{0, 2}].score = 50;
  options.num_temporal_neighbors = 0;
  options.intra_rig_pairs = true;
  pairs = SelectPairs(rig, images, votes, false, options);
  ASSERT_EQ(pairs.size(), 4u);
  EXPECT_EQ(pairs[0].a, 0);
  EXPECT_EQ(pairs[0].b, 1);
  EXPECT_EQ(pairs[1].a, 0);
  EXPECT_EQ(pairs[1].b, 2);
  EXPECT_EQ(pairs[1].source, PairSource::kCovisibility);
  EXPECT_EQ(pairs[1].count, 50);
}

TEST(InterpolatePoseSe3, ExactOnAScrewMotion) {
  Vec6 xi;
  xi << 0.3, -0.2, 0.5, 1.0, 0.4, -0.2;  // per second
  Trajectory trajectory;
  for (int k = 0; k <= 10; ++k) trajectory.PushBack({k * 100000000LL, SE3::Exp(xi * 0.1 * k)});
  for (TimestampNs t : {0LL, 37000000LL, 555555555LL, 1000000000LL}) {
    const auto pose = InterpolatePoseSe3(trajectory, t);
    ASSERT_TRUE(pose.has_value());
    const SE3 expected = SE3::Exp(xi * NsToSeconds(t));
    EXPECT_LT((pose->Inverse() * expected).Log().norm(), 1e-12) << t;
  }
  EXPECT_FALSE(InterpolatePoseSe3(trajectory, -1).has_value());
  EXPECT_FALSE(InterpolatePoseSe3(trajectory, 1000000001LL).has_value());
}

// The priors' interpolation against the simulator's exact camera poses: a
// walk sampled at 100 Hz (groundtruth.txt's rate) and interpolated at camera
// times between the samples reproduces walk(t) * imu_from_cam.
TEST(InterpolatePoseSe3, MatchesSimulatedCameraPoses) {
  const auto scene = sim::Scene::Generate(sim::DefaultSceneOptions("office"));
  const sim::SplineTrajectory walk =
      sim::GenerateWalking(scene->route(), 20.0, 0, 1, ThreeStopWalk(), nullptr);
  Trajectory trajectory;
  for (TimestampNs t = 0; t <= SecondsToNs(20.0); t += 10000000) {
    trajectory.PushBack({t, walk.Pose(t)});
  }
  const RigCamera camera = MakeCamera("cam0", true);
  double max_pos = 0, max_rot = 0;
  for (TimestampNs t = 3456789; t < SecondsToNs(19.9); t += 123456789) {
    const SE3 prior = *InterpolatePoseSe3(trajectory, t) * camera.cam_from_imu.Inverse();
    const SE3 exact = walk.Pose(t) * camera.cam_from_imu.Inverse();
    max_pos = std::max(max_pos, (prior.translation() - exact.translation()).norm());
    max_rot = std::max(max_rot, so3::AngularDistance(prior.rotation(), exact.rotation()));
  }
  // Between 100 Hz samples the error is that of a chord: |a| dt^2 / 8 with
  // walking accelerations of a few m/s^2 and dt = 10 ms, ~0.1 mm; likewise
  // |alpha| dt^2 / 8 for the rotation (head turns of ~10 rad/s^2): ~1e-4 rad.
  EXPECT_LT(max_pos, 2e-4);
  EXPECT_LT(max_rot, 0.01 * kDegToRad);
}

TEST(ReexpressConstraints, ExactBetweenRigFramesAndAttachesInTheMapper) {
  Vec6 xi;
  xi << 0.2, 0.1, -0.3, 0.8, -0.3, 0.1;
  Trajectory trajectory;  // 10 Hz, lio-like
  for (int k = 0; k <= 50; ++k) trajectory.PushBack({k * 100000000LL, SE3::Exp(xi * 0.1 * k)});
  auto world_from_imu = [&](TimestampNs t) { return SE3::Exp(xi * NsToSeconds(t)); };
  // Rig frames at 1 Hz, camera stamps 3 ms before the IMU time.
  std::vector<ImporterFrame> frames;
  for (int f = 0; f < 5; ++f) {
    ImporterFrame frame;
    frame.t_imu_ns = f * 1000000000LL + 250000000LL;
    frame.stamp_ns = frame.t_imu_ns - 3000000;
    frame.world_from_imu = world_from_imu(frame.t_imu_ns);
    frames.push_back(frame);
  }
  // Keyframe constraints at scan ends (x.1 s), exact.
  std::vector<LidarConstraintRecord> records;
  for (int k = 0; k + 1 < 5; ++k) {
    LidarConstraintRecord r;
    r.t_i_ns = k * 1000000000LL + 100000000LL;
    r.t_j_ns = (k + 1) * 1000000000LL + 100000000LL;
    r.i_from_j = world_from_imu(r.t_i_ns).Inverse() * world_from_imu(r.t_j_ns);
    r.covariance = Mat6::Identity() * 1e-4;
    records.push_back(r);
  }
  size_t dropped = 0;
  const auto out =
      ReexpressConstraints(records, trajectory, {}, frames, ImporterPriorOptions(), &dropped);
  EXPECT_EQ(dropped, 0u);
  ASSERT_EQ(out.size(), records.size());
  for (size_t k = 0; k < out.size(); ++k) {
    EXPECT_EQ(out[k].t_i_ns, frames[k].stamp_ns);
    EXPECT_EQ(out[k].t_j_ns, frames[k + 1].stamp_ns);
    const SE3 expected = frames[k].world_from_imu.Inverse() * frames[k + 1].world_from_imu;
    EXPECT_LT((out[k].i_from_j.Inverse() * expected).Log().norm(), 1e-9);
    // Propagated and inflated: at least the input's covariance scale.
    EXPECT_GT(out[k].covariance.trace(), 0.9 * records[k].covariance.trace());
    EXPECT_TRUE(out[k].covariance.isApprox(out[k].covariance.transpose()));
  }
  // global_mapper's attachment: frames named camK/data/<stamp>.png.
  colmap::MapperState state;
  for (size_t f = 0; f < frames.size(); ++f) {
    colmap::SfmFrame frame;
    frame.frame_id = static_cast<colmap::frame_t>(f + 1);
    frame.stamp_ns = frames[f].stamp_ns;
    state.frames[frame.frame_id] = frame;
  }
  EXPECT_EQ(colmap::AttachLidarConstraints(out, colmap::kDefaultLidarConstraintToleranceNs, &state),
            out.size());
  // The keyframe stamps themselves would not attach (100-250 ms away).
  colmap::MapperState state2 = state;
  state2.lidar_constraints.clear();
  EXPECT_EQ(
      colmap::AttachLidarConstraints(records, colmap::kDefaultLidarConstraintToleranceNs, &state2),
      0u);
}

TEST(ReadImageSize, PngAndJpegHeaders) {
  test::TempDir dir;
  // PNG signature + IHDR with width 720, height 540.
  const unsigned char png[] = {0x89, 'P', 'N', 'G', 0x0d, 0x0a, 0x1a, 0x0a, 0, 0, 0,    13,
                               'I',  'H', 'D', 'R', 0,    0,    0x02, 0xd0, 0, 0, 0x02, 0x1c};
  {
    std::ofstream f(dir.File("a.png"), std::ios::binary);
    f.write(reinterpret_cast<const char*>(png), sizeof(png));
  }
  EXPECT_EQ(ReadImageSize(dir.File("a.png")), std::make_pair(720, 540));
  test::WriteText(dir.File("b.png"), "not an image");
  EXPECT_THROW(ReadImageSize(dir.File("b.png")), InputError);
  const std::string jpg = test::SharedData("hilti_exp4_small/images/0.jpg");
  if (!jpg.empty() && FileExists(jpg)) {
    EXPECT_EQ(ReadImageSize(jpg), std::make_pair(720, 540));
  }
}

}  // namespace
}  // namespace lisfm
