// The bad-input matrix: every `lisfm` command, every path option, given a
// missing file, an empty file, a folder where a file is expected, a file where a
// folder is expected, an empty folder, a truncated file, random bytes, or an
// output location that cannot be created; and every numeric option with a
// range (as `-h` prints it) given NaN and values outside that range.
//
// Contract checked per cell: the process exits (no signal: exit code in
// [1, 127]), non-zero (2 for option values), stderr has exactly one line
// starting "error:" and that line names the bad path (or option), no
// sanitizer report, and nothing exists under the command's final output name
// (outputs are written to a temporary name and renamed on success). A cell
// whose input is legitimately empty (an empty constraints list) instead exits
// 0 with a "warning" on stderr.
//
// The table is `kPathRows` (one line per command x path option) and the
// numeric cells are derived from `lisfm <command> -h`, so a new command or
// option is one line (or none). The summary prints the number of cells.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "colmap_ext/io/model_io.h"
#include "colmap_ext/testing/synthetic.h"
#include "core/file_utils.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/rig_io.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;
using colmap::SynthesizeDataset;
using colmap::SyntheticDatasetOptions;

// What a path option expects (which bad kinds apply to it).
enum class PathType {
  kFile,    // an input file: missing, empty, folder, truncated, random bytes
  kDir,     // an input folder: missing, a file instead, an empty folder
  kOutput,  // an output (folder or file): under a regular file (cannot be created)
};

enum class Kind {
  kMissing,
  kEmpty,
  kDirectory,
  kTruncated,
  kRandom,
  kFile,
  kEmptyDir,
  kUnwritable
};

const char* KindName(Kind k) {
  switch (k) {
    case Kind::kMissing:
      return "missing";
    case Kind::kEmpty:
      return "empty file";
    case Kind::kDirectory:
      return "folder for a file";
    case Kind::kTruncated:
      return "truncated";
    case Kind::kRandom:
      return "random bytes";
    case Kind::kFile:
      return "file for a folder";
    case Kind::kEmptyDir:
      return "empty folder";
    case Kind::kUnwritable:
      return "unwritable output";
  }
  return "?";
}

std::vector<Kind> KindsOf(PathType t) {
  switch (t) {
    case PathType::kFile:
      return {Kind::kMissing, Kind::kEmpty, Kind::kDirectory, Kind::kTruncated, Kind::kRandom};
    case PathType::kDir:
      return {Kind::kMissing, Kind::kFile, Kind::kEmptyDir};
    case PathType::kOutput:
      return {Kind::kUnwritable};
  }
  return {};
}

// One command line: `lisfm <command> --<option> <value> ...`, values naming
// fixtures as {name} (see Fixtures::Resolve) and {out} for the cell's output.
struct PathRow {
  std::string command;
  std::string option;  // the path option under test (its value in `args` is replaced)
  PathType type;
  std::string output_option;  // the option whose final name must not appear ("" none)
  std::string args;           // a valid command line (every input a good fixture)
};

