// Camera projection models of the rig calibration (Kalibr naming):
// camera_model "pinhole" with distortion_model "radtan" (k1, k2, p1, p2),
// "equidistant" (k1..k4, the Kannala-Brandt / OpenCV fisheye model) or "none".
// Pixel convention: OpenCV/Kalibr (centre of the top-left pixel at (0, 0));
// COLMAP's (0.5, 0.5) offset is applied only when writing COLMAP cameras.
#pragma once

#include <string>
#include <vector>

#include "core/types.h"

namespace lisfm {

enum class DistortionModel { kNone, kRadtan, kEquidistant };

std::string DistortionModelName(DistortionModel model);
// Throws InputError for an unknown name.
DistortionModel ParseDistortionModel(const std::string& name);

struct CameraModel {
  int width = 0, height = 0;           // pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  DistortionModel distortion = DistortionModel::kNone;
  std::vector<double> distortion_coeffs;  // 4 for radtan and equidistant, 0 for none

  // Projects a point in the camera frame (z forward). Returns false when the
  // point is behind the camera (z <= 0 for radtan/none; angle > max for
  // equidistant) or projects outside the image (only when `check_bounds`).
  bool Project(const Vec3& x_in_cam, Vec2* pixel, bool check_bounds = true) const;
  // Unit-length ray through `pixel` (iterative undistortion, converges to 1e-10).
  Vec3 Unproject(const Vec2& pixel) const;
  bool InImage(const Vec2& pixel) const;
  // Checks sizes/values; throws InputError naming `where` ("rig.yaml:cam2").
  void Validate(const std::string& where) const;
};

}  // namespace lisfm
