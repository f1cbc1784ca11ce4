#include "colmap_ext/io/camera_models.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <fmt/format.h>

#include "core/errors.h"

namespace lisfm {
namespace colmap {

namespace {

struct ModelInfo {
  std::string name;
  int num_params = 0;
  std::string params_info;
  int num_focal_params = 0;  // 1: f; 2: fx, fy
};

// The constants of every model struct of core/camera_models.h, by id.
const std::array<ModelInfo, kNumCameraModels>& Models() {
  static const std::array<ModelInfo, kNumCameraModels> models = [] {
    std::array<ModelInfo, kNumCameraModels> table;
    for (int id = 0; id < kNumCameraModels; ++id) {
      table[id] = VisitCameraModel(id, [](auto model) {
        using Model = decltype(model);
        return ModelInfo{
            Model::kName, Model::kNumParams, Model::kParamsInfo, Model::kNumFocalParams};
      });
    }
    return table;
  }();
  return models;
}

}  // namespace

bool ExistsCameraModel(int model_id) { return model_id >= 0 && model_id < kNumCameraModels; }

std::string CameraModelName(int model_id) {
  return ExistsCameraModel(model_id) ? Models()[model_id].name : "";
}

int CameraModelIdFromName(const std::string& name) {
  for (int i = 0; i < kNumCameraModels; ++i) {
    if (name == Models()[i].name) return i;
  }
  return static_cast<int>(CameraModelId::kInvalid);
}

int CameraModelNumParams(int model_id) {
  return ExistsCameraModel(model_id) ? Models()[model_id].num_params : -1;
}

std::string CameraModelParamsInfo(int model_id) {
  return ExistsCameraModel(model_id) ? Models()[model_id].params_info : "";
}

bool Camera::VerifyParams() const {
  if (!ExistsCameraModel(model_id)) return false;
  if (static_cast<int>(params.size()) != CameraModelNumParams(model_id)) return false;
  for (double p : params) {
    if (!std::isfinite(p)) return false;
  }
  return true;
}

double Camera::MeanFocalLength() const {
  THROW_CHECK(VerifyParams());
  return Models()[model_id].num_focal_params == 1 ? params[0] : 0.5 * (params[0] + params[1]);
}

bool Camera::HasBogusParams(double min_focal_length_ratio,
                            double max_focal_length_ratio,
                            double max_extra_param,
                            std::string* reason) const {
  THROW_CHECK(VerifyParams());
  const int num_focal = Models()[model_id].num_focal_params;
  const double max_size = static_cast<double>(std::max(width, height));
  for (int i = 0; i < num_focal; ++i) {
    const double ratio = params[i] / max_size;
    if (ratio < min_focal_length_ratio || ratio > max_focal_length_ratio) {
      if (reason != nullptr) {
        *reason = fmt::format("{} = {:.1f} px is {:.2f}x max(width, height), outside [{}, {}]",
                              num_focal == 1 ? "f" : (i == 0 ? "fx" : "fy"), params[i], ratio,
                              min_focal_length_ratio, max_focal_length_ratio);
      }
      return true;
    }
  }
  for (size_t i = static_cast<size_t>(num_focal) + 2; i < params.size(); ++i) {
    if (std::abs(params[i]) > max_extra_param) {
      if (reason != nullptr) {
        *reason = fmt::format("extra parameter {} = {:.3g}, |value| > {}",
                              i - static_cast<size_t>(num_focal) - 2, params[i], max_extra_param);
      }
      return true;
    }
  }
  return false;
}

double Camera::PrincipalPointX() const {
  THROW_CHECK(VerifyParams());
  return params[Models()[model_id].num_focal_params];
}

double Camera::PrincipalPointY() const {
  THROW_CHECK(VerifyParams());
  return params[Models()[model_id].num_focal_params + 1];
}

Vec2 Camera::ImgFromCam(const Vec2& normalized) const {
  THROW_CHECK_MSG(VerifyParams(), "camera " << camera_id << " has invalid parameters");
  Vec2 pixel;
  VisitCameraModel(model_id, [&](auto model) {
    decltype(model)::ImgFromCam(
        params.data(), normalized.x(), normalized.y(), &pixel.x(), &pixel.y());
    return 0;
  });
  return pixel;
}

Vec2 Camera::CamFromImg(const Vec2& pixel) const {
  THROW_CHECK_MSG(VerifyParams(), "camera " << camera_id << " has invalid parameters");
  Vec2 normalized;
  VisitCameraModel(model_id, [&](auto model) {
    return decltype(model)::CamFromImg(
        params.data(), pixel.x(), pixel.y(), &normalized.x(), &normalized.y());
  });
  return normalized;
}

bool Camera::Project(const Vec3& x_in_cam, Vec2* pixel) const {
  if (!(x_in_cam.z() > 0.0)) return false;
  *pixel = ImgFromCam(x_in_cam.head<2>() / x_in_cam.z());
  return pixel->allFinite();
}

Vec3 Camera::Unproject(const Vec2& pixel) const {
  return CamFromImg(pixel).homogeneous().normalized();
}

Camera CameraFromCameraModel(const CameraModel& model, camera_t camera_id) {
  if (model.distortion != DistortionModel::kNone && model.distortion_coeffs.size() != 4) {
    throw InputError("camera " + std::to_string(camera_id),
                     "",
                     "expected 4 distortion coefficients, found " +
                         std::to_string(model.distortion_coeffs.size()));
  }
  Camera camera;
  camera.camera_id = camera_id;
  camera.model_id = static_cast<int>(model.ModelId());
  camera.width = static_cast<uint64_t>(model.width);
  camera.height = static_cast<uint64_t>(model.height);
  camera.has_prior_focal_length = true;
  // fx, fy, cx, cy (+ distortion): the principal point moves to COLMAP's
  // convention (centre of the top-left pixel at (0.5, 0.5)).
  camera.params = model.Params();
  camera.params.resize(CameraModelNumParams(camera.model_id));
  camera.params[2] += 0.5;
  camera.params[3] += 0.5;
  return camera;
}

}  // namespace colmap
}  // namespace lisfm