// clang-format off
const std::vector<PathRow> kPathRows = {
  // simulate: the output folder is what it writes; inputs are read before.
  {"simulate", "--rig_path", PathType::kFile, "--output_path",
   "--output_path {out} --duration 1 --camera_rate 0 --lidars none --rig_path {rig} --config_path "
   "{config}"},
  {"simulate", "--trajectory_path", PathType::kFile, "--output_path",
   "--output_path {out} --duration 1 --camera_rate 0 --lidars none --trajectory_path {tum} "
   "--config_path {config}"},
  {"simulate", "--config_path", PathType::kFile, "--output_path",
   "--output_path {out} --duration 1 --camera_rate 0 --lidars none --config_path {config}"},
  {"simulate", "--output_path", PathType::kOutput, "",
   "--output_path {out} --duration 1 --camera_rate 0 --lidars none"},
  {"lio", "--input_path", PathType::kDir, "--output_path",
   "--input_path {seq} --output_path {out}"},
  {"lio", "--output_path", PathType::kOutput, "",
   "--input_path {seq} --output_path {out}"},
  {"lio", "--config_path", PathType::kFile, "--output_path",
   "--input_path {seq} --output_path {out} --config_path {config}"},
  {"evaluate", "--reference_path", PathType::kFile, "--output_path",
   "--reference_path {tum} --estimate_path {tum} --output_path {out}"},
  {"evaluate", "--estimate_path", PathType::kFile, "--output_path",
   "--reference_path {tum} --estimate_path {tum} --output_path {out}"},
  {"evaluate", "--output_path", PathType::kOutput, "",
   "--reference_path {tum} --estimate_path {tum} --output_path {out}"},
  {"icp", "--source_path", PathType::kFile, "--output_path",
   "--source_path {pcd} --target_path {pcd} --output_path {out}"},
  {"icp", "--target_path", PathType::kFile, "--output_path",
   "--source_path {pcd} --target_path {ply} --output_path {out}"},
  {"icp", "--init_path", PathType::kFile, "--output_path",
   "--source_path {pcd} --target_path {pcd} --init_path {init} --output_path {out}"},
  {"icp", "--output_path", PathType::kOutput, "",
   "--source_path {pcd} --target_path {pcd} --output_path {out}"},
  {"fusion", "--input_path", PathType::kDir, "--output_path",
   "--input_path {seq} --output_path {out} --pose_source groundtruth"},
  {"fusion", "--intrinsics_path", PathType::kFile, "--output_path",
   "--input_path {seq} --output_path {out} --pose_source groundtruth --intrinsics_path "
   "{rgbd_camera}"},
  {"fusion", "--output_path", PathType::kOutput, "",
   "--input_path {seq} --output_path {out} --pose_source groundtruth"},
  {"pose_graph", "--input_path", PathType::kFile, "--output_path",
   "--input_path {g2o} --output_path {out}"},
  {"pose_graph", "--output_path", PathType::kOutput, "",
   "--input_path {g2o} --output_path {out}"},
  {"pose_slam", "--input_path", PathType::kDir, "--output_path",
   "--input_path {seq} --lio_path {lio} --output_path {out}"},
  {"pose_slam", "--lio_path", PathType::kDir, "--output_path",
   "--input_path {seq} --lio_path {lio} --output_path {out}"},
  {"pose_slam", "--output_path", PathType::kOutput, "",
   "--input_path {seq} --lio_path {lio} --output_path {out}"},
  {"model_converter", "--input_path", PathType::kDir, "--output_path",
   "--input_path {model} --output_path {out} --output_type TXT"},
  {"model_converter", "--output_path", PathType::kOutput, "",
   "--input_path {model} --output_path {out} --output_type TXT"},
  {"model_converter", "--output_path", PathType::kOutput, "",
   "--input_path {model} --output_path {out}.ply --output_type PLY"},
  {"model_analyzer", "--path", PathType::kDir, "",
   "--path {model}"},
  {"database_info", "--database_path", PathType::kFile, "",
   "--database_path {db}"},
  {"bag_importer", "--input_path", PathType::kFile, "--output_path",
   "--input_path {bag} --output_path {out} --rig_path {rig}"},
  {"bag_importer", "--rig_path", PathType::kFile, "--output_path",
   "--input_path {bag} --output_path {out} --rig_path {rig}"},
  {"bag_importer", "--preset", PathType::kFile, "--output_path",
   "--input_path {bag} --output_path {out} --rig_path {rig} --preset {preset}"},
  {"bag_importer", "--output_path", PathType::kOutput, "",
   "--input_path {bag} --output_path {out} --rig_path {rig}"},
  {"bag_exporter", "--input_path", PathType::kDir, "--output_path",
   "--input_path {seq} --output_path {out}.bag"},
  {"bag_exporter", "--output_path", PathType::kOutput, "",
   "--input_path {seq} --output_path {out}.bag"},
  {"kitti_importer", "--input_path", PathType::kDir, "--output_path",
   "--input_path {kitti} --output_path {out}"},
  {"kitti_importer", "--poses_path", PathType::kFile, "--output_path",
   "--input_path {kitti} --output_path {out} --poses_path {kitti_poses}"},
  {"kitti_importer", "--output_path", PathType::kOutput, "",
   "--input_path {kitti} --output_path {out}"},
  {"database_importer", "--input_path", PathType::kDir, "--output_path",
   "--input_path {seq} --lio_path {lio} --pose_slam_path {ps} --output_path {out}"},
  {"database_importer", "--lio_path", PathType::kDir, "--output_path",
   "--input_path {seq} --lio_path {lio} --pose_slam_path {ps} --output_path {out}"},
  {"database_importer", "--pose_slam_path", PathType::kDir, "--output_path",
   "--input_path {seq} --lio_path {lio} --pose_slam_path {ps} --output_path {out}"},
  {"database_importer", "--image_path", PathType::kDir, "--output_path",
   "--input_path {seq} --image_path {seq} --lio_path {lio} --pose_slam_path {ps} --output_path "
   "{out}"},
  {"database_importer", "--output_path", PathType::kOutput, "",
   "--input_path {seq} --lio_path {lio} --pose_slam_path {ps} --output_path {out}"},
  {"global_mapper", "--database_path", PathType::kFile, "--output_path",
   "--database_path {syn_db} --output_path {out}"},
  {"global_mapper", "--image_path", PathType::kDir, "--output_path",
   "--database_path {syn_db} --output_path {out} --image_path {seq}"},
  {"global_mapper", "--rig_path", PathType::kFile, "--output_path",
   "--database_path {syn_db} --output_path {out} --rig_path {syn_rig}"},
  {"global_mapper", "--lidar_constraints_path", PathType::kFile, "--output_path",
   "--database_path {syn_db} --output_path {out} --lidar_constraints_path {syn_constraints}"},
  {"global_mapper", "--output_path", PathType::kOutput, "",
   "--database_path {syn_db} --output_path {out}"},
  {"pipeline", "--input_path", PathType::kDir, "--output_path",
   "--input_path {seq} --output_path {out}"},
  {"pipeline", "--rig_path", PathType::kFile, "--output_path",
   "--input_path {bag} --output_path {out} --rig_path {rig}"},
  {"pipeline", "--output_path", PathType::kOutput, "",
   "--input_path {seq} --output_path {out}"},
  {"model_evaluator", "--model_path", PathType::kDir, "--output_path",
   "--model_path {model} --reference_path {model} --output_path {out}.json"},
  {"model_evaluator", "--reference_path", PathType::kDir, "--output_path",
   "--model_path {model} --reference_path {model} --output_path {out}.json"},
  {"model_evaluator", "--output_path", PathType::kOutput, "",
   "--model_path {model} --reference_path {model} --output_path {out}.json"},
};

