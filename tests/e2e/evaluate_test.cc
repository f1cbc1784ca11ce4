// `lisfm evaluate` end to end: TUM files written here (not with lisfm's
// writer), metrics.json checked against numbers computed in the test, the HILTI
// 2022 control-point mode on the real ground truth, and bad input -> exit 1
// / 2.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/geometry.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using test::LisfmBinary;
using test::RunCommand;
using test::TempDir;

struct Pose {
  int64_t t_ns;
  Vec3 p;
  Quat q;
};

// 10 Hz smooth 3D path starting at t = 1000 s.
std::vector<Pose> Path(int n) {
  std::vector<Pose> poses;
  for (int k = 0; k < n; ++k) {
    const double t = 0.1 * k;
    poses.push_back(
        {1000LL * 1000000000LL + k * 100000000LL,
         Vec3(4 * std::cos(0.25 * t) + 0.2 * t,
              3 * std::sin(0.35 * t),
              0.4 * std::sin(t)),
         so3::Exp(Vec3(0.1 * std::sin(t), 0.1 * std::cos(t), 0.2 * t))});
  }
  return poses;
}

// Plain TUM writer: 9-decimal seconds, values with 17 significant digits.
void WriteTumFile(const std::string& path, const std::vector<Pose>& poses) {
  std::ofstream out(path);
  out << "# t x y z qx qy qz qw\n";
  char line[512];
  for (const auto& x : poses) {
    std::snprintf(line,
                  sizeof(line),
                  "%lld.%09lld %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                  static_cast<long long>(x.t_ns / 1000000000LL),
                  static_cast<long long>(x.t_ns % 1000000000LL),
                  x.p.x(),
                  x.p.y(),
                  x.p.z(),
                  x.q.x(),
                  x.q.y(),
                  x.q.z(),
                  x.q.w());
    out << line;
  }
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

std::string Evaluate(const std::string& args, int* code) {
  std::string out;
  *code = RunCommand(LisfmBinary() + " evaluate " + args, &out);
  return out;
}

TEST(Evaluate, AteWithoutAlignmentMatchesTheNoise) {
  TempDir dir;
  const std::vector<Pose> ref = Path(300);
  std::vector<Pose> est = ref;
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.03);
  double sum_sq = 0;
  for (auto& x : est) {
    const Vec3 n(noise(rng), noise(rng), noise(rng));
    x.p += n;
    x.t_ns +=
        3000000;  // 3 ms later: inside the default 10 ms association window
  }
  for (size_t k = 0; k < ref.size(); ++k)
    sum_sq += (est[k].p - ref[k].p).squaredNorm();
  WriteTumFile(dir.File("ref.txt"), ref);
  WriteTumFile(dir.File("est.txt"), est);

  int code = 0;
  const std::string out =
      Evaluate("--reference " + dir.File("ref.txt") + " --estimate " +
                   dir.File("est.txt") + " --align none --output_path " +
                   dir.File("out"),
               &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("ATE translation [m]"), std::string::npos) << out;
  EXPECT_NE(out.find("evaluate summary"), std::string::npos) << out;
  const nlohmann::json m = ReadJson(dir.File("out/metrics.json"));
  EXPECT_EQ(m["num_associated"].get<int>(), 300);
  EXPECT_EQ(m["alignment"].get<std::string>(), "none");
  // 17-digit text round-trips exactly; the sums differ only by order (~1e-16).
  EXPECT_NEAR(m["ate"]["translation_m"]["rmse"].get<double>(),
              std::sqrt(sum_sq / 300),
              1e-12);
  EXPECT_EQ(m["ate"]["translation_m"]["count"].get<int>(), 300);
  EXPECT_EQ(m["rpe"]["distance"].size(), 3u);
  EXPECT_TRUE(std::filesystem::exists(dir.File("out/evaluation.png")));
  EXPECT_TRUE(std::filesystem::exists(dir.File("out/evaluate_config.yaml")));
  // The former names (--reference, --estimate, --align) are aliases; the
  // effective config names the options by their current names.
  std::ifstream config_file(dir.File("out/evaluate_config.yaml"));
  const std::string config((std::istreambuf_iterator<char>(config_file)),
                           std::istreambuf_iterator<char>());
  EXPECT_NE(config.find("reference_path: " + dir.File("ref.txt")),
            std::string::npos)
      << config;
  EXPECT_NE(config.find("estimate_path: " + dir.File("est.txt")),
            std::string::npos)
      << config;
  EXPECT_NE(config.find("alignment: none"), std::string::npos) << config;

  // A 2 ms window misses the 3 ms offset: no overlap, exit 1 naming the files.
  const std::string miss =
      Evaluate("--reference_path " + dir.File("ref.txt") + " --estimate_path " +
                   dir.File("est.txt") + " --max_dt 0.002",
               &code);
  EXPECT_EQ(code, 1) << miss;
  EXPECT_NE(miss.find(dir.File("est.txt")), std::string::npos) << miss;
  EXPECT_NE(miss.find("max_dt"), std::string::npos) << miss;
}

