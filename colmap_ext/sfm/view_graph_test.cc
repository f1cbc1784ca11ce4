#include "colmap_ext/sfm/view_graph.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <set>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

constexpr double kFocal = 500.0;  // px
constexpr double kNoisePx = 0.5;  // keypoint noise std (px)
constexpr int kNumPoints = 150;   // true correspondences per image
constexpr int kNumOutlierKeypoints =
    60;  // extra keypoints used for wrong matches

Camera MakeCamera(camera_t camera_id) {
  Camera camera;
  camera.camera_id = camera_id;
  camera.model_id = static_cast<int>(CameraModelId::kPinhole);
  camera.width = 640;
  camera.height = 480;
  camera.params = {kFocal, kFocal, 320.0, 240.0};
  camera.has_prior_focal_length = true;
  return camera;
}

// Four cameras (image ids 1..4) looking at a box of points 5-9 m ahead.
// Keypoint k < kNumPoints of every image observes point k; the others are
// random pixels.
struct Scene {
  std::vector<SE3> cam_from_world;
  std::vector<std::vector<Vec2>> keypoints;
};

Scene MakeScene(int num_images) {
  std::mt19937& rng = test::Rng();
  std::uniform_real_distribution<double> ux(-3.0, 3.0), uy(-2.0, 2.0),
      uz(5.0, 9.0);
  std::uniform_real_distribution<double> angle(-0.15, 0.15), px(0.0, 640.0),
      py(0.0, 480.0);
  std::normal_distribution<double> noise(0.0, kNoisePx);
  std::vector<Vec3> points;
  for (int k = 0; k < kNumPoints; ++k)
    points.emplace_back(ux(rng), uy(rng), uz(rng));
  Scene scene;
  const Camera camera = MakeCamera(1);
  for (int i = 0; i < num_images; ++i) {
    const Vec3 center(0.8 * i - 1.2, angle(rng), angle(rng));
    const Quat rotation = so3::Exp(Vec3(angle(rng), angle(rng), angle(rng)));
    const SE3 cam_from_world(rotation, -(rotation * center));
    scene.cam_from_world.push_back(cam_from_world);
    std::vector<Vec2> keypoints;
    for (const Vec3& p : points) {
      Vec2 pixel;
      EXPECT_TRUE(camera.Project(cam_from_world * p, &pixel));
      keypoints.push_back(pixel + Vec2(noise(rng), noise(rng)));
    }
    for (int k = 0; k < kNumOutlierKeypoints; ++k)
      keypoints.emplace_back(px(rng), py(rng));
    scene.keypoints.push_back(keypoints);
  }
  return scene;
}

// Writes cameras (one per image when `camera_per_image`), images and keypoints.
void WriteScene(const Scene& scene, bool camera_per_image, Database* database) {
  const size_t n = scene.cam_from_world.size();
  for (size_t i = 0; i < (camera_per_image ? n : 1); ++i) {
    database->WriteCamera(MakeCamera(static_cast<camera_t>(i + 1)), true);
  }
  for (size_t i = 0; i < n; ++i) {
    DbImage image;
    image.image_id = static_cast<image_t>(i + 1);
    image.name = "image" + std::to_string(i + 1) + ".png";
    image.camera_id = camera_per_image ? static_cast<camera_t>(i + 1) : 1;
    database->WriteImage(image, true);
    KeypointsBlob blob(scene.keypoints[i].size(), 2);
    for (size_t k = 0; k < scene.keypoints[i].size(); ++k) {
      blob(k, 0) = static_cast<float>(scene.keypoints[i][k].x());
      blob(k, 1) = static_cast<float>(scene.keypoints[i][k].y());
    }
    database->WriteKeypoints(image.image_id, blob);
  }
}

