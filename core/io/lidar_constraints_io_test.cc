#include "core/io/lidar_constraints_io.h"

#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/errors.h"
#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

Mat6 RandomCovariance() {
  std::normal_distribution<double> normal(0.0, 1e-3);
  Mat6 a;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) a(r, c) = normal(test::Rng());
  }
  return a * a.transpose() + 1e-8 * Mat6::Identity();
}

std::vector<LidarConstraintRecord> RandomRecords(bool with_stamps, int n) {
  std::vector<LidarConstraintRecord> records;
  for (int k = 0; k < n; ++k) {
    LidarConstraintRecord record;
    record.has_stamps = with_stamps;
    if (with_stamps) {
      record.t_i_ns = 1650000000000000000 + 100000000LL * k;
      record.t_j_ns = record.t_i_ns + 300000000;
    } else {
      record.index_i = k;
      record.index_j = k + 2;
    }
    record.i_from_j = test::RandomPose();
    record.covariance = RandomCovariance();
    records.push_back(record);
  }
  return records;
}

void ExpectSameRecords(const std::vector<LidarConstraintRecord>& expected,
                       const std::vector<LidarConstraintRecord>& actual) {
  ASSERT_EQ(expected.size(), actual.size());
  for (size_t k = 0; k < expected.size(); ++k) {
    EXPECT_EQ(expected[k].has_stamps, actual[k].has_stamps);
    if (expected[k].has_stamps) {
      EXPECT_EQ(expected[k].t_i_ns, actual[k].t_i_ns);
      EXPECT_EQ(expected[k].t_j_ns, actual[k].t_j_ns);
    } else {
      EXPECT_EQ(expected[k].index_i, actual[k].index_i);
      EXPECT_EQ(expected[k].index_j, actual[k].index_j);
    }
    // 17 significant digits round-trip doubles exactly; the GTSFM path goes
    // through a rotation matrix and back (~1e-15).
    EXPECT_TRUE(test::PosesNear(expected[k].i_from_j, actual[k].i_from_j, 1e-13, 1e-13));
    EXPECT_LE((expected[k].covariance - actual[k].covariance).cwiseAbs().maxCoeff(),
              1e-15 * expected[k].covariance.cwiseAbs().maxCoeff());
  }
}

TEST(LidarConstraintsIo, LisfmFormatRoundTrip) {
  test::TempDir dir;
  const auto records = RandomRecords(true, 5);
  WriteLidarConstraints(records, dir.File("c.txt"));
  const std::string text = ReadFile(dir.File("c.txt"));
  EXPECT_EQ(text[0], '#');
  // One header of 3 comment lines + 5 records with 30 fields each.
  const auto lines = SplitString(text, "\n");
  ASSERT_EQ(lines.size(), 8u);
  EXPECT_EQ(SplitString(lines[3], " ").size(), 30u);
  ExpectSameRecords(records, ReadLidarConstraints(dir.File("c.txt")));
}

TEST(LidarConstraintsIo, GtsfmFormatRoundTrip) {
  test::TempDir dir;
  const auto records = RandomRecords(false, 4);
  WriteLidarConstraints(records, dir.File("c.txt"));
  const auto lines = SplitString(ReadFile(dir.File("c.txt")), "\n");
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(SplitString(lines[0], " ").size(), 75u);
  ExpectSameRecords(records, ReadLidarConstraints(dir.File("c.txt")));
}

TEST(LidarConstraintsIo, EmptyAndCommentOnlyFiles) {
  test::TempDir dir;
  test::WriteText(dir.File("c.txt"), "# nothing\n\n   \n");
  EXPECT_TRUE(ReadLidarConstraints(dir.File("c.txt")).empty());
  WriteLidarConstraints({}, dir.File("d.txt"));
  EXPECT_TRUE(ReadLidarConstraints(dir.File("d.txt")).empty());
  EXPECT_THROW(ReadLidarConstraints(dir.File("missing.txt")), InputError);
}