TEST(Evaluate, Se3AndSim3RecoverTheAppliedTransform) {
  TempDir dir;
  const std::vector<Pose> ref = Path(300);
  test::Rng().seed(test::kTestSeed);
  Sim3 moved;
  moved.pose = test::RandomPose(2.5, 8.0);
  moved.scale = 1.0 / 1.3;
  std::vector<Pose> rigid = ref;
  std::vector<Pose> scaled = ref;
  for (size_t k = 0; k < ref.size(); ++k) {
    rigid[k].p = moved.pose * ref[k].p;
    rigid[k].q = moved.pose.rotation() * ref[k].q;
    scaled[k].p = moved * ref[k].p;
    scaled[k].q = rigid[k].q;
  }
  WriteTumFile(dir.File("ref.txt"), ref);
  WriteTumFile(dir.File("rigid.txt"), rigid);
  WriteTumFile(dir.File("scaled.txt"), scaled);

  int code = 0;
  std::string out =
      Evaluate("--reference_path " + dir.File("ref.txt") + " --estimate_path " +
                   dir.File("rigid.txt") + " --output_path " + dir.File("se3"),
               &code);
  ASSERT_EQ(code, 0) << out;
  nlohmann::json m = ReadJson(dir.File("se3/metrics.json"));
  EXPECT_EQ(m["alignment"].get<std::string>(), "se3");  // the default
  // Exact data: the fit is accurate to ~1e-12 m on metre-scale coordinates.
  EXPECT_LT(m["ate"]["translation_m"]["max"].get<double>(), 1e-9);
  const auto t = m["reference_from_estimate"]["translation_m"];
  const Vec3 expected_t = moved.pose.Inverse().translation();
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(t[i].get<double>(), expected_t[i], 1e-9);

  out = Evaluate("--reference_path " + dir.File("ref.txt") +
                     " --estimate_path " + dir.File("scaled.txt") +
                     " --alignment sim3 --output_path " + dir.File("sim3"),
                 &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("scale 1.3"), std::string::npos) << out;
  m = ReadJson(dir.File("sim3/metrics.json"));
  EXPECT_NEAR(m["scale"].get<double>(), 1.3, 1e-9);
  EXPECT_LT(m["ate"]["translation_m"]["max"].get<double>(), 1e-9);

  out = Evaluate("--reference_path " + dir.File("ref.txt") +
                     " --estimate_path " + dir.File("scaled.txt") +
                     " --alignment se3 --output_path " + dir.File("se3_scaled"),
                 &code);
  ASSERT_EQ(code, 0) << out;
  m = ReadJson(dir.File("se3_scaled/metrics.json"));
  EXPECT_EQ(m["scale"].get<double>(), 1.0);
  EXPECT_GT(m["ate"]["translation_m"]["rmse"].get<double>(), 0.1);
}