// Cells where the bad input is legitimate: accepted (exit 0) with a warning.
const std::vector<std::tuple<std::string, std::string, Kind>> kAcceptedWithWarning = {
  // An empty constraints list: the mapper runs on the images alone.
  {"global_mapper", "--lidar_constraints_path", Kind::kEmpty},
  // An empty config file sets no option.
  {"simulate", "--config_path", Kind::kEmpty},
  {"lio", "--config_path", Kind::kEmpty},
  // Images only give the points their colours: without them the points are grey.
  {"global_mapper", "--image_path", Kind::kEmptyDir},
};
// clang-format on

struct RunResult {
  int code = 0;  // exit code; -1 when the process ended by a signal
  std::string err;
};

RunResult RunLisfm(const std::string& args, const std::string& scratch) {
  const std::string err_path = scratch + "/stderr.txt";
  const std::string command =
      test::LisfmBinary() + " " + args + " </dev/null >/dev/null 2>" + err_path;
  const int status = std::system(command.c_str());
  RunResult r;
  // sh reports a child killed by signal N as exit code 128 + N.
  r.code = (WIFEXITED(status) && WEXITSTATUS(status) < 128) ? WEXITSTATUS(status) : -1;
  r.err = FileExists(err_path) ? ReadFile(err_path) : "";
  fs::remove(err_path);
  return r;
}

std::vector<std::string> ErrorLines(const std::string& err) {
  std::vector<std::string> lines;
  std::istringstream in(err);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("error:", 0) == 0) lines.push_back(line);
  }
  return lines;
}

bool HasSanitizerReport(const std::string& err) {
  return err.find("Sanitizer") != std::string::npos ||
         err.find("runtime error:") != std::string::npos;
}

std::string Replace(std::string s, const std::string& from, const std::string& to) {
  for (size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + to.size())) {
    s.replace(p, from.size(), to);
  }
  return s;
}

