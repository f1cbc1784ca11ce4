#include "colmap_ext/sfm/triangulation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

constexpr double kPi = 3.14159265358979323846;

Camera MakeCamera(camera_t id, CameraModelId model) {
  Camera camera;
  camera.camera_id = id;
  camera.model_id = static_cast<int>(model);
  camera.width = 640;
  camera.height = 480;
  switch (model) {
    case CameraModelId::kPinhole:
      camera.params = {500, 510, 320.5, 240.5};
      break;
    case CameraModelId::kOpenCV:  // moderate radial + tangential distortion
      camera.params = {480, 490, 318, 242, -0.12, 0.03, 0.001, -0.0015};
      break;
    case CameraModelId::kOpenCVFisheye:
      camera.params = {300, 300, 321, 239, 0.05, -0.01, 0.003, -0.001};
      break;
    default:
      ADD_FAILURE() << "unsupported model in the test";
  }
  return camera;
}

// cam_from_world of a camera at `center` looking at `target` (z forward,
// y roughly along world +y), rolled by `roll` rad about its optical axis.
SE3 LookAt(const Vec3& center, const Vec3& target, double roll) {
  const Vec3 z = (target - center).normalized();
  const Vec3 x = Vec3(0, 1, 0).cross(z).normalized();
  const Vec3 y = z.cross(x);
  Mat3 world_from_cam;
  world_from_cam << x, y, z;
  const Mat3 cam_from_world =
      Eigen::AngleAxisd(roll, Vec3::UnitZ()).toRotationMatrix() * world_from_cam.transpose();
  return SE3(cam_from_world, -cam_from_world * center);
}

// A state with the given cameras, one image per frame, all registered.
// Camera 2 (when present) sits in a non-trivial rig: cam_from_rig is not the
// identity, so the test also checks that poses come from CamFromWorld.
struct Scene {
  MapperState state;
  std::vector<Vec3> points;  // ground truth of track t
};

void AddImage(Scene* scene, image_t image_id, camera_t camera_id, const SE3& cam_from_world) {
  MapperState& state = scene->state;
  SfmImage image;
  image.image_id = image_id;
  image.camera_id = camera_id;
  image.frame_id = image_id;
  state.images[image_id] = image;
  SfmFrame frame;
  frame.frame_id = image_id;
  frame.image_ids = {image_id};
  frame.registered = true;
  frame.rig_from_world = state.cam_from_rig.at(camera_id).Inverse() * cam_from_world;
  state.frames[image_id] = frame;
}

// Adds an observation of `xyz` in `image_id` as a new keypoint. With
// allow_behind the pixel is computed from x/z, y/z even for z < 0 (the pixel
// a camera would see for the mirrored point: consistent with the linear
// equations but behind the camera).
point2D_t Observe(Scene* scene,
                  image_t image_id,
                  const Vec3& xyz,
                  double noise_px,
                  bool allow_behind = false) {
  MapperState& state = scene->state;
  SfmImage& image = state.images.at(image_id);
  const Camera& camera = state.cameras.at(image.camera_id);
  const Vec3 x_in_cam = state.CamFromWorld(image_id) * xyz;
  EXPECT_TRUE(allow_behind || x_in_cam.z() > 0.0);
  std::normal_distribution<double> noise(0.0, 1.0);
  Vec2 pixel = camera.ImgFromCam(x_in_cam.head<2>() / x_in_cam.z());
  if (noise_px > 0.0) pixel += noise_px * Vec2(noise(test::Rng()), noise(test::Rng()));
  image.keypoints.push_back(pixel);
  image.normalized.push_back(camera.CamFromImg(pixel));
  image.track_ids.push_back(-1);
  return static_cast<point2D_t>(image.keypoints.size() - 1);
}

void AddTrack(Scene* scene, const Vec3& xyz, const std::vector<TrackElement>& elements) {
  const int track_id = static_cast<int>(scene->state.tracks.size());
  Track track;
  track.elements = elements;
  for (const TrackElement& e : elements) {
    scene->state.images.at(e.image_id).track_ids.at(e.point2D_idx) = track_id;
  }
  scene->state.tracks.push_back(track);
  scene->points.push_back(xyz);
}