TEST(Evaluate, HiltiControlPoints) {
  const std::string dense =
      "hilti2022_groundtruth/"
      "exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt";
  const std::string points =
      "hilti2022_groundtruth/exp04_construction_upper_level.txt";
  LISFM_REQUIRE_SHARED_DATA(dense);
  LISFM_REQUIRE_SHARED_DATA(points);
  TempDir dir;
  int code = 0;
  const std::string out = Evaluate(
      "--reference_path " + test::SharedData(points) + " --estimate_path " +
          test::SharedData(dense) +
          " --reference_type control_points --output_path " + dir.File("out"),
      &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("HILTI 2022 score"), std::string::npos) << out;
  const nlohmann::json m = ReadJson(dir.File("out/metrics.json"));
  EXPECT_EQ(m["max_dt_s"].get<double>(), 2.0);  // the control-point default
  EXPECT_EQ(m["num_associated"].get<int>(), 7);
  const double score = m["hilti2022"]["score"].get<double>();
  // Ground truth vs survey differ by ~1-6 cm: a real score, never 100.
  EXPECT_GT(score, 0.0);
  EXPECT_LT(score, 100.0);
  // The score is the normalised sum of the per-point scores.
  int total = 0;
  for (const auto& p : m["hilti2022"]["points"])
    total += p["points"].get<int>();
  EXPECT_DOUBLE_EQ(score, 100.0 * total / 70.0);
  EXPECT_TRUE(std::filesystem::exists(dir.File("out/evaluation.png")));
}

