// The `lisfm` executable: `lisfm help`, `lisfm version`, `lisfm <command> [options]`.
#include <exception>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

#include "apps/commands.h"
#include "core/errors.h"
#include "core/mpi/mpi_world.h"
#include "core/options.h"

#ifndef LISFM_VERSION
#define LISFM_VERSION "unknown"
#endif

namespace lisfm {

const std::vector<Command>& Commands() {
  static const std::vector<Command> commands = {
      {"simulate", "simulate a HILTI-style recording (IMU, LiDARs, cameras) with exact ground truth",
       &RunSimulate},
      {"lio", "LiDAR-inertial odometry (FAST-LIO2-style iterated EKF) on a sequence folder",
       &RunLio},
      {"evaluate", "score a trajectory against ground truth (ATE, RPE, HILTI 2022 score)",
       &RunEvaluate},
      {"icp", "register two clouds: point-to-plane or Bayesian ICP, with covariance", &RunIcp},
      {"fusion", "dense RGB-D SLAM: projective ICP tracking and surfel fusion -> surfels.ply",
       &RunFusion},
      {"pose_graph",
       "optimise a g2o pose graph (2D/3D): chordal initialisation, then Levenberg-Marquardt on "
       "SE-Sync's objective",
       &RunPoseGraph},
      {"pose_slam",
       "batch pose graph on lio's output: Bayesian ICP pairs, IMU preintegration, zero velocity "
       "at rests",
       &RunPoseSlam},
      {"model_converter", "convert a COLMAP sparse model between BIN, TXT and PLY",
       &RunModelConverter},
      {"model_analyzer", "print COLMAP model statistics (as colmap model_analyzer)",
       &RunModelAnalyzer},
      {"database_info", "COLMAP database: schema, rows per table, pose priors",
       &RunDatabaseInfo},
      {"bag_importer", "a ROS1 bag (HILTI 2022 topics or a preset) -> a sequence folder",
       &RunBagImporter},
      {"bag_exporter", "a sequence folder -> a ROS1 bag in a preset's message layouts",
       &RunBagExporter},
      {"kitti_importer", "a KITTI odometry sequence (.bin scans, times, poses) -> a sequence folder",
       &RunKittiImporter},
      {"database_importer",
       "COLMAP database with pose priors, rig and a LiDAR-proxy co-visibility pair list from a "
       "sequence + pose_slam output",
       &RunDatabaseImporter},
      {"global_mapper",
       "global SfM on a COLMAP database (rotation/translation averaging, rig BA with priors and "
       "LiDAR constraints)",
       &RunGlobalMapper},
      {"pipeline",
       "recording -> lio -> pose_slam -> database_importer -> stock colmap features and matches "
       "-> global_mapper -> evaluation; one folder per stage, a report and resume",
       &RunPipeline},
      {"model_evaluator", "score a COLMAP model's cameras against reference cameras (AUC, errors)",
       &RunModelEvaluator},
  };
  return commands;
}

namespace {

void PrintHelp() {
  std::cout << "lisfm " << LISFM_VERSION
            << " -- LiDAR-inertial structure from motion\n\n"
               "Usage: lisfm <command> [--option value] [--Section.option value]\n"
               "       lisfm <command> -h     lists every option with its default\n\n"
               "Commands:\n";
  std::cout << "  " << std::left << std::setw(20) << "help" << "this list\n";
  std::cout << "  " << std::left << std::setw(20) << "version" << "print the version\n";
  for (const auto& c : Commands()) {
    std::cout << "  " << std::left << std::setw(20) << c.name << c.summary << "\n";
  }
}

int Main(int argc, char** argv) {
  if (argc < 2) {
    PrintHelp();
    return 2;
  }
  const std::string name = argv[1];
  if (name == "help" || name == "-h" || name == "--help") {
    PrintHelp();
    return 0;
  }
  if (name == "version" || name == "--version") {
    std::cout << "lisfm " << LISFM_VERSION << "\n";
    return 0;
  }
  std::vector<std::string> names;
  for (const auto& c : Commands()) {
    names.push_back(c.name);
    if (c.name == name) {
      // Under `mpirun -np N` (N > 1) only the commands that split their work
      // across the ranks run; any other would run N times into one output.
      if (mpi::WorldSize() > 1 && name != "pose_slam" && name != "database_importer" &&
          name != "global_mapper") {
        throw UsageError("lisfm " + name +
                         " does not run under mpirun with more than one process (only "
                         "pose_slam, database_importer and global_mapper do)");
      }
      std::string arg0 = "lisfm " + name;
      std::vector<char*> args;
      args.push_back(arg0.data());
      for (int i = 2; i < argc; ++i) args.push_back(argv[i]);
      return c.run(static_cast<int>(args.size()), args.data());
    }
  }
  const std::string near = NearestName(name, names);
  throw UsageError("unknown command '" + name + "'" +
                   (near.empty() ? "" : " (did you mean '" + near + "'?)") +
                   "; see 'lisfm help'");
}

}  // namespace
}  // namespace lisfm

// Under mpirun every rank runs main; a rank's failure ends the run on every
// rank with a non-zero exit code (core/mpi/mpi_world.h).
int main(int argc, char** argv) {
  lisfm::mpi::Init(&argc, &argv);
  int code = 0;
  try {
    code = lisfm::Main(argc, argv);
  } catch (const lisfm::mpi::RankError& e) {
    // Every rank has this error: printed once.
    if (lisfm::mpi::IsRoot()) std::cerr << "error: " << e.what() << "\n";
    return lisfm::mpi::Finish(e.exit_code(), /*collective_error=*/true);
  } catch (const lisfm::UsageError& e) {
    std::cerr << "error: " << e.what() << "\n";
    code = 2;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    code = 1;
  }
  return lisfm::mpi::Finish(code, /*collective_error=*/false);
}
