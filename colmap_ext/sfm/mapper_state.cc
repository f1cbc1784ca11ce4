#include "colmap_ext/sfm/mapper_state.h"

#include <algorithm>
#include <cmath>
#include <regex>

#include <tbb/parallel_for.h>

#include "core/io/image_codec.h"
#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"
#include "core/rig.h"

namespace lisfm {
namespace colmap {

size_t ViewGraph::NumValidEdges() const {
  return static_cast<size_t>(std::count_if(edges.begin(), edges.end(),
                                           [](const ViewGraphEdge& e) { return e.valid; }));
}

void ViewGraph::AddEdge(ViewGraphEdge edge) {
  THROW_CHECK_NE(edge.image_id1, edge.image_id2);
  if (edge.image_id1 > edge.image_id2) {
    std::swap(edge.image_id1, edge.image_id2);
    for (auto& m : edge.inliers) std::swap(m.first, m.second);
    edge.cam2_from_cam1 = edge.cam2_from_cam1.Inverse();
    if (!edge.metric) {
      // Keep the direction-only convention |t| = 1.
      const double norm = edge.cam2_from_cam1.translation().norm();
      if (norm > 0) edge.cam2_from_cam1.SetTranslation(edge.cam2_from_cam1.translation() / norm);
    }
  }
  const image_pair_t pair_id = ImagePairToPairId(edge.image_id1, edge.image_id2);
  THROW_CHECK_MSG(edge_index.count(pair_id) == 0, "duplicate view-graph edge");
  edge_index.emplace(pair_id, edges.size());
  edges.push_back(std::move(edge));
}

const SfmFrame& MapperState::FrameOf(image_t image_id) const {
  const auto it = images.find(image_id);
  THROW_CHECK_MSG(it != images.end(), "unknown image id " + std::to_string(image_id));
  const auto frame = frames.find(it->second.frame_id);
  THROW_CHECK_MSG(frame != frames.end(), "image without frame");
  return frame->second;
}

SE3 MapperState::CamFromWorld(image_t image_id) const {
  const SfmFrame& frame = FrameOf(image_id);
  return cam_from_rig.at(images.at(image_id).camera_id) * frame.rig_from_world;
}

Vec3 MapperState::ProjectionCenter(image_t image_id) const {
  return CamFromWorld(image_id).Inverse().translation();
}

bool MapperState::IsRegistered(image_t image_id) const {
  return FrameOf(image_id).registered;
}

size_t MapperState::NumRegisteredFrames() const {
  size_t n = 0;
  for (const auto& [id, frame] : frames) n += frame.registered ? 1 : 0;
  return n;
}

size_t MapperState::NumRegisteredImages() const {
  size_t n = 0;
  for (const auto& [id, frame] : frames) n += frame.registered ? frame.image_ids.size() : 0;
  return n;
}

bool ParseRigImageName(const std::string& name, int* camera_index, int64_t* stamp_ns) {
  static const std::regex kPattern(R"((^|.*/)cam([0-9]+)/data/([0-9]+)\.[A-Za-z0-9]+$)");
  std::smatch match;
  if (!std::regex_match(name, match, kPattern)) return false;
  try {
    *camera_index = std::stoi(match[2].str());
    *stamp_ns = std::stoll(match[3].str());
  } catch (const std::exception&) {
    return false;
  }
  return true;
}

namespace {

void CheckCamera(const Database& database, const Camera& camera) {
  const std::string where = "cameras record camera_id=" + std::to_string(camera.camera_id);
  if (!camera.VerifyParams()) {
    throw InputError(database.path(), where,
                     "camera model " + std::to_string(camera.model_id) + " with " +
                         std::to_string(camera.params.size()) +
                         " parameters is not a usable COLMAP camera");
  }
  if (camera.width == 0 || camera.height == 0) {
    throw InputError(database.path(), where, "image size is 0");
  }
  // Every focal length (f, or fx and fy) must be positive.
  const bool single_focal = CameraModelParamsInfo(camera.model_id).rfind("f,", 0) == 0;
  for (int i = 0; i < (single_focal ? 1 : 2); ++i) {
    if (!(camera.params[i] > 0)) {
      throw InputError(database.path(), where,
                       "focal length must be positive, found " +
                           std::to_string(camera.params[i]));
    }
  }
}

}  // namespace

bool LoadMapperStateOptions::Check() const {
  CHECK_OPTION_GT(prior_position_sigma, 0.0);
  CHECK_OPTION_GT(prior_rotation_sigma, 0.0);
  return true;
}

MapperState LoadMapperState(const Database& database, const Rig* rig,
                            const LoadMapperStateOptions& options) {
  THROW_CHECK_OPTIONS(options);
  MapperState state;
  state.has_rig = rig != nullptr;
  size_t num_without_prior_focal = 0;
  for (Camera& camera : database.ReadAllCameras()) {
    CheckCamera(database, camera);
    if (!camera.has_prior_focal_length) ++num_without_prior_focal;
    state.cameras.emplace(camera.camera_id, std::move(camera));
  }
  if (num_without_prior_focal > 0) {
    LogWarning(std::to_string(num_without_prior_focal) +
               " camera(s) without a prior focal length in " + database.path() +
               ": the global mapper relies on the stored intrinsics and refines them only in "
               "bundle adjustment");
  }

  std::map<camera_t, int> rig_index_of_camera;
  std::map<int64_t, frame_t> frame_of_stamp;
  std::vector<DbImage> db_images = database.ReadAllImages();
  if (rig != nullptr) {
    // Frame ids in stamp order.
    for (const DbImage& image : db_images) {
      int k = 0;
      int64_t ns = 0;
      if (!ParseRigImageName(image.name, &k, &ns)) {
        throw InputError(database.path(),
                         "images record image_id=" + std::to_string(image.image_id),
                         "with a rig, image names must end in camK/data/<ns>.<ext>, found '" +
                             image.name + "'");
      }
      frame_of_stamp.emplace(ns, 0);
    }
    frame_t next = 1;
    for (auto& [ns, id] : frame_of_stamp) id = next++;
  }

  for (const DbImage& db_image : db_images) {
    const std::string where = "images record image_id=" + std::to_string(db_image.image_id);
    const auto camera_it = state.cameras.find(db_image.camera_id);
    if (camera_it == state.cameras.end()) {
      throw InputError(database.path(), where,
                       "camera_id " + std::to_string(db_image.camera_id) + " does not exist");
    }
    const Camera& camera = camera_it->second;
    SfmImage image;
    image.image_id = db_image.image_id;
    image.camera_id = db_image.camera_id;
    image.name = db_image.name;

    if (rig != nullptr) {
      int k = 0;
      int64_t ns = 0;
      ParseRigImageName(image.name, &k, &ns);
      if (k < 0 || static_cast<size_t>(k) >= rig->cameras.size()) {
        throw InputError(database.path(), where,
                         "image '" + image.name + "' belongs to cam" + std::to_string(k) +
                             ", which the rig (" + std::to_string(rig->cameras.size()) +
                             " cameras) does not have");
      }
      const auto [it, inserted] = rig_index_of_camera.emplace(image.camera_id, k);
      if (!inserted && it->second != k) {
        throw InputError(database.path(), where,
                         "camera_id " + std::to_string(image.camera_id) +
                             " is used by images of cam" + std::to_string(it->second) +
                             " and cam" + std::to_string(k) +
                             "; each rig camera needs its own COLMAP camera");
      }
      state.cam_from_rig[image.camera_id] = rig->cameras[k].cam_from_imu;
      image.frame_id = frame_of_stamp.at(ns);
      SfmFrame& frame = state.frames[image.frame_id];
      frame.frame_id = image.frame_id;
      frame.stamp_ns = ns;
      frame.image_ids.push_back(image.image_id);
    } else {
      state.cam_from_rig[image.camera_id] = SE3::Identity();
      image.frame_id = image.image_id;
      SfmFrame& frame = state.frames[image.frame_id];
      frame.frame_id = image.frame_id;
      frame.image_ids.push_back(image.image_id);
    }

    const KeypointsBlob keypoints = database.ReadKeypoints(image.image_id);
    image.keypoints.resize(keypoints.rows());
    image.normalized.resize(keypoints.rows());
    for (Eigen::Index i = 0; i < keypoints.rows(); ++i) {
      image.keypoints[i] = Vec2(keypoints(i, 0), keypoints(i, 1));
      image.normalized[i] = camera.CamFromImg(image.keypoints[i]);
    }
    image.track_ids.assign(keypoints.rows(), -1);

    if (options.use_priors) {
      const bool rotation_ok = db_image.has_prior_rotation && db_image.prior_qvec.allFinite() &&
                               db_image.prior_qvec.norm() > 0.5;
      if (rotation_ok) {
        image.has_prior_rotation = true;
        const Vec4 q = db_image.prior_qvec.normalized();
        image.prior_cam_from_world_rotation = Quat(q(0), q(1), q(2), q(3));
      }
      if (db_image.has_prior_position && db_image.prior_position.allFinite() &&
          db_image.prior_coordinate_system != PriorCoordinateSystem::kWgs84) {
        image.has_prior_position = true;
        image.prior_position = db_image.prior_position;
        const Mat3& cov = db_image.prior_position_covariance;
        const bool cov_ok = cov.allFinite() && cov.isApprox(cov.transpose(), 1e-9) &&
                            Eigen::LLT<Mat3>(cov).info() == Eigen::Success;
        image.prior_position_covariance =
            cov_ok ? cov
                   : Mat3(Mat3::Identity() * options.prior_position_sigma *
                          options.prior_position_sigma);
      }
    }
    state.images.emplace(image.image_id, std::move(image));
  }
  if (rig != nullptr) {
    for (size_t k = 0; k < rig->cameras.size(); ++k) {
      const bool used = std::any_of(rig_index_of_camera.begin(), rig_index_of_camera.end(),
                                    [&](const auto& p) { return p.second == static_cast<int>(k); });
      if (!used) {
        LogWarning("rig camera cam" + std::to_string(k) + " has no image in " + database.path());
      }
    }
  }

  // Frame priors from the images' priors.
  for (auto& [frame_id, frame] : state.frames) {
    std::vector<Vec3> origins;
    Mat3 covariance = Mat3::Zero();
    for (const image_t image_id : frame.image_ids) {
      const SfmImage& image = state.images.at(image_id);
      const SE3& cam_from_rig = state.cam_from_rig.at(image.camera_id);
      if (image.has_prior_rotation && !frame.has_prior_rotation) {
        frame.has_prior_rotation = true;
        frame.prior_rig_from_world_rotation =
            (cam_from_rig.rotation().conjugate() * image.prior_cam_from_world_rotation)
                .normalized();
        frame.prior_rotation_sigma = options.prior_rotation_sigma;
      }
      if (!image.has_prior_position) continue;
      // Camera centre in the rig frame.
      const Vec3 center_in_rig = cam_from_rig.Inverse().translation();
      Mat3 cov = image.prior_position_covariance;
      Vec3 origin = image.prior_position;
      if (center_in_rig.norm() > 0) {
        if (frame.has_prior_rotation) {
          origin -= frame.prior_rig_from_world_rotation.conjugate() * center_in_rig;
        } else {
          // Unknown orientation: the lever arm becomes position uncertainty.
          cov += Mat3::Identity() * center_in_rig.squaredNorm();
        }
      }
      origins.push_back(origin);
      covariance += cov;
    }
    if (!origins.empty()) {
      Vec3 mean = Vec3::Zero();
      for (const Vec3& o : origins) mean += o;
      frame.has_prior_position = true;
      frame.prior_position = mean / static_cast<double>(origins.size());
      // The images of one frame share one pose: their priors are not
      // independent, so the mean keeps the mean covariance.
      frame.prior_position_covariance = covariance / static_cast<double>(origins.size());
    }
  }
  return state;
}

Reconstruction ToReconstruction(const MapperState& state, const std::string& image_path) {
  Reconstruction reconstruction;
  for (const auto& [camera_id, camera] : state.cameras) reconstruction.AddCamera(camera);
  for (const auto& [image_id, sfm_image] : state.images) {
    if (!state.IsRegistered(image_id)) continue;
    Image image;
    image.image_id = image_id;
    image.name = sfm_image.name;
    image.camera_id = sfm_image.camera_id;
    image.SetCamFromWorld(state.CamFromWorld(image_id));
    image.points2D.resize(sfm_image.keypoints.size());
    for (size_t i = 0; i < sfm_image.keypoints.size(); ++i) {
      image.points2D[i].xy = sfm_image.keypoints[i];
    }
    reconstruction.AddImage(std::move(image));
  }

  // Colours: mean over each track's observations.
  std::vector<Vec3> color_sum(state.tracks.size(), Vec3::Zero());
  std::vector<int> color_count(state.tracks.size(), 0);
  if (!image_path.empty()) {
    // Decoding the images dominates: in parallel, one colour sample list per
    // image, summed in image order afterwards (deterministic).
    std::vector<const SfmImage*> registered;
    for (const auto& [image_id, sfm_image] : state.images) {
      if (state.IsRegistered(image_id)) registered.push_back(&sfm_image);
    }
    std::vector<std::vector<std::pair<int, Vec3>>> samples(registered.size());
    std::vector<char> unreadable(registered.size(), 0);
    tbb::parallel_for(size_t{0}, registered.size(), [&](size_t k) {
      const SfmImage& sfm_image = *registered[k];
      const cv::Mat bgr = ReadImageFile(image_path + "/" + sfm_image.name, ImageReadMode::kColor);
      if (bgr.empty()) {
        unreadable[k] = 1;
        return;
      }
      for (size_t i = 0; i < sfm_image.track_ids.size(); ++i) {
        const int track_id = sfm_image.track_ids[i];
        if (track_id < 0 || !state.tracks[track_id].triangulated) continue;
        // COLMAP pixel centres are at +0.5.
        const int x = static_cast<int>(std::floor(sfm_image.keypoints[i].x()));
        const int y = static_cast<int>(std::floor(sfm_image.keypoints[i].y()));
        if (x < 0 || y < 0 || x >= bgr.cols || y >= bgr.rows) continue;
        const cv::Vec3b c = bgr.at<cv::Vec3b>(y, x);
        samples[k].emplace_back(track_id, Vec3(c[2], c[1], c[0]));
      }
    });
    for (size_t k = 0; k < registered.size(); ++k) {
      if (unreadable[k]) {
        LogWarning("cannot read " + image_path + "/" + registered[k]->name +
                   " for point colours; they stay black");
      }
      for (const auto& [track_id, rgb] : samples[k]) {
        color_sum[track_id] += rgb;
        ++color_count[track_id];
      }
    }
  }

  for (size_t t = 0; t < state.tracks.size(); ++t) {
    const Track& track = state.tracks[t];
    if (!track.triangulated || track.elements.size() < 2) continue;
    Point3D point;
    point.xyz = track.xyz;
    point.error = track.error;
    point.track = track.elements;
    if (color_count[t] > 0) {
      const Vec3 c = color_sum[t] / color_count[t];
      for (int k = 0; k < 3; ++k) {
        point.color[k] = static_cast<uint8_t>(std::clamp(std::round(c(k)), 0.0, 255.0));
      }
    }
    reconstruction.AddPoint3DWithTrack(std::move(point));
  }

  if (state.has_rig && reconstruction.NumImages() > 0) {
    // COLMAP 3.12 rig: the frame is the reference camera's frame.
    // Reference: the rig camera with the smallest camera id.
    const camera_t ref_camera = state.cam_from_rig.begin()->first;
    const SE3 ref_from_rig = state.cam_from_rig.at(ref_camera);
    ModelRig model_rig;
    model_rig.rig_id = 1;
    model_rig.has_ref_sensor = true;
    model_rig.ref_sensor = SensorId{SensorType::kCamera, ref_camera};
    for (const auto& [camera_id, cam_from_rig] : state.cam_from_rig) {
      if (camera_id == ref_camera) continue;
      RigSensor sensor;
      sensor.sensor = SensorId{SensorType::kCamera, camera_id};
      sensor.has_pose = true;
      const SE3 sensor_from_ref = cam_from_rig * ref_from_rig.Inverse();
      const Quat& q = sensor_from_ref.rotation();
      sensor.qvec = Vec4(q.w(), q.x(), q.y(), q.z());
      sensor.tvec = sensor_from_ref.translation();
      model_rig.sensors.push_back(sensor);
    }
    reconstruction.Rigs().push_back(model_rig);
    for (const auto& [frame_id, frame] : state.frames) {
      if (!frame.registered) continue;
      ModelFrame model_frame;
      model_frame.frame_id = frame_id;
      model_frame.rig_id = 1;
      const SE3 ref_from_world = ref_from_rig * frame.rig_from_world;
      const Quat& q = ref_from_world.rotation();
      model_frame.qvec = Vec4(q.w(), q.x(), q.y(), q.z());
      model_frame.tvec = ref_from_world.translation();
      for (const image_t image_id : frame.image_ids) {
        model_frame.data.push_back(FrameData{SensorId{SensorType::kCamera,
                                                      state.images.at(image_id).camera_id},
                                             image_id});
      }
      reconstruction.Frames().push_back(model_frame);
    }
  }
  return reconstruction;
}

}  // namespace colmap
}  // namespace lisfm