TEST(Evaluate, BadInputExitsWithOneClearError) {
  TempDir dir;
  const std::vector<Pose> ref = Path(50);
  WriteTumFile(dir.File("ref.txt"), ref);
  const std::string ref_arg = "--reference_path " + dir.File("ref.txt");
  int code = 0;

  // Missing file.
  std::string out =
      Evaluate(ref_arg + " --estimate_path " + dir.File("nope.txt"), &code);
  EXPECT_EQ(code, 1) << out;
  // Exactly one `error: ...` line (after the stage header on stderr).
  EXPECT_NE(out.find("\nerror: "), std::string::npos) << out;
  EXPECT_EQ(out.find("error: "), out.rfind("error: ")) << out;
  EXPECT_NE(out.find(dir.File("nope.txt")), std::string::npos) << out;

  // Malformed line 4 (one value missing).
  test::WriteText(
      dir.File("bad.txt"),
      "# t x y z qx qy qz qw\n1000 0 0 0 0 0 0 1\n1000.1 1 0 0 0 0 0 1\n"
      "1000.2 2 0 0 0 0 1\n");
  out = Evaluate(ref_arg + " --estimate_path " + dir.File("bad.txt") +
                     " --output_path " + dir.File("out"),
                 &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find(dir.File("bad.txt") + ":line 4"), std::string::npos)
      << out;
  EXPECT_NE(out.find("expected 8 columns"), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(dir.File("out/metrics.json")));

  // Unsorted times.
  test::WriteText(
      dir.File("unsorted.txt"),
      "1000 0 0 0 0 0 0 1\n1000.2 1 0 0 0 0 0 1\n1000.1 2 0 0 0 0 0 1\n");
  out =
      Evaluate(ref_arg + " --estimate_path " + dir.File("unsorted.txt"), &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find(dir.File("unsorted.txt") + ":line 3"), std::string::npos)
      << out;
  EXPECT_NE(out.find("strictly increasing"), std::string::npos) << out;

  // No overlap in time: the estimate is an hour later.
  std::vector<Pose> later = ref;
  for (auto& x : later) x.t_ns += 3600LL * 1000000000LL;
  WriteTumFile(dir.File("later.txt"), later);
  out = Evaluate(ref_arg + " --estimate_path " + dir.File("later.txt"), &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find(dir.File("later.txt")), std::string::npos) << out;
  EXPECT_NE(out.find("no estimate pose"), std::string::npos) << out;

  // Usage errors exit 2.
  out = Evaluate(
      ref_arg + " --estimate_path " + dir.File("ref.txt") + " --alignment foo",
      &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--align"), std::string::npos) << out;
  out = Evaluate(
      ref_arg + " --estimate_path " + dir.File("ref.txt") + " --max_dt -1",
      &code);
  EXPECT_EQ(code, 2) << out;
  out = Evaluate(  // beyond the int64 nanosecond range: no silent wrap
      ref_arg + " --estimate " + dir.File("ref.txt") + " --max_dt 1e10", &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--max_dt"), std::string::npos) << out;
  out = Evaluate(ref_arg, &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--estimate"), std::string::npos) << out;
}

// A short, nearly straight path: the SE(3) alignment's rotation about the path
// rests on 1 cm of position noise, so the rotation ATE is the alignment's
// error. The command warns and says so in metrics.json; a curved path with
// real orientation errors does not warn.
TEST(Evaluate, WarnsWhenTheAlignmentDominatesTheRotationAte) {
  TempDir dir;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<Pose> line;
  for (int k = 0; k < 40; ++k) {
    line.push_back({1000LL * 1000000000LL + k * 100000000LL, Vec3(0.1 * k, 0.0, 1.0),
                    so3::Exp(Vec3(0.0, 0.0, 0.02 * k))});
  }
  std::vector<Pose> line_est = line;
  for (auto& x : line_est) x.p += Vec3(noise(rng), noise(rng), noise(rng));
  WriteTumFile(dir.File("line.txt"), line);
  WriteTumFile(dir.File("line_est.txt"), line_est);
  int code = 0;
  std::string out = Evaluate("--reference " + dir.File("line.txt") + " --estimate " +
                                 dir.File("line_est.txt") + " --output_path " + dir.File("line"),
                             &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_NE(out.find("[W "), std::string::npos) << out;
  EXPECT_NE(out.find("rotation ATE"), std::string::npos) << out;
  EXPECT_NE(out.find("dominated by the se3 alignment"), std::string::npos) << out;
  nlohmann::json m = ReadJson(dir.File("line/metrics.json"));
  EXPECT_TRUE(m["alignment_conditioning"]["rotation_ate_dominated_by_alignment"].get<bool>());
  EXPECT_GT(std::abs(m["alignment_conditioning"]["weak_axis"][0].get<double>()), 0.99);

  const std::vector<Pose> ref = Path(300);
  std::vector<Pose> est = ref;
  std::normal_distribution<double> tilt(0.0, 0.01);
  for (auto& x : est) {
    x.p += Vec3(noise(rng), noise(rng), noise(rng));
    x.q = x.q * so3::Exp(Vec3(tilt(rng), tilt(rng), tilt(rng)));
  }
  WriteTumFile(dir.File("ref.txt"), ref);
  WriteTumFile(dir.File("est.txt"), est);
  out = Evaluate("--reference " + dir.File("ref.txt") + " --estimate " + dir.File("est.txt") +
                     " --output_path " + dir.File("curve"),
                 &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_EQ(out.find("dominated"), std::string::npos) << out;
  m = ReadJson(dir.File("curve/metrics.json"));
  EXPECT_FALSE(m["alignment_conditioning"]["rotation_ate_dominated_by_alignment"].get<bool>());
}

// The output folder is checked before the evaluation, and an earlier output
// is replaced only with --overwrite 1.
TEST(Evaluate, OutputFolderIsCheckedFirstAndReplacedOnlyOnRequest) {
  TempDir dir;
  WriteTumFile(dir.File("ref.txt"), Path(50));
  const std::string args =
      "--reference " + dir.File("ref.txt") + " --estimate " + dir.File("ref.txt");
  test::WriteText(dir.File("file"), "x");
  int code = 0;
  std::string out = Evaluate(args + " --output_path " + dir.File("file/out"), &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find(dir.File("file/out")), std::string::npos) << out;
  EXPECT_EQ(out.find("ATE translation"), std::string::npos) << out;  // nothing evaluated
  ASSERT_EQ((Evaluate(args + " --output_path " + dir.File("out"), &code), code), 0);
  out = Evaluate(args + " --output_path " + dir.File("out"), &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--overwrite 1"), std::string::npos) << out;
  out = Evaluate(args + " --output_path " + dir.File("out") + " --overwrite 1", &code);
  EXPECT_EQ(code, 0) << out;
}

}  // namespace
}  // namespace lisfm