void AddCameras(Scene* scene) {
  MapperState& state = scene->state;
  state.cameras[1] = MakeCamera(1, CameraModelId::kPinhole);
  state.cameras[2] = MakeCamera(2, CameraModelId::kOpenCV);
  state.cameras[3] = MakeCamera(3, CameraModelId::kOpenCVFisheye);
  state.cam_from_rig[1] = SE3::Identity();
  state.cam_from_rig[2] = SE3(so3::Exp(Vec3(0.1, -0.2, 0.05)), Vec3(0.3, -0.1, 0.2));
  state.cam_from_rig[3] = SE3::Identity();
}

// `num_images` cameras (cycling PINHOLE, OPENCV, OPENCV_FISHEYE) on an arc of
// radius 10 spanning 60 deg, all looking at the origin; `num_points` points
// uniform in [-2, 2]^3, each seen by every image (keypoint noise `noise_px`).
Scene MakeScene(int num_images, int num_points, double noise_px) {
  Scene scene;
  AddCameras(&scene);
  std::uniform_real_distribution<double> roll(-0.2, 0.2);
  for (int i = 0; i < num_images; ++i) {
    const double angle = (-30.0 + 60.0 * i / std::max(1, num_images - 1)) * kPi / 180.0;
    const Vec3 center(10.0 * std::sin(angle), 0.5 * i - 1.0, -10.0 * std::cos(angle));
    AddImage(&scene, i + 1, 1 + i % 3, LookAt(center, Vec3::Zero(), roll(test::Rng())));
  }
  std::uniform_real_distribution<double> coord(-2.0, 2.0);
  for (int p = 0; p < num_points; ++p) {
    const Vec3 xyz(coord(test::Rng()), coord(test::Rng()), coord(test::Rng()));
    std::vector<TrackElement> elements;
    for (int i = 1; i <= num_images; ++i) {
      elements.push_back({static_cast<image_t>(i), Observe(&scene, i, xyz, noise_px)});
    }
    AddTrack(&scene, xyz, elements);
  }
  return scene;
}

// Sum of squared pixel errors of `xyz` over the track's elements.
double SquaredError(const MapperState& state, const Track& track, const Vec3& xyz) {
  double sum = 0.0;
  for (const TrackElement& e : track.elements) {
    const SfmImage& image = state.images.at(e.image_id);
    Vec2 pixel;
    EXPECT_TRUE(state.cameras.at(image.camera_id).Project(state.CamFromWorld(e.image_id) * xyz,
                                                          &pixel));
    sum += (pixel - image.keypoints[e.point2D_idx]).squaredNorm();
  }
  return sum;
}

bool ContainsImage(const std::vector<TrackElement>& elements, image_t image_id) {
  for (const TrackElement& e : elements) {
    if (e.image_id == image_id) return true;
  }
  return false;
}

TEST(TriangulateTracks, ExactOnNoiseFreeDataForAllCameraModels) {
  Scene scene = MakeScene(6, 100, 0.0);
  const TriangulationStats stats = TriangulateTracks(TriangulationOptions(), &scene.state);
  EXPECT_EQ(stats.num_tracks_considered, 100u);
  EXPECT_EQ(stats.num_tracks_triangulated, 100u);
  EXPECT_EQ(stats.num_tracks_robust, 0u);
  EXPECT_EQ(stats.num_observations, 600u);
  EXPECT_EQ(stats.num_observations_rejected_depth + stats.num_observations_rejected_reprojection,
            0u);
  for (size_t t = 0; t < scene.points.size(); ++t) {
    const Track& track = scene.state.tracks[t];
    ASSERT_TRUE(track.triangulated);
    EXPECT_EQ(track.elements.size(), 6u);
    // Exact data: only rounding and the ~1e-12 undistortion tolerance remain;
    // 1e-6 relative to the ~10 m viewing distance.
    EXPECT_LT((track.xyz - scene.points[t]).norm(), 1e-6 * 10.0) << "track " << t;
    EXPECT_LT(track.error, 1e-6);
  }
  EXPECT_LT(stats.mean_reprojection_error_px, 1e-6);
}

