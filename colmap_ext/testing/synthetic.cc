#include "colmap_ext/testing/synthetic.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/errors.h"

namespace lisfm {
namespace colmap {

bool SyntheticModelOptions::Check() const {
  return num_cameras >= 1 && num_images >= 1 && num_points >= 0 && track_length >= 1 &&
         track_length <= num_images && unobserved_per_image >= 0 && pixel_noise >= 0.0;
}

Reconstruction SynthesizeModel(const SyntheticModelOptions& options) {
  THROW_CHECK(options.Check());
  std::mt19937 rng(options.seed);
  Reconstruction model;
  const int models[3] = {static_cast<int>(CameraModelId::kPinhole),
                         static_cast<int>(CameraModelId::kOpenCVFisheye),
                         static_cast<int>(CameraModelId::kOpenCV)};
  for (int c = 0; c < options.num_cameras; ++c) {
    Camera camera;
    camera.camera_id = static_cast<camera_t>(c + 1);
    camera.model_id = models[c % 3];
    camera.width = 1280;
    camera.height = 960;
    camera.params = {800.0 + 10.0 * c, 805.0 + 10.0 * c, 640.5, 480.5};
    if (camera.model_id == static_cast<int>(CameraModelId::kOpenCVFisheye)) {
      camera.params.insert(camera.params.end(), {0.05, -0.01, 0.002, -0.0005});
    } else if (camera.model_id == static_cast<int>(CameraModelId::kOpenCV)) {
      camera.params.insert(camera.params.end(), {-0.1, 0.02, 0.001, -0.002});
    }
    camera.has_prior_focal_length = true;
    model.AddCamera(camera);
  }
  // Cameras on a ring of radius 10 m at height 1 m, looking at the origin.
  std::vector<SE3> poses;
  for (int i = 0; i < options.num_images; ++i) {
    const double a = 2.0 * M_PI * i / options.num_images;
    const Vec3 centre(10.0 * std::cos(a), 10.0 * std::sin(a), 1.0 + 0.1 * std::sin(3 * a));
    const Vec3 z = (-centre).normalized();
    const Vec3 x = z.cross(Vec3::UnitZ()).normalized();
    const Vec3 y = z.cross(x);
    Mat3 world_from_cam;
    world_from_cam << x, y, z;
    const SE3 cam_from_world = SE3(Mat3(world_from_cam), centre).Inverse();
    Image image;
    image.image_id = static_cast<image_t>(i + 1);
    image.camera_id = static_cast<camera_t>(i % options.num_cameras + 1);
    char name[64];
    std::snprintf(name, sizeof(name), "cam%d/data/%012d.png", i % options.num_cameras, i);
    image.name = name;
    image.SetCamFromWorld(cam_from_world);
    image.qvec = StableQvec(image.qvec);  // survives COLMAP's re-normalisation
    poses.push_back(cam_from_world);
    model.AddImage(image);
  }
  std::uniform_real_distribution<double> cube(-2.0, 2.0);
  std::normal_distribution<double> noise(0.0, options.pixel_noise);
  std::vector<int> order(options.num_images);
  for (int i = 0; i < options.num_images; ++i) order[i] = i;
  std::vector<Image>& images = model.MutableImages();
  for (int p = 0; p < options.num_points; ++p) {
    Point3D point;
    point.xyz = Vec3(cube(rng), cube(rng), cube(rng));
    point.color = {static_cast<uint8_t>(rng() % 256), static_cast<uint8_t>(rng() % 256),
                   static_cast<uint8_t>(rng() % 256)};
    // Partial Fisher-Yates: the first track_length entries are distinct images.
    for (int k = 0; k < options.track_length; ++k) {
      std::uniform_int_distribution<int> pick(k, options.num_images - 1);
      std::swap(order[k], order[pick(rng)]);
    }
    const point3D_t id = static_cast<point3D_t>(p + 1);
    double error_sum = 0.0;
    for (int k = 0; k < options.track_length; ++k) {
      Image& image = images[order[k]];
      const Camera& camera = model.GetCamera(image.camera_id);
      Vec2 pixel;
      THROW_CHECK(camera.Project(poses[order[k]] * point.xyz, &pixel));
      const Vec2 observed = pixel + Vec2(noise(rng), noise(rng));
      error_sum += (observed - pixel).norm();
      Point2D point2D;
      point2D.xy = observed;
      point2D.point3D_id = id;
      point.track.push_back(
          {image.image_id, static_cast<point2D_t>(image.points2D.size())});
      image.points2D.push_back(point2D);
    }
    point.error = error_sum / options.track_length;
    model.AddPoint3D(id, std::move(point));
  }
  std::uniform_real_distribution<double> u(0.5, 1279.5), v(0.5, 959.5);
  for (Image& image : images) {
    for (int k = 0; k < options.unobserved_per_image; ++k) {
      Point2D point2D;
      point2D.xy = Vec2(u(rng), v(rng));
      image.points2D.push_back(point2D);
    }
  }
  return model;
}

}  // namespace colmap
}  // namespace lisfm
