// TUM / EuRoC / control-point readers and writers: exact round trips in ns,
// the real HILTI 2022 files, every documented input error, and the PNG plot.
#include "core/io/trajectory_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/errors.h"
#include "core/io/plot.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using test::TempDir;
using test::WriteText;

// Stamps with all 19 digits significant (sub-microsecond parts), which a
// double in seconds cannot hold exactly.
Trajectory RandomTrajectory(int n) {
  std::vector<StampedPose> poses;
  TimestampNs t = 1646304541627162123LL;
  std::uniform_int_distribution<int64_t> step(1, 200000000);
  for (int k = 0; k < n; ++k) {
    poses.push_back({t, test::RandomPose(3.0, 50.0)});
    t += step(test::Rng());
  }
  return Trajectory(poses);
}

void ExpectSameTrajectory(const Trajectory& a, const Trajectory& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].t_ns, b[i].t_ns) << "pose " << i;
    // Values are written with the shortest text that reads back exactly.
    EXPECT_EQ(a[i].pose.translation(), b[i].pose.translation()) << "pose " << i;
    // The reader re-normalises the quaternion, which may move the last bit.
    EXPECT_TRUE(a[i].pose.rotation().coeffs().isApprox(
        b[i].pose.rotation().coeffs(), 1e-15))
        << "pose " << i;
  }
}

// Counts lines that are neither blank nor `#` comments, independently of the
// reader.
size_t CountDataLines(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  size_t n = 0;
  while (std::getline(in, line)) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first != std::string::npos && line[first] != '#') ++n;
  }
  return n;
}

TEST(TrajectoryIo, TumRoundTripIsExactInNs) {
  TempDir dir;
  const Trajectory traj = RandomTrajectory(200);
  const std::string path = dir.File("traj.txt");
  WriteTum(path, traj);
  ExpectSameTrajectory(traj, ReadTum(path));
  ExpectSameTrajectory(traj, ReadTrajectory(path));
  // Nothing but the output is left in the folder (atomic write).
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()),
                          std::filesystem::directory_iterator()),
            1);
}

TEST(TrajectoryIo, EurocRoundTripIsExactInNs) {
  TempDir dir;
  const Trajectory traj = RandomTrajectory(200);
  const std::string path = dir.File("groundtruth.csv");
  WriteEurocCsv(path, traj);
  std::ifstream in(path);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header,
            "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w "
            "[],q_RS_x [],"
            "q_RS_y [],q_RS_z []");
  ExpectSameTrajectory(traj, ReadEurocCsv(path));
  ExpectSameTrajectory(traj, ReadTrajectory(path));
}

TEST(TrajectoryIo, EurocExtraColumnsAreIgnored) {
  TempDir dir;
  const std::string path = dir.File("gt.csv");
  WriteText(path,
            "#timestamp,p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w "
            "[],q_RS_x [],q_RS_y [],"
            "q_RS_z [],v_RS_R_x [m s^-1],v_RS_R_y [m s^-1],v_RS_R_z [m "
            "s^-1],b_w_RS_S_x\n"
            "1403636579758555392,4.688319,-1.786938,0.783338,0.534108,-0."
            "153029,-0.827383,"
            "-0.082152,-0.027876,0.033207,0.800006,-0.003172\n"
            "1403636579763555584, "
            "4.688177,-1.786770,0.787350,0.535076,-0.152851,-0.826688,"
            "-0.082005,-0.029272,0.033657,0.800030,-0.003172\n");
  const Trajectory t = ReadEurocCsv(path);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].t_ns, 1403636579758555392LL);
  EXPECT_EQ(t[1].t_ns, 1403636579763555584LL);
  EXPECT_EQ(t[1].pose.translation(), Vec3(4.688177, -1.786770, 0.787350));
  // Columns are w x y z; the norm is within 1e-3 of 1 and gets normalised.
  const Quat q = Quat(0.534108, -0.153029, -0.827383, -0.082152).normalized();
  EXPECT_TRUE(t[0].pose.rotation().coeffs().isApprox(q.coeffs(), 1e-15));
}