TEST(TriangulateTracks, BoundedErrorWithHalfPixelNoise) {
  constexpr double kSigma = 0.5;  // px
  Scene scene = MakeScene(6, 200, kSigma);
  const TriangulationStats stats = TriangulateTracks(TriangulationOptions(), &scene.state);
  // 4 px is 8 sigma: P(|n| > 4 px) = exp(-32) for 2D Gaussian noise, so no
  // observation may be rejected.
  EXPECT_EQ(stats.num_tracks_triangulated, 200u);
  EXPECT_EQ(stats.num_observations, 1200u);
  // The fitted residual norm has mean sigma * sqrt(pi / 2) * sqrt((2L - 3) /
  // 2L) ~= 0.54 px for L = 6 views; its standard error over 1200
  // observations is ~0.01 px, so 0.7 px is a > 10 sigma bound.
  EXPECT_LT(stats.mean_reprojection_error_px, 0.7);
  EXPECT_GT(stats.mean_reprojection_error_px, 0.35);
  double sum_d2 = 0.0, max_d2 = 0.0;
  for (size_t t = 0; t < scene.points.size(); ++t) {
    const Track& track = scene.state.tracks[t];
    ASSERT_TRUE(track.triangulated);
    // Maximum likelihood: the refined point fits the noisy keypoints at least
    // as well as the true point does (up to the LM stopping tolerance).
    EXPECT_LE(SquaredError(scene.state, track, track.xyz),
              SquaredError(scene.state, track, scene.points[t]) + 1e-9);
    // The position error against its predicted covariance sigma^2 (J^T J)^-1
    // (J: stacked pixel projections at the true point): the squared
    // Mahalanobis distance |J e|^2 / sigma^2 is chi-square with 3 dof.
    const auto project = [&](const Eigen::VectorXd& xyz) {
      Eigen::VectorXd pixels(2 * track.elements.size());
      for (size_t k = 0; k < track.elements.size(); ++k) {
        const image_t image_id = track.elements[k].image_id;
        Vec2 pixel;
        scene.state.cameras.at(scene.state.images.at(image_id).camera_id)
            .Project(scene.state.CamFromWorld(image_id) * Vec3(xyz), &pixel);
        pixels.segment<2>(2 * k) = pixel;
      }
      return pixels;
    };
    const Eigen::MatrixXd j = test::NumericJacobian(project, scene.points[t], 1e-6);
    const double d2 = (j * (track.xyz - scene.points[t])).squaredNorm() / (kSigma * kSigma);
    sum_d2 += d2;
    max_d2 = std::max(max_d2, d2);
  }
  // chi2(3): P(d2 > 30) ~ 1.4e-6 per point; the mean of 200 draws is 3 with
  // a standard error of sqrt(6 / 200) ~ 0.17, so [2, 4] is a ~6 sigma band.
  EXPECT_LT(max_d2, 30.0);
  EXPECT_GT(sum_d2 / 200.0, 2.0);
  EXPECT_LT(sum_d2 / 200.0, 4.0);
}

TEST(TriangulateTracks, RejectsOutlierObservations) {
  Scene scene = MakeScene(6, 50, 0.0);
  // Move one keypoint of tracks 0..9 by 40 px (10x the threshold), and two
  // keypoints of track 10.
  auto corrupt = [&](size_t track_id, size_t element) {
    const TrackElement e = scene.state.tracks[track_id].elements[element];
    SfmImage& image = scene.state.images.at(e.image_id);
    image.keypoints[e.point2D_idx] += Vec2(40.0, -15.0);
    image.normalized[e.point2D_idx] =
        scene.state.cameras.at(image.camera_id).CamFromImg(image.keypoints[e.point2D_idx]);
    return e.image_id;
  };
  std::vector<image_t> corrupted(11);
  for (size_t t = 0; t < 10; ++t) corrupted[t] = corrupt(t, t % 6);
  const image_t second = corrupt(10, 1);
  corrupted[10] = corrupt(10, 4);

  const TriangulationStats stats = TriangulateTracks(TriangulationOptions(), &scene.state);
  EXPECT_EQ(stats.num_tracks_triangulated, 50u);
  EXPECT_EQ(stats.num_observations_rejected_reprojection, 12u);
  EXPECT_EQ(stats.num_observations_rejected_depth, 0u);
  EXPECT_EQ(stats.num_tracks_robust, 11u);
  for (size_t t = 0; t < scene.points.size(); ++t) {
    const Track& track = scene.state.tracks[t];
    ASSERT_TRUE(track.triangulated);
    // The remaining observations are exact: same bound as the noise-free test.
    EXPECT_LT((track.xyz - scene.points[t]).norm(), 1e-5);
    if (t < 11) {
      EXPECT_TRUE(ContainsImage(track.rejected, corrupted[t])) << "track " << t;
      EXPECT_FALSE(ContainsImage(track.elements, corrupted[t]));
      EXPECT_EQ(track.elements.size() + track.rejected.size(), 6u);
    } else {
      EXPECT_TRUE(track.rejected.empty());
    }
  }
  EXPECT_TRUE(ContainsImage(scene.state.tracks[10].rejected, second));
  EXPECT_EQ(scene.state.tracks[10].elements.size(), 4u);
}