// The value of `option` in `args` ("" when absent).
std::string OptionValue(const std::string& args, const std::string& option) {
  std::istringstream in(args);
  std::string token;
  while (in >> token) {
    if (token == option && in >> token) return token;
  }
  return "";
}

std::string WithOption(const std::string& args,
                       const std::string& option,
                       const std::string& value) {
  std::istringstream in(args);
  std::string token;
  std::string out;
  while (in >> token) {
    out += (out.empty() ? "" : " ") + token;
    if (token == option && in >> token) out += " " + value;
  }
  return out;
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary);
  f << bytes;
}

// Runs f(0..n-1) on two threads (each cell is an independent process).
void ForEachOnTwoThreads(size_t n, const std::function<void(size_t)>& f) {
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t i = next++; i < n; i = next++) f(i);
  };
  std::thread worker(work);
  work();
  worker.join();
}

class BadInput : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    fixtures_ = new std::map<std::string, std::string>();
    auto& f = *fixtures_;
    const std::string d = dir_->path();
    std::string out;
    auto lisfm = [&](const std::string& args) {
      const int code = test::RunCommand(test::LisfmBinary() + " " + args + " --quiet 1", &out);
      if (code != 0) ADD_FAILURE() << "fixture: lisfm " << args << " -> " << code << "\n" << out;
    };
    // A 6 s walk: LiDAR, IMU, five cameras at 0.5 Hz and an RGB-D camera at 2 Hz.
    lisfm("simulate --output_path " + d +
          "/seq --duration 6 --camera_rate 0.5 --rgbd 1 "
          "--rgbd_rate 2 --error_sources none");
    lisfm("lio --input_path " + d + "/seq --output_path " + d +
          "/lio --Lio.keyframe_distance 0.2 --Lio.keyframe_angle_deg 5");
    lisfm("pose_slam --input_path " + d + "/seq --lio_path " + d + "/lio --output_path " + d +
          "/ps");
    lisfm("bag_exporter --input_path " + d + "/seq --output_path " + d + "/seq.bag");
    f["seq"] = d + "/seq";
    f["lio"] = d + "/lio";
    f["ps"] = d + "/ps";
    f["bag"] = d + "/seq.bag";
    f["rig"] = d + "/seq/rig.yaml";
    f["tum"] = d + "/seq/groundtruth.txt";
    f["rgbd_camera"] = d + "/seq/rgbd0/camera.yaml";
    f["constraints"] = d + "/ps/constraints.txt";
    f["preset"] = test::SourceDir() + "/configs/bags/hilti2022.yaml";
    f["pcd"] = test::SourceDir() + "/tests/data/clouds/pcl_xyzi_compressed.pcd";
    f["ply"] = test::SourceDir() + "/tests/data/clouds/pcl_xyzi_binary.ply";
    f["init"] = d + "/init.txt";
    test::WriteText(f["init"], "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
    f["config"] = d + "/config.yaml";
    test::WriteText(f["config"], "verbose: 0\nquiet: 1\n");
    // A 2D pose graph: a triangle with odometry and one loop edge.
    f["g2o"] = d + "/graph.g2o";
    test::WriteText(f["g2o"],
                    "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 1.5708\nVERTEX_SE2 2 1 1 3.1416\n"
                    "EDGE_SE2 0 1 1 0 1.5708 100 0 0 100 0 1000\n"
                    "EDGE_SE2 1 2 1 0 1.5708 100 0 0 100 0 1000\n"
                    "EDGE_SE2 2 0 1.4142 0.0 2.3562 100 0 0 100 0 1000\n");
    // A KITTI sequence of two scans (float32 x y z intensity).
    f["kitti"] = d + "/kitti";
    f["kitti_poses"] = d + "/kitti/poses.txt";
    fs::create_directories(d + "/kitti/velodyne");
    for (int s = 0; s < 2; ++s) {
      std::string bytes;
      for (int i = 0; i < 500; ++i) {
        const float p[4] = {5.0f + 0.01f * i, 0.02f * (i % 50), 0.5f - 0.001f * i, 0.5f};
        bytes.append(reinterpret_cast<const char*>(p), sizeof(p));
      }
      WriteBytes(d + "/kitti/velodyne/00000" + std::to_string(s) + ".bin", bytes);
    }
    test::WriteText(d + "/kitti/times.txt", "0.000000e+00\n1.000000e-01\n");
    test::WriteText(d + "/kitti/calib.txt", "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
    test::WriteText(f["kitti_poses"], "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0.5 0 1 0 0 0 0 1 0\n");
    // A synthetic rig recording as COLMAP model and as database with matches,
    // its rig and LiDAR constraints (as in global_mapper_command_test).
    SyntheticDatasetOptions o;
    o.num_frames = 8;
    o.with_rig = true;
    o.num_cameras = 3;
    o.trajectory = colmap::SyntheticTrajectory::kRoom;
    o.num_points = 300;
    o.pixel_noise = 0.5;
    o.prior_position_noise = 0.02;
    o.prior_rotation_noise = 0.005;
    o.num_lidar_neighbors = 1;
    const colmap::SyntheticDataset dataset = SynthesizeDataset(o);
    f["model"] = d + "/model";
    colmap::WriteModelBinary(colmap::SyntheticReconstruction(dataset), f["model"]);
    f["syn_db"] = d + "/syn.db";
    colmap::WriteSyntheticDatabase(dataset, f["syn_db"]);
    f["syn_rig"] = d + "/syn_rig.yaml";
    WriteRigYaml(f["syn_rig"], dataset.rig);
    f["syn_constraints"] = d + "/syn_constraints.txt";
    WriteLidarConstraints(dataset.constraints, f["syn_constraints"]);
    f["db"] = f["syn_db"];
  }

  static void TearDownTestSuite() {
    delete fixtures_;
    delete dir_;
  }

  static std::string Resolve(std::string args, const std::string& out) {
    for (const auto& [name, path] : *fixtures_) args = Replace(args, "{" + name + "}", path);
    return Replace(args, "{out}", out);
  }

  static test::TempDir* dir_;
  static std::map<std::string, std::string>* fixtures_;
};