// A geometry whose inlier list holds `num_true` true correspondences and
// `num_wrong` wrong ones (a true keypoint of image 1 matched to a random
// keypoint of image 2); the raw matches are those plus `num_extra_raw`.
void WritePair(Database* database,
               image_t id1,
               image_t id2,
               int num_true,
               int num_wrong,
               int num_extra_raw,
               TwoViewConfig config) {
  std::uniform_int_distribution<int> wrong(
      kNumPoints, kNumPoints + kNumOutlierKeypoints - 1);
  std::vector<std::pair<uint32_t, uint32_t>> matches;
  for (int k = 0; k < num_true; ++k) matches.emplace_back(k, k);
  for (int k = 0; k < num_wrong; ++k)
    matches.emplace_back(num_true + k, wrong(test::Rng()));
  TwoViewGeometry geometry;
  geometry.config = static_cast<int>(config);
  geometry.inlier_matches.resize(matches.size(), 2);
  for (size_t k = 0; k < matches.size(); ++k) {
    geometry.inlier_matches(k, 0) = matches[k].first;
    geometry.inlier_matches(k, 1) = matches[k].second;
  }
  MatchesBlob raw(matches.size() + num_extra_raw, 2);
  raw.topRows(matches.size()) = geometry.inlier_matches;
  for (int k = 0; k < num_extra_raw; ++k) {
    raw(matches.size() + k, 0) = wrong(test::Rng());
    raw(matches.size() + k, 1) = wrong(test::Rng());
  }
  database->WriteMatches(id1, id2, raw);
  database->WriteTwoViewGeometry(id1, id2, geometry);
}

// Predicted RMS rotation and direction errors (deg) of the least-squares
// relative pose from the first kNumPoints correspondences (see the test).
void PredictedPoseErrors(const std::vector<Vec2>& x1,
                         const std::vector<Vec2>& x2,
                         const SE3& truth,
                         double residual_std,
                         double* rotation_deg,
                         double* direction_deg) {
  const Vec3 t = truth.translation().normalized();
  Vec3 u = t.unitOrthogonal();
  const Vec3 v = t.cross(u);
  const auto residuals = [&](const Eigen::VectorXd& d) {
    const Mat3 R =
        (so3::Exp(d.head<3>()) * truth.rotation()).toRotationMatrix();
    const Vec3 td = (t + d(3) * u + d(4) * v).normalized();
    const Mat3 E = Hat(td) * R;
    Eigen::VectorXd r(kNumPoints);
    for (int k = 0; k < kNumPoints; ++k) {
      const Vec3 a = E * x1[k].homogeneous(),
                 b = E.transpose() * x2[k].homogeneous();
      r(k) = x2[k].homogeneous().dot(a) /
             std::sqrt(a.head<2>().squaredNorm() + b.head<2>().squaredNorm());
    }
    return r;
  };
  const Eigen::MatrixXd J =
      test::NumericJacobian(residuals, Eigen::VectorXd::Zero(5));
  const Eigen::MatrixXd covariance =
      residual_std * residual_std * (J.transpose() * J).inverse();
  *rotation_deg =
      std::sqrt(covariance.topLeftCorner<3, 3>().trace()) * 180.0 / M_PI;
  *direction_deg =
      std::sqrt(covariance.bottomRightCorner<2, 2>().trace()) * 180.0 / M_PI;
}

