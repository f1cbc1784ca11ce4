#include "colmap_ext/io/rig_config.h"

#include <gtest/gtest.h>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

TEST(RigConfig, RelativePosesAreCamFromRefCamera) {
  Rig rig;
  for (int i = 0; i < 3; ++i) {
    RigCamera camera;
    camera.name = "cam" + std::to_string(i);
    camera.cam_from_imu = test::RandomPose(3.0, 0.3);
    rig.cameras.push_back(camera);
  }
  const RigConfig config = RigConfigFromRig(rig, {4, 5, 6}, {}, 1);
  EXPECT_EQ(config.ref_camera_id, 5u);
  ASSERT_EQ(config.cameras.size(), 3u);
  EXPECT_EQ(config.cameras[0].image_prefix, "cam0/data/");
  test::TempDir dir;
  WriteRigConfigs({config}, dir.File("rig.json"));
  const auto read = ReadRigConfigs(dir.File("rig.json"));
  ASSERT_EQ(read.size(), 1u);
  ASSERT_EQ(read[0].cameras.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const RigConfigCamera& c = read[0].cameras[i];
    EXPECT_EQ(c.camera_id, static_cast<camera_t>(4 + i));
    ASSERT_TRUE(c.has_rel_pose);
    const SE3 cam_from_rig(Quat(c.rel_qvec(0), c.rel_qvec(1), c.rel_qvec(2), c.rel_qvec(3)),
                           c.rel_tvec);
    // cam_i_from_imu must equal cam_i_from_ref * ref_from_imu; JSON keeps
    // doubles to the last digit, so only rounding of the composition remains.
    EXPECT_TRUE(test::PosesNear(cam_from_rig * rig.cameras[1].cam_from_imu,
                                rig.cameras[i].cam_from_imu, 1e-12, 1e-12));
  }
  EXPECT_EQ(read[0].cameras[1].rel_qvec, Vec4(1, 0, 0, 0));
}

TEST(RigConfig, BadInputsAreInputErrors) {
  Rig rig;
  rig.cameras.resize(2);
  EXPECT_THROW(RigConfigFromRig(rig, {1}), InputError);
  EXPECT_THROW(RigConfigFromRig(rig, {1, 2}, {}, 2), InputError);
  test::TempDir dir;
  test::WriteText(dir.File("bad.json"), "[{\"cameras\": []}]");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadRigConfigs(dir.File("bad.json")); }, {"bad.json:rig 0"}));
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
