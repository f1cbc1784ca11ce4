// In-memory COLMAP sparse model: cameras, registered images with
// cam_from_world poses and 2D points, 3D points with tracks, colour and
// error, plus the optional rigs / frames of COLMAP 3.12+.
//
// Conventions (COLMAP, REFERENCES.md section 1):
//  - image/camera/rig/frame ids are u32, point3D ids u64, point2D indices u32;
//    kInvalid* = max value;
//  - an image pose is cam_from_world (x_cam = R x_world + t) stored exactly as
//    the file holds it: qvec = (qw, qx, qy, qz) Hamilton, tvec; camera centre
//    C = -R^T t;
//  - pixels use COLMAP's convention (top-left pixel centre at (0.5, 0.5)).
//
// Order: cameras, images and points keep the order in which they were added
// (for a model read from disk, the file order), so a read + write reproduces
// the files byte for byte. Lookups by id are O(1).
// Not thread-safe for concurrent modification.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "colmap_ext/io/camera_models.h"
#include "core/geometry.h"

namespace lisfm {
namespace colmap {

using image_t = uint32_t;
using point2D_t = uint32_t;
using point3D_t = uint64_t;
using rig_t = uint32_t;
using frame_t = uint32_t;
constexpr image_t kInvalidImageId = std::numeric_limits<image_t>::max();
constexpr point2D_t kInvalidPoint2DIdx = std::numeric_limits<point2D_t>::max();
constexpr point3D_t kInvalidPoint3DId = std::numeric_limits<point3D_t>::max();

struct Point2D {
  Vec2 xy = Vec2::Zero();  // pixels, COLMAP convention
  point3D_t point3D_id = kInvalidPoint3DId;
  bool HasPoint3D() const { return point3D_id != kInvalidPoint3DId; }
};

struct Image {
  image_t image_id = kInvalidImageId;
  std::string name;  // relative to the image folder
  camera_t camera_id = kInvalidCameraId;
  Vec4 qvec = Vec4(1, 0, 0, 0);  // cam_from_world rotation (qw, qx, qy, qz)
  Vec3 tvec = Vec3::Zero();      // cam_from_world translation
  std::vector<Point2D> points2D;

  SE3 CamFromWorld() const;  // normalises the rotation
  void SetCamFromWorld(const SE3& cam_from_world);
  Vec3 ProjectionCenter() const;  // camera centre in world, -R^T t
  size_t NumPoints3D() const;     // 2D points with a 3D point
};

struct TrackElement {
  image_t image_id = kInvalidImageId;
  point2D_t point2D_idx = kInvalidPoint2DIdx;
};

struct Point3D {
  Vec3 xyz = Vec3::Zero();             // world frame
  std::array<uint8_t, 3> color{{0, 0, 0}};  // RGB
  double error = -1.0;                 // mean reprojection error (px); -1 = unknown
  std::vector<TrackElement> track;
  bool HasError() const { return error != -1.0; }
};

// Sensor ids of COLMAP 3.12+ (type CAMERA 0, IMU 1; the id is the camera id).
enum class SensorType : int { kInvalid = -1, kCamera = 0, kImu = 1 };
struct SensorId {
  SensorType type = SensorType::kInvalid;
  uint32_t id = 0;
};

struct RigSensor {
  SensorId sensor;
  bool has_pose = false;
  Vec4 qvec = Vec4(1, 0, 0, 0);  // sensor_from_rig (qw, qx, qy, qz)
  Vec3 tvec = Vec3::Zero();
};

// COLMAP 3.12 rig: a reference sensor (rig frame = its frame) and others.
struct ModelRig {
  rig_t rig_id = 0;
  bool has_ref_sensor = false;
  SensorId ref_sensor;
  std::vector<RigSensor> sensors;  // non-reference sensors, file order
};

struct FrameData {
  SensorId sensor;
  uint64_t data_id = 0;  // the image id for cameras
};

// COLMAP 3.12 frame: one rig pose; cam_from_world = sensor_from_rig * rig_from_world.
struct ModelFrame {
  frame_t frame_id = 0;
  rig_t rig_id = 0;
  Vec4 qvec = Vec4(1, 0, 0, 0);  // rig_from_world (qw, qx, qy, qz)
  Vec3 tvec = Vec3::Zero();
  std::vector<FrameData> data;
};

class Reconstruction {
 public:
  size_t NumCameras() const { return cameras_.size(); }
  size_t NumImages() const { return images_.size(); }
  size_t NumPoints3D() const { return points3D_.size(); }

