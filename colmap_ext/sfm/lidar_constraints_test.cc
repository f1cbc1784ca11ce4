#include "colmap_ext/sfm/lidar_constraints.h"

#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace {

// n records (i, j) = (k, k + 2) by index, or stamped 0.3 s apart.
std::vector<LidarConstraintRecord> Records(bool with_stamps, int n) {
  std::vector<LidarConstraintRecord> records(n);
  for (int k = 0; k < n; ++k) {
    LidarConstraintRecord& record = records[k];
    record.has_stamps = with_stamps;
    record.t_i_ns = with_stamps ? 1650000000000000000 + 100000000LL * k : -1;
    record.t_j_ns = with_stamps ? record.t_i_ns + 300000000 : -1;
    record.index_i = with_stamps ? -1 : k;
    record.index_j = with_stamps ? -1 : k + 2;
    record.i_from_j = test::RandomPose();
    record.covariance = (k + 1) * 1e-4 * Mat6::Identity();
  }
  return records;
}

MapperState StateWithFrames(const std::vector<std::pair<frame_t, int64_t>>& frames) {
  MapperState state;
  for (const auto& [frame_id, stamp_ns] : frames) {
    SfmFrame frame;
    frame.frame_id = frame_id;
    frame.stamp_ns = stamp_ns;
    state.frames[frame_id] = frame;
  }
  return state;
}

TEST(LidarConstraints, AttachByStampWithinTolerance) {
  MapperState state = StateWithFrames({{10, 1000000000}, {11, 1200000000}, {12, 1400000000}});
  auto records = Records(true, 4);
  records[0].t_i_ns = 1000000000 + 500000;  // 0.5 ms late: attaches to frame 10
  records[0].t_j_ns = 1400000000 - 999999;  // just inside 1 ms: frame 12
  records[1].t_i_ns = 1200000000;
  records[1].t_j_ns = 1000000000 - 1000000;  // exactly 1 ms early: frame 10 (inclusive)
  records[2].t_i_ns = 1200000000;
  records[2].t_j_ns = 1400000000 + 1000001;  // 1 ms + 1 ns late: no frame
  records[3].t_i_ns = 1100000000;            // between frames: no frame
  records[3].t_j_ns = 1200000000;
  EXPECT_EQ(AttachLidarConstraints(records, kDefaultLidarConstraintToleranceNs, &state), 2u);
  ASSERT_EQ(state.lidar_constraints.size(), 2u);
  EXPECT_EQ(state.lidar_constraints[0].frame_id1, 10u);
  EXPECT_EQ(state.lidar_constraints[0].frame_id2, 12u);
  EXPECT_EQ(state.lidar_constraints[1].frame_id1, 11u);
  EXPECT_EQ(state.lidar_constraints[1].frame_id2, 10u);
  EXPECT_TRUE(test::PosesNear(state.lidar_constraints[0].rig1_from_rig2, records[0].i_from_j,
                              1e-12, 0.0));
  EXPECT_EQ(state.lidar_constraints[1].covariance, records[1].covariance);
  // A zero tolerance only accepts exact stamps (only record 3 has them now).
  records[3].t_i_ns = 1200000000;
  records[3].t_j_ns = 1400000000;
  MapperState exact = StateWithFrames({{10, 1000000000}, {11, 1200000000}, {12, 1400000000}});
  EXPECT_EQ(AttachLidarConstraints(records, 0, &exact), 1u);
}

TEST(LidarConstraints, AttachByKeyframeIndex) {
  auto records = Records(false, 3);  // (0, 2), (1, 3), (2, 4)
  // Frames without stamps: frame-id order, index 0 -> frame 3, 2 -> frame 7.
  MapperState unstamped = StateWithFrames({{3, -1}, {5, -1}, {7, -1}, {9, -1}});
  EXPECT_EQ(AttachLidarConstraints(records, kDefaultLidarConstraintToleranceNs, &unstamped), 2u);
  ASSERT_EQ(unstamped.lidar_constraints.size(), 2u);
  EXPECT_EQ(unstamped.lidar_constraints[0].frame_id1, 3u);
  EXPECT_EQ(unstamped.lidar_constraints[0].frame_id2, 7u);
  EXPECT_EQ(unstamped.lidar_constraints[1].frame_id1, 5u);
  EXPECT_EQ(unstamped.lidar_constraints[1].frame_id2, 9u);
  // All frames stamped: stamp order (frame 2 is the earliest).
  MapperState stamped = StateWithFrames({{1, 300}, {2, 100}, {3, 200}});
  EXPECT_EQ(AttachLidarConstraints(records, 0, &stamped), 1u);
  ASSERT_EQ(stamped.lidar_constraints.size(), 1u);
  EXPECT_EQ(stamped.lidar_constraints[0].frame_id1, 2u);
  EXPECT_EQ(stamped.lidar_constraints[0].frame_id2, 1u);
}

}  // namespace
}  // namespace colmap
}  // namespace lisfm
