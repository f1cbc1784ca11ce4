#include "colmap_ext/testing/synthetic.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <unordered_map>
#include <utility>

#include <fmt/format.h>

#include "core/camera_model.h"
#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {
namespace colmap {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMinDepth = 0.2;             // m, closer points are not observed
constexpr double kMinCovarianceSigma = 1e-6;  // rad / m, floor of the constraint covariance
// A point of a track_length dataset is drawn again at most this often before
// the geometry is declared unable to give its images `track_length` views.
constexpr int kMaxPointDraws = 1000;

// The independent random streams of a dataset (see the header).
enum class Stream : uint32_t {
  kGeometry = 1,
  kObservations = 2,
  kPriors = 3,
  kConstraints = 4,
  kOutliers = 5,
};

std::mt19937 MakeStream(uint32_t seed, Stream stream) {
  std::seed_seq sequence{seed, static_cast<uint32_t>(stream)};
  return std::mt19937(sequence);
}

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
SE3 CamFromBody(const Vec3& x_in_body,
                const Vec3& y_in_body,
                const Vec3& position,
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
    case 0:
      return CamFromBody(-ey, -ez, Vec3(0.05, 0.055, 0.0), error);
    case 1:
      return CamFromBody(-ey, -ez, Vec3(0.05, -0.055, 0.0), error);
    case 2:
      return CamFromBody(-ey, ex, Vec3(0.0, 0.0, 0.05), error);
    case 3:
      return CamFromBody(ex, -ez, Vec3(0.0, 0.06, 0.0), error);
    default:
      return CamFromBody(-ex, -ez, Vec3(0.0, -0.06, 0.0), error);
  }
}

bool KnownCameraModel(const std::string& name) {
  return name == "PINHOLE" || name == "OPENCV" || name == "OPENCV_FISHEYE";
}

