#include "colmap_ext/io/reconstruction.h"

#include <algorithm>
#include <cmath>

#include "core/errors.h"

namespace lisfm {
namespace colmap {

Vec4 NormalizeQvec(const Vec4& qvec) {
  const double norm = qvec.norm();
  if (norm == 0) return Vec4(1.0, qvec(1), qvec(2), qvec(3));
  return qvec / norm;
}

Vec4 StableQvec(const Vec4& qvec) {
  Vec4 q = NormalizeQvec(qvec);
  for (int i = 0; i < 8; ++i) {
    const Vec4 next = NormalizeQvec(q);
    if (next == q) break;
    q = next;
  }
  return q;
}

Vec4 QvecForWriting(const Vec4& qvec) {
  if (std::abs(qvec.squaredNorm() - 1.0) <= 8 * std::numeric_limits<double>::epsilon()) {
    return qvec;
  }
  return StableQvec(qvec);
}

SE3 Image::CamFromWorld() const {
  return SE3(Quat(qvec(0), qvec(1), qvec(2), qvec(3)), tvec);
}

void Image::SetCamFromWorld(const SE3& cam_from_world) {
  const Quat& q = cam_from_world.rotation();
  qvec = Vec4(q.w(), q.x(), q.y(), q.z());
  tvec = cam_from_world.translation();
}

Vec3 Image::ProjectionCenter() const {
  return -(CamFromWorld().RotationMatrix().transpose() * tvec);
}

size_t Image::NumPoints3D() const {
  size_t n = 0;
  for (const Point2D& p : points2D) n += p.HasPoint3D() ? 1 : 0;
  return n;
}

void Reconstruction::AddCamera(Camera camera) {
  THROW_CHECK_MSG(!ExistsCamera(camera.camera_id), "duplicate camera id " << camera.camera_id);
  camera_index_.emplace(camera.camera_id, cameras_.size());
  cameras_.push_back(std::move(camera));
}

void Reconstruction::AddImage(Image image) {
  THROW_CHECK_MSG(!ExistsImage(image.image_id), "duplicate image id " << image.image_id);
  image_index_.emplace(image.image_id, images_.size());
  images_.push_back(std::move(image));
}

void Reconstruction::AddPoint3D(point3D_t point3D_id, Point3D point) {
  THROW_CHECK_MSG(!ExistsPoint3D(point3D_id), "duplicate point3D id " << point3D_id);
  point_index_.emplace(point3D_id, points3D_.size());
  points3D_.emplace_back(point3D_id, std::move(point));
  max_point3D_id_ = std::max(max_point3D_id_, point3D_id);
}

point3D_t Reconstruction::AddPoint3DWithTrack(Point3D point) {
  const point3D_t id = max_point3D_id_ + 1;
  for (const TrackElement& el : point.track) {
    Image& image = GetImage(el.image_id);
    THROW_CHECK_LT(el.point2D_idx, image.points2D.size());
    THROW_CHECK(!image.points2D[el.point2D_idx].HasPoint3D());
    image.points2D[el.point2D_idx].point3D_id = id;
  }
  AddPoint3D(id, std::move(point));
  return id;
}

const Camera& Reconstruction::GetCamera(camera_t id) const {
  const auto it = camera_index_.find(id);
  THROW_CHECK_MSG(it != camera_index_.end(), "no camera " << id);
  return cameras_[it->second];
}
Camera& Reconstruction::GetCamera(camera_t id) {
  return const_cast<Camera&>(static_cast<const Reconstruction&>(*this).GetCamera(id));
}
const Image& Reconstruction::GetImage(image_t id) const {
  const auto it = image_index_.find(id);
  THROW_CHECK_MSG(it != image_index_.end(), "no image " << id);
  return images_[it->second];
}
Image& Reconstruction::GetImage(image_t id) {
  return const_cast<Image&>(static_cast<const Reconstruction&>(*this).GetImage(id));
}
const Point3D& Reconstruction::GetPoint3D(point3D_t id) const {
  const auto it = point_index_.find(id);
  THROW_CHECK_MSG(it != point_index_.end(), "no point3D " << id);
  return points3D_[it->second].second;
}
Point3D& Reconstruction::GetPoint3D(point3D_t id) {
  return const_cast<Point3D&>(static_cast<const Reconstruction&>(*this).GetPoint3D(id));
}

size_t Reconstruction::ComputeNumObservations() const {
  size_t n = 0;
  for (const Image& image : images_) n += image.NumPoints3D();
  return n;
}

double Reconstruction::ComputeMeanTrackLength() const {
  if (points3D_.empty()) return 0.0;
  return ComputeNumObservations() / static_cast<double>(points3D_.size());
}

double Reconstruction::ComputeMeanObservationsPerRegImage() const {
  if (images_.empty()) return 0.0;
  return ComputeNumObservations() / static_cast<double>(images_.size());
}

double Reconstruction::ComputeMeanReprojectionError() const {
  double sum = 0.0;
  size_t n = 0;
  for (const auto& p : points3D_) {
    if (p.second.HasError()) {
      sum += p.second.error;
      ++n;
    }
  }
  return n == 0 ? 0.0 : sum / n;
}

void Reconstruction::UpdatePointErrors() {
  for (auto& entry : points3D_) {
    Point3D& point = entry.second;
    double sum = 0.0;
    bool ok = !point.track.empty();
    for (const TrackElement& el : point.track) {
      const Image& image = GetImage(el.image_id);
      const Camera& camera = GetCamera(image.camera_id);
      Vec2 pixel;
      if (!camera.Project(image.CamFromWorld() * point.xyz, &pixel)) {
        ok = false;
        break;
      }
      sum += (pixel - image.points2D.at(el.point2D_idx).xy).norm();
    }
    point.error = ok ? sum / point.track.size() : -1.0;
  }
}

void Reconstruction::Validate(const std::string& source) const {
  for (const Camera& camera : cameras_) {
    if (!camera.VerifyParams()) {
      throw InputError(source, "camera " + std::to_string(camera.camera_id),
                       "expected a known model with " +
                           std::to_string(CameraModelNumParams(camera.model_id)) +
                           " finite parameters, found model id " +
                           std::to_string(camera.model_id) + " with " +
                           std::to_string(camera.params.size()) + " parameters");
    }
  }
  for (const Image& image : images_) {
    if (!ExistsCamera(image.camera_id)) {
      throw InputError(source, "image " + std::to_string(image.image_id),
                       "expected an existing camera id, found " +
                           std::to_string(image.camera_id));
    }
    for (size_t i = 0; i < image.points2D.size(); ++i) {
      const point3D_t pid = image.points2D[i].point3D_id;
      if (!image.points2D[i].HasPoint3D()) continue;
      const auto it = point_index_.find(pid);
      bool listed = false;
      if (it != point_index_.end()) {
        for (const TrackElement& el : points3D_[it->second].second.track) {
          listed |= el.image_id == image.image_id && el.point2D_idx == i;
        }
      }
      if (!listed) {
        throw InputError(source,
                         "image " + std::to_string(image.image_id) + " point2D " +
                             std::to_string(i),
                         "expected point3D " + std::to_string(pid) +
                             " to exist and list this observation in its track");
      }
    }
  }
  for (const auto& entry : points3D_) {
    for (const TrackElement& el : entry.second.track) {
      const auto it = image_index_.find(el.image_id);
      if (it == image_index_.end() ||
          el.point2D_idx >= images_[it->second].points2D.size() ||
          images_[it->second].points2D[el.point2D_idx].point3D_id != entry.first) {
        throw InputError(source, "point3D " + std::to_string(entry.first),
                         "track element (image " + std::to_string(el.image_id) +
                             ", point2D " + std::to_string(el.point2D_idx) +
                             ") does not refer back to this point");
      }
    }
  }
}

void Reconstruction::Clear() { *this = Reconstruction(); }

}  // namespace colmap
}  // namespace lisfm