TEST(LidarConstraintsIo, GtsfmFloatIndicesAndNoCounts) {
  // numpy.savetxt writes indices as floats; the 25 counts are optional.
  test::TempDir dir;
  std::string line = "0.000000000000000000e+00 3.000000000000000000e+00";
  for (const double v : {1., 0., 0., 0.5, 0., 1., 0., 0.25, 0., 0., 1., -1.}) {
    line += " " + std::to_string(v);
  }
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) line += r == c ? " 1e-4" : " 0";
  }
  test::WriteText(dir.File("c.txt"), line + "\n");
  const auto records = ReadLidarConstraints(dir.File("c.txt"));
  ASSERT_EQ(records.size(), 1u);
  EXPECT_FALSE(records[0].has_stamps);
  EXPECT_EQ(records[0].index_i, 0);
  EXPECT_EQ(records[0].index_j, 3);
  EXPECT_TRUE(records[0].i_from_j.translation().isApprox(Vec3(0.5, 0.25, -1.0)));
  EXPECT_DOUBLE_EQ(records[0].covariance(4, 4), 1e-4);
}

// The real GTSFM HILTI file: 3 constraints between keyframes 0-2.
TEST(LidarConstraintsIo, ReadsGtsfmHiltiFile) {
  LISFM_REQUIRE_SHARED_DATA("hilti_exp4_small/lidar/constraints.txt");
  const auto records =
      ReadLidarConstraints(test::SharedData("hilti_exp4_small/lidar/constraints.txt"));
  ASSERT_EQ(records.size(), 3u);
  const std::vector<std::pair<int64_t, int64_t>> expected_pairs = {{1, 2}, {0, 2}, {0, 1}};
  for (size_t k = 0; k < records.size(); ++k) {
    EXPECT_FALSE(records[k].has_stamps);
    EXPECT_EQ(records[k].index_i, expected_pairs[k].first);
    EXPECT_EQ(records[k].index_j, expected_pairs[k].second);
  }
  // Values of the first line: t is the 4th column of the 3x4 matrix, the
  // covariance is the full 6x6 (row-major) that follows.
  EXPECT_DOUBLE_EQ(records[0].i_from_j.translation().x(), -0.00197101916043594);
  EXPECT_DOUBLE_EQ(records[0].i_from_j.translation().y(), -0.00313535578160279);
  EXPECT_DOUBLE_EQ(records[0].i_from_j.translation().z(), -0.00461651519089804);
  EXPECT_DOUBLE_EQ(records[0].covariance(0, 0), 3.66063230799257e-05);
  EXPECT_DOUBLE_EQ(records[0].covariance(0, 1), 9.9545265818141e-06);
  EXPECT_DOUBLE_EQ(records[0].covariance(5, 5), 3.35653839569578e-05);
  // R(1, 2) of the first line is -0.0117176535308903.
  EXPECT_NEAR(records[0].i_from_j.RotationMatrix()(1, 2), -0.0117176535308903, 1e-12);

  // Direction check against the FAST-LIO2 keyframe poses (world_from_imu,
  // g2o VERTEX_SE3:QUAT x y z qx qy qz qw) that GTSFM uses with these
  // constraints: i_from_j ~= pose_i^-1 * pose_j. GTSFM's own inlier gate is
  // 4 cm / 5 deg; the constraints agree with the odometry far better.
  LISFM_REQUIRE_SHARED_DATA("hilti_exp4_small/lidar/fastlio2.g2o");
  LineReader reader(test::SharedData("hilti_exp4_small/lidar/fastlio2.g2o"));
  std::map<int64_t, SE3> world_from_keyframe;
  std::string line;
  while (reader.Next(&line) && world_from_keyframe.size() < 3) {
    const auto f = SplitString(line, " ");
    ASSERT_EQ(f.size(), 9u);
    const Quat q(std::stod(f[8]), std::stod(f[5]), std::stod(f[6]), std::stod(f[7]));
    world_from_keyframe[std::stoll(f[1])] =
        SE3(q.normalized(), Vec3(std::stod(f[2]), std::stod(f[3]), std::stod(f[4])));
  }
  for (const auto& record : records) {
    const SE3 odometry = world_from_keyframe.at(record.index_i).Inverse() *
                         world_from_keyframe.at(record.index_j);
    EXPECT_TRUE(test::PosesNear(record.i_from_j, odometry, 5.0 * M_PI / 180.0, 0.04));
    // The reversed reading (j_from_i) agrees worse with the odometry.
    const double error = (record.i_from_j.translation() - odometry.translation()).norm();
    const double reversed_error =
        (record.i_from_j.Inverse().translation() - odometry.translation()).norm();
    EXPECT_LT(error, reversed_error) << error << " vs " << reversed_error;
  }
}