TEST(TriangulateTracks, PointsBehindCamerasAreNotTriangulated) {
  Scene scene;
  AddCameras(&scene);
  // Cameras 1 and 2 look along +z from z = -10 (2 m apart); camera 3 looks
  // along +z from z = +5, so the origin region is behind it.
  AddImage(&scene, 1, 1, SE3(Quat::Identity(), -Vec3(-1, 0, -10)));
  AddImage(&scene, 2, 2, SE3(Quat::Identity(), -Vec3(1, 0, -10)));
  AddImage(&scene, 3, 3, SE3(Quat::Identity(), -Vec3(0, 0, 5)));
  // Track 0: in front of 1 and 2, behind 3.
  const Vec3 x(0.2, 0.5, 0.0);
  AddTrack(&scene, x,
           {{1, Observe(&scene, 1, x, 0.0)},
            {2, Observe(&scene, 2, x, 0.0)},
            {3, Observe(&scene, 3, x, 0.0, /*allow_behind=*/true)}});
  // Track 1: behind both 1 and 2 (the linear solution fits exactly).
  const Vec3 y(0.1, 0.5, -20.0);
  AddTrack(&scene, y,
           {{1, Observe(&scene, 1, y, 0.0, true)}, {2, Observe(&scene, 2, y, 0.0, true)}});

  const TriangulationStats stats = TriangulateTracks(TriangulationOptions(), &scene.state);
  const Track& front = scene.state.tracks[0];
  ASSERT_TRUE(front.triangulated);
  EXPECT_LT((front.xyz - x).norm(), 1e-6);
  EXPECT_EQ(front.elements.size(), 2u);
  ASSERT_EQ(front.rejected.size(), 1u);
  EXPECT_EQ(front.rejected[0].image_id, 3u);
  EXPECT_EQ(stats.num_observations_rejected_depth, 1u);

  const Track& behind = scene.state.tracks[1];
  EXPECT_FALSE(behind.triangulated);
  EXPECT_EQ(behind.elements.size(), 2u);  // a failed track keeps its observations
  EXPECT_EQ(stats.num_tracks_failed_depth, 1u);
  EXPECT_EQ(stats.num_tracks_triangulated, 1u);
}

TEST(TriangulateTracks, TinyTriangulationAngleIsNotTriangulated) {
  Scene scene;
  AddCameras(&scene);
  // Two cameras 10 m from the point: 1 mm apart (0.006 deg) and 0.35 m apart
  // (2.0 deg, just above the 1.5 deg default).
  AddImage(&scene, 1, 1, SE3(Quat::Identity(), -Vec3(0, 0, -10)));
  AddImage(&scene, 2, 1, SE3(Quat::Identity(), -Vec3(0.001, 0, -10)));
  AddImage(&scene, 3, 1, SE3(Quat::Identity(), -Vec3(0.35, 0, -10)));
  const Vec3 x(0.0, 0.1, 0.0);
  AddTrack(&scene, x, {{1, Observe(&scene, 1, x, 0.0)}, {2, Observe(&scene, 2, x, 0.0)}});
  AddTrack(&scene, x, {{1, Observe(&scene, 1, x, 0.0)}, {3, Observe(&scene, 3, x, 0.0)}});

  TriangulationOptions options;
  const TriangulationStats stats = TriangulateTracks(options, &scene.state);
  EXPECT_FALSE(scene.state.tracks[0].triangulated);
  EXPECT_EQ(scene.state.tracks[0].elements.size(), 2u);
  EXPECT_EQ(stats.num_tracks_failed_angle, 1u);
  ASSERT_TRUE(scene.state.tracks[1].triangulated);
  EXPECT_LT((scene.state.tracks[1].xyz - x).norm(), 1e-6);

  // With a 2.5 deg minimum the wider pair fails as well.
  options.min_triangulation_angle_deg = 2.5;
  TriangulateTracks(options, &scene.state);
  EXPECT_FALSE(scene.state.tracks[1].triangulated);
}

