// The command table of the single `lisfm` executable. Each command is
// `int RunXxx(int argc, char** argv)` where argv[0] is "lisfm <command>"; it
// returns the exit code. Errors are thrown (InputError -> 1, UsageError -> 2)
// and turned into one `error: ...` line by main().
#pragma once

#include <string>
#include <vector>

namespace lisfm {

struct Command {
  std::string name;
  std::string summary;  // one line for `lisfm help`
  int (*run)(int argc, char** argv);
};

const std::vector<Command>& Commands();

// Commands, one .cc per group.
int RunEvaluate(int argc, char** argv);  // evaluate_command.cc
int RunIcp(int argc, char** argv);       // icp_command.cc
int RunModelConverter(int argc, char** argv);  // colmap_commands.cc
int RunModelAnalyzer(int argc, char** argv);   // colmap_commands.cc
int RunDatabaseInfo(int argc, char** argv);    // colmap_commands.cc
int RunSimulate(int argc, char** argv);  // simulate_command.cc
int RunLio(int argc, char** argv);       // lio_command.cc
int RunModelEvaluator(int argc, char** argv);  // model_evaluator_command.cc
int RunGlobalMapper(int argc, char** argv);    // global_mapper_command.cc
int RunPoseGraph(int argc, char** argv);       // pose_graph_command.cc
int RunDatabaseImporter(int argc, char** argv);  // database_importer_command.cc
int RunPoseSlam(int argc, char** argv);        // pose_slam_command.cc
int RunBagImporter(int argc, char** argv);       // bag_commands.cc
int RunBagExporter(int argc, char** argv);       // bag_commands.cc
int RunPipeline(int argc, char** argv);          // pipeline_command.cc
int RunFusion(int argc, char** argv);            // fusion_command.cc

}  // namespace lisfm