test::TempDir* BadInput::dir_ = nullptr;
std::map<std::string, std::string>* BadInput::fixtures_ = nullptr;

// Makes the bad value of kind `k` in `cell` for a good value `good`; returns
// the path to pass and sets *named to what the error line must contain.
std::string MakeBad(Kind k, const std::string& cell, const std::string& good, std::string* named) {
  const std::string base = fs::path(good).filename().string();
  const std::string bad = cell + "/" + (base.empty() ? "bad" : base);
  *named = bad;
  switch (k) {
    case Kind::kMissing:
      break;
    case Kind::kEmpty:
      WriteBytes(bad, "");
      break;
    case Kind::kDirectory:
      fs::create_directories(bad);
      break;
    case Kind::kTruncated: {
      // Cut at half, then back to the last separator of that line: a text
      // record loses its last field (a record cut inside a number could still
      // parse); binary data is simply short.
      const std::string bytes = ReadFile(good);
      size_t cut = bytes.size() / 2;
      while (cut > 0 && bytes[cut - 1] != '\n' && bytes[cut] != ' ' && bytes[cut] != ',' &&
             bytes[cut] != '\t') {
        --cut;
      }
      WriteBytes(bad, bytes.substr(0, cut));
      break;
    }
    case Kind::kRandom: {
      std::mt19937 rng(test::kTestSeed);
      std::string bytes(4096, '\0');
      for (char& c : bytes) c = static_cast<char>(rng() & 0xff);
      WriteBytes(bad, bytes);
      break;
    }
    case Kind::kFile:
      WriteBytes(bad, "not a folder\n");
      break;
    case Kind::kEmptyDir:
      fs::create_directories(bad);
      break;
    case Kind::kUnwritable: {
      // Below a regular file: no folder or file can be created there (even as root).
      WriteBytes(cell + "/blocker", "a file, not a folder\n");
      *named = cell + "/blocker";
      return cell + "/blocker/" + (base.empty() ? "out" : base);
    }
  }
  return bad;
}