TEST(TrajectoryIo, TumSkipsCommentsAndBlankLines) {
  TempDir dir;
  const std::string path = dir.File("t.tum");
  WriteText(path,
            "# t x y z qx qy qz qw\n\n"
            "1.5 1 2 3 0 0 0 1\n"
            "   \n"
            "  # indented comment\n"
            "2.000000001\t4 5 6 0 0 1 0\r\n");
  const Trajectory t = ReadTrajectory(path);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].t_ns, 1500000000LL);
  EXPECT_EQ(t[1].t_ns, 2000000001LL);
  EXPECT_EQ(t[1].pose.translation(), Vec3(4, 5, 6));
  EXPECT_NEAR(std::abs(t[1].pose.rotation().z()), 1.0, 1e-15);
}

constexpr const char* kExp04Dense =
    "hilti2022_groundtruth/"
    "exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt";
constexpr const char* kExp05Dense =
    "hilti2022_groundtruth/"
    "exp_05_construction_upper_level_easy_2022-03-03-11-46-10_imu.txt";
constexpr const char* kExp04Points =
    "hilti2022_groundtruth/exp04_construction_upper_level.txt";
constexpr const char* kExp05Points =
    "hilti2022_groundtruth/exp05_construction_upper_level_2.txt";

TEST(TrajectoryIo, RealHiltiGroundTruthLoads) {
  LISFM_REQUIRE_SHARED_DATA(kExp04Dense);
  for (const char* rel : {kExp04Dense, kExp05Dense}) {
    const std::string path = test::SharedData(rel);
    const Trajectory t = ReadTrajectory(path);
    EXPECT_EQ(t.size(), CountDataLines(path)) << rel;
    EXPECT_GT(t.size(), 1000u) << rel;  // ~125 s at 10 Hz
    EXPECT_GT(t.PathLength(), 10.0) << rel;
  }
  // First line of exp04: "1646304541.627162 -3.45 6.27 1.79 0.6602272584 ...".
  const Trajectory t = ReadTum(test::SharedData(kExp04Dense));
  EXPECT_EQ(t[0].t_ns, 1646304541627162000LL);
  EXPECT_EQ(t[0].pose.translation(), Vec3(-3.45, 6.27, 1.79));
  EXPECT_NEAR(t[0].pose.rotation().x(), 0.6602272584, 1e-9);
  EXPECT_NEAR(t[0].pose.rotation().w(), -0.006783616141, 1e-9);
}

TEST(TrajectoryIo, RealHiltiControlPointsLoad) {
  LISFM_REQUIRE_SHARED_DATA(kExp04Points);
  for (const char* rel : {kExp04Points, kExp05Points}) {
    const std::string path = test::SharedData(rel);
    const auto points = ReadControlPoints(path);
    EXPECT_EQ(points.size(), CountDataLines(path)) << rel;
  }
  // Despite the `# timestamp_s id x y z` header the rows are `t x y z 0 0 0 1`.
  const auto points = ReadControlPoints(test::SharedData(kExp04Points));
  ASSERT_EQ(points.size(), 7u);
  EXPECT_EQ(points[0].t_ns, 1646304543157159300LL);
  EXPECT_EQ(points[0].position, Vec3(-3.45665, 6.33555, 1.9089));
  EXPECT_EQ(points[3].position,
            Vec3(-12.2634, -10.0199666666667, 1.91803333333333));
  EXPECT_TRUE(points[0].id.empty());
}

