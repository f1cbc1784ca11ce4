#include "colmap_ext/testing/sfm_synthetic.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <unordered_map>
#include <utility>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/io/rig_io.h"
#include "core/option_check.h"

namespace lisfm {
namespace colmap {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMinDepth = 0.2;           // m, closer points are not observed
constexpr double kMinCovarianceSigma = 1e-6;  // rad / m, floor of the constraint covariance

// World-from-body rotation whose x axis is `forward` and z axis is as close
// to `up` as possible (body: x forward, y left, z up).
Mat3 WorldFromBodyRotation(const Vec3& forward, const Vec3& up) {
  const Vec3 x = forward.normalized();
  const Vec3 y = up.cross(x).normalized();
  Mat3 rotation;
  rotation.col(0) = x;
  rotation.col(1) = y;
  rotation.col(2) = x.cross(y);
  return rotation;
}

// cam_from_body for a camera whose x (right) and y (down) axes are given in
// the body frame, mounted at `position` (m) with a small rotation error.
SE3 CamFromBody(const Vec3& x_in_body, const Vec3& y_in_body, const Vec3& position,
                const Vec3& mounting_error_rad) {
  Mat3 body_from_cam;
  body_from_cam.col(0) = x_in_body;
  body_from_cam.col(1) = y_in_body;
  body_from_cam.col(2) = x_in_body.cross(y_in_body);
  const Mat3 rotation = body_from_cam * so3::ExpMatrix(mounting_error_rad);
  return SE3(rotation, position).Inverse();
}

// The HILTI-like 5-camera ring (see the header); index 0..4.
SE3 RigCamFromImu(int k) {
  const Vec3 ex(1, 0, 0), ey(0, 1, 0), ez(0, 0, 1);
  const Vec3 error = Vec3(0.010, -0.012, 0.008) * (1.0 + 0.3 * k);  // ~1 deg
  switch (k) {
    case 0: return CamFromBody(-ey, -ez, Vec3(0.05, 0.055, 0.0), error);
    case 1: return CamFromBody(-ey, -ez, Vec3(0.05, -0.055, 0.0), error);
    case 2: return CamFromBody(-ey, ex, Vec3(0.0, 0.0, 0.05), error);
    case 3: return CamFromBody(ex, -ez, Vec3(0.0, 0.06, 0.0), error);
    default: return CamFromBody(-ex, -ez, Vec3(0.0, -0.06, 0.0), error);
  }
}

CameraModel MakeIntrinsics(const SyntheticSfmOptions& options, int k) {
  CameraModel model;
  model.width = options.image_width;
  model.height = options.image_height;
  model.fx = options.focal_length + 2.0 * k;
  model.fy = 1.002 * model.fx;
  model.cx = 0.5 * options.image_width - 0.5 + 3.3 - k;  // OpenCV pixel convention
  model.cy = 0.5 * options.image_height - 0.5 - 2.1 + k;
  if (options.camera_model == "OPENCV") {
    model.distortion = DistortionModel::kRadtan;
    model.distortion_coeffs = {-0.08, 0.012, 2e-4, -1.5e-4};
  } else if (options.camera_model == "OPENCV_FISHEYE") {
    model.distortion = DistortionModel::kEquidistant;
    model.distortion_coeffs = {-0.04, 0.003, -0.002, 0.0004};
  }
  return model;
}

Vec3 GaussianVec3(double sigma, std::mt19937* rng) {
  if (sigma <= 0.0) return Vec3::Zero();
  std::normal_distribution<double> normal(0.0, sigma);
  const double x = normal(*rng);
  const double y = normal(*rng);
  const double z = normal(*rng);
  return Vec3(x, y, z);
}

double Uniform(double a, double b, std::mt19937* rng) {
  return std::uniform_real_distribution<double>(a, b)(*rng);
}

// world_from_rig of frame k.
SE3 WorldFromRig(const SyntheticSfmOptions& options, int k, std::mt19937* rng) {
  const double s = 2.0 * kPi * k / options.num_frames;
  const Vec3 up(0, 0, 1);
  if (options.trajectory == SyntheticTrajectory::kRing) {
    const Vec3 centre(6.0 * std::cos(s), 6.0 * std::sin(s), 1.5 + 0.5 * std::sin(3.0 * s));
    const Vec3 target(Uniform(-0.3, 0.3, rng), Uniform(-0.3, 0.3, rng), Uniform(-0.3, 0.3, rng));
    const Mat3 rotation = WorldFromBodyRotation(target - centre, up) *
                          so3::ExpMatrix(Vec3(Uniform(-0.05, 0.05, rng), 0.0, 0.0));
    return SE3(rotation, centre);
  }
  const Vec3 centre(3.5 * std::cos(s), 2.0 * std::sin(s), 1.5 + 0.1 * std::sin(2.0 * s));
  const Vec3 tangent(-3.5 * std::sin(s), 2.0 * std::cos(s), 0.2 * std::cos(2.0 * s));
  const Vec3 wobble(Uniform(-0.03, 0.03, rng), Uniform(-0.03, 0.03, rng),
                    Uniform(-0.08, 0.08, rng));
  return SE3(WorldFromBodyRotation(tangent, up) * so3::ExpMatrix(wobble), centre);
}

std::vector<Vec3> MakePoints(const SyntheticSfmOptions& options, std::mt19937* rng) {
  std::vector<Vec3> points;
  points.reserve(static_cast<size_t>(options.num_points));
  if (options.trajectory == SyntheticTrajectory::kRing) {
    for (int i = 0; i < options.num_points; ++i) {
      const double x = Uniform(-2.0, 2.0, rng);
      const double y = Uniform(-2.0, 2.0, rng);
      const double z = Uniform(-2.0, 2.0, rng);
      points.emplace_back(x, y, z);
    }
    return points;
  }
  // Room [-6, 6] x [-4, 4] x [0, 3]: faces drawn by area.
  const Vec3 lo(-6.0, -4.0, 0.0), hi(6.0, 4.0, 3.0);
  const Vec3 size = hi - lo;
  const std::vector<double> areas = {size.y() * size.z(), size.y() * size.z(),
                                     size.x() * size.z(), size.x() * size.z(),
                                     size.x() * size.y(), size.x() * size.y()};
  std::discrete_distribution<int> face_distribution(areas.begin(), areas.end());
  for (int i = 0; i < options.num_points; ++i) {
    const int face = face_distribution(*rng);
    Vec3 p;
    for (int a = 0; a < 3; ++a) p(a) = Uniform(lo(a), hi(a), rng);
    const int axis = face / 2;
    p(axis) = face % 2 == 0 ? lo(axis) : hi(axis);
    points.push_back(p);
  }
  return points;
}

Mat3 PinholeK(const Camera& camera) {
  Mat3 k = Mat3::Identity();
  k(0, 0) = camera.params[0];
  k(1, 1) = camera.params[1];
  k(0, 2) = camera.params[2];
  k(1, 2) = camera.params[3];
  return k;
}

Vec4 QVec(const Quat& q) { return Vec4(q.w(), q.x(), q.y(), q.z()); }

// Removes a file on scope exit unless released.
class TempFileGuard {
 public:
  explicit TempFileGuard(std::string path) : path_(std::move(path)) {}
  ~TempFileGuard() {
    if (!path_.empty()) std::remove(path_.c_str());
  }
  void Release() { path_.clear(); }