TEST_F(BadInput, EveryPathOptionOfEveryCommand) {
  ASSERT_FALSE(HasFailure()) << "fixtures failed";
  struct Cell {
    const PathRow* row;
    Kind kind;
    std::string problem;
  };
  std::vector<Cell> cells;
  for (const PathRow& row : kPathRows) {
    for (const Kind kind : KindsOf(row.type)) cells.push_back({&row, kind, ""});
  }
  ForEachOnTwoThreads(cells.size(), [&](size_t i) {
    const PathRow& row = *cells[i].row;
    const Kind kind = cells[i].kind;
    const std::string cell = dir_->path() + "/cell" + std::to_string(i);
    fs::create_directories(cell);
    const std::string args = Resolve(row.args, cell + "/out");
    const std::string good = OptionValue(args, row.option);
    std::string named;
    const std::string bad = MakeBad(kind, cell, good, &named);
    const std::string cell_args = row.command + " " + WithOption(args, row.option, bad);
    const RunResult r = RunLisfm(cell_args, cell);
    const std::string final_output =
        row.output_option.empty() ? "" : OptionValue(cell_args, row.output_option);
    bool accept = false;
    for (const auto& [c, o, k] : kAcceptedWithWarning) {
      accept |= (c == row.command && o == row.option && k == kind);
    }
    std::string& problem = cells[i].problem;
    const std::vector<std::string> errors = ErrorLines(r.err);
    if (HasSanitizerReport(r.err)) {
      problem = "sanitizer report";
    } else if (r.code < 0) {
      problem = "killed by a signal";
    } else if (accept) {
      if (r.code != 0) {
        problem = "exit " + std::to_string(r.code) + ", expected 0 (accepted)";
      } else if (r.err.find("warning") == std::string::npos &&
                 r.err.find("[W ") == std::string::npos) {
        problem = "accepted without a warning";
      }
    } else if (r.code == 0) {
      problem = "exit 0";
    } else if (errors.size() != 1) {
      problem = std::to_string(errors.size()) + " error: lines";
    } else if (errors[0].find(named) == std::string::npos) {
      problem = "the error line does not name " + named;
    } else if (!final_output.empty() && fs::exists(final_output)) {
      problem = "output left at " + final_output;
    }
    if (!problem.empty()) {
      problem = row.command + " " + row.option + " [" + KindName(kind) + "]: " + problem +
                "\n    lisfm " + cell_args + "\n    exit " + std::to_string(r.code) +
                ", stderr: " + r.err.substr(0, 600);
    }
    fs::remove_all(cell);
  });
  int passed = 0;
  for (const Cell& c : cells) {
    if (c.problem.empty())
      ++passed;
    else
      ADD_FAILURE() << c.problem;
  }
  std::printf("bad input, path options: %zu rows, %zu cells, %d passed\n",
              kPathRows.size(),
              cells.size(),
              passed);
}

// A numeric option as `-h` prints it: `--name  (=default, RANGE) ...`.
struct NumericOption {
  std::string name;
  std::string range;             // as printed: ">= 0", "in (0, 2]", "-1 or >= 1", ...
  std::vector<std::string> bad;  // values outside the range
};

// The commands `lisfm help` lists.
std::vector<std::string> Commands() {
  std::string out;
  test::RunCommand(test::LisfmBinary() + " help", &out);
  std::vector<std::string> commands;
  std::istringstream in(out);
  std::string line;
  bool listing = false;
  while (std::getline(in, line)) {
    if (line.rfind("Commands:", 0) == 0) {
      listing = true;
      continue;
    }
    std::istringstream words(line);
    std::string name;
    if (!listing || !(words >> name) || name == "help" || name == "version") continue;
    commands.push_back(name);
  }
  return commands;
}

// Parses a printed bound ("0.5", "-1", "1e+05").
double Number(const std::string& token) { return std::stod(token); }