TEST(TriangulateTracks, ObservationsInUnregisteredImagesAreSetAside) {
  Scene scene = MakeScene(4, 20, 0.0);
  scene.state.frames.at(4).registered = false;
  const TriangulationStats stats = TriangulateTracks(TriangulationOptions(), &scene.state);
  EXPECT_EQ(stats.num_observations_unregistered, 20u);
  EXPECT_EQ(stats.num_tracks_triangulated, 20u);
  for (const Track& track : scene.state.tracks) {
    EXPECT_EQ(track.elements.size(), 3u);
    EXPECT_TRUE(ContainsImage(track.rejected, 4));
  }
  // Once image 4 is registered again, retriangulation re-adds it.
  scene.state.frames.at(4).registered = true;
  EXPECT_EQ(RetriangulateTracks(TriangulationOptions(), &scene.state), 20u);
  for (const Track& track : scene.state.tracks) EXPECT_EQ(track.elements.size(), 4u);
}

TEST(TriangulateTracks, ResultsDoNotDependOnThreads) {
  Scene a = MakeScene(6, 300, 0.5);
  // A few gross outliers so that the robust path runs too.
  for (size_t t = 0; t < 300; t += 7) {
    const TrackElement e = a.state.tracks[t].elements[t % 6];
    a.state.images.at(e.image_id).keypoints[e.point2D_idx] += Vec2(25.0, 30.0);
  }
  Scene b = a;
  TriangulationOptions options;
  options.num_threads = 1;
  const TriangulationStats sa = TriangulateTracks(options, &a.state);
  options.num_threads = 2;
  const TriangulationStats sb = TriangulateTracks(options, &b.state);
  EXPECT_EQ(sa.num_observations, sb.num_observations);
  EXPECT_GT(sa.num_observations_rejected_reprojection, 0u);
  for (size_t t = 0; t < a.state.tracks.size(); ++t) {
    EXPECT_EQ(a.state.tracks[t].xyz, b.state.tracks[t].xyz);  // bit for bit
    EXPECT_EQ(a.state.tracks[t].elements.size(), b.state.tracks[t].elements.size());
  }
}

TEST(FilterAndRetriangulate, RestoreObservationsAfterPoseCorrection) {
  Scene scene = MakeScene(6, 50, 0.0);
  // Tracks 0..4 keep only images 3 and 4: they become untriangulated when
  // image 3 is filtered out.
  for (size_t t = 0; t < 5; ++t) {
    std::vector<TrackElement> kept;
    for (const TrackElement& e : scene.state.tracks[t].elements) {
      if (e.image_id == 3 || e.image_id == 4) {
        kept.push_back(e);
      } else {
        scene.state.images.at(e.image_id).track_ids[e.point2D_idx] = -1;
      }
    }
    scene.state.tracks[t].elements = kept;
  }
  const TriangulationOptions options;
  ASSERT_EQ(TriangulateTracks(options, &scene.state).num_tracks_triangulated, 50u);

  // Tilt camera 3 (fisheye, f = 300 px) by 3 deg about its x axis: its
  // keypoints move ~16 px vertically, far beyond 4 px and across the (nearly
  // horizontal) epipolar lines, so no two-view point can absorb the error.
  SfmFrame& frame = scene.state.frames.at(3);
  const SE3 correct = frame.rig_from_world;
  frame.rig_from_world = SE3(so3::Exp(Vec3(3.0 * kPi / 180.0, 0, 0)), Vec3::Zero()) * correct;
  const FilterStats filter = FilterTracks(options, &scene.state);
  EXPECT_EQ(filter.num_tracks_checked, 50u);
  EXPECT_EQ(filter.num_observations_rejected_reprojection, 50u);
  EXPECT_EQ(filter.num_tracks_untriangulated_few_observations, 5u);
  EXPECT_EQ(filter.num_tracks_triangulated, 45u);
  EXPECT_EQ(filter.num_observations, 45u * 5u);
  for (size_t t = 0; t < 50; ++t) {
    const Track& track = scene.state.tracks[t];
    EXPECT_EQ(track.triangulated, t >= 5);
    EXPECT_TRUE(ContainsImage(track.rejected, 3));
    EXPECT_FALSE(ContainsImage(track.elements, 3));
  }
  // Nothing fits while the pose is still wrong.
  EXPECT_EQ(RetriangulateTracks(options, &scene.state), 0u);

  frame.rig_from_world = correct;
  // 45 re-added observations + 5 re-triangulated two-view tracks.
  EXPECT_EQ(RetriangulateTracks(options, &scene.state), 45u + 5u * 2u);
  for (size_t t = 0; t < 50; ++t) {
    const Track& track = scene.state.tracks[t];
    ASSERT_TRUE(track.triangulated);
    EXPECT_TRUE(track.rejected.empty());
    EXPECT_EQ(track.elements.size(), t < 5 ? 2u : 6u);
    EXPECT_TRUE(ContainsImage(track.elements, 3));
    EXPECT_LT(track.error, 1e-6);
    EXPECT_LT((track.xyz - scene.points[t]).norm(), 1e-6 * 10.0);
  }
}