double AngleDeg(const Vec3& a, const Vec3& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

TEST(ViewGraph, RecoversRelativePosesAndRejectsWeakPairs) {
  test::TempDir dir;
  const Scene scene = MakeScene(4);
  const std::string path = dir.File("db.db");
  {
    Database database(path, Database::OpenMode::kCreate);
    WriteScene(scene, false, &database);
    // Good pairs: 150 true + 30 wrong matches (17 % outliers).
    WritePair(&database, 1, 3, kNumPoints, 30, 0, TwoViewConfig::kCalibrated);
    WritePair(&database,
              4,
              1,
              kNumPoints,
              30,
              0,
              TwoViewConfig::kCalibrated);  // stored swapped
    WritePair(&database, 2, 3, kNumPoints, 30, 0, TwoViewConfig::kUncalibrated);
    // 20 inliers < min_num_inliers = 30.
    WritePair(&database, 1, 2, 20, 0, 0, TwoViewConfig::kCalibrated);
    // 60 inliers of 400 raw matches: ratio 0.15 < 0.25.
    WritePair(&database, 2, 4, 60, 0, 340, TwoViewConfig::kCalibrated);
    // Enough inliers but a degenerate configuration.
    WritePair(&database, 3, 4, kNumPoints, 0, 0, TwoViewConfig::kDegenerate);
  }
  Database database(path, Database::OpenMode::kReadOnly);
  MapperState state =
      LoadMapperState(database, nullptr, LoadMapperStateOptions());
  ViewGraphOptions options;
  const ViewGraphStats stats = BuildViewGraph(database, options, &state);
  EXPECT_EQ(stats.num_pairs_in_database, 6u);
  EXPECT_EQ(stats.num_edges, 3u);
  EXPECT_EQ(stats.num_rejected_few_inliers, 2u);
  EXPECT_EQ(stats.num_skipped_config, 1u);
  EXPECT_EQ(stats.num_rejected_reestimation, 0u);
  ASSERT_EQ(state.view_graph.edges.size(), 3u);
  EXPECT_EQ(state.view_graph.edge_index.count(ImagePairToPairId(1, 2)), 0u);
  EXPECT_EQ(state.view_graph.edge_index.count(ImagePairToPairId(2, 4)), 0u);
  EXPECT_EQ(state.view_graph.edge_index.count(ImagePairToPairId(3, 4)), 0u);

  // Bounds from the injected noise: the Sampson residual of a true match has
  // std s = noise / f (first order, noise in both images), so the least-squares
  // pose has covariance s^2 (J^T J)^-1, J = d residuals / d (rotation 3,
  // direction 2) at the truth (this includes the rotation-translation
  // coupling of a narrow field of view). Each error must stay below 4x the
  // predicted RMS (> 5 sigma for a chi(3) / chi(2) distributed error).
  for (const ViewGraphEdge& edge : state.view_graph.edges) {
    SCOPED_TRACE("edge " + std::to_string(edge.image_id1) + "-" +
                 std::to_string(edge.image_id2));
    EXPECT_LT(edge.image_id1, edge.image_id2);
    const SE3 truth = scene.cam_from_world[edge.image_id2 - 1] *
                      scene.cam_from_world[edge.image_id1 - 1].Inverse();
    double rotation_bound_deg = 0.0, translation_bound_deg = 0.0;
    PredictedPoseErrors(state.images.at(edge.image_id1).normalized,
                        state.images.at(edge.image_id2).normalized,
                        truth,
                        kNoisePx / kFocal,
                        &rotation_bound_deg,
                        &translation_bound_deg);
    rotation_bound_deg *= 4.0;
    translation_bound_deg *= 4.0;
    const double rotation_error =
        so3::AngularDistance(edge.cam2_from_cam1.rotation(), truth.rotation()) *
        180.0 / M_PI;
    const double translation_error =
        AngleDeg(edge.cam2_from_cam1.translation(), truth.translation());
    EXPECT_LT(rotation_error, rotation_bound_deg);
    EXPECT_LT(translation_error, translation_bound_deg);
    EXPECT_NEAR(edge.cam2_from_cam1.translation().norm(), 1.0, 1e-9);
    EXPECT_FALSE(edge.metric);
    EXPECT_TRUE(edge.valid);
    std::printf(
        "edge %u-%u: rotation error %.4f deg (bound %.4f), direction error "
        "%.4f deg "
        "(bound %.4f)\n",
        edge.image_id1,
        edge.image_id2,
        rotation_error,
        rotation_bound_deg,
        translation_error,
        translation_bound_deg);
    // Inliers: the true matches survive (noise 0.5 px vs a 4 px threshold,
    // > 5 sigma of the Sampson distance), wrong ones mostly do not: a random
    // keypoint lies within 4 px of the epipolar line with probability
    // ~ 2 * 4 / 600, so at most a few of the 30 may pass.
    int num_true = 0, num_wrong = 0;
    for (const auto& [k1, k2] : edge.inliers) {
      if (k1 == k2 && k1 < kNumPoints) {
        ++num_true;
      } else {
        ++num_wrong;
      }
    }
    EXPECT_EQ(num_true, kNumPoints);
    EXPECT_LE(num_wrong, 3);
    EXPECT_EQ(edge.weight, static_cast<double>(edge.inliers.size()));
  }
  // The swapped pair (4, 1) is stored as 1 -> 4 with its matches swapped.
  const ViewGraphEdge& swapped =
      state.view_graph
          .edges[state.view_graph.edge_index.at(ImagePairToPairId(1, 4))];
  EXPECT_EQ(swapped.image_id1, 1u);
  EXPECT_EQ(swapped.image_id2, 4u);
}

// The analytic Levenberg-Marquardt polish reaches a stationary point of the
// robust Sampson cost: from a start 1 deg / 5 deg (direction) off, with 10 %
// wrong matches, the numeric gradient of the cost over the 5 degrees of
// freedom vanishes at the result (a wrong analytic Jacobian would stop
// elsewhere), the cost drops, and the pose is near the truth.
TEST(ViewGraph, RefineRelativePoseReachesAStationaryPoint) {
  std::mt19937& rng = test::Rng();
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(4.0, 10.0);
  std::normal_distribution<double> noise(0.0, kNoisePx / kFocal);
  const SE3 truth(so3::Exp(Vec3(0.05, -0.1, 0.02)), Vec3(1.0, 0.1, 0.2).normalized());
  std::vector<Vec2> x1, x2;
  for (int i = 0; i < 300; ++i) {
    const Vec3 p(3.0 * u(rng), 2.0 * u(rng), depth(rng));
    const Vec3 q = truth * p;
    x1.push_back(p.hnormalized() + Vec2(noise(rng), noise(rng)));
    x2.push_back(i % 10 == 0 ? Vec2(0.6 * u(rng), 0.5 * u(rng))
                             : Vec2(q.hnormalized() + Vec2(noise(rng), noise(rng))));
  }
  const double loss_scale = 1.0 / kFocal;  // 1 px
  const SE3 start(so3::Exp(Vec3(0.01, 0.012, -0.008)) * truth.rotation(),
                  (truth.translation() + Vec3(0.0, 0.06, -0.05)).normalized());
  const SE3 refined = RefineRelativePose(start, x1, x2, loss_scale);
  EXPECT_NEAR(refined.translation().norm(), 1.0, 1e-12);
  EXPECT_LT(SampsonCost(refined, x1, x2, loss_scale), SampsonCost(start, x1, x2, loss_scale));
  // Max |numeric gradient| of the cost over rotation (left) and the two
  // directions orthogonal to t; central differences, h = 1e-7.
  auto max_gradient = [&](const SE3& pose) {
    const Vec3 t = pose.translation().normalized();
    const Vec3 b1 = t.cross(Vec3::UnitY()).normalized(), b2 = t.cross(b1);
    const double h = 1e-7;
    double m = 0.0;
    for (int k = 0; k < 5; ++k) {
      auto moved = [&](double s) {
        Vec3 dtheta = Vec3::Zero();
        Vec3 dt = Vec3::Zero();
        if (k < 3) dtheta(k) = s;
        if (k == 3) dt = s * b1;
        if (k == 4) dt = s * b2;
        return SE3(so3::Exp(dtheta) * pose.rotation(), (t + dt).normalized());
      };
      m = std::max(m, std::abs(SampsonCost(moved(h), x1, x2, loss_scale) -
                               SampsonCost(moved(-h), x1, x2, loss_scale)) /
                          (2.0 * h));
    }
    return m;
  };
  const double start_gradient = max_gradient(start);
  const double refined_gradient = max_gradient(refined);
  std::printf("max |gradient|: start %.3e, refined %.3e\n", start_gradient, refined_gradient);
  // A stationary point: the gradient falls by > 3 orders of magnitude (the
  // stopping rule, relative cost change 1e-10, leaves ~1e-5 of it; a wrong
  // Jacobian direction would stall much earlier).
  EXPECT_LT(refined_gradient, 1e-3 * start_gradient);
  // Accuracy: within 4x the RMS predicted from the noise (as above), on the
  // true matches.
  std::vector<Vec2> in1, in2;
  for (size_t i = 0; i < x1.size(); ++i) {
    if (i % 10 != 0) {
      in1.push_back(x1[i]);
      in2.push_back(x2[i]);
    }
  }
  double rotation_bound_deg = 0.0, direction_bound_deg = 0.0;
  PredictedPoseErrors(in1, in2, truth, kNoisePx / kFocal, &rotation_bound_deg,
                      &direction_bound_deg);
  EXPECT_LT(so3::AngularDistance(refined.rotation(), truth.rotation()) * 180.0 / M_PI,
            4.0 * rotation_bound_deg);
  EXPECT_LT(AngleDeg(refined.translation(), truth.translation()), 4.0 * direction_bound_deg);
}

TEST(ViewGraph, IntraFramePairUsesTheRigPose) {
  test::TempDir dir;
  const Scene scene = MakeScene(2);
  const std::string path = dir.File("db.db");
  {
    Database database(path, Database::OpenMode::kCreate);
    WriteScene(
        scene, true, &database);  // camera 1 for image 1, camera 2 for image 2
    WritePair(&database, 1, 2, kNumPoints, 40, 0, TwoViewConfig::kCalibrated);
  }
  Database database(path, Database::OpenMode::kReadOnly);
  MapperState state =
      LoadMapperState(database, nullptr, LoadMapperStateOptions());
  // Group both images into frame 1: rig = camera 1 (cam_from_rig = I).
  state.has_rig = true;
  state.frames.erase(2);
  state.frames.at(1).image_ids = {1, 2};
  state.images.at(2).frame_id = 1;
  state.cam_from_rig[1] = SE3::Identity();
  state.cam_from_rig[2] =
      scene.cam_from_world[1] * scene.cam_from_world[0].Inverse();

  const ViewGraphStats stats =
      BuildViewGraph(database, ViewGraphOptions(), &state);
  ASSERT_EQ(stats.num_edges, 1u);
  EXPECT_EQ(stats.num_intra_frame_edges, 1u);
  const ViewGraphEdge& edge = state.view_graph.edges[0];
  EXPECT_TRUE(edge.metric);
  // The known pose is copied exactly (metric translation, not re-estimated).
  EXPECT_TRUE(test::PosesNear(
      edge.cam2_from_cam1, state.cam_from_rig[2], 1e-12, 1e-12));
  int num_true = 0;
  for (const auto& [k1, k2] : edge.inliers)
    num_true += (k1 == k2 && k1 < kNumPoints) ? 1 : 0;
  EXPECT_EQ(num_true, kNumPoints);
  EXPECT_LE(static_cast<int>(edge.inliers.size()) - num_true,
            3);  // see the test above
}

TEST(ViewGraph, DatabaseWithoutTwoViewGeometriesIsAnInputError) {
  test::TempDir dir;
  const std::string path = dir.File("db.db");
  {
    Database database(path, Database::OpenMode::kCreate);
    WriteScene(MakeScene(2), false, &database);
  }
  Database database(path, Database::OpenMode::kReadOnly);
  MapperState state =
      LoadMapperState(database, nullptr, LoadMapperStateOptions());
  EXPECT_TRUE(test::ThrowsInputError([&] { BuildViewGraph(database, ViewGraphOptions(), &state); },
                                     {path, "two_view_geometries"}));
}

TEST(ViewGraph, MatchBeyondTheKeypointsIsAnInputError) {
  test::TempDir dir;
  const std::string path = dir.File("db.db");
  {
    Database database(path, Database::OpenMode::kCreate);
    WriteScene(MakeScene(2), false, &database);
    TwoViewGeometry geometry;
    geometry.config = static_cast<int>(TwoViewConfig::kCalibrated);
    geometry.inlier_matches.resize(40, 2);
    for (int k = 0; k < 40; ++k) {
      geometry.inlier_matches(k, 0) = k;
      geometry.inlier_matches(k, 1) = k == 39 ? 100000 : k;
    }
    database.WriteTwoViewGeometry(1, 2, geometry);
  }
  Database database(path, Database::OpenMode::kReadOnly);
  MapperState state =
      LoadMapperState(database, nullptr, LoadMapperStateOptions());
  EXPECT_THROW(BuildViewGraph(database, ViewGraphOptions(), &state),
               InputError);
}

TEST(ViewGraph, FrameComponents) {
  MapperState state;
  for (frame_t f = 1; f <= 7; ++f) {
    SfmImage image;
    image.image_id = f;
    image.camera_id = 1;
    image.frame_id = f;
    state.images[f] = image;
    state.frames[f].frame_id = f;
    state.frames[f].image_ids = {f};
  }
  // Image 8 shares frame 6 with image 6 (an edge between them links nothing).
  SfmImage extra;
  extra.image_id = 8;
  extra.camera_id = 2;
  extra.frame_id = 6;
  state.images[8] = extra;
  state.frames[6].image_ids.push_back(8);
  auto add_edge = [&](image_t a, image_t b, bool valid) {
    ViewGraphEdge edge;
    edge.image_id1 = a;
    edge.image_id2 = b;
    edge.valid = valid;
    state.view_graph.AddEdge(edge);
  };
  add_edge(1, 2, true);
  add_edge(2, 3, true);
  add_edge(4, 5, true);
  add_edge(3, 4, false);  // invalid: does not link
  add_edge(6, 8, true);   // same frame: does not link
  LidarConstraint constraint;
  constraint.frame_id1 = 7;
  constraint.frame_id2 = 5;
  state.lidar_constraints.push_back(constraint);
  const auto components = FrameComponents(state);
  ASSERT_EQ(components.size(), 3u);
  EXPECT_EQ(components[0],
            (std::vector<frame_t>{1, 2, 3}));  // tie with {4,5,7}: smaller id
  EXPECT_EQ(components[1], (std::vector<frame_t>{4, 5, 7}));
  EXPECT_EQ(components[2], (std::vector<frame_t>{6}));
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