// Intrinsics of camera k (OpenCV pixel convention).
CameraModel MakeIntrinsics(const SyntheticDatasetOptions& options, int k) {
  const std::string& name =
      options.camera_models[static_cast<size_t>(k) % options.camera_models.size()];
  CameraModel model;
  model.width = options.image_width;
  model.height = options.image_height;
  model.fx = options.focal_length + 2.0 * k;
  model.fy = 1.002 * model.fx;
  model.cx = 0.5 * options.image_width - 0.5 + 3.3 - k;
  model.cy = 0.5 * options.image_height - 0.5 - 2.1 + k;
  if (name == "OPENCV") {
    model.distortion = DistortionModel::kRadtan;
    model.distortion_coeffs = {-0.08, 0.012, 2e-4, -1.5e-4};
  } else if (name == "OPENCV_FISHEYE") {
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

// world_from_rig of frame f.
SE3 WorldFromRig(const SyntheticDatasetOptions& options, int f, std::mt19937* rng) {
  const double s = 2.0 * kPi * f / options.num_frames;
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
  const Vec3 wobble(
      Uniform(-0.03, 0.03, rng), Uniform(-0.03, 0.03, rng), Uniform(-0.08, 0.08, rng));
  return SE3(WorldFromBodyRotation(tangent, up) * so3::ExpMatrix(wobble), centre);
}

// Draws points of the scene: uniform in the cube (kRing) or uniform over the
// room's faces by area (kRoom, [-6, 6] x [-4, 4] x [0, 3]).
class PointSampler {
 public:
  explicit PointSampler(SyntheticTrajectory trajectory)
      : trajectory_(trajectory),
        lo_(-6.0, -4.0, 0.0),
        hi_(6.0, 4.0, 3.0),
        faces_({(hi_ - lo_).y() * (hi_ - lo_).z(),
                (hi_ - lo_).y() * (hi_ - lo_).z(),
                (hi_ - lo_).x() * (hi_ - lo_).z(),
                (hi_ - lo_).x() * (hi_ - lo_).z(),
                (hi_ - lo_).x() * (hi_ - lo_).y(),
                (hi_ - lo_).x() * (hi_ - lo_).y()}) {}

  Vec3 Draw(std::mt19937* rng) {
    if (trajectory_ == SyntheticTrajectory::kRing) {
      const double x = Uniform(-2.0, 2.0, rng);
      const double y = Uniform(-2.0, 2.0, rng);
      const double z = Uniform(-2.0, 2.0, rng);
      return Vec3(x, y, z);
    }
    const int face = faces_(*rng);
    Vec3 p;
    for (int a = 0; a < 3; ++a) p(a) = Uniform(lo_(a), hi_(a), rng);
    const int axis = face / 2;
    p(axis) = face % 2 == 0 ? lo_(axis) : hi_(axis);
    return p;
  }

 private:
  SyntheticTrajectory trajectory_;
  Vec3 lo_, hi_;
  std::discrete_distribution<int> faces_;  // by area: x = lo, x = hi, y = lo, ...
};

// The projection of a point into one image, with the visibility rules of the
// header.
class ImageProjector {
 public:
  ImageProjector(const Camera& camera, const CameraModel& model, const SE3& cam_from_world)
      : camera_(&camera), model_(model), cam_from_world_(cam_from_world) {}

  // True when the image sees `x_in_world`; `pixel` is then its exact
  // projection (COLMAP convention). The cheap tests (depth, COLMAP projection
  // inside the image) come before the invertibility test of the model.
  bool Project(const Vec3& x_in_world, Vec2* pixel) const {
    const Vec3 x_in_cam = cam_from_world_ * x_in_world;
    if (!(x_in_cam.z() > kMinDepth) || !camera_->Project(x_in_cam, pixel)) return false;
    if (!(pixel->x() >= 0.0 && pixel->y() >= 0.0 &&
          pixel->x() <= static_cast<double>(camera_->width) &&
          pixel->y() <= static_cast<double>(camera_->height))) {
      return false;
    }
    Vec2 opencv_pixel;
    return model_.Project(x_in_cam, &opencv_pixel, true);
  }

 private:
  const Camera* camera_;
  CameraModel model_;
  SE3 cam_from_world_;
};

struct Observation {
  int point_index = 0;
  Vec2 pixel = Vec2::Zero();  // exact projection
};

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

// Adds the cameras, the rig, the frames (poses from `rng`) and their images;
// returns the intrinsics of camera_id k + 1 at index k.
std::vector<CameraModel> AddCamerasAndFrames(const SyntheticDatasetOptions& options,
                                             std::mt19937* rng,
                                             SyntheticDataset* dataset) {
  const bool with_rig = options.with_rig;
  const int images_per_frame = options.ImagesPerFrame();
  // Without a rig every camera looks along the body x axis from the body origin.
  const SE3 no_rig_cam_from_body(RigCamFromImu(0).rotation(), Vec3::Zero());
  std::vector<CameraModel> models;
  for (int k = 0; k < options.num_cameras; ++k) {
    const camera_t camera_id = static_cast<camera_t>(k + 1);
    models.push_back(MakeIntrinsics(options, k));
    dataset->cameras[camera_id] = CameraFromCameraModel(models.back(), camera_id);
    dataset->cam_from_rig[camera_id] = with_rig ? RigCamFromImu(k) : SE3::Identity();
    if (with_rig) {
      RigCamera rig_camera;
      rig_camera.name = "cam" + std::to_string(k);
      rig_camera.model = models.back();
      rig_camera.cam_from_imu = RigCamFromImu(k);
      dataset->rig.cameras.push_back(rig_camera);
    }
  }
  for (int f = 0; f < options.num_frames; ++f) {
    SyntheticFrame frame;
    frame.stamp_ns = options.first_stamp_ns + f * options.frame_period_ns;
    const SE3 body_from_world = WorldFromRig(options, f, rng).Inverse();
    frame.gt_rig_from_world = with_rig ? body_from_world : no_rig_cam_from_body * body_from_world;
    frame.prior_rig_from_world = frame.gt_rig_from_world;
    for (int k = 0; k < images_per_frame; ++k) {
      SyntheticImage image;
      image.image_id = static_cast<image_t>(1 + f * images_per_frame + k);
      image.camera_id = static_cast<camera_t>((with_rig ? k : f % options.num_cameras) + 1);
      image.frame_index = static_cast<size_t>(f);
      image.name = with_rig ? fmt::format("cam{}/data/{}.png", k, frame.stamp_ns)
                            : fmt::format("image_{:04d}.png", f + 1);
      image.gt_cam_from_world = dataset->cam_from_rig[image.camera_id] * frame.gt_rig_from_world;
      frame.image_ids.push_back(image.image_id);
      dataset->images.push_back(std::move(image));
    }
    dataset->frames.push_back(std::move(frame));
  }
  return models;
}

// Adds the points and their colours (from `geometry_rng`) and returns, per
// image, the exact projections of the points it observes (in point order):
// with track_length = 0 all it sees, otherwise track_length images per point
// drawn from `observation_rng` (a point seen by fewer images is drawn again).
std::vector<std::vector<Observation>> AddPoints(const SyntheticDatasetOptions& options,
                                                const std::vector<ImageProjector>& projectors,
                                                std::mt19937* geometry_rng,
                                                std::mt19937* observation_rng,
                                                SyntheticDataset* dataset) {
  const size_t num_images = projectors.size();
  std::vector<std::vector<Observation>> observations(num_images);
  PointSampler sampler(options.trajectory);
  dataset->points.reserve(static_cast<size_t>(options.num_points));
  dataset->point_colors.reserve(static_cast<size_t>(options.num_points));
  std::vector<size_t> order(num_images);
  for (size_t i = 0; i < num_images; ++i) order[i] = i;
  std::uniform_int_distribution<int> color_channel(0, 255);
  for (int p = 0; p < options.num_points; ++p) {
    Vec3 x = sampler.Draw(geometry_rng);
    for (int draw = 1; options.track_length > 0; ++draw) {
      // Partial Fisher-Yates over the images until track_length of them see x.
      int accepted = 0;
      for (size_t k = 0; k < num_images && accepted < options.track_length; ++k) {
        std::uniform_int_distribution<size_t> pick(k, num_images - 1);
        std::swap(order[k], order[pick(*observation_rng)]);
        Vec2 pixel;
        if (projectors[order[k]].Project(x, &pixel)) {
          observations[order[k]].push_back({p, pixel});
          ++accepted;
        }
      }
      if (accepted == options.track_length) break;
      for (std::vector<Observation>& image_observations : observations) {
        if (!image_observations.empty() && image_observations.back().point_index == p) {
          image_observations.pop_back();
        }
      }
      THROW_CHECK_MSG(
          draw < kMaxPointDraws,
          "no point of the scene is seen by track_length = " << options.track_length << " images");
      x = sampler.Draw(geometry_rng);
    }
    dataset->points.push_back(x);
    std::array<uint8_t, 3> color;
    for (uint8_t& channel : color) channel = static_cast<uint8_t>(color_channel(*geometry_rng));
    dataset->point_colors.push_back(color);
  }
  if (options.track_length == 0) {
    for (size_t i = 0; i < num_images; ++i) {
      for (size_t p = 0; p < dataset->points.size(); ++p) {
        Vec2 pixel;
        if (projectors[i].Project(dataset->points[p], &pixel)) {
          observations[i].push_back({static_cast<int>(p), pixel});
        }
      }
    }
  }
  return observations;
}

// The keypoints of every image (consuming `observations`): the observations
// with pixel noise, then the random keypoints, shuffled; all from `rng`.
void AddKeypoints(const SyntheticDatasetOptions& options,
                  std::vector<std::vector<Observation>>* observations,
                  std::mt19937* rng,
                  SyntheticDataset* dataset) {
  std::normal_distribution<double> pixel_noise(0.0, std::max(options.pixel_noise, 1e-300));
  for (size_t i = 0; i < dataset->images.size(); ++i) {
    SyntheticImage& image = dataset->images[i];
    const Camera& camera = dataset->cameras.at(image.camera_id);
    image.keypoints.reserve((*observations)[i].size() +
                            static_cast<size_t>(options.num_random_keypoints));
    for (const Observation& observation : (*observations)[i]) {
      Vec2 xy = observation.pixel;
      if (options.pixel_noise > 0.0) {
        xy.x() += pixel_noise(*rng);
        xy.y() += pixel_noise(*rng);
      }
      image.keypoints.push_back({xy, observation.point_index, (xy - observation.pixel).norm()});
    }
    std::vector<Observation>().swap((*observations)[i]);
    for (int r = 0; r < options.num_random_keypoints; ++r) {
      const double u = Uniform(0.0, static_cast<double>(camera.width), rng);
      const double v = Uniform(0.0, static_cast<double>(camera.height), rng);
      image.keypoints.push_back({Vec2(u, v), -1, 0.0});
    }
    std::shuffle(image.keypoints.begin(), image.keypoints.end(), *rng);
  }
}

// One prior perturbation per frame (see the header).
void AddPriors(const SyntheticDatasetOptions& options,
               std::mt19937* rng,
               SyntheticDataset* dataset) {
  for (SyntheticFrame& frame : dataset->frames) {
    const SE3 world_from_rig = frame.gt_rig_from_world.Inverse();
    const Quat rotation =
        world_from_rig.rotation() * so3::Exp(GaussianVec3(options.prior_rotation_noise, rng));
    const Vec3 centre =
        world_from_rig.translation() + GaussianVec3(options.prior_position_noise, rng);
    frame.prior_rig_from_world = SE3(rotation, centre).Inverse();
  }
}

// Noisy relative poses between frame k and k + n, n = 1..num_lidar_neighbors.
void AddLidarConstraints(const SyntheticDatasetOptions& options,
                         std::mt19937* rng,
                         SyntheticDataset* dataset) {
  Vec6 sigma;
  sigma << Vec3::Constant(std::max(options.lidar_rotation_noise, kMinCovarianceSigma)),
      Vec3::Constant(std::max(options.lidar_translation_noise, kMinCovarianceSigma));
  const Mat6 covariance = sigma.cwiseProduct(sigma).asDiagonal();
  for (int f = 0; f < options.num_frames; ++f) {
    for (int n = 1; n <= options.num_lidar_neighbors && f + n < options.num_frames; ++n) {
      const SyntheticFrame& frame_i = dataset->frames[static_cast<size_t>(f)];
      const SyntheticFrame& frame_j = dataset->frames[static_cast<size_t>(f + n)];
      Vec6 xi;
      xi << GaussianVec3(options.lidar_rotation_noise, rng),
          GaussianVec3(options.lidar_translation_noise, rng);
      LidarConstraintRecord record;
      record.has_stamps = options.with_rig;
      record.t_i_ns = frame_i.stamp_ns;
      record.t_j_ns = frame_j.stamp_ns;
      record.index_i = f;
      record.index_j = f + n;
      record.i_from_j =
          frame_i.gt_rig_from_world * frame_j.gt_rig_from_world.Inverse() * SE3::Exp(xi);
      record.covariance = covariance;
      dataset->constraints.push_back(record);
    }
  }
}

}  // namespace

bool SyntheticDatasetOptions::Check() const {
  CHECK_OPTION_GE(num_frames, 1);
  CHECK_OPTION_GE(num_cameras, 1);
  CHECK_OPTION_MSG(num_cameras, !with_rig || num_cameras <= 5, "<= 5 with a rig");
  CHECK_OPTION_MSG(camera_models,
                   !camera_models.empty() && std::all_of(camera_models.begin(),
                                                         camera_models.end(),
                                                         KnownCameraModel),
                   "non-empty, each PINHOLE, OPENCV or OPENCV_FISHEYE");
  CHECK_OPTION_GT(image_width, 0);
  CHECK_OPTION_GT(image_height, 0);
  CHECK_OPTION_GT(focal_length, 0.0);
  CHECK_OPTION_GT(frame_period_ns, 0);
  CHECK_OPTION_GE(first_stamp_ns, 0);
  CHECK_OPTION_GE(num_points, 0);
  CHECK_OPTION_GE(track_length, 0);
  CHECK_OPTION_LE(track_length, num_frames * ImagesPerFrame());
  CHECK_OPTION_GE(pixel_noise, 0.0);
  CHECK_OPTION_GE(num_random_keypoints, 0);
  CHECK_OPTION_GE(prior_position_noise, 0.0);
  CHECK_OPTION_GE(prior_rotation_noise, 0.0);
  CHECK_OPTION_GE(num_lidar_neighbors, 0);
  CHECK_OPTION_GE(lidar_translation_noise, 0.0);
  CHECK_OPTION_GE(lidar_rotation_noise, 0.0);
  CHECK_OPTION_GE(min_shared_points, 1);
  CHECK_OPTION_GE(max_frame_gap, 0);
  CHECK_OPTION_GE(outlier_match_ratio, 0.0);
  CHECK_OPTION_GE(outlier_pair_ratio, 0.0);
  CHECK_OPTION_LE(outlier_pair_ratio, 1.0);
  return true;
}

const SyntheticImage& SyntheticDataset::GetImage(image_t image_id) const {
  THROW_CHECK_MSG(image_id >= 1 && image_id <= images.size(), "no synthetic image " << image_id);
  return images[image_id - 1];
}

SyntheticDataset SynthesizeDataset(const SyntheticDatasetOptions& options) {
  THROW_CHECK_OPTIONS(options);
  SyntheticDataset dataset;
  dataset.options = options;
  std::mt19937 geometry_rng = MakeStream(options.seed, Stream::kGeometry);
  std::mt19937 observation_rng = MakeStream(options.seed, Stream::kObservations);
  std::mt19937 prior_rng = MakeStream(options.seed, Stream::kPriors);
  std::mt19937 constraint_rng = MakeStream(options.seed, Stream::kConstraints);
  const std::vector<CameraModel> models = AddCamerasAndFrames(options, &geometry_rng, &dataset);
  std::vector<ImageProjector> projectors;
  projectors.reserve(dataset.images.size());
  for (const SyntheticImage& image : dataset.images) {
    projectors.emplace_back(
        dataset.cameras.at(image.camera_id), models[image.camera_id - 1], image.gt_cam_from_world);
  }
  std::vector<std::vector<Observation>> observations =
      AddPoints(options, projectors, &geometry_rng, &observation_rng, &dataset);
  AddKeypoints(options, &observations, &observation_rng, &dataset);
  AddPriors(options, &prior_rng, &dataset);
  AddLidarConstraints(options, &constraint_rng, &dataset);
  return dataset;
}

Reconstruction SyntheticReconstruction(const SyntheticDataset& dataset) {
  Reconstruction model;
  for (const auto& [camera_id, camera] : dataset.cameras) model.AddCamera(camera);
  for (const SyntheticImage& synthetic : dataset.images) {
    Image image;
    image.image_id = synthetic.image_id;
    image.camera_id = synthetic.camera_id;
    image.name = synthetic.name;
    image.SetCamFromWorld(synthetic.gt_cam_from_world);
    image.qvec = StableQvec(image.qvec);  // survives COLMAP's re-normalisation
    image.points2D.resize(synthetic.keypoints.size());
    for (size_t k = 0; k < synthetic.keypoints.size(); ++k) {
      image.points2D[k].xy = synthetic.keypoints[k].xy;
      if (synthetic.keypoints[k].point_index >= 0) {
        image.points2D[k].point3D_id =
            static_cast<point3D_t>(synthetic.keypoints[k].point_index) + 1;
      }
    }
    model.AddImage(std::move(image));
  }

  // The tracks, point by point: the observations sorted by point (counting
  // sort), tracks[begin[p], begin[p + 1]) those of point p in image order and
  // errors[...] their distances from the exact projections.
  const size_t num_points = dataset.points.size();
  std::vector<size_t> begin(num_points + 1, 0);
  for (const SyntheticImage& image : dataset.images) {
    for (const SyntheticKeypoint& keypoint : image.keypoints) {
      if (keypoint.point_index >= 0) ++begin[static_cast<size_t>(keypoint.point_index) + 1];
    }
  }
  for (size_t p = 0; p < num_points; ++p) begin[p + 1] += begin[p];
  std::vector<TrackElement> tracks(begin[num_points]);
  std::vector<double> errors(begin[num_points]);
  std::vector<size_t> next(begin.begin(), begin.end() - 1);
  for (const SyntheticImage& image : dataset.images) {
    for (size_t k = 0; k < image.keypoints.size(); ++k) {
      const int p = image.keypoints[k].point_index;
      if (p < 0) continue;
      const size_t slot = next[static_cast<size_t>(p)]++;
      tracks[slot] = {image.image_id, static_cast<point2D_t>(k)};
      errors[slot] = image.keypoints[k].error;
    }
  }
  for (size_t p = 0; p < num_points; ++p) {
    if (begin[p] == begin[p + 1]) continue;
    Point3D point;
    point.xyz = dataset.points[p];
    point.color = dataset.point_colors[p];
    point.track.assign(tracks.begin() + static_cast<std::ptrdiff_t>(begin[p]),
                       tracks.begin() + static_cast<std::ptrdiff_t>(begin[p + 1]));
    double error_sum = 0.0;
    for (size_t slot = begin[p]; slot < begin[p + 1]; ++slot) error_sum += errors[slot];
    point.error = error_sum / static_cast<double>(point.track.size());
    model.AddPoint3D(static_cast<point3D_t>(p + 1), std::move(point));
  }

  if (dataset.options.with_rig) {
    // COLMAP 3.12 rig: the frame is the reference camera's (camera 1) frame.
    const camera_t ref_camera = dataset.cam_from_rig.begin()->first;
    const SE3& ref_from_rig = dataset.cam_from_rig.begin()->second;
    ModelRig rig;
    rig.rig_id = 1;
    rig.has_ref_sensor = true;
    rig.ref_sensor = SensorId{SensorType::kCamera, ref_camera};
    for (const auto& [camera_id, cam_from_rig] : dataset.cam_from_rig) {
      if (camera_id == ref_camera) continue;
      RigSensor sensor;
      sensor.sensor = SensorId{SensorType::kCamera, camera_id};
      sensor.has_pose = true;
      const SE3 sensor_from_ref = cam_from_rig * ref_from_rig.Inverse();
      sensor.qvec = QVec(sensor_from_ref.rotation());
      sensor.tvec = sensor_from_ref.translation();
      rig.sensors.push_back(sensor);
    }
    model.Rigs().push_back(rig);
    for (size_t f = 0; f < dataset.frames.size(); ++f) {
      const SyntheticFrame& frame = dataset.frames[f];
      ModelFrame model_frame;
      model_frame.frame_id = static_cast<frame_t>(f + 1);
      model_frame.rig_id = 1;
      const SE3 ref_from_world = ref_from_rig * frame.gt_rig_from_world;
      model_frame.qvec = QVec(ref_from_world.rotation());
      model_frame.tvec = ref_from_world.translation();
      for (const image_t image_id : frame.image_ids) {
        model_frame.data.push_back(FrameData{
            SensorId{SensorType::kCamera, dataset.GetImage(image_id).camera_id}, image_id});
      }
      model.Frames().push_back(model_frame);
    }
  }
  return model;
}

SyntheticMatches WriteSyntheticDatabase(const SyntheticDataset& dataset, const std::string& path) {
  const SyntheticDatasetOptions& options = dataset.options;
  SyntheticMatches result;
  std::mt19937 rng = MakeStream(options.seed, Stream::kOutliers);

  // True correspondences per image pair (image index i < j).
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> point_keypoints(dataset.points.size());
  for (size_t i = 0; i < dataset.images.size(); ++i) {
    const std::vector<SyntheticKeypoint>& keypoints = dataset.images[i].keypoints;
    for (size_t k = 0; k < keypoints.size(); ++k) {
      if (keypoints[k].point_index < 0) continue;
      point_keypoints[static_cast<size_t>(keypoints[k].point_index)].emplace_back(
          static_cast<uint32_t>(i), static_cast<uint32_t>(k));
    }
  }
  auto frame_of = [&](uint32_t image_index) {
    return static_cast<int>(dataset.images[image_index].frame_index);
  };
  std::unordered_map<uint64_t, std::vector<std::pair<uint32_t, uint32_t>>> pair_matches;
  for (const auto& observations : point_keypoints) {
    for (size_t a = 0; a < observations.size(); ++a) {
      for (size_t b = a + 1; b < observations.size(); ++b) {
        auto first = observations[a];
        auto second = observations[b];
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
  const std::string temp_path = path + ".tmp-" + std::to_string(static_cast<long>(::getpid()));
  std::remove(temp_path.c_str());
  TempFileGuard guard(temp_path);
  {
    Database database(temp_path, Database::OpenMode::kCreate);
    DatabaseTransaction transaction(&database);
    for (const auto& [camera_id, camera] : dataset.cameras) database.WriteCamera(camera, true);

    const bool with_position_prior = options.prior_position_noise > 0.0;
    const bool with_rotation_prior = options.prior_rotation_noise > 0.0;
    for (const SyntheticImage& synthetic : dataset.images) {
      DbImage image;
      image.image_id = synthetic.image_id;
      image.name = synthetic.name;
      image.camera_id = synthetic.camera_id;
      const SE3 prior_cam_from_world = dataset.cam_from_rig.at(synthetic.camera_id) *
                                       dataset.frames[synthetic.frame_index].prior_rig_from_world;
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

    for (const SyntheticImage& image : dataset.images) {
      KeypointsBlob blob(static_cast<Eigen::Index>(image.keypoints.size()), 2);
      for (size_t k = 0; k < image.keypoints.size(); ++k) {
        blob(static_cast<Eigen::Index>(k), 0) = static_cast<float>(image.keypoints[k].xy.x());
        blob(static_cast<Eigen::Index>(k), 1) = static_cast<float>(image.keypoints[k].xy.y());
      }
      database.WriteKeypoints(image.image_id, blob);
    }

    std::bernoulli_distribution outlier_pair(options.outlier_pair_ratio);
    for (const uint64_t key : pair_keys) {
      const SyntheticImage& image1 = dataset.images[static_cast<size_t>(key >> 32)];
      const SyntheticImage& image2 = dataset.images[static_cast<size_t>(key & 0xffffffffu)];
      const std::vector<std::pair<uint32_t, uint32_t>>& true_matches = pair_matches[key];
      std::vector<std::pair<uint32_t, uint32_t>> matches;
      SE3 cam2_from_cam1 = image2.gt_cam_from_world * image1.gt_cam_from_world.Inverse();
      auto unused_shuffled = [&](const std::vector<SyntheticKeypoint>& keypoints, bool first) {
        std::vector<char> used(keypoints.size(), 0);
        for (const auto& match : matches) used[first ? match.first : match.second] = 1;
        std::vector<uint32_t> unused;
        for (size_t k = 0; k < keypoints.size(); ++k) {
          if (!used[k]) unused.push_back(static_cast<uint32_t>(k));
        }
        std::shuffle(unused.begin(), unused.end(), rng);
        return unused;
      };
      // Appends up to `count` wrong 1-to-1 matches among keypoints not matched yet.
      auto add_wrong_matches = [&](size_t count) {
        const std::vector<uint32_t> unused1 = unused_shuffled(image1.keypoints, true);
        const std::vector<uint32_t> unused2 = unused_shuffled(image2.keypoints, false);
        const size_t n = std::min({count, unused1.size(), unused2.size()});
        for (size_t k = 0; k < n; ++k) {
          const int p1 = image1.keypoints[unused1[k]].point_index;
          if (p1 >= 0 && p1 == image2.keypoints[unused2[k]].point_index) continue;  // right
          matches.emplace_back(unused1[k], unused2[k]);
          ++result.num_outlier_matches;
        }
      };
      if (outlier_pair(rng)) {
        add_wrong_matches(true_matches.size());
        // A wrong relative pose: rotation at least 0.3 rad away from the truth.
        const Vec3 axis = GaussianVec3(1.0, &rng).normalized();
        cam2_from_cam1 = SE3(cam2_from_cam1.rotation() * so3::Exp(Uniform(0.3, kPi, &rng) * axis),
                             GaussianVec3(1.0, &rng));
        result.outlier_pairs.insert(ImagePairToPairId(image1.image_id, image2.image_id));
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
      const Mat3 k1 = PinholeK(dataset.cameras.at(image1.camera_id));
      const Mat3 k2 = PinholeK(dataset.cameras.at(image2.camera_id));
      geometry.F = k2.inverse().transpose() * geometry.E * k1.inverse();
      geometry.qvec = QVec(cam2_from_cam1.rotation());
      geometry.tvec = cam2_from_cam1.translation();
      database.WriteMatches(image1.image_id, image2.image_id, geometry.inlier_matches);
      database.WriteTwoViewGeometry(image1.image_id, image2.image_id, geometry);
      ++result.num_pairs;
      result.num_matches += matches.size();
    }
    transaction.Commit();
  }
  std::error_code error;
  std::filesystem::rename(temp_path, path, error);
  if (error) {
    throw InputError(path, "", "cannot rename " + temp_path + ": " + error.message());
  }
  guard.Release();
  return result;
}

}  // namespace colmap
}  // namespace lisfm
