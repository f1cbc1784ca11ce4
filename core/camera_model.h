// Camera projection models of the rig calibration (Kalibr naming):
// camera_model "pinhole" with distortion_model "radtan" (k1, k2, p1, p2),
// "equidistant" (k1..k4, the Kannala-Brandt / OpenCV fisheye model) or "none".
// Pixel convention: OpenCV/Kalibr (centre of the top-left pixel at (0, 0));
// COLMAP's (0.5, 0.5) offset is applied only when writing COLMAP cameras.
//
// The formulas are those of core/camera_models.h, with (x, y, z) a point in
// the camera frame (z forward, x right, y down):
//  - none -> PINHOLE:       m = (x/z, y/z);  pixel = (fx m_x + cx, fy m_y + cy)
//  - radtan -> OPENCV:      m as above, r2 = |m|^2,
//                 m' = m (1 + k1 r2 + k2 r2^2) + (2 p1 m_x m_y + p2 (r2 + 2
//                 m_x^2),
//                                                 p1 (r2 + 2 m_y^2) + 2 p2 m_x
//                                                 m_y)
//                 (OpenCV cv::projectPoints with [k1 k2 p1 p2], Kalibr
//                 "radtan")
//  - equidistant -> OPENCV_FISHEYE: theta = atan2(|(x, y)|, z),
//                 theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 +
//                 k4 theta^8), m' = theta_d (x, y) / |(x, y)|
//                 (cv::fisheye::projectPoints, Kalibr "equidistant"); rays
//                 beyond 90 degrees project too.
// This struct adds the rig's contract on top: rays behind the camera, the
// invertible field of view and the image bounds.
// Thread safety: all const methods are pure functions of the fields.
#pragma once

#include <string>
#include <vector>

#include "core/camera_models.h"
#include "core/types.h"

namespace lisfm {

enum class DistortionModel { kNone, kRadtan, kEquidistant };

// "none", "radtan", "equidistant".
std::string DistortionModelName(DistortionModel model);
// Throws InputError for an unknown name (message lists the valid names).
DistortionModel ParseDistortionModel(const std::string& name);
// Number of coefficients the model takes: 0 for none, 4 for radtan/equidistant.
int NumDistortionCoeffs(DistortionModel model);

struct CameraModel {
  int width = 0, height = 0;           // pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  DistortionModel distortion = DistortionModel::kNone;
  std::vector<double> distortion_coeffs;  // 4 for radtan and equidistant, 0 for none

  // Projects a point in the camera frame (z forward). Returns false when the
  // point is behind the camera (z <= 0 for radtan/none; for equidistant when
  // the incidence angle theta >= pi), outside the invertible field of view
  // (radtan: r (1 + k1 r^2 + k2 r^4) not increasing on [0, |m|]; equidistant:
  // theta_d(theta) not increasing on [0, theta]; such points would fold back
  // into the image), or projects outside the image (only when `check_bounds`).
  // `pixel` is written whenever the projection formula itself is defined.
  bool Project(const Vec3& x_in_cam, Vec2* pixel, bool check_bounds = true) const;
  // Unit-length ray through `pixel` (iterative undistortion, converges to 1e-10).
  // For a pixel outside the invertible region this is the best estimate found.
  Vec3 Unproject(const Vec2& pixel) const;
  // As above; returns false when the undistortion did not converge to 1e-10
  // (pixel outside the invertible region of the distortion model).
  bool Unproject(const Vec2& pixel, Vec3* ray) const;
  // True when the pixel lies on the image area: -0.5 <= u < width - 0.5 and
  // -0.5 <= v < height - 0.5 (pixel centres at integer coordinates).
  bool InImage(const Vec2& pixel) const;
  // The model of core/camera_models.h that evaluates this camera: none ->
  // kPinhole, radtan -> kOpenCV, equidistant -> kOpenCVFisheye.
  CameraModelId ModelId() const;
  // That model's parameters: fx, fy, cx, cy (OpenCV pixel convention, as
  // stored here), then distortion_coeffs.
  std::vector<double> Params() const;
  // Checks sizes/values (positive resolution and focal lengths, finite values,
  // coefficient count of the model); throws InputError naming `where`
  // ("rig.yaml:cam2") and the field, e.g. "rig.yaml:cam2.intrinsics: ...".
  void Validate(const std::string& where) const;
};

}  // namespace lisfm
