// Option values are checked when the command line is parsed, before any input
// is read: for every command an out-of-range value is one `error:` line naming
// the option, its value and the allowed range (exit 2); `-h` shows the ranges
// and the aliases (former names), and giving an option under both names is a
// usage error.
#include <gtest/gtest.h>

#include <string>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using test::LisfmBinary;
using test::RunCommand;

// Runs `lisfm <args>`; returns stdout + stderr and sets *code.
std::string Lisfm(const std::string& args, int* code) {
  std::string out;
  *code = RunCommand(LisfmBinary() + " " + args, &out);
  return out;
}

// The whole output must be exactly this one error line, with exit code 2.
void ExpectUsageError(const std::string& args, const std::string& message) {
  int code = 0;
  const std::string out = Lisfm(args, &code);
  EXPECT_EQ(code, 2) << args << "\n" << out;
  EXPECT_EQ(out, "error: " + message + "\n") << args;
}

void ExpectHelpContains(const std::string& command, const std::string& text) {
  int code = 0;
  const std::string out = Lisfm(command + " -h", &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find(text), std::string::npos)
      << command << " -h lacks '" << text << "'\n"
      << out;
}

TEST(OptionRanges, PoseGraph) {
  const std::string pose_graph = "pose_graph --input_path g.g2o";
  ExpectUsageError(pose_graph + " --Solver.max_num_iterations 0",
                   "--Solver.max_num_iterations 0 is out of range: must be >= 1");
  ExpectUsageError(pose_graph + " --Solver.num_threads 0",
                   "--Solver.num_threads 0 is out of range: must be -1 or >= 1");
  ExpectHelpContains("pose_graph", "--Solver.function_tolerance");
}

TEST(OptionRanges, PoseSlam) {
  const std::string pose_slam = "pose_slam --input_path s --lio_path l --output_path o";
  ExpectUsageError(pose_slam + " --PoseSlam.knn 0",
                   "--PoseSlam.knn 0 is out of range: must be >= 1");
  ExpectUsageError(pose_slam + " --PoseSlam.max_translation_difference 0",
                   "--PoseSlam.max_translation_difference 0 is out of range: must be > 0");
  for (const char* option : {"--PoseSlam.max_rotation_difference_deg", "--PoseSlam.use_imu",
                             "--Stationary.window", "--ZeroVelocity.velocity_sigma",
                             "--Bayesian.kernel", "--Bayesian.num_iterations",
                             "--Solver.max_num_iterations", "--num_threads"}) {
    ExpectHelpContains("pose_slam", option);
  }
}

TEST(OptionRanges, Icp) {
  const std::string icp = "icp --source_path a.pcd --target_path b.pcd";
  ExpectUsageError(icp + " --Icp.max_iterations 0",
                   "--Icp.max_iterations 0 is out of range: must be >= 1");
  ExpectUsageError(
      icp + " --Icp.source_voxel_size -0.25",
      "--Icp.source_voxel_size -0.25 is out of range: must be >= 0");
  // Values given under a former name are reported under that name.
  ExpectUsageError(
      icp + " --Icp.max_correspondence_distance 0",
      "--Icp.max_correspondence_distance 0 is out of range: must be > 0");
  ExpectUsageError(icp + " --method bayesian --Bayesian.burn_in 2000",
                   "--Bayesian.burn_in 2000 is out of range: must be < "
                   "--Bayesian.num_iterations (1000)");
  ExpectUsageError(
      icp + " --Icp.kernel_scale 0.2 --Icp.kernel_scale_m 0.3",
      "--Icp.kernel_scale and --Icp.kernel_scale_m are the same option "
      "(--Icp.kernel_scale_m); give it once");
  ExpectHelpContains("icp", "--Icp.max_iterations");
  ExpectHelpContains("icp", "(=50, >= 1)");
  ExpectHelpContains("icp", "[alias: --Icp.max_correspondence_distance]");
  ExpectHelpContains("icp", "(=0.5, in (0, 2))");  // Bayesian.step_size
}

TEST(OptionRanges, Lio) {
  const std::string lio = "lio --input_path seq --output_path out";
  ExpectUsageError(lio + " --max_scans -1",
                   "--max_scans -1 is out of range: must be >= 0");
  ExpectUsageError(lio + " --Map.voxel_size -0.5",
                   "--Map.voxel_size -0.5 is out of range: must be > 0");
  ExpectUsageError(lio + " --Lio.scan_voxel_size -0.4",
                   "--Lio.scan_voxel_size -0.4 is out of range: must be >= 0");
  ExpectUsageError(
      lio + " --Lio.min_range 200",
      "--Lio.min_range 200 is out of range: must be < --Lio.max_range (100)");
  ExpectUsageError(
      lio + " --Lio.max_range 0.3",
      "--Lio.max_range 0.3 is out of range: must be > --Lio.min_range (0.5)");
  ExpectHelpContains("lio", "(=0, >= 0) stop after this many frames");
  ExpectHelpContains("lio", "--Map.voxel_size");
}