TEST(TrajectoryIo, ControlPointLayouts) {
  TempDir dir;
  const std::string path = dir.File("cp.txt");
  WriteText(path,
            "# timestamp_s id x y z\n"
            "10.5 CP1 1 2 3\n"
            "11.25 4 5 6\n"
            "12 7 8 9 0 0 0 1\n");
  const auto points = ReadControlPoints(path);
  ASSERT_EQ(points.size(), 3u);
  EXPECT_EQ(points[0].id, "CP1");
  EXPECT_EQ(points[0].t_ns, 10500000000LL);
  EXPECT_EQ(points[0].position, Vec3(1, 2, 3));
  EXPECT_EQ(points[1].position, Vec3(4, 5, 6));
  EXPECT_EQ(points[2].t_ns, 12000000000LL);
  EXPECT_EQ(points[2].position, Vec3(7, 8, 9));

  WriteText(path, "10 1 2 3\n11 1 2 3 4 5\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadControlPoints(path); },
                                     {path, "line 2", "6 columns", "'t id x y z' (5 columns)"}));
  WriteText(path, "10 1 2 3\n9 1 2 3\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadControlPoints(path); },
                                     {path, "line 2", "strictly increasing"}));
  WriteText(path, "10 1 2 3\n11 1 y 3\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadControlPoints(path); },
                                     {path, "line 2", "column 3", "'y'"}));
  WriteText(path, "# timestamp_s id x y z\n");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadControlPoints(path); }, {path, "no control points"}));
}

TEST(TrajectoryIo, InputErrorsNameFileLineAndExpectation) {
  TempDir dir;
  const std::string path = dir.File("bad.txt");
  const std::string good = "1.0 0 0 0 0 0 0 1\n";

  EXPECT_TRUE(test::ThrowsInputError([&] { ReadTum(dir.File("missing.txt")); },
                                     {"missing.txt", "not found"}));
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadTrajectory(dir.File("missing.csv")); },
                                     {"missing.csv", "not found"}));

  WriteText(path, good + "2.0 0 0 0 0 0 1\n");
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { ReadTum(path); },
      {path, "line 2", "expected 8 columns 't x y z qx qy qz qw', found 7"}));
  WriteText(path, "# header\n" + good + "2.0 0 abc 0 0 0 0 1\n");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadTum(path); }, {path, "line 3", "column 3", "found 'abc'"}));
  WriteText(path, "1.0x 0 0 0 0 0 0 1\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadTum(path); },
                                     {path, "line 1", "time in seconds", "'1.0x'"}));
  WriteText(path, good + "0.5 0 0 0 0 0 0 1\n");
  EXPECT_TRUE(test::ThrowsInputError(
      [&] { ReadTum(path); },
      {path, "line 2", "strictly increasing", "after 1.000000000 s (line 1)"}));
  WriteText(path, good + "1.0 0 0 0 0 0 0 1\n");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadTum(path); }, {path, "line 2", "strictly increasing"}));
  WriteText(path, good + "2.0 0 0 0 0 0 0 1.1\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadTum(path); },
                                     {path, "line 2", "unit quaternion", "norm 1.1"}));
  WriteText(path, good + "2.0 0 0 0 0 0 0 0\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadTum(path); },
                                     {path, "line 2", "unit quaternion", "norm 0"}));
  WriteText(path, "# nothing\n\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadTum(path); }, {path, "no poses"}));
  WriteText(path, "");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadTrajectory(path); }, {path, "no poses"}));

  // Within 1e-3 of unit norm: normalised, not an error.
  WriteText(path, "1.0 0 0 0 0 0 0 1.0005\n");
  EXPECT_NEAR(ReadTum(path)[0].pose.rotation().norm(), 1.0, 1e-15);

  const std::string csv = dir.File("bad.csv");
  WriteText(csv,
            "#timestamp "
            "[ns],x,y,z,qw,qx,qy,qz\n100,0,0,0,1,0,0,0\n1.5e2,0,0,0,1,0,0,0\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadEurocCsv(csv); },
                                     {csv, "line 3", "integer time in ns", "'1.5e2'"}));
  WriteText(csv, "100,0,0,0,1,0,0,0\n200,0,0,0,1,0\n");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadEurocCsv(csv); }, {csv, "line 2", "at least 8", "found 6"}));
  WriteText(csv, "100,0,0,0,1,0,0,0\n200,0,,0,1,0,0,0\n");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadEurocCsv(csv); }, {csv, "line 2", "column 3", "found ''"}));
  WriteText(csv, "100,0,0,0,1,0,0,0\n100,0,0,0,1,0,0,0\n");
  EXPECT_TRUE(
      test::ThrowsInputError([&] { ReadTrajectory(csv); }, {csv, "line 2", "strictly increasing"}));
}

