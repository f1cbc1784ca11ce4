// `lisfm icp` end to end: runs the binary like a user (test::LisfmBinary()) on
// clouds written here (ascii PCD, not with lisfm's writer) and on the real
// registration_lidar_pair; checks the printed/written transform and covariance,
// the not-converged warning, and bad input -> exit 1 (input) / 2 (usage).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using test::LisfmBinary;
using test::RunCommand;
using test::TempDir;

void WriteAsciiPcd(const std::string& path, const std::vector<Vec3>& points) {
  std::ofstream out(path);
  out << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
      << "WIDTH " << points.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS "
      << points.size() << "\nDATA ascii\n";
  out.precision(9);
  for (const auto& p : points) out << p.x() << " " << p.y() << " " << p.z() << "\n";
}

// Floor, two walls and a box: constrains all 6 DoF. 5 cm grid.
std::vector<Vec3> Room() {
  std::vector<Vec3> pts;
  for (double a = 0; a <= 4.0; a += 0.05) {
    for (double b = 0; b <= 3.0; b += 0.05) {
      pts.emplace_back(a, b, 0);        // floor
      pts.emplace_back(a, 0, b * 0.8);  // wall y = 0
      pts.emplace_back(0, b, b * 0.8 * a / 4.0 + 0.0 * a);  // wall x = 0 (z up to 2.4 m)
    }
  }
  for (double a = 0; a <= 0.6; a += 0.05) {
    for (double b = 0; b <= 0.6; b += 0.05) {
      pts.emplace_back(2 + a, 1.5 + b, 0.6);  // box top
      pts.emplace_back(2 + a, 1.5, b);        // box side
      pts.emplace_back(2, 1.5 + a, b);        // box side
    }
  }
  return pts;
}

std::vector<Vec3> Transformed(const std::vector<Vec3>& pts, const SE3& T) {
  std::vector<Vec3> out;
  for (const auto& p : pts) out.push_back(T * p);
  return out;
}

Eigen::MatrixXd ReadMatrix(const std::string& path, int rows, int cols) {
  std::ifstream in(path);
  Eigen::MatrixXd m(rows, cols);
  for (int i = 0; i < rows * cols; ++i) in >> m(i / cols, i % cols);
  EXPECT_TRUE(static_cast<bool>(in)) << "cannot read " << rows << "x" << cols << " from " << path;
  return m;
}

SE3 ToSE3(const Eigen::MatrixXd& m) {
  const Eigen::JacobiSVD<Mat3> svd(Mat3(m.topLeftCorner(3, 3)),
                                   Eigen::ComputeFullU | Eigen::ComputeFullV);
  return SE3(Mat3(svd.matrixU() * svd.matrixV().transpose()), Vec3(m.topRightCorner(3, 1)));
}