std::string Format(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

// Values violating `range`: always NaN; below a lower bound (the bound itself
// when it is exclusive, one less when inclusive: zero and negative values);
// 1e30 above an upper bound (an interval's too); the gap of "a or >= b".
std::vector<std::string> BadValues(const std::string& range) {
  std::vector<std::string> bad = {"nan"};
  std::smatch m;
  const std::string num = "(-?[0-9.]+(?:e[-+]?[0-9]+)?)";
  if (std::regex_match(range, m, std::regex(">= " + num))) {
    bad.push_back(Format(Number(m[1]) - 1));
  } else if (std::regex_match(range, m, std::regex("> " + num))) {
    bad.push_back(m[1]);
  } else if (std::regex_match(range, m, std::regex("(<|<=) " + num))) {
    bad.push_back("1e30");
  } else if (std::regex_match(
                 range, m, std::regex("in ([\\[(])" + num + ", " + num + "([\\])])"))) {
    bad.push_back("1e30");
  } else if (std::regex_match(range, m, std::regex(num + " or >= " + num))) {
    bad.push_back(Format((Number(m[1]) + Number(m[2])) / 2));
  } else {
    ADD_FAILURE() << "unknown range form '" << range << "' (teach BadValues)";
  }
  return bad;
}

// The numeric options of `command` (with a range) and a command line giving
// every required option a placeholder value.
std::vector<NumericOption> NumericOptions(const std::string& command, std::string* required) {
  std::string out;
  test::RunCommand(test::LisfmBinary() + " " + command + " -h", &out);
  std::vector<NumericOption> options;
  std::istringstream in(out);
  std::string line;
  const std::regex option_line("^\\s+(--[A-Za-z0-9_.]+)\\s+\\((.*)$");
  while (std::getline(in, line)) {
    std::smatch m;
    if (!std::regex_match(line, m, option_line)) continue;
    const std::string name = m[1];
    const std::string rest = m[2];
    if (rest.rfind("required)", 0) == 0) {
      *required += " " + name + " placeholder_" + name.substr(2);
      continue;
    }
    // "(=default, RANGE) ..." with RANGE possibly holding brackets.
    if (rest.rfind("=", 0) != 0) continue;
    const size_t comma = rest.find(", ");
    const size_t close = rest.find(")");
    if (comma == std::string::npos || close < comma) continue;
    int depth = 0;
    size_t end = comma + 2;
    for (; end < rest.size(); ++end) {
      if (rest[end] == '(' || rest[end] == '[') ++depth;
      if (rest[end] == ')' || rest[end] == ']') {
        if (depth == 0) break;
        --depth;
      }
    }
    const std::string range = rest.substr(comma + 2, end - comma - 2);
    options.push_back({name, range, BadValues(range)});
  }
  return options;
}

TEST(BadInputOptions, EveryNumericOptionOutOfRange) {
  test::TempDir dir;
  struct Cell {
    std::string label;
    std::string option;
    std::string args;
    std::string scratch;
    std::string problem;
  };
  std::vector<Cell> cells;
  int options = 0;
  for (const std::string& command : Commands()) {
    std::string required;
    for (const NumericOption& option : NumericOptions(command, &required)) {
      ++options;
      for (const std::string& value : option.bad) {
        Cell c;
        c.scratch = dir.File("cell" + std::to_string(cells.size()));
        c.label = command + " " + option.name + " (" + option.range + ") = " + value;
        c.option = option.name;
        c.args = command + Replace(required, "placeholder_", c.scratch + "/out/") + " " +
                 option.name + " " + value;
        cells.push_back(c);
      }
    }
  }
  ForEachOnTwoThreads(cells.size(), [&](size_t i) {
    Cell& c = cells[i];
    fs::create_directories(c.scratch);
    const RunResult r = RunLisfm(c.args, c.scratch);
    const std::vector<std::string> errors = ErrorLines(r.err);
    if (HasSanitizerReport(r.err))
      c.problem = "sanitizer report";
    else if (r.code != 2)
      c.problem = "exit " + std::to_string(r.code) + ", expected 2";
    else if (errors.size() != 1)
      c.problem = std::to_string(errors.size()) + " error: lines";
    else if (errors[0].find(c.option) == std::string::npos)
      c.problem = "the error line does not name " + c.option;
    else if (fs::exists(c.scratch + "/out"))
      c.problem = "wrote " + c.scratch + "/out";
    if (!c.problem.empty()) c.problem += "\n    lisfm " + c.args + "\n    stderr: " + r.err;
    fs::remove_all(c.scratch);
  });
  int passed = 0;
  for (const Cell& c : cells) {
    if (c.problem.empty())
      ++passed;
    else
      ADD_FAILURE() << c.label << ": " << c.problem;
  }
  EXPECT_GT(options, 100);
  std::printf("bad input, numeric options: %d options, %zu cells, %d passed\n",
              options,
              cells.size(),
              passed);
}

}  // namespace
}  // namespace lisfm