// A stamp outside the int64 nanosecond range, in any notation, is an error
// naming file and line (never a silently wrapped time).
TEST(TrajectoryIo, StampsOutsideTheNanosecondRangeAreRejected) {
  TempDir dir;
  const std::string path = dir.File("far.txt");
  for (const std::string stamp : {"1e10", "-1e10", "9300000000.5", "1E+12"}) {
    WriteText(path, "1.0 0 0 0 0 0 0 1\n" + stamp + " 0 0 0 0 0 0 1\n");
    EXPECT_TRUE(test::ThrowsInputError([&] { ReadTum(path); },
                                       {path, "line 2", "int64 nanoseconds", stamp}));
  }
  const std::string points = dir.File("points.txt");
  WriteText(points, "1e10 0 0 0\n");
  EXPECT_TRUE(test::ThrowsInputError([&] { ReadControlPoints(points); },
                                     {points, "line 1", "int64 nanoseconds"}));
  // In range, exponent form is fine.
  WriteText(path, "1e9 0 0 0 0 0 0 1\n");
  EXPECT_EQ(ReadTum(path)[0].t_ns, 1000000000LL * kNsPerSecond);
}

TEST(TrajectoryIo, ExtensionDispatchAndSniffing) {
  TempDir dir;
  const Trajectory traj = RandomTrajectory(5);
  WriteTum(dir.File("a.log"), traj);
  WriteEurocCsv(dir.File("b.dat"), traj);
  ExpectSameTrajectory(traj, ReadTrajectory(dir.File("a.log")));
  ExpectSameTrajectory(traj, ReadTrajectory(dir.File("b.dat")));
}

// Reads a big-endian uint32 at `offset`.
uint32_t BigEndian32(const std::string& s, size_t offset) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i)
    v = (v << 8) | static_cast<unsigned char>(s[offset + i]);
  return v;
}

TEST(Plot, WritesAPngAtomically) {
  TempDir dir;
  TrajectoryPlotData data;
  data.title = "test";
  for (int k = 0; k < 100; ++k) {
    const double a = 0.1 * k;
    data.reference.emplace_back(10 * std::cos(a), 4 * std::sin(a), 0);
    data.estimate.emplace_back(10 * std::cos(a) + 0.1, 4 * std::sin(a), 0);
    data.error_time_s.push_back(a);
    data.error_m.push_back(0.1 + 0.01 * std::sin(a));
  }
  const std::string path = dir.File("plot.png");
  WriteTrajectoryPlot(path, data);
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)),
                          std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 24u);
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(bytes.substr(12, 4), "IHDR");
  EXPECT_EQ(BigEndian32(bytes, 16), 1200u);  // width
  EXPECT_EQ(BigEndian32(bytes, 20), 1000u);  // height
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()),
                          std::filesystem::directory_iterator()),
            1);
  // Degenerate input: one point, markers, no errors.
  TrajectoryPlotData one;
  one.reference = {Vec3(1, 1, 1)};
  one.reference_as_markers = true;
  EXPECT_NO_THROW(WriteTrajectoryPlot(dir.File("one.png"), one));
  EXPECT_THROW(WriteTrajectoryPlot(dir.File("none.png"), TrajectoryPlotData()),
               InternalError);
}

}  // namespace
}  // namespace lisfm
