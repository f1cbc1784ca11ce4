// `lisfm global_mapper` on a simulated HILTI-style rig recording:
// images rendered by the simulator for three of the five real HILTI 2022
// cameras, stock COLMAP SIFT extraction and exhaustive matching, pose priors
// perturbed by 2 cm / 0.5 deg (what a LiDAR stage gives) and LiDAR relative
// constraints perturbed by 5 mm / 0.1 deg. Target: every image registered,
// rotation error <= 0.05 deg and position error <= 5 mm after an SE(3)
// alignment (metric, no scale), and the model in the priors' frame.
#include <cmath>
#include <iomanip>
#include <map>
#include <random>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "colmap_ext/io/database.h"
#include "core/io/lidar_constraints_io.h"
#include "colmap_ext/io/model_io.h"
#include "core/file_utils.h"
#include "core/io/rig_io.h"
#include "sim/camera_simulator.h"
#include "sim/motion.h"
#include "tests/common/sim_walks.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

TEST(GlobalMapperSim, RigWithPriorsAndConstraintsOnRenderedImages) {
  LISFM_REQUIRE_SHARED_DATA("hilti_exp4_small/calibration");
  std::string out;
  if (test::RunCommand("colmap help > /dev/null 2>&1", &out) != 0) {
    GTEST_SKIP() << "colmap binary not found";
  }
  const std::string calibration = test::SharedData("hilti_exp4_small/calibration");
  const Rig rig = LoadHiltiCalibration(calibration);
  const auto scene = sim::Scene::Generate(sim::DefaultSceneOptions("office"));
  const sim::SplineTrajectory walk =
      sim::GenerateWalking(scene->route(), 40.0, 0, 1, ThreeStopWalk(), nullptr);
  test::TempDir dir;
  const std::vector<int> cams = {0, 1, 3};
  const int frames = 8;  // 0.4 s apart while walking: 24 images
  std::vector<TimestampNs> stamps;
  for (int f = 0; f < frames; ++f) stamps.push_back(SecondsToNs(5.0 + 0.4 * f));
  std::map<std::string, SE3> gt_cam_from_world;
  sim::CameraSimOptions options;
  for (int c : cams) {
    const sim::CameraRenderer renderer(*scene, rig.cameras[c].model, sim::TextureOptions(),
                                       options);
    const std::string folder = "cam" + std::to_string(c) + "/data";
    CreateDirs(dir.File("images/" + folder));
    std::ofstream list(dir.File("list" + std::to_string(c) + ".txt"));
    for (int f = 0; f < frames; ++f) {
      const SE3 world_from_cam = walk.Pose(stamps[f]) * rig.cameras[c].cam_from_imu.Inverse();
      const std::string name = folder + "/" + std::to_string(stamps[f]) + ".png";
      cv::imwrite(dir.File("images/" + name), renderer.Render(world_from_cam, f * 10 + c));
      list << name << "\n";
      gt_cam_from_world[name] = world_from_cam.Inverse();
    }
  }
  // Stock COLMAP: one OPENCV_FISHEYE camera per rig camera (the calibration).
  const std::string env = "QT_QPA_PLATFORM=offscreen ";
  const std::string db = dir.File("db.db");
  for (int c : cams) {
    const CameraModel& m = rig.cameras[c].model;
    std::ostringstream params;
    params << std::setprecision(12) << m.fx << "," << m.fy << "," << m.cx + 0.5 << ","
           << m.cy + 0.5 << "," << m.distortion_coeffs[0] << "," << m.distortion_coeffs[1]
           << "," << m.distortion_coeffs[2] << "," << m.distortion_coeffs[3];
    ASSERT_EQ(test::RunCommand(
                  env + "colmap feature_extractor --database_path " + db + " --image_path " +
                      dir.File("images") + " --image_list_path " +
                      dir.File("list" + std::to_string(c) + ".txt") +
                      " --ImageReader.camera_model OPENCV_FISHEYE --ImageReader.single_camera 1"
                      " --ImageReader.camera_params " + params.str() +
                      " --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads 2"
                      " --SiftExtraction.max_num_features 2048"
                      " --SiftExtraction.first_octave 0 2>&1",
                  &out),
              0)
        << out;
  }
  ASSERT_EQ(test::RunCommand(env + "colmap exhaustive_matcher --database_path " + db +
                                 " --SiftMatching.use_gpu 0 --SiftMatching.num_threads 2 2>&1",
                             &out),
            0)
      << out;

  // Priors: one perturbation of the rig (IMU) pose per frame, 2 cm / 0.5 deg
  // per axis, propagated to the cameras; LiDAR constraints between
  // consecutive frames, 5 mm / 0.1 deg per axis.
  std::mt19937 rng(3);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto noise = [&](double sigma_rot, double sigma_pos) {
    Vec6 xi;
    for (int i = 0; i < 3; ++i) xi(i) = sigma_rot * normal(rng);
    for (int i = 3; i < 6; ++i) xi(i) = sigma_pos * normal(rng);
    return SE3::Exp(xi);
  };
  std::map<TimestampNs, SE3> noisy_world_from_imu;
  for (const TimestampNs t : stamps) {
    noisy_world_from_imu[t] = walk.Pose(t) * noise(0.5 * kDegToRad, 0.0);
    noisy_world_from_imu[t].SetTranslation(walk.Pose(t).translation() +
                                           Vec3(normal(rng), normal(rng), normal(rng)) * 0.02);
  }
  {
    colmap::Database database(db, colmap::Database::OpenMode::kReadWrite);
    for (colmap::DbImage image : database.ReadAllImages()) {
      const size_t k = image.name.find("cam");
      ASSERT_NE(k, std::string::npos);
      const int c = image.name[k + 3] - '0';
      const TimestampNs t = std::stoll(image.name.substr(image.name.rfind('/') + 1));
      const SE3 cam_from_world =
          rig.cameras[c].cam_from_imu * noisy_world_from_imu.at(t).Inverse();
      const Quat& q = cam_from_world.rotation();
      image.has_prior_rotation = true;
      image.prior_qvec = Vec4(q.w(), q.x(), q.y(), q.z());
      image.has_prior_position = true;
      image.prior_position = cam_from_world.Inverse().translation();
      image.prior_position_covariance = Mat3::Identity() * 0.02 * 0.02;
      database.UpdateImage(image);
    }
  }
  std::vector<LidarConstraintRecord> constraints;
  const double sr = 0.1 * kDegToRad, st = 0.005;
  for (int f = 0; f + 1 < frames; ++f) {
    LidarConstraintRecord r;
    r.t_i_ns = stamps[f];
    r.t_j_ns = stamps[f + 1];
    r.i_from_j = walk.Pose(stamps[f]).Inverse() * walk.Pose(stamps[f + 1]) * noise(sr, st);
    r.covariance = Mat6::Zero();
    r.covariance.diagonal() << sr * sr, sr * sr, sr * sr, st * st, st * st, st * st;
    constraints.push_back(r);
  }
  WriteLidarConstraints(constraints, dir.File("constraints.txt"));

  ASSERT_EQ(test::RunCommand(test::LisfmBinary() + " global_mapper --database_path " + db +
                                 " --image_path " + dir.File("images") + " --output_path " +
                                 dir.File("sparse") + " --rig_path " + calibration +
                                 " --lidar_constraints_path " + dir.File("constraints.txt") +
                                 " --Priors.rotation_sigma 0.0087"
                                 " --BundleAdjustment.refine_focal_length 0"
                                 " --BundleAdjustment.refine_extra_params 0 2>&1",
                             &out),
            0)
      << out;
  const colmap::Reconstruction model = colmap::ReadModel(dir.File("sparse/0"));
  EXPECT_EQ(model.NumImages(), cams.size() * frames);
  std::vector<std::string> names;
  Eigen::Matrix3Xd est(3, model.NumImages()), gt(3, model.NumImages());
  for (const colmap::Image& image : model.Images()) {
    ASSERT_TRUE(gt_cam_from_world.count(image.name)) << image.name;
    est.col(names.size()) = image.ProjectionCenter();
    gt.col(names.size()) = gt_cam_from_world.at(image.name).Inverse().translation();
    names.push_back(image.name);
  }
  const Sim3 align = AlignUmeyama(est, gt, /*estimate_scale=*/false);
  double max_rot_deg = 0.0, max_pos = 0.0, max_pos_unaligned = 0.0;
  for (size_t i = 0; i < names.size(); ++i) {
    const colmap::Image& image = model.Images()[i];
    max_pos = std::max(max_pos, (align * est.col(i) - gt.col(i)).norm());
    max_pos_unaligned = std::max(max_pos_unaligned, (est.col(i) - gt.col(i)).norm());
    const Quat r_est = image.CamFromWorld().rotation() * align.pose.rotation().conjugate();
    max_rot_deg = std::max(
        max_rot_deg,
        so3::AngularDistance(r_est, gt_cam_from_world.at(names[i]).rotation()) / kDegToRad);
  }
  std::cout << "global_mapper on rendered rig images: max rotation error " << max_rot_deg
            << " deg, max position error " << max_pos * 1000 << " mm (SE3), "
            << max_pos_unaligned * 1000 << " mm without alignment\n";
  EXPECT_LT(max_rot_deg, 0.05);
  EXPECT_LT(max_pos, 0.005);
  // In the priors' frame without alignment: the priors fix the gauge, so the
  // whole model may be off by their mean error — 2 cm / sqrt(8 frames) = 7 mm
  // per axis plus 0.5 deg / sqrt(8) of rotation at ~3 m (9 mm); 5 cm is ~3
  // sigma of the 3D offset. (Measured: 19 mm.)
  EXPECT_LT(max_pos_unaligned, 0.05);
}

}  // namespace
}  // namespace lisfm