struct MalformedCase {
  std::string name;
  std::vector<std::string> lines;
  std::string location;  // "line N"
  std::string message;   // substring of the error
};

std::string LisfmLine(const std::string& pose, const std::string& covariance_head = "1e-4") {
  // Diagonal covariance: entries (0,0), (1,1), ... of the upper triangle.
  std::string line = "100 200 " + pose;
  int k = 0;
  for (int r = 0; r < 6; ++r) {
    for (int c = r; c < 6; ++c, ++k) {
      line += " " + (r == c ? (r == 0 ? covariance_head : std::string("1e-4")) : std::string("0"));
    }
  }
  return line;
}

std::string GtsfmLine(const std::string& rt, double c01, double c10) {
  std::string line = "0 1 " + rt;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) {
      double v = r == c ? 1e-4 : 0.0;
      if (r == 0 && c == 1) v = c01;
      if (r == 1 && c == 0) v = c10;
      line += " " + std::to_string(v);
    }
  }
  return line;
}

TEST(LidarConstraintsIo, MalformedFilesNameFileAndLine) {
  const std::string good_pose = "0.1 0.2 0.3 0 0 0 1";
  const std::string good_rt = "1 0 0 0.1 0 1 0 0.2 0 0 1 0.3";
  const std::vector<MalformedCase> cases = {
      {"field count", {"# c", "1 2 3"}, "line 2", "found 3"},
      {"non-numeric", {LisfmLine("0.1 abc 0.3 0 0 0 1")}, "line 1", "'abc'"},
      {"non-finite", {LisfmLine("0.1 inf 0.3 0 0 0 1")}, "line 1", "finite number"},
      {"nan", {LisfmLine("0.1 nan 0.3 0 0 0 1")}, "line 1", "finite number"},
      {"stamp", {"1.5" + LisfmLine(good_pose).substr(3)}, "line 1", "integer stamp"},
      {"same stamps", {"100 100" + LisfmLine(good_pose).substr(7)}, "line 1", "different stamps"},
      {"quaternion", {LisfmLine("0.1 0.2 0.3 0 0 0 1.01")}, "line 1", "unit quaternion"},
      {"not PD", {LisfmLine(good_pose, "-1e-4")}, "line 1", "positive-definite"},
      {"zero cov", {LisfmLine(good_pose, "0")}, "line 1", "positive-definite"},
      {"mixed", {LisfmLine(good_pose), GtsfmLine(good_rt, 0, 0)}, "line 2", "like the first"},
      {"asymmetric", {GtsfmLine(good_rt, 1e-5, 0)}, "line 1", "symmetric"},
      {"not a rotation", {GtsfmLine("1 0 0 0.1 0 1.1 0 0.2 0 0 1 0.3", 0, 0)}, "line 1",
       "rotation matrix"},
      {"reflection", {GtsfmLine("-1 0 0 0.1 0 1 0 0.2 0 0 1 0.3", 0, 0)}, "line 1",
       "rotation matrix"},
      {"same index", {"1 1" + GtsfmLine(good_rt, 0, 0).substr(3)}, "line 1", "different"},
      {"fractional index", {"0.5 1" + GtsfmLine(good_rt, 0, 0).substr(3)}, "line 1",
       "keyframe index"},
  };
  test::TempDir dir;
  for (const MalformedCase& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string path = dir.File("bad.txt");
    std::string text;
    for (const auto& line : c.lines) text += line + "\n";
    test::WriteText(path, text);
    EXPECT_TRUE(
        test::ThrowsInputError([&] { ReadLidarConstraints(path); }, {path, c.location, c.message}));
  }
}

TEST(LidarConstraintsIo, SmallQuaternionErrorIsNormalised) {
  test::TempDir dir;
  // |q| = 1 + 5e-7: within the 1e-6 tolerance, normalised on read.
  test::WriteText(dir.File("c.txt"), LisfmLine("0.1 0.2 0.3 0 0 0 1.0000005") + "\n");
  const auto records = ReadLidarConstraints(dir.File("c.txt"));
  ASSERT_EQ(records.size(), 1u);
  EXPECT_NEAR(records[0].i_from_j.rotation().norm(), 1.0, 1e-15);
}

}  // namespace
}  // namespace lisfm