TEST(FilterTracks, UntriangulatesTracksByObservationsAndAngle) {
  Scene scene = MakeScene(2, 10, 0.0);
  TriangulationOptions options;
  ASSERT_EQ(TriangulateTracks(options, &scene.state).num_tracks_triangulated, 10u);
  // The two cameras are 60 deg apart on the arc, so the points (within 2 m of
  // the arc centre at 10 m) are seen under 60 +- 25 deg: a 89 deg minimum
  // un-triangulates all of them without rejecting any observation.
  options.min_triangulation_angle_deg = 89.0;
  FilterStats stats = FilterTracks(options, &scene.state);
  EXPECT_EQ(stats.num_tracks_untriangulated_angle, 10u);
  EXPECT_EQ(stats.num_observations_rejected_reprojection, 0u);
  EXPECT_EQ(stats.num_tracks_triangulated, 0u);
  for (const Track& track : scene.state.tracks) EXPECT_EQ(track.elements.size(), 2u);

  // Moving the points 100x further along camera 1's ray keeps them on image
  // 1's keypoints but moves them far off in image 2: one observation left.
  options = TriangulationOptions();
  ASSERT_EQ(TriangulateTracks(options, &scene.state).num_tracks_triangulated, 10u);
  const Vec3 c = scene.state.ProjectionCenter(1);
  for (Track& track : scene.state.tracks) track.xyz = c + 100.0 * (track.xyz - c);
  stats = FilterTracks(options, &scene.state);
  EXPECT_EQ(stats.num_tracks_untriangulated_few_observations, 10u);
  EXPECT_EQ(stats.num_observations_rejected_reprojection + stats.num_observations_rejected_depth,
            10u);
  for (const Track& track : scene.state.tracks) {
    EXPECT_FALSE(track.triangulated);
    ASSERT_EQ(track.elements.size(), 1u);
    EXPECT_EQ(track.elements[0].image_id, 1u);
  }
}