std::string ReadAll(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Synthetic room, source = target moved by T^-1: the command must recover
// T_target_source (exact data: 1 mm / 0.05 deg covers float32 I/O and the
// convergence threshold of 1e-4), with an --init_path guess, and write the files.
TEST(IcpCommand, RecoversAKnownTransformAndWritesOutputs) {
  TempDir dir;
  const std::vector<Vec3> target = Room();
  const SE3 truth(so3::Exp(Vec3(0.02, -0.03, 0.12)), Vec3(0.25, -0.15, 0.05));
  WriteAsciiPcd(dir.File("target.pcd"), target);
  WriteAsciiPcd(dir.File("source.pcd"), Transformed(target, truth.Inverse()));
  // Initial guess: the truth perturbed by ~3 deg and 10 cm.
  const SE3 init = truth * SE3(so3::Exp(Vec3(0.0, 0.0, 0.05)), Vec3(0.1, 0.0, 0.0));
  std::ostringstream init_text;
  init_text.precision(12);
  init_text << init.Matrix() << "\n";
  test::WriteText(dir.File("init.txt"), init_text.str());
  for (const std::string method : {"point_to_plane", "bayesian"}) {
    const std::string out_dir = dir.File("out_" + method);
    std::string output;
    const int code = RunCommand(LisfmBinary() + " icp --source_path " + dir.File("source.pcd") +
                                    " --target_path " + dir.File("target.pcd") + " --init_path " +
                                    dir.File("init.txt") + " --method " + method +
                                    " --Icp.source_voxel_size 0 --Icp.target_voxel_size 0" +
                                    " --output_path " + out_dir,
                                &output);
    ASSERT_EQ(code, 0) << output;
    EXPECT_NE(output.find("T_target_source:"), std::string::npos) << output;
    EXPECT_NE(output.find("converged: true"), std::string::npos) << output;
    EXPECT_EQ(output.find("WARNING"), std::string::npos) << output;
    const SE3 estimate = ToSE3(ReadMatrix(out_dir + "/T_target_source.txt", 4, 4));
    EXPECT_TRUE(test::PosesNear(estimate, truth, 0.05 * M_PI / 180.0, 1e-3)) << method;
    const Eigen::MatrixXd cov = ReadMatrix(out_dir + "/covariance.txt", 6, 6);
    EXPECT_LT((cov - cov.transpose()).norm(), 1e-6 * cov.norm()) << method;
    for (int i = 0; i < 6; ++i) EXPECT_GT(cov(i, i), 0.0) << method << " diagonal " << i;
    EXPECT_NE(ReadAll(out_dir + "/result.yaml").find("converged: true"), std::string::npos);
    const std::string config = ReadAll(out_dir + "/config.yaml");
    EXPECT_NE(config.find("Bayesian.kernel: cauchy"), std::string::npos) << config;
    EXPECT_NE(config.find("Icp.kernel: huber"), std::string::npos) << config;
  }
}

// --method bayesian takes its normal k from Bayesian.normal_neighbors: a bad value
// there is a usage error (exit 2). Every given value is checked, also one the
// chosen method does not use.
TEST(IcpCommand, BayesianNormalNeighborsAreChecked) {
  TempDir dir;
  WriteAsciiPcd(dir.File("target.pcd"), Room());
  const std::string base = LisfmBinary() + " icp --source_path " + dir.File("target.pcd") +
                           " --target_path " + dir.File("target.pcd") +
                           " --Icp.source_voxel_size 0 --Icp.target_voxel_size 0" +
                           " --Bayesian.normal_neighbors 2 --method ";
  std::string output;
  EXPECT_EQ(RunCommand(base + "bayesian", &output), 2) << output;
  EXPECT_NE(output.find("Bayesian.normal_neighbors 2 is out of range: must be in [3, 64]"),
            std::string::npos)
      << output;
  EXPECT_EQ(RunCommand(base + "point_to_plane", &output), 2) << output;
}

// The planarity gate, leverage power, refinement distance and view gates of
// --method bayesian are range-checked (usage error, exit 2) and written to config.yaml with the value
// used, under their current names when given under a former one (alias).
TEST(IcpCommand, BayesianGateAndLeveragePowerAreCheckedAndRecorded) {
  TempDir dir;
  WriteAsciiPcd(dir.File("target.pcd"), Room());
  const std::string base = LisfmBinary() + " icp --method bayesian --source_path " +
                           dir.File("target.pcd") + " --target_path " + dir.File("target.pcd") +
                           " --Icp.source_voxel_size 0 --Icp.target_voxel_size 0";
  std::string output;
  EXPECT_EQ(RunCommand(base + " --Bayesian.min_planarity 1.5", &output), 2) << output;
  EXPECT_NE(output.find("Bayesian"), std::string::npos) << output;
  EXPECT_EQ(RunCommand(base + " --Bayesian.leverage_power -1", &output), 2) << output;
  EXPECT_EQ(RunCommand(base + " --Bayesian.refine_max_correspondence_distance -0.1", &output), 2)
      << output;
  EXPECT_EQ(RunCommand(base + " --Bayesian.visibility_gate -0.1", &output), 2) << output;
  const std::string out_dir = dir.File("out");
  EXPECT_EQ(RunCommand(base + " --Bayesian.min_planarity 0.2 "
                             "--Bayesian.refine_max_correspondence_distance 0.2 "
                             "--Bayesian.field_of_view_gate 0 --Bayesian.visibility_gate 0.05 "
                             "--output_path " +
                             out_dir,
                         &output),
            0)
      << output;
  const std::string config = ReadAll(out_dir + "/config.yaml");
  EXPECT_NE(config.find("Bayesian.min_planarity: 0.2"), std::string::npos) << config;
  EXPECT_NE(config.find("Bayesian.jackknife_leverage_power: 1"), std::string::npos) << config;
  EXPECT_NE(config.find("Bayesian.field_of_view_gate: 0"), std::string::npos) << config;
  EXPECT_NE(config.find("Bayesian.visibility_gate_m: 0.05"), std::string::npos) << config;
  EXPECT_NE(config.find("Bayesian.refine_max_correspondence_distance_m: 0.2"), std::string::npos)
      << config;
  EXPECT_EQ(config.find("Bayesian.visibility_gate:"), std::string::npos) << config;
}

// A single plane is degenerate: exit 0 (a result, not an error) but a WARNING
// line and converged: false on stdout and in result.yaml.
TEST(IcpCommand, DegeneratePlaneWarnsAndReportsNotConverged) {
  TempDir dir;
  std::vector<Vec3> plane;
  for (double a = 0; a <= 3.0; a += 0.05) {
    for (double b = 0; b <= 3.0; b += 0.05) plane.emplace_back(a, b, 0);
  }
  WriteAsciiPcd(dir.File("target.pcd"), plane);
  WriteAsciiPcd(dir.File("source.pcd"), Transformed(plane, SE3(Mat3::Identity(), Vec3(0.1, 0, 0.02))));
  std::string output;
  const int code = RunCommand(LisfmBinary() + " icp --source_path " + dir.File("source.pcd") +
                                  " --target_path " + dir.File("target.pcd") +
                                  " --Icp.source_voxel_size 0 --Icp.target_voxel_size 0" +
                                  " --output_path " + dir.File("out"),
                              &output);
  EXPECT_EQ(code, 0) << output;
  EXPECT_NE(output.find("converged: false"), std::string::npos) << output;
  EXPECT_NE(output.find("WARNING: not converged"), std::string::npos) << output;
  EXPECT_NE(ReadAll(dir.File("out/result.yaml")).find("converged: false"), std::string::npos);
}

// The real pair: within fast_gicp's acceptance (5 cm / 1 deg) of relative.txt.
TEST(IcpCommand, RegistrationLidarPair) {
  LISFM_REQUIRE_SHARED_DATA("registration_lidar_pair/relative.txt");
  const std::string data = test::SharedData("registration_lidar_pair");
  const SE3 reference = ToSE3(ReadMatrix(data + "/relative.txt", 4, 4));
  TempDir dir;
  std::string output;
  const int code = RunCommand(LisfmBinary() + " icp --source_path " + data + "/251371071.pcd" +
                                  " --target_path " + data + "/251370668.pcd --output_path " +
                                  dir.File("out"),
                              &output);
  ASSERT_EQ(code, 0) << output;
  const SE3 estimate = ToSE3(ReadMatrix(dir.File("out/T_target_source.txt"), 4, 4));
  EXPECT_TRUE(test::PosesNear(estimate, reference, M_PI / 180.0, 0.05)) << output;
}

TEST(IcpCommand, MissingFileIsAnInputError) {
  TempDir dir;
  WriteAsciiPcd(dir.File("target.pcd"), Room());
  std::string output;
  const int code = RunCommand(LisfmBinary() + " icp --source_path " + dir.File("nope.pcd") +
                                  " --target_path " + dir.File("target.pcd"),
                              &output);
  EXPECT_EQ(code, 1) << output;
  EXPECT_NE(output.find("nope.pcd"), std::string::npos) << output;
}

TEST(IcpCommand, MalformedPcdIsAnInputError) {
  TempDir dir;
  WriteAsciiPcd(dir.File("target.pcd"), Room());
  test::WriteText(dir.File("bad.pcd"),
                  "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                  "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n"
                  "1 2 3\n4 five 6\n");
  std::string output;
  const int code = RunCommand(LisfmBinary() + " icp --source_path " + dir.File("bad.pcd") +
                                  " --target_path " + dir.File("target.pcd") + " --output_path " +
                                  dir.File("out"),
                              &output);
  EXPECT_EQ(code, 1) << output;
  EXPECT_NE(output.find("bad.pcd"), std::string::npos) << output;
  std::ifstream absent(dir.File("out/T_target_source.txt"));
  EXPECT_FALSE(absent.good()) << "no output may be written on an input error";
}

TEST(IcpCommand, UnknownMethodIsAUsageError) {
  TempDir dir;
  WriteAsciiPcd(dir.File("target.pcd"), Room());
  std::string output;
  const int code = RunCommand(LisfmBinary() + " icp --source_path " + dir.File("target.pcd") +
                                  " --target_path " + dir.File("target.pcd") +
                                  " --method point_to_point",
                              &output);
  EXPECT_EQ(code, 2) << output;
}

}  // namespace
}  // namespace lisfm