  // Add* throw InternalError when the id already exists.
  void AddCamera(Camera camera);
  void AddImage(Image image);
  void AddPoint3D(point3D_t point3D_id, Point3D point);
  // Adds a point with the next free id (max id + 1) and links its track into
  // the images' 2D points. Returns the id.
  point3D_t AddPoint3DWithTrack(Point3D point);

  bool ExistsCamera(camera_t id) const { return camera_index_.count(id) > 0; }
  bool ExistsImage(image_t id) const { return image_index_.count(id) > 0; }
  bool ExistsPoint3D(point3D_t id) const { return point_index_.count(id) > 0; }
  // Throw InternalError for a missing id.
  const Camera& GetCamera(camera_t id) const;
  Camera& GetCamera(camera_t id);
  const Image& GetImage(image_t id) const;
  Image& GetImage(image_t id);
  const Point3D& GetPoint3D(point3D_t id) const;
  Point3D& GetPoint3D(point3D_t id);

  // In insertion (file) order.
  const std::vector<Camera>& Cameras() const { return cameras_; }
  const std::vector<Image>& Images() const { return images_; }
  const std::vector<std::pair<point3D_t, Point3D>>& Points3D() const { return points3D_; }
  std::vector<Image>& MutableImages() { return images_; }

  // COLMAP 3.12+ optional rigs / frames (empty for 3.8 models).
  std::vector<ModelRig>& Rigs() { return rigs_; }
  const std::vector<ModelRig>& Rigs() const { return rigs_; }
  std::vector<ModelFrame>& Frames() { return frames_; }
  const std::vector<ModelFrame>& Frames() const { return frames_; }

  // COLMAP's statistics (model_analyzer): observations = 2D points with a 3D
  // point over all images; mean track length = observations / points;
  // mean observations per image = observations / images; mean reprojection
  // error = mean of the points' stored errors (those != -1). 0 when empty.
  size_t ComputeNumObservations() const;
  double ComputeMeanTrackLength() const;
  double ComputeMeanObservationsPerRegImage() const;
  double ComputeMeanReprojectionError() const;
  // Recomputes every point's error from the geometry (mean pixel distance over
  // its track); points whose track does not project get error -1.
  void UpdatePointErrors();

  // Checks that cameras exist for all images with valid parameters, tracks
  // reference existing images/2D points that point back to the same 3D point,
  // and every 2D point's 3D point exists and lists it. Throws InputError with
  // `source` (the folder or file) and the offending record.
  void Validate(const std::string& source) const;

  void Clear();

 private:
  std::vector<Camera> cameras_;
  std::vector<Image> images_;
  std::vector<std::pair<point3D_t, Point3D>> points3D_;
  std::unordered_map<camera_t, size_t> camera_index_;
  std::unordered_map<image_t, size_t> image_index_;
  std::unordered_map<point3D_t, size_t> point_index_;
  point3D_t max_point3D_id_ = 0;  // largest id added (AddPoint3DWithTrack uses max + 1)
  std::vector<ModelRig> rigs_;
  std::vector<ModelFrame> frames_;
};

// COLMAP's NormalizeQuaternion (qvec / |qvec|; (1, x, y, z) for a zero norm),
// with the same floating-point operations as COLMAP.
Vec4 NormalizeQvec(const Vec4& qvec);
// A fixed point of NormalizeQvec reached from qvec (NormalizeQvec applied
// until the value stops changing): COLMAP normalises on every read and write,
// and such values survive that bit for bit.
Vec4 StableQvec(const Vec4& qvec);
// What the model writers store: qvec unchanged when it is unit-norm to within
// rounding (|q|^2 - 1| <= 8 eps, e.g. anything COLMAP wrote), so that COLMAP's
// files round-trip byte for byte; StableQvec(qvec) otherwise. COLMAP itself
// re-normalises on every write, which may change the last bit of a unit
// quaternion that is not a fixed point; the rotation is the same.
Vec4 QvecForWriting(const Vec4& qvec);

}  // namespace colmap
}  // namespace lisfm