// Completion and merging on a synthetic scene: 8 images, every point seen in
// all of them with 0.5 px noise, 20 % of the keypoints corrupted by 10-40 px
// (outliers that are still matched); the match graph links every pair of
// keypoints of the same point. Tracks 0..199 miss two clean observations
// each; points 200..299 are split into two tracks (images 1-4 and 5-8); 50
// false matches link observations of different points. Completion and merging
// must rebuild exactly the clean ground-truth tracks.
TEST(CompleteAndMergeTracks, RecoversDroppedObservationsAndSplitTracksWithoutOutliers) {
  constexpr int kImages = 8;
  constexpr int kCompletionPoints = 200;
  constexpr int kSplitPoints = 100;
  Scene scene = MakeScene(kImages, 0, 0.0);
  std::uniform_real_distribution<double> coord(-2.0, 2.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // keypoint[p][i]: the keypoint of point p in image i + 1; clean[p][i]: not corrupted.
  std::vector<std::vector<point2D_t>> keypoint;
  std::vector<std::vector<bool>> clean;
  std::vector<Vec3> truth;
  size_t num_corrupt = 0;
  for (int p = 0; p < kCompletionPoints + kSplitPoints; ++p) {
    const Vec3 xyz(coord(test::Rng()), coord(test::Rng()), coord(test::Rng()));
    truth.push_back(xyz);
    keypoint.emplace_back();
    clean.emplace_back();
    // Each observation is corrupted with probability 0.2; a half (images 1-4,
    // 5-8) left with fewer than two clean ones stays clean.
    std::vector<bool> corrupt(kImages);
    for (int i = 0; i < kImages; ++i) corrupt[i] = uniform(test::Rng()) < 0.2;
    for (int half = 0; half < 2; ++half) {
      const int num_clean = static_cast<int>(
          std::count(corrupt.begin() + 4 * half, corrupt.begin() + 4 * half + 4, false));
      if (num_clean < 2)
        std::fill(corrupt.begin() + 4 * half, corrupt.begin() + 4 * half + 4, false);
    }
    for (int i = 0; i < kImages; ++i) {
      const image_t image_id = i + 1;
      const point2D_t idx = Observe(&scene, image_id, xyz, 0.5);
      if (corrupt[i]) {
        SfmImage& image = scene.state.images.at(image_id);
        const double angle = 2.0 * kPi * uniform(test::Rng());
        image.keypoints[idx] +=
            (10.0 + 30.0 * uniform(test::Rng())) * Vec2(std::cos(angle), std::sin(angle));
        image.normalized[idx] =
            scene.state.cameras.at(image.camera_id).CamFromImg(image.keypoints[idx]);
      }
      keypoint.back().push_back(idx);
      clean.back().push_back(!corrupt[i]);
    }
    num_corrupt += std::count(corrupt.begin(), corrupt.end(), true);
  }
  // The ground-truth track of p: its clean observations.
  auto clean_track = [&](int p, int first, int last) {
    std::vector<TrackElement> elements;
    for (int i = first; i <= last; ++i) {
      if (clean[p][i]) elements.push_back({static_cast<image_t>(i + 1), keypoint[p][i]});
    }
    return elements;
  };
  // Initial tracks: completion points without two of their clean observations
  // (when four or more stay), split points as two halves (when each keeps two).
  std::vector<int> first_track(truth.size(), -1), second_track(truth.size(), -1);
  size_t num_dropped = 0, num_split = 0;
  for (int p = 0; p < static_cast<int>(truth.size()); ++p) {
    std::vector<TrackElement> all = clean_track(p, 0, kImages - 1);
    if (p >= kCompletionPoints) {
      std::vector<TrackElement> a = clean_track(p, 0, 3), b = clean_track(p, 4, kImages - 1);
      if (a.size() >= 2 && b.size() >= 2) {
        first_track[p] = static_cast<int>(scene.state.tracks.size());
        AddTrack(&scene, truth[p], a);
        second_track[p] = static_cast<int>(scene.state.tracks.size());
        AddTrack(&scene, truth[p], b);
        ++num_split;
        continue;
      }
    } else if (all.size() >= 4) {
      std::shuffle(all.begin(), all.end(), test::Rng());
      all.resize(all.size() - 2);
      num_dropped += 2;
      std::sort(all.begin(), all.end(), [](const TrackElement& x, const TrackElement& y) {
        return x.image_id < y.image_id;
      });
    }
    first_track[p] = static_cast<int>(scene.state.tracks.size());
    AddTrack(&scene, truth[p], all);
  }
  // About 19 % of the 2400 keypoints stay corrupted (a half is left clean with
  // probability 0.027); every point is split or loses two observations.
  ASSERT_GT(num_corrupt, 400u);
  ASSERT_EQ(num_dropped, 2u * kCompletionPoints);
  ASSERT_EQ(num_split, static_cast<size_t>(kSplitPoints));
  // Correspondences: every pair of keypoints of one point, plus false matches.
  std::vector<ViewGraphEdge> correspondences;
  for (int i = 0; i < kImages; ++i) {
    for (int j = i + 1; j < kImages; ++j) {
      ViewGraphEdge edge;
      edge.image_id1 = i + 1;
      edge.image_id2 = j + 1;
      for (size_t p = 0; p < truth.size(); ++p) {
        edge.inliers.emplace_back(keypoint[p][i], keypoint[p][j]);
      }
      if (i == 0 && j == kImages - 1) {
        for (size_t p = 0; p + 1 < 100; p += 2) {
          edge.inliers.emplace_back(keypoint[p][i], keypoint[p + 201][j]);
        }
      }
      correspondences.push_back(std::move(edge));
    }
  }
  TriangulateTracks(TriangulationOptions(), &scene.state);
  for (size_t t = 0; t < scene.state.tracks.size(); ++t) {
    ASSERT_TRUE(scene.state.tracks[t].triangulated)
        << "track " << t << " of " << scene.state.tracks[t].elements.size() << " + "
        << scene.state.tracks[t].rejected.size();
  }

  TrackCompletionOptions options;
  options.complete = true;
  options.merge = true;
  const TrackCompletionStats stats =
      CompleteAndMergeTracks(options, TriangulationOptions(), correspondences, &scene.state);
  EXPECT_EQ(stats.num_observations_completed, num_dropped);
  EXPECT_EQ(stats.num_merges, num_split);
  for (size_t p = 0; p < truth.size(); ++p) {
    const Track& track = scene.state.tracks[first_track[p]];
    ASSERT_TRUE(track.triangulated) << "point " << p;
    const std::vector<TrackElement> expected = clean_track(p, 0, kImages - 1);
    ASSERT_EQ(track.elements.size(), expected.size()) << "point " << p;
    for (size_t k = 0; k < expected.size(); ++k) {
      EXPECT_EQ(track.elements[k].image_id, expected[k].image_id) << "point " << p;
      EXPECT_EQ(track.elements[k].point2D_idx, expected[k].point2D_idx) << "point " << p;
      EXPECT_EQ(scene.state.images.at(expected[k].image_id).track_ids[expected[k].point2D_idx],
                first_track[p]);
    }
    // Completion keeps xyz; two views 8.6 deg apart at 10 m with 0.5 px noise
    // (f = 500 px) give a depth standard deviation of about 0.07 m.
    EXPECT_LT((track.xyz - truth[p]).norm(), 0.3) << "point " << p;
    if (second_track[p] >= 0) {
      const Track& merged_away = scene.state.tracks[second_track[p]];
      EXPECT_FALSE(merged_away.triangulated);
      EXPECT_TRUE(merged_away.elements.empty());
    }
  }
  // Every corrupted keypoint stays outside the tracks.
  for (size_t p = 0; p < truth.size(); ++p) {
    for (int i = 0; i < kImages; ++i) {
      if (!clean[p][i]) {
        EXPECT_EQ(scene.state.images.at(i + 1).track_ids[keypoint[p][i]], -1) << "point " << p;
      }
    }
  }
}

TEST(CompleteAndMergeTracks, OffChangesNothing) {
  Scene scene = MakeScene(4, 20, 0.5);
  TriangulateTracks(TriangulationOptions(), &scene.state);
  const Track last = scene.state.tracks.back();
  scene.state.tracks.back().elements.pop_back();  // droppable observation, linked below
  ViewGraphEdge edge;
  edge.image_id1 = 1;
  edge.image_id2 = 4;
  edge.inliers = {{last.elements.front().point2D_idx, last.elements.back().point2D_idx}};
  TrackCompletionOptions options;
  options.complete = false;
  options.merge = false;
  EXPECT_EQ(CompleteAndMergeTracks(options, TriangulationOptions(), {edge}, &scene.state)
                .num_observations_completed,
            0u);
  EXPECT_EQ(scene.state.tracks.back().elements.size(), 3u);
  options.complete = true;
  scene.state.images.at(4).track_ids[last.elements.back().point2D_idx] = -1;
  EXPECT_EQ(CompleteAndMergeTracks(options, TriangulationOptions(), {edge}, &scene.state)
                .num_observations_completed,
            1u);
  EXPECT_EQ(scene.state.tracks.back().elements.size(), 4u);
}

TEST(TriangulationOptions, Check) {
  TriangulationOptions options;
  EXPECT_TRUE(options.Check());
  options.max_reprojection_error_px = 0.0;
  EXPECT_FALSE(options.Check());
  Scene scene = MakeScene(2, 1, 0.0);
  EXPECT_THROW(TriangulateTracks(options, &scene.state), InternalError);
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
