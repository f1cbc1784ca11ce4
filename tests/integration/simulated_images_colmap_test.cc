// Stock COLMAP on rendered office images (slow): feature_extractor (CPU SIFT,
// 2048 features, first_octave 0), exhaustive_matcher, mapper. Proves that the
// rendered images are good enough for SfM: >= 90 % registered and camera
// centres within 5 cm of the ground truth after a similarity alignment.
#include <fstream>
#include <map>
#include <iomanip>
#include <sstream>

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "core/file_utils.h"
#include "core/io/rig_io.h"
#include "sim/camera_simulator.h"
#include "sim/motion.h"
#include "tests/common/sim_walks.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace sim {
namespace {

TEST(ColmapEndToEnd, StockColmapReconstructsRenderedImages) {
  LISFM_REQUIRE_SHARED_DATA("hilti_exp4_small/calibration");
  std::string out;
  if (test::RunCommand("colmap help > /dev/null 2>&1", &out) != 0) {
    GTEST_SKIP() << "colmap binary not found";
  }
  const Rig rig = LoadHiltiCalibration(test::SharedData("hilti_exp4_small/calibration"));
  const auto scene = Scene::Generate(DefaultSceneOptions("office"));
  const SplineTrajectory walk =
      GenerateWalking(scene->route(), 40.0, 0, 1, ThreeStopWalk(), nullptr);
  test::TempDir dir;
  const std::vector<int> cams = {0, 1, 3};
  const int frames = 8;  // 8 rig frames x 3 cameras = 24 images, 0.4 s apart while walking
  std::map<std::string, Vec3> centres;
  CameraSimOptions options;
  for (int c : cams) {
    const CameraRenderer renderer(*scene, rig.cameras[c].model, TextureOptions(), options);
    CreateDirs(dir.File("images/cam" + std::to_string(c)));
    std::ofstream list(dir.File("list" + std::to_string(c) + ".txt"));
    for (int f = 0; f < frames; ++f) {
      const TimestampNs t = SecondsToNs(5.0 + 0.4 * f);
      const SE3 world_from_cam = walk.Pose(t) * rig.cameras[c].cam_from_imu.Inverse();
      const std::string name = "cam" + std::to_string(c) + "/" + std::to_string(f) + ".png";
      cv::imwrite(dir.File("images/" + name), renderer.Render(world_from_cam, f * 10 + c));
      list << name << "\n";
      centres[name] = world_from_cam.translation();
    }
  }
  const std::string env = "QT_QPA_PLATFORM=offscreen ";
  const std::string db = dir.File("db.db");
  for (int c : cams) {
    const CameraModel& m = rig.cameras[c].model;
    // COLMAP's pixel centres are at +0.5 (core/camera_model.h).
    std::ostringstream params;
    params << std::setprecision(12) << m.fx << "," << m.fy << "," << m.cx + 0.5 << ","
           << m.cy + 0.5 << "," << m.distortion_coeffs[0] << "," << m.distortion_coeffs[1]
           << "," << m.distortion_coeffs[2] << "," << m.distortion_coeffs[3];
    const std::string cmd =
        env + "colmap feature_extractor --database_path " + db + " --image_path " +
        dir.File("images") + " --image_list_path " + dir.File("list" + std::to_string(c) + ".txt") +
        " --ImageReader.camera_model OPENCV_FISHEYE --ImageReader.single_camera 1"
        " --ImageReader.camera_params " + params.str() +
        " --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads 2"
        " --SiftExtraction.max_num_features 2048 --SiftExtraction.first_octave 0 2>&1";
    ASSERT_EQ(test::RunCommand(cmd, &out), 0) << out;
  }
  ASSERT_EQ(test::RunCommand(env + "colmap exhaustive_matcher --database_path " + db +
                                 " --SiftMatching.use_gpu 0 --SiftMatching.num_threads 2 2>&1",
                             &out), 0) << out;
  CreateDirs(dir.File("sparse"));
  ASSERT_EQ(test::RunCommand(env + "colmap mapper --database_path " + db + " --image_path " +
                                 dir.File("images") + " --output_path " + dir.File("sparse") +
                                 " --Mapper.num_threads 2 --Mapper.ba_refine_focal_length 0"
                                 " --Mapper.ba_refine_principal_point 0"
                                 " --Mapper.ba_refine_extra_params 0 2>&1",
                             &out), 0) << out;
  CreateDirs(dir.File("txt"));
  ASSERT_EQ(test::RunCommand("colmap model_converter --input_path " + dir.File("sparse/0") +
                                 " --output_path " + dir.File("txt") +
                                 " --output_type TXT 2>&1",
                             &out), 0) << out;
  // images.txt: IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, then a 2D-point line.
  LineReader reader(dir.File("txt/images.txt"));
  std::string line;
  std::vector<Vec3> estimated, truth;
  bool pose_line = true;
  while (reader.Next(&line)) {
    if (line.empty() || line[0] == '#') continue;
    if (pose_line) {
      std::istringstream s(line);
      int id, cam;
      double qw, qx, qy, qz, tx, ty, tz;
      std::string name;
      s >> id >> qw >> qx >> qy >> qz >> tx >> ty >> tz >> cam >> name;
      const SE3 cam_from_world(Quat(qw, qx, qy, qz).normalized(), Vec3(tx, ty, tz));
      ASSERT_TRUE(centres.count(name)) << name;
      estimated.push_back(cam_from_world.Inverse().translation());
      truth.push_back(centres[name]);
    }
    pose_line = !pose_line;
  }
  const size_t total = cams.size() * frames;
  EXPECT_GE(estimated.size(), (total * 9 + 9) / 10) << "registered " << estimated.size();
  ASSERT_GE(estimated.size(), 3u);
  Eigen::Matrix3Xd src(3, estimated.size()), dst(3, truth.size());
  for (size_t i = 0; i < estimated.size(); ++i) {
    src.col(i) = estimated[i];
    dst.col(i) = truth[i];
  }
  const Sim3 sim3 = AlignUmeyama(src, dst, true);
  for (size_t i = 0; i < estimated.size(); ++i) {
    EXPECT_LT((sim3 * estimated[i] - truth[i]).norm(), 0.05) << "image " << i;
  }
}

}  // namespace
}  // namespace sim
}  // namespace lisfm