TEST(OptionRanges, Evaluate) {
  const std::string evaluate =
      "evaluate --reference_path a.txt --estimate_path b.txt";
  ExpectUsageError(evaluate + " --max_dt -1",
                   "--max_dt -1 is out of range: must be >= 0");
  ExpectUsageError(
      "evaluate --reference a.txt --reference_path b.txt --estimate_path c.txt",
      "--reference and --reference_path are the same option "
      "(--reference_path); "
      "give it once");
  int code = 0;
  const std::string out = Lisfm(evaluate + " --align affine", &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--alignment"), std::string::npos) << out;
  ExpectHelpContains("evaluate", "[alias: --reference]");
  ExpectHelpContains("evaluate", "[alias: --estimate]");
  ExpectHelpContains("evaluate", "[alias: --align]");
}

TEST(OptionRanges, Simulate) {
  const std::string simulate = "simulate --output_path out";
  ExpectUsageError(simulate + " --camera_rate 120",
                   "--camera_rate 120 is out of range: must be in [0, 100]");
  ExpectUsageError(simulate + " --supersampling 0",
                   "--supersampling 0 is out of range: must be in [1, 8]");
  // Constraints between options come from SimulatorOptions::Check().
  ExpectUsageError(simulate + " --duration 0.2",
                   "--duration 0.2 is out of range: must be > 0.5 s without a "
                   "trajectory_path");
  ExpectUsageError(
      simulate + " --lidars spinning,velodyne",
      "--lidars spinning,velodyne is out of range: must be a comma list of "
      "spinning, livox, none");
  ExpectHelpContains("simulate", "(=2, in [0, 100]) rig frames per second");
  ExpectUsageError(simulate + " --error_sources dynamics,rain",
                   "--error_sources dynamics,rain is out of range: must be all, none, or a "
                   "comma list of calibration, imu, lidar, camera, dynamics");
  ExpectUsageError(simulate + " --Walk.num_stops 1",
                   "--Walk.num_stops 1 is out of range: must be in [2, 1000]");
  ExpectUsageError(simulate + " --Dynamics.people_per_100m -1",
                   "--Dynamics.people_per_100m -1 is out of range: must be in [0, 100]");
  // Every error source's size is documented with its source.
  ExpectHelpContains("simulate", "--Dynamics.people_per_100m");
  ExpectHelpContains("simulate", "Bohannon 1997");
  ExpectHelpContains("simulate", "office | staircase | hall | site");
}

TEST(OptionRanges, GlobalMapper) {
  const std::string mapper =
      "global_mapper --database_path db.db --output_path out";
  ExpectUsageError(
      mapper + " --Mapper.num_refinement_rounds -1",
      "--Mapper.num_refinement_rounds -1 is out of range: must be >= 0");
  ExpectUsageError(mapper + " --num_threads 0",
                   "--num_threads 0 is out of range: must be -1 or >= 1");
  ExpectUsageError(mapper + " --Priors.position_sigma 0",
                   "--Priors.position_sigma 0 is out of range: must be > 0");
  ExpectUsageError(mapper + " --Priors.use 0 --Priors.use_priors 1",
                   "--Priors.use and --Priors.use_priors are the same option "
                   "(--Priors.use_priors); give it once");
  ExpectHelpContains("global_mapper", "(=1, >= 0) rounds of bundle adjustment");
  ExpectHelpContains("global_mapper", "[alias: --Priors.use]");
  ExpectHelpContains("global_mapper", "--Mapper.skip_bundle_adjustment");
}

TEST(OptionRanges, ModelEvaluatorAndModelConverterChoices) {
  int code = 0;
  std::string out = Lisfm(
      "model_evaluator --model_path m --reference_path r --alignment affine",
      &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--alignment"), std::string::npos) << out;
  EXPECT_NE(out.find("affine"), std::string::npos) << out;
  out =
      Lisfm("model_converter --input_path m --output_path o --output_type NVM",
            &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--output_type"), std::string::npos) << out;
}

TEST(OptionRanges, ConfigFileValuesAreCheckedWithFileAndLine) {
  test::TempDir dir;
  test::WriteText(dir.File("lio.yaml"), "Lio:\n  max_iterations: 0\n");
  int code = 0;
  const std::string out =
      Lisfm("lio --input_path seq --output_path out --config_path " +
                dir.File("lio.yaml"),
            &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_EQ(
      out,
      "error: " + dir.File("lio.yaml") +
          ":line 2: Lio.max_iterations 0 is out of range: must be >= 1\n");
}

}  // namespace
}  // namespace lisfm
