// COLMAP camera models 0-10 (stable ids and parameter orders since COLMAP 3.8,
// REFERENCES.md section 1) and the COLMAP `Camera` record.
//
// Frames and units: a point in the camera frame has z forward, x right, y down
// (metres or any unit); pixels follow COLMAP's convention, the centre of the
// top-left pixel is at (0.5, 0.5), so cx_colmap = cx_opencv + 0.5. Projection
// goes camera frame -> normalised image plane (x/z, y/z) -> distortion ->
// pixel, with COLMAP 3.8's formulas for each model: the model structs of
// core/camera_models.h, dispatched by model id. Unprojection inverts the
// distortion iteratively (Newton, numeric Jacobian) to ~1e-12 in the
// normalised plane (core/camera_models.h IterativeUndistortion).
//
// Failures: unknown model ids/names and wrong parameter counts are user data
// errors; VerifyParams() reports them and the file readers throw InputError.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "core/camera_model.h"
#include "core/camera_models.h"
#include "core/types.h"

namespace lisfm {
namespace colmap {

// COLMAP's model ids (the numeric values are part of the file formats) and
// their count, defined with the models in core/camera_models.h.
using ::lisfm::CameraModelId;
using ::lisfm::kNumCameraModels;

bool ExistsCameraModel(int model_id);
// "SIMPLE_PINHOLE", ... ; "" for an unknown id.
std::string CameraModelName(int model_id);
// kInvalid (-1) for an unknown name.
int CameraModelIdFromName(const std::string& name);
// Number of parameters; -1 for an unknown id.
int CameraModelNumParams(int model_id);
// "fx, fy, cx, cy, k1, k2, p1, p2" etc.; "" for an unknown id.
std::string CameraModelParamsInfo(int model_id);

using camera_t = uint32_t;
constexpr camera_t kInvalidCameraId = std::numeric_limits<camera_t>::max();

// A COLMAP camera (cameras table row / cameras.bin record).
struct Camera {
  camera_t camera_id = kInvalidCameraId;
  int model_id = static_cast<int>(CameraModelId::kInvalid);
  uint64_t width = 0;   // pixels
  uint64_t height = 0;  // pixels
  std::vector<double> params;  // in the model's order, pixels / unitless
  // Database only: focal length known (set it for calibrated cameras, or
  // COLMAP 3.8 stores UNCALIBRATED two-view geometries).
  bool has_prior_focal_length = false;

  std::string ModelName() const { return CameraModelName(model_id); }
  // Known model and the right number of finite parameters.
  bool VerifyParams() const;
  double MeanFocalLength() const;
  double PrincipalPointX() const;
  double PrincipalPointY() const;
  // COLMAP's bogus-parameter test (Camera::HasBogusParams): a focal length
  // divided by max(width, height) outside [min_focal_length_ratio,
  // max_focal_length_ratio], or an extra (distortion) parameter with
  // |value| > max_extra_param. `reason` (optional) gets which, e.g.
  // "fx = 66444.0 px is 92.28x max(width, height)".
  bool HasBogusParams(double min_focal_length_ratio,
                      double max_focal_length_ratio,
                      double max_extra_param,
                      std::string* reason = nullptr) const;

  // Normalised image plane (x/z, y/z) -> pixel, with distortion.
  Vec2 ImgFromCam(const Vec2& normalized) const;
  // Pixel -> normalised image plane (inverse of ImgFromCam); NaN when the
  // undistortion diverged (fisheye models: also for incidence angles >= 90
  // degrees, which have no point on the normalised plane).
  Vec2 CamFromImg(const Vec2& pixel) const;
  // Camera frame -> pixel; false for points with z <= 0 (behind the camera).
  bool Project(const Vec3& x_in_cam, Vec2* pixel) const;
  // Pixel -> unit ray in the camera frame.
  Vec3 Unproject(const Vec2& pixel) const;
};

// COLMAP camera from a rig calibration camera (core/camera_model.h, OpenCV
// pixel convention): none -> PINHOLE, radtan -> OPENCV, equidistant ->
// OPENCV_FISHEYE; cx, cy shifted by +0.5; has_prior_focal_length = true.
Camera CameraFromCameraModel(const CameraModel& model, camera_t camera_id);

}  // namespace colmap
}  // namespace lisfm