 private:
  std::string path_;
};

struct Keypoint {
  Vec2 pixel;
  int point_id = -1;
};

}  // namespace

bool SyntheticSfmOptions::Check() const {
  const bool model_ok = camera_model == "PINHOLE" || camera_model == "OPENCV" ||
                        camera_model == "OPENCV_FISHEYE";
  return num_frames >= 2 && num_rig_cameras >= 0 && num_rig_cameras <= 5 && model_ok &&
         image_width > 0 && image_height > 0 && focal_length > 0.0 && num_points >= 0 &&
         pixel_noise >= 0.0 && num_random_keypoints >= 0 && min_shared_points >= 1 &&
         max_frame_gap >= 0 && outlier_match_ratio >= 0.0 && outlier_pair_ratio >= 0.0 &&
         outlier_pair_ratio <= 1.0 && prior_position_noise >= 0.0 &&
         prior_rotation_noise >= 0.0 && num_lidar_neighbors >= 0 &&
         lidar_translation_noise >= 0.0 && lidar_rotation_noise >= 0.0 &&
         first_stamp_ns >= 0 && frame_period_ns > 0 &&
         (rig_path.empty() || num_rig_cameras > 0);
}

SyntheticSfmScene WriteSyntheticSfmDatabase(const SyntheticSfmOptions& options,
                                            const std::string& database_path) {
  THROW_CHECK_OPTIONS(options);
  std::mt19937 rng(options.seed);
  SyntheticSfmScene scene;
  const bool with_rig = options.num_rig_cameras > 0;
  const int num_cameras = with_rig ? options.num_rig_cameras : 1;

  // Cameras and the rig.
  for (int k = 0; k < num_cameras; ++k) {
    const camera_t camera_id = static_cast<camera_t>(k + 1);
    const CameraModel model = MakeIntrinsics(options, with_rig ? k : 0);
    scene.cameras[camera_id] = CameraFromCameraModel(model, camera_id);
    // Without a rig the single camera looks along the body x axis from the body origin.
    const SE3 cam_from_body =
        with_rig ? RigCamFromImu(k)
                 : SE3(RigCamFromImu(0).rotation(), Vec3::Zero());
    scene.cam_from_rig[camera_id] = with_rig ? cam_from_body : SE3::Identity();
    if (with_rig) {
      RigCamera rig_camera;
      rig_camera.name = "cam" + std::to_string(k);
      rig_camera.model = model;
      rig_camera.cam_from_imu = cam_from_body;
      scene.rig.cameras.push_back(rig_camera);
    }
  }
  const SE3 no_rig_cam_from_body(RigCamFromImu(0).rotation(), Vec3::Zero());

  // Frames and images.
  for (int f = 0; f < options.num_frames; ++f) {
    SyntheticSfmFrame frame;
    frame.stamp_ns = options.first_stamp_ns + f * options.frame_period_ns;
    const SE3 body_from_world = WorldFromRig(options, f, &rng).Inverse();
    frame.gt_rig_from_world = with_rig ? body_from_world : no_rig_cam_from_body * body_from_world;
    for (int k = 0; k < num_cameras; ++k) {
      const image_t image_id = static_cast<image_t>(1 + f * num_cameras + k);
      const camera_t camera_id = static_cast<camera_t>(k + 1);
      frame.image_ids.push_back(image_id);
      scene.image_names[image_id] = with_rig
                                        ? fmt::format("cam{}/data/{}.png", k, frame.stamp_ns)
                                        : fmt::format("image_{:04d}.png", f + 1);
      scene.image_camera_ids[image_id] = camera_id;
      scene.gt_cam_from_world[image_id] = scene.cam_from_rig[camera_id] * frame.gt_rig_from_world;
    }
    scene.gt_rig_from_world[frame.stamp_ns] = frame.gt_rig_from_world;
    scene.frames.push_back(frame);
  }
  scene.points = MakePoints(options, &rng);
  const int num_points = static_cast<int>(scene.points.size());

  // Keypoints: visible points + random ones, shuffled.
  const size_t num_images = scene.image_names.size();
  std::vector<image_t> image_ids;
  for (const auto& entry : scene.image_names) image_ids.push_back(entry.first);
  std::vector<std::vector<Keypoint>> keypoints(num_images);
  // Per point: (image index, keypoint index) observations.
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> observations(scene.points.size());
  std::normal_distribution<double> pixel_noise(0.0, std::max(options.pixel_noise, 1e-300));
  for (size_t i = 0; i < num_images; ++i) {
    const image_t image_id = image_ids[i];
    const camera_t camera_id = scene.image_camera_ids[image_id];
    const Camera& camera = scene.cameras[camera_id];
    const CameraModel model = MakeIntrinsics(options, with_rig ? static_cast<int>(camera_id) - 1 : 0);
    const SE3& cam_from_world = scene.gt_cam_from_world[image_id];
    std::vector<Keypoint>& image_keypoints = keypoints[i];
    for (int p = 0; p < num_points; ++p) {
      const Vec3 x_in_cam = cam_from_world * scene.points[static_cast<size_t>(p)];
      Vec2 opencv_pixel;
      Vec2 pixel;
      if (x_in_cam.z() <= kMinDepth || !model.Project(x_in_cam, &opencv_pixel, true) ||
          !camera.Project(x_in_cam, &pixel)) {
        continue;
      }
      if (options.pixel_noise > 0.0) {
        pixel.x() += pixel_noise(rng);
        pixel.y() += pixel_noise(rng);
      }
      image_keypoints.push_back({pixel, p});
    }
    for (int r = 0; r < options.num_random_keypoints; ++r) {
      const double u = Uniform(0.0, static_cast<double>(camera.width), &rng);
      const double v = Uniform(0.0, static_cast<double>(camera.height), &rng);
      image_keypoints.push_back({Vec2(u, v), -1});
    }
    std::shuffle(image_keypoints.begin(), image_keypoints.end(), rng);
    std::vector<int>& point_ids = scene.keypoint_point_ids[image_id];
    point_ids.reserve(image_keypoints.size());
    for (size_t k = 0; k < image_keypoints.size(); ++k) {
      point_ids.push_back(image_keypoints[k].point_id);
      if (image_keypoints[k].point_id >= 0) {
        observations[static_cast<size_t>(image_keypoints[k].point_id)].emplace_back(
            static_cast<uint32_t>(i), static_cast<uint32_t>(k));
      }
    }
  }

  // True correspondences per image pair (image index i < j).
  auto frame_of = [&](size_t image_index) {
    return static_cast<int>(image_index) / num_cameras;
  };
  std::unordered_map<uint64_t, std::vector<std::pair<uint32_t, uint32_t>>> pair_matches;
  for (const auto& point_observations : observations) {
    for (size_t a = 0; a < point_observations.size(); ++a) {
      for (size_t b = a + 1; b < point_observations.size(); ++b) {
        auto first = point_observations[a];
        auto second = point_observations[b];
        if (first.first > second.first) std::swap(first, second);
        if (options.max_frame_gap > 0 &&
            std::abs(frame_of(first.first) - frame_of(second.first)) > options.max_frame_gap) {
          continue;
        }
        const uint64_t key = (static_cast<uint64_t>(first.first) << 32) | second.first;
        pair_matches[key].emplace_back(first.second, second.second);
      }
    }
  }
  std::vector<uint64_t> pair_keys;
  for (const auto& entry : pair_matches) {
    if (entry.second.size() >= static_cast<size_t>(options.min_shared_points)) {
      pair_keys.push_back(entry.first);
    }
  }
  std::sort(pair_keys.begin(), pair_keys.end());

  // Write the database under a temporary name.
  const std::string temp_path =
      database_path + ".tmp-" + std::to_string(static_cast<long>(::getpid()));
  std::remove(temp_path.c_str());
  TempFileGuard guard(temp_path);
  {
    Database database(temp_path, Database::OpenMode::kCreate);
    DatabaseTransaction transaction(&database);
    for (const auto& [camera_id, camera] : scene.cameras) database.WriteCamera(camera, true);

    // Priors: one perturbation per frame, propagated to its cameras.
    const bool with_position_prior = options.prior_position_noise > 0.0;
    const bool with_rotation_prior = options.prior_rotation_noise > 0.0;
    for (const SyntheticSfmFrame& frame : scene.frames) {
      const SE3 world_from_rig = frame.gt_rig_from_world.Inverse();
      const Quat prior_rotation =
          world_from_rig.rotation() * so3::Exp(GaussianVec3(options.prior_rotation_noise, &rng));
      const Vec3 prior_centre =
          world_from_rig.translation() + GaussianVec3(options.prior_position_noise, &rng);
      const SE3 prior_rig_from_world = SE3(prior_rotation, prior_centre).Inverse();
      for (size_t k = 0; k < frame.image_ids.size(); ++k) {
        const image_t image_id = frame.image_ids[k];
        DbImage image;
        image.image_id = image_id;
        image.name = scene.image_names[image_id];
        image.camera_id = scene.image_camera_ids[image_id];
        const SE3 prior_cam_from_world = scene.cam_from_rig[image.camera_id] * prior_rig_from_world;
        image.has_prior_rotation = with_rotation_prior;
        if (with_rotation_prior) image.prior_qvec = QVec(prior_cam_from_world.rotation());
        image.has_prior_position = with_position_prior;
        if (with_position_prior) {
          image.prior_position = prior_cam_from_world.Inverse().translation();
          image.prior_position_covariance =
              options.prior_position_noise * options.prior_position_noise * Mat3::Identity();
        }
        database.WriteImage(image, true);
      }
    }

    for (size_t i = 0; i < num_images; ++i) {
      KeypointsBlob blob(static_cast<Eigen::Index>(keypoints[i].size()), 2);
      for (size_t k = 0; k < keypoints[i].size(); ++k) {
        blob(static_cast<Eigen::Index>(k), 0) = static_cast<float>(keypoints[i][k].pixel.x());
        blob(static_cast<Eigen::Index>(k), 1) = static_cast<float>(keypoints[i][k].pixel.y());
      }
      database.WriteKeypoints(image_ids[i], blob);
    }

    std::bernoulli_distribution outlier_pair(options.outlier_pair_ratio);
    for (const uint64_t key : pair_keys) {
      const size_t i = static_cast<size_t>(key >> 32);
      const size_t j = static_cast<size_t>(key & 0xffffffffu);
      const image_t image_id1 = image_ids[i];
      const image_t image_id2 = image_ids[j];
      const std::vector<int>& points1 = scene.keypoint_point_ids[image_id1];
      const std::vector<int>& points2 = scene.keypoint_point_ids[image_id2];
      const std::vector<std::pair<uint32_t, uint32_t>>& true_matches = pair_matches[key];
      std::vector<std::pair<uint32_t, uint32_t>> matches;
      SE3 cam2_from_cam1 = scene.gt_cam_from_world[image_id2] *
                           scene.gt_cam_from_world[image_id1].Inverse();
      auto unused_shuffled = [&](const std::vector<int>& point_ids, bool first) {
        std::vector<char> used(point_ids.size(), 0);
        for (const auto& match : matches) used[first ? match.first : match.second] = 1;
        std::vector<uint32_t> unused;
        for (size_t k = 0; k < point_ids.size(); ++k) {
          if (!used[k]) unused.push_back(static_cast<uint32_t>(k));
        }
        std::shuffle(unused.begin(), unused.end(), rng);
        return unused;
      };
      // Appends up to `count` wrong 1-to-1 matches among keypoints not matched yet.
      auto add_wrong_matches = [&](size_t count) {
        const std::vector<uint32_t> unused1 = unused_shuffled(points1, true);
        const std::vector<uint32_t> unused2 = unused_shuffled(points2, false);
        const size_t n = std::min({count, unused1.size(), unused2.size()});
        for (size_t k = 0; k < n; ++k) {
          const int p1 = points1[unused1[k]];
          if (p1 >= 0 && p1 == points2[unused2[k]]) continue;  // accidentally right
          matches.emplace_back(unused1[k], unused2[k]);
          ++scene.num_outlier_matches;
        }
      };
      if (outlier_pair(rng)) {
        add_wrong_matches(true_matches.size());
        // A wrong relative pose: rotation at least 0.3 rad away from the truth.
        const Vec3 axis = GaussianVec3(1.0, &rng).normalized();
        cam2_from_cam1 = SE3(cam2_from_cam1.rotation() * so3::Exp(Uniform(0.3, kPi, &rng) * axis),
                             GaussianVec3(1.0, &rng));
        scene.outlier_pairs.insert(ImagePairToPairId(image_id1, image_id2));
      } else {
        matches = true_matches;
        add_wrong_matches(static_cast<size_t>(
            std::lround(options.outlier_match_ratio * static_cast<double>(true_matches.size()))));
      }
      if (matches.empty()) continue;
      cam2_from_cam1.SetTranslation(cam2_from_cam1.translation().normalized());

      TwoViewGeometry geometry;
      geometry.config = static_cast<int>(TwoViewConfig::kCalibrated);
      geometry.inlier_matches.resize(static_cast<Eigen::Index>(matches.size()), 2);
      for (size_t m = 0; m < matches.size(); ++m) {
        geometry.inlier_matches(static_cast<Eigen::Index>(m), 0) = matches[m].first;
        geometry.inlier_matches(static_cast<Eigen::Index>(m), 1) = matches[m].second;
      }
      geometry.E = Hat(cam2_from_cam1.translation()) * cam2_from_cam1.RotationMatrix();
      const Mat3 k1 = PinholeK(scene.cameras[scene.image_camera_ids[image_id1]]);
      const Mat3 k2 = PinholeK(scene.cameras[scene.image_camera_ids[image_id2]]);
      geometry.F = k2.inverse().transpose() * geometry.E * k1.inverse();
      geometry.qvec = QVec(cam2_from_cam1.rotation());
      geometry.tvec = cam2_from_cam1.translation();
      database.WriteMatches(image_id1, image_id2, geometry.inlier_matches);
      database.WriteTwoViewGeometry(image_id1, image_id2, geometry);
      ++scene.num_pairs;
      scene.num_matches += matches.size();
    }
    transaction.Commit();
  }
  std::error_code error;
  std::filesystem::rename(temp_path, database_path, error);
  if (error) {
    throw InputError(database_path, "", "cannot rename " + temp_path + ": " + error.message());
  }
  guard.Release();

  // LiDAR constraints between frame k and k + n.
  const Vec3 rotation_sigma = Vec3::Constant(std::max(options.lidar_rotation_noise,
                                                      kMinCovarianceSigma));
  const Vec3 translation_sigma = Vec3::Constant(std::max(options.lidar_translation_noise,
                                                         kMinCovarianceSigma));
  Vec6 sigma;
  sigma << rotation_sigma, translation_sigma;
  const Mat6 covariance = sigma.cwiseProduct(sigma).asDiagonal();
  for (int f = 0; f < options.num_frames; ++f) {
    for (int n = 1; n <= options.num_lidar_neighbors && f + n < options.num_frames; ++n) {
      const SyntheticSfmFrame& frame_i = scene.frames[static_cast<size_t>(f)];
      const SyntheticSfmFrame& frame_j = scene.frames[static_cast<size_t>(f + n)];
      Vec6 xi;
      xi << GaussianVec3(options.lidar_rotation_noise, &rng),
          GaussianVec3(options.lidar_translation_noise, &rng);
      LidarConstraintRecord record;
      record.has_stamps = with_rig;
      record.t_i_ns = frame_i.stamp_ns;
      record.t_j_ns = frame_j.stamp_ns;
      record.index_i = f;
      record.index_j = f + n;
      record.i_from_j = frame_i.gt_rig_from_world * frame_j.gt_rig_from_world.Inverse() *
                        SE3::Exp(xi);
      record.covariance = covariance;
      scene.constraints.push_back(record);
    }
  }
  if (!options.lidar_constraints_path.empty()) {
    WriteLidarConstraints(scene.constraints, options.lidar_constraints_path);
  }
  if (!options.rig_path.empty()) {
    WriteRigYaml(options.rig_path, scene.rig,
                 fmt::format("synthetic rig (lisfm sfm_synthetic, seed {})", options.seed));
  }
  return scene;
}

}  // namespace colmap
}  // namespace lisfm
