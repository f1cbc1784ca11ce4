// `lisfm pipeline`: one command from a recording (sequence folder or ROS1 bag)
// to a metric COLMAP model, with a report:
//
//   bag_importer (bag input) -> lio -> pose_slam -> database_importer ->
//   colmap feature_extractor -> colmap matches_importer (pair list) ->
//   global_mapper -> [stock_mapper] -> [exhaustive_mapper] -> evaluate -> report
//
// Each stage runs as a child process (this executable for lisfm stages, the
// `colmap` executable for stock stages) with its stdout+stderr in a log, and
// writes into OUT/<stage>/. A stage is complete when OUT/<stage>/DONE exists;
// DONE is written last (JSON: stage, command lines, seconds, finish time). The
// log is OUT/<stage>.log while the stage runs and OUT/<stage>/stage.log once it
// has finished; a failed stage keeps OUT/<stage>.log and has no DONE.
// OUT/report.json, OUT/report.md and OUT/plots/ summarise the run
// (docs/FORMATS.md, "lisfm pipeline outputs").
#include <fcntl.h>
#include <fmt/format.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <deque>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "apps/commands.h"
#include "apps/stage_progress.h"
#include "colmap_ext/io/database.h"
#include "colmap_ext/io/model_io.h"
#include "colmap_ext/io/reconstruction.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/rig_io.h"
#include "core/logging.h"
#include "core/options.h"
#include "core/rig.h"

#ifndef LISFM_SOURCE_DIR
#define LISFM_SOURCE_DIR ""
#endif

extern char** environ;

namespace lisfm {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

// Every stage in running order. bag_importer runs for bag input only,
// stock_mapper with --compare_stock 1, exhaustive_mapper with --compare_exhaustive 1.
const std::vector<std::string>& StageNames() {
  static const std::vector<std::string> names = {"bag_importer",
                                                 "lio",
                                                 "pose_slam",
                                                 "database_importer",
                                                 "feature_extractor",
                                                 "matches_importer",
                                                 "global_mapper",
                                                 "stock_mapper",
                                                 "exhaustive_mapper",
                                                 "evaluate",
                                                 "report"};
  return names;
}

// Keys of the pipeline config file: the stages' option maps. `evaluate` is
// passed to `lisfm evaluate`, `model_evaluator` to `lisfm model_evaluator`,
// `mapper` to both stock `colmap mapper` runs, `exhaustive_matcher` to the
// stock exhaustive matching of exhaustive_mapper.
const std::vector<std::string>& ConfigKeys() {
  static const std::vector<std::string> keys = {"bag_importer",
                                                "lio",
                                                "pose_slam",
                                                "database_importer",
                                                "feature_extractor",
                                                "matches_importer",
                                                "global_mapper",
                                                "mapper",
                                                "exhaustive_matcher",
                                                "evaluate",
                                                "model_evaluator"};
  return keys;
}

// Options the pipeline sets itself (paths); a config file may not override them.
const std::set<std::string>& ReservedOptions() {
  static const std::set<std::string> names = {"input_path",
                                              "output_path",
                                              "lio_path",
                                              "pose_slam_path",
                                              "database_path",
                                              "image_path",
                                              "image_list_path",
                                              "match_list_path",
                                              "match_type",
                                              "lidar_constraints_path",
                                              "model_path",
                                              "reference_path",
                                              "estimate_path",
                                              "reference_type",
                                              "overwrite",
                                              "config_path"};
  return names;
}

// An ordered list of `--name value` options; Set replaces an earlier value.
class OptionList {
 public:
  void Set(const std::string& name, const std::string& value) {
    for (auto& [n, v] : items_) {
      if (n == name) {
        v = value;
        return;
      }
    }
    items_.emplace_back(name, value);
  }
  void AppendTo(std::vector<std::string>* args) const {
    for (const auto& [n, v] : items_) {
      args->push_back("--" + n);
      args->push_back(v);
    }
  }
  const std::vector<std::pair<std::string, std::string>>& items() const { return items_; }

 private:
  std::vector<std::pair<std::string, std::string>> items_;
};

// The pipeline config file: per key of ConfigKeys() a map of option -> value.
std::map<std::string, OptionList> ReadPipelineConfig(const std::string& path) {
  std::map<std::string, OptionList> config;
  if (path.empty()) return config;
  CheckFileExists(path, "pipeline config file");
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw InputError(path, "line " + std::to_string(e.mark.line + 1), "malformed YAML: " + e.msg);
  }
  if (root.IsNull()) return config;
  if (!root.IsMap()) {
    throw InputError(path, "", "expected a mapping of stage names to option maps");
  }
  for (const auto& item : root) {
    const std::string where = "line " + std::to_string(item.first.Mark().line + 1);
    if (!item.first.IsScalar()) throw InputError(path, where, "expected a stage name as map key");
    const std::string key = item.first.Scalar();
    const auto& keys = ConfigKeys();
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) {
      const std::string near = NearestName(key, keys);
      std::string all;
      for (const auto& k : keys) all += (all.empty() ? "" : ", ") + k;
      throw InputError(path,
                       where,
                       "unknown key '" + key + "'" +
                           (near.empty() ? "" : " (did you mean '" + near + "'?)") +
                           "; expected one of " + all);
    }
    if (config.count(key)) throw InputError(path, where, "key '" + key + "' given twice");
    OptionList& options = config[key];
    if (item.second.IsNull()) continue;
    if (!item.second.IsMap()) {
      throw InputError(path, where, "'" + key + "' must be a map of option names to values");
    }
    for (const auto& option : item.second) {
      const std::string option_where = "line " + std::to_string(option.first.Mark().line + 1);
      if (!option.first.IsScalar()) {
        throw InputError(path, option_where, "expected an option name as map key in '" + key + "'");
      }
      std::string name = option.first.Scalar();
      while (!name.empty() && name.front() == '-') name.erase(name.begin());
      if (name.empty()) throw InputError(path, option_where, "empty option name in '" + key + "'");
      if (!option.second.IsScalar()) {
        throw InputError(path,
                         option_where,
                         "'" + key + "." + name + "' must be a single value (number or text)");
      }
      if (ReservedOptions().count(name)) {
        throw InputError(
            path, option_where, "'" + key + "." + name + "' is set by lisfm pipeline itself");
      }
      options.Set(name, option.second.as<std::string>());
    }
  }
  return config;
}

std::string ShellQuote(const std::string& s) {
  if (!s.empty() && s.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                        "0123456789_-./=:,+") == std::string::npos) {
    return s;
  }
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string CommandLine(const std::vector<std::string>& args) {
  std::string line;
  for (const auto& a : args) line += (line.empty() ? "" : " ") + ShellQuote(a);
  return line;
}

// The running stage's status on stderr while its child processes run: the
// stage label, elapsed seconds and the latest progress counter found in the
// child's log (ParseStageProgress). On a terminal one status line is redrawn
// every 0.25 s and cleared when the stage ends; otherwise a plain line is
// printed at most every 10 s. The log itself is only read, never changed.
class StageMonitor {
 public:
  void Start(const std::string& label) {
    label_ = label;
    active_ = true;
    tty_ = isatty(STDERR_FILENO) != 0;
    start_ = std::chrono::steady_clock::now();
    last_print_ = start_;
    progress_.reset();
    log_path_.clear();
    offset_ = 0;
    partial_.clear();
  }
  // Reads what the child appended to `log_path` since the last call and updates the status.
  void Poll(const std::string& log_path) {
    if (!active_) return;
    if (log_path != log_path_) {
      log_path_ = log_path;
      offset_ = 0;
      partial_.clear();
    }
    std::ifstream in(log_path, std::ios::binary);
    if (in) {
      in.seekg(static_cast<std::streamoff>(offset_));
      std::string chunk((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      offset_ += chunk.size();
      partial_ += chunk;
      size_t begin = 0;
      for (size_t end; (end = partial_.find_first_of("\r\n", begin)) != std::string::npos;
           begin = end + 1) {
        if (auto p = ParseStageProgress(partial_.substr(begin, end - begin))) progress_ = p;
      }
      partial_.erase(0, begin);
    }
    const auto now = std::chrono::steady_clock::now();
    const double since = std::chrono::duration<double>(now - last_print_).count();
    if (since < (tty_ ? 0.25 : 10.0)) return;
    last_print_ = now;
    const std::string text =
        FormatStageStatus(label_, std::chrono::duration<double>(now - start_).count(), progress_);
    if (tty_) {
      ShowStatusLine(text);
    } else {
      std::cerr << text << "\n" << std::flush;
    }
  }
  // Clears the terminal status line; later Poll calls do nothing.
  void Stop() {
    if (active_ && tty_) ShowStatusLine("");
    active_ = false;
  }
  bool active() const { return active_; }

 private:
  std::string label_;
  bool active_ = false;
  bool tty_ = false;
  std::chrono::steady_clock::time_point start_, last_print_;
  std::optional<StageProgress> progress_;
  std::string log_path_;
  size_t offset_ = 0;
  std::string partial_;  // the last, unfinished log line
};

StageMonitor& Monitor() {
  static StageMonitor monitor;
  return monitor;
}

// Runs `args` (args[0] an executable path) with stdout and stderr appended to
// `log_path`; QT_QPA_PLATFORM=offscreen so that stock COLMAP needs no display.
// While a stage is monitored (Monitor().active()) its status is updated every
// 0.25 s from the log. Returns the exit code (128 + signal when killed; 127 when
// it cannot start).
int RunChild(const std::vector<std::string>& args, const std::string& log_path) {
  {
    std::ofstream log(log_path, std::ios::app);
    log << "$ " << CommandLine(args) << "\n";
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(
      &actions, 1, log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  std::vector<std::string> env_strings;
  for (char** e = environ; *e != nullptr; ++e) {
    if (std::string(*e).rfind("QT_QPA_PLATFORM=", 0) != 0) env_strings.emplace_back(*e);
  }
  env_strings.emplace_back("QT_QPA_PLATFORM=offscreen");
  std::vector<char*> env;
  for (auto& s : env_strings) env.push_back(s.data());
  env.push_back(nullptr);
  std::vector<std::string> copy = args;
  std::vector<char*> argv;
  for (auto& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int error = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), env.data());
  posix_spawn_file_actions_destroy(&actions);
  if (error != 0) {
    std::ofstream log(log_path, std::ios::app);
    log << "cannot start " << args[0] << ": " << std::strerror(error) << "\n";
    return 127;
  }
  int status = 0;
  for (;;) {
    const pid_t done = waitpid(pid, &status, Monitor().active() ? WNOHANG : 0);
    if (done == pid) break;
    if (done < 0) {
      if (errno != EINTR) return 127;
      continue;
    }
    Monitor().Poll(log_path);
    usleep(250000);
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return 1;
}

// The last `n` lines of a text file.
std::string Tail(const std::string& path, size_t n) {
  std::ifstream in(path);
  std::deque<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    lines.push_back(line);
    if (lines.size() > n) lines.pop_front();
  }
  std::string out;
  for (const auto& l : lines) out += "  | " + l + "\n";
  return out;
}

std::string NowUtc() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buffer;
}

// The path of `name` on PATH, or `name` itself when it holds a '/'; "" when
// there is no such executable.
std::string FindExecutable(const std::string& name) {
  if (name.find('/') != std::string::npos) {
    return access(name.c_str(), X_OK) == 0 && !DirExists(name) ? name : "";
  }
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string candidate = JoinPaths(dir.empty() ? "." : dir, name);
    if (access(candidate.c_str(), X_OK) == 0 && !DirExists(candidate)) return candidate;
  }
  return "";
}

std::optional<json> ReadJson(const std::string& path) {
  if (!FileExists(path)) return std::nullopt;
  try {
    return json::parse(ReadFile(path));
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// Data rows of a CSV file with one header line (0 when missing).
int64_t CountCsvRows(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  int64_t rows = 0;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] != '#') ++rows;
  }
  return rows;
}

// The numbered model under `folder` with the most images ("" when none).
std::string LargestModel(const std::string& folder) {
  std::string best;
  size_t best_images = 0;
  if (!DirExists(folder)) return best;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_directory() || name.empty() ||
        name.find_first_not_of("0123456789") != std::string::npos ||
        !colmap::HasModel(entry.path().string(), colmap::ModelFormat::kBinary)) {
      continue;
    }
    const size_t images = colmap::ReadModel(entry.path().string()).NumImages();
    if (best.empty() || images > best_images) {
      best = entry.path().string();
      best_images = images;
    }
  }
  return best;
}

json ModelCounts(const std::string& model_path, size_t num_database_images) {
  const colmap::Reconstruction model = colmap::ReadModel(model_path);
  return {{"model_path", model_path},
          {"images", num_database_images},
          {"registered_images", model.NumImages()},
          {"points", model.NumPoints3D()},
          {"observations", model.ComputeNumObservations()},
          {"mean_track_length", model.ComputeMeanTrackLength()},
          {"mean_reprojection_error_px", model.ComputeMeanReprojectionError()}};
}

// Pairs of image names with verified geometry (at least one inlier match).
std::set<std::pair<std::string, std::string>> VerifiedPairs(const colmap::Database& db) {
  std::map<colmap::image_t, std::string> names;
  for (const auto& image : db.ReadAllImages()) names[image.image_id] = image.name;
  std::set<std::pair<std::string, std::string>> pairs;
  for (const auto& [pair_id, geometry] : db.ReadAllTwoViewGeometries()) {
    if (geometry.inlier_matches.rows() == 0) continue;
    colmap::image_t a = 0, b = 0;
    colmap::PairIdToImagePair(pair_id, &a, &b);
    pairs.insert({std::min(names[a], names[b]), std::max(names[a], names[b])});
  }
  return pairs;
}

std::set<std::pair<std::string, std::string>> ListedPairs(const std::string& path) {
  std::set<std::pair<std::string, std::string>> pairs;
  std::ifstream in(path);
  std::string a, b;
  while (in >> a >> b) pairs.insert({std::min(a, b), std::max(a, b)});
  return pairs;
}

double RotationAngleDeg(const Quat& q) {
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w())) * 180.0 / M_PI;
}

Quat QuatFromQvec(const Vec4& qvec) {
  return Quat(qvec(0), qvec(1), qvec(2), qvec(3)).normalized();
}

// Per rig camera k > 0: cam_k_from_cam0 of the model's rig (rigs.bin, camera
// id k+1 = rig camera k) and of the believed calibration, against the truth.
json RigErrors(const std::string& model_path, const Rig& believed, const Rig& truth) {
  const colmap::Reconstruction model = colmap::ReadModel(model_path);
  json cameras = json::array();
  if (model.Rigs().empty() || truth.cameras.size() != believed.cameras.size()) return cameras;
  const colmap::ModelRig& rig = model.Rigs().front();
  const auto relative = [](const Rig& r, size_t k) {
    return r.cameras[k].cam_from_imu * r.cameras[0].cam_from_imu.Inverse();
  };
  for (const colmap::RigSensor& sensor : rig.sensors) {
    if (sensor.sensor.type != colmap::SensorType::kCamera || !sensor.has_pose) continue;
    const size_t k = sensor.sensor.id - 1;
    if (k == 0 || k >= truth.cameras.size()) continue;
    const SE3 estimate(QuatFromQvec(sensor.qvec), sensor.tvec);
    const SE3 true_pose = relative(truth, k);
    const SE3 e = estimate * true_pose.Inverse();
    const SE3 b = relative(believed, k) * true_pose.Inverse();
    cameras.push_back(
        {{"camera", k},
         {"refined_rotation_error_deg", RotationAngleDeg(e.rotation())},
         {"refined_translation_error_mm",
          (estimate.translation() - true_pose.translation()).norm() * 1000},
         {"calibration_rotation_error_deg", RotationAngleDeg(b.rotation())},
         {"calibration_translation_error_mm",
          (relative(believed, k).translation() - true_pose.translation()).norm() * 1000}});
  }
  return cameras;
}

json PoseJson(const SE3& pose) {
  const Vec3 omega_deg = so3::Log(pose.rotation()) * 180.0 / M_PI;
  const Vec3 t_mm = pose.translation() * 1e3;
  return {{"rotation_deg", omega_deg.norm()},
          {"rotation_vector_deg", {omega_deg.x(), omega_deg.y(), omega_deg.z()}},
          {"translation_mm", {t_mm.x(), t_mm.y(), t_mm.z()}}};
}

// global_mapper's X = rig_from_prior (BundleAdjustment.refine_prior_frame) of
// the largest component, and, given the truth, the value it should take. lio
// registers scans with the believed imu_from_lidar, so its "IMU" frame (the
// priors' and LiDAR constraints' frame) is world_from_lidar * lidar_from_imu
// (believed) = world_from_imu * E_L with the LiDAR calibration error E_L =
// imu_from_lidar (true) * imu_from_lidar (believed)^-1; the rig frame is the
// IMU frame as seen through cam0's believed extrinsics (cam0 is the fixed
// reference), rig_from_imu = E_C = cam0_from_imu (believed)^-1 * cam0_from_imu
// (true). Hence X should be E_C * E_L (vectors in the IMU axes).
json PriorFrameReport(const json& mapper_summary,
                      const std::string& believed_rig_path,
                      const std::string& truth_rig_path) {
  if (!mapper_summary.contains("components")) return json();
  const json* best = nullptr;  // points into mapper_summary
  for (const json& c : mapper_summary["components"]) {
    if (!c.contains("rig_from_prior") || !c.contains("model")) continue;
    if (best == nullptr ||
        c["model"].value("registered_images", 0) > (*best)["model"].value("registered_images", 0)) {
      best = &c;
    }
  }
  if (best == nullptr) return json();
  json j = {{"estimated", (*best)["rig_from_prior"]}};
  if (!FileExists(truth_rig_path) || !FileExists(believed_rig_path)) return j;
  const Rig believed = ReadRigYaml(believed_rig_path);
  const Rig truth = ReadRigYaml(truth_rig_path);
  if (believed.cameras.empty() || truth.cameras.empty() || believed.lidars.empty() ||
      truth.lidars.empty()) {
    return j;
  }
  const SE3 lidar_error =
      truth.lidars[0].imu_from_lidar * believed.lidars[0].imu_from_lidar.Inverse();
  const SE3 cam0_error = believed.cameras[0].cam_from_imu.Inverse() * truth.cameras[0].cam_from_imu;
  const SE3 expected = cam0_error * lidar_error;
  const json& e = (*best)["rig_from_prior"];
  const std::vector<double> w = e["rotation_vector_deg"].get<std::vector<double>>();
  const std::vector<double> t = e["translation_mm"].get<std::vector<double>>();
  const SE3 estimated(so3::Exp(Vec3(w[0], w[1], w[2]) * M_PI / 180.0),
                      Vec3(t[0], t[1], t[2]) * 1e-3);
  j["lidar_calibration_error"] = PoseJson(lidar_error);
  j["cam0_calibration_error"] = PoseJson(cam0_error);
  j["expected"] = PoseJson(expected);
  j["estimated_minus_expected"] = {
      {"rotation_deg", RotationAngleDeg(estimated.rotation() * expected.rotation().conjugate())},
      {"translation_mm", (estimated.translation() - expected.translation()).norm() * 1e3}};
  return j;
}

// How much of rig_from_prior's translation global_mapper refined (summary
// "rig_from_prior": translation_directions_refined, 0-3).
std::string TranslationRefinedText(const json& rig_from_prior) {
  const int n = rig_from_prior.value("translation_directions_refined",
                                     rig_from_prior.value("translation_refined", false) ? 3 : 0);
  if (n <= 0) return "held";
  if (n >= 3) return "refined";
  return fmt::format("refined along {} of 3 directions", n);
}

struct StageState {
  std::string name;
  bool enabled = true;
  std::string status = "not run";  // done | skipped | failed | not run | disabled
  double seconds = 0;
  std::vector<std::string> commands;
};

class Pipeline {
 public:
  std::string input_path, output_path, rig_path, config_path, colmap_path = "colmap";
  std::string start_stage, end_stage, scripts_path = LISFM_SOURCE_DIR "/scripts";
  std::string python_path = "/usr/bin/python3";
  bool overwrite = false, compare_stock = false, compare_exhaustive = false;
  int mpi_ranks = 0;  // > 0: pose_slam, database_importer, global_mapper under mpirun -np N

  int Run(int argc, char** argv);

 private:
  std::string Dir(const std::string& stage) const { return JoinPaths(output_path, stage); }
  std::string Done(const std::string& stage) const { return JoinPaths(Dir(stage), "DONE"); }
  std::string RunningLog(const std::string& stage) const {
    return JoinPaths(output_path, stage + ".log");
  }
  // Runs one command of `stage`; throws naming the stage, the command and the log's tail.
  void Exec(StageState* stage, const std::vector<std::string>& args);
  std::vector<std::string> Lisfm(const std::string& command) const { return {self_, command}; }
  // `lisfm command` under `mpirun --oversubscribe --bind-to none -np mpi_ranks` when
  // mpi_ranks > 0 (the command splits its work across the ranks; core/mpi/mpi_world.h).
  // Unbound: a rank bound to one core runs SuiteSparse's OpenMP with one thread, which
  // changes the last digits of pose_slam's covariances.
  std::vector<std::string> MpiLisfm(const std::string& command) const {
    if (mpi_ranks <= 0) return Lisfm(command);
    // The children start without a PATH search (posix_spawn).
    const std::string mpirun = FindExecutable("mpirun");
    if (mpirun.empty()) {
      throw InputError(
          fmt::format("--mpi_ranks {}: mpirun is not on PATH (install Open MPI: "
                      "apt-get install openmpi-bin)",
                      mpi_ranks));
    }
    return {mpirun,
            "--oversubscribe",
            "--bind-to",
            "none",
            "-np",
            std::to_string(mpi_ranks),
            self_,
            command};
  }
  std::vector<std::string> Colmap(const std::string& command) const { return {colmap_, command}; }
  void Append(const std::string& key, std::vector<std::string>* args) const {
    if (config_.count(key)) config_.at(key).AppendTo(args);
  }
  // Copies `from` to OUT/<stage>/database.db and returns the copy's path.
  std::string CopyDatabase(const std::string& from, const std::string& stage) const;
  void RunStage(StageState* stage);
  void CheckColmap(const std::string& first_stock_stage);
  json CollectReport();
  void WriteReport(const json& report);
  void RunPlots();

  std::string self_, colmap_, colmap_version_, sequence_;
  bool bag_input_ = false;
  std::map<std::string, OptionList> config_;
  std::vector<StageState> stages_;
  std::vector<std::string> notes_;  // warnings of the running stage, printed after its line
};

void Pipeline::Exec(StageState* stage, const std::vector<std::string>& args) {
  stage->commands.push_back(CommandLine(args));
  const int code = RunChild(args, RunningLog(stage->name));
  if (code != 0) {
    throw InputError(fmt::format("stage {} failed (exit code {}): {}\nlast lines of {}:\n{}",
                                 stage->name,
                                 code,
                                 CommandLine(args),
                                 RunningLog(stage->name),
                                 Tail(RunningLog(stage->name), 20)));
  }
}

std::string Pipeline::CopyDatabase(const std::string& from, const std::string& stage) const {
  CheckFileExists(from, "database");
  const std::string to = JoinPaths(Dir(stage), "database.db");
  fs::copy_file(from, to, fs::copy_options::overwrite_existing);
  return to;
}

void Pipeline::RunStage(StageState* stage) {
  const std::string& name = stage->name;
  const std::string dir = Dir(name);
  const std::string importer = Dir("database_importer");
  if (name == "bag_importer") {
    std::vector<std::string> a = Lisfm("bag_importer");
    a.insert(a.end(), {"--input_path", input_path, "--output_path", dir});
    if (!rig_path.empty()) a.insert(a.end(), {"--rig_path", rig_path});
    Append(name, &a);
    Exec(stage, a);
  } else if (name == "lio") {
    std::vector<std::string> a = Lisfm("lio");
    a.insert(a.end(), {"--input_path", sequence_, "--output_path", dir});
    Append(name, &a);
    Exec(stage, a);
  } else if (name == "pose_slam") {
    std::vector<std::string> a = MpiLisfm("pose_slam");
    a.insert(a.end(), {"--input_path", sequence_, "--lio_path", Dir("lio"), "--output_path", dir});
    Append(name, &a);
    Exec(stage, a);
  } else if (name == "database_importer") {
    std::vector<std::string> a = MpiLisfm("database_importer");
    a.insert(a.end(),
             {"--input_path",
              sequence_,
              "--pose_slam_path",
              Dir("pose_slam"),
              "--lio_path",
              Dir("lio"),
              "--output_path",
              dir});
    Append(name, &a);
    Exec(stage, a);
  } else if (name == "feature_extractor") {
    CreateDirs(dir);
    const std::string db = CopyDatabase(JoinPaths(importer, "database.db"), name);
    std::vector<std::string> a = Colmap("feature_extractor");
    a.insert(a.end(),
             {"--database_path",
              db,
              "--image_path",
              sequence_,
              "--image_list_path",
              JoinPaths(importer, "image_list.txt")});
    OptionList options;
    options.Set("SiftExtraction.use_gpu", "0");
    if (config_.count(name)) {
      for (const auto& [n, v] : config_.at(name).items()) options.Set(n, v);
    }
    options.AppendTo(&a);
    Exec(stage, a);
  } else if (name == "matches_importer") {
    CreateDirs(dir);
    const std::string db = CopyDatabase(JoinPaths(Dir("feature_extractor"), "database.db"), name);
    std::vector<std::string> a = Colmap("matches_importer");
    a.insert(a.end(),
             {"--database_path",
              db,
              "--match_list_path",
              JoinPaths(importer, "pairs.txt"),
              "--match_type",
              "pairs"});
    OptionList options;
    options.Set("SiftMatching.use_gpu", "0");
    if (config_.count(name)) {
      for (const auto& [n, v] : config_.at(name).items()) options.Set(n, v);
    }
    options.AppendTo(&a);
    Exec(stage, a);
  } else if (name == "global_mapper") {
    std::vector<std::string> a = MpiLisfm("global_mapper");
    a.insert(a.end(),
             {"--database_path",
              JoinPaths(Dir("matches_importer"), "database.db"),
              "--image_path",
              sequence_,
              "--output_path",
              dir,
              "--rig_path",
              JoinPaths(importer, "rig.yaml"),
              "--lidar_constraints_path",
              JoinPaths(importer, "constraints.txt")});
    OptionList options;
    options.Set("BundleAdjustment.refine_cam_from_rig", "1");
    if (config_.count(name)) {
      for (const auto& [n, v] : config_.at(name).items()) options.Set(n, v);
    }
    options.AppendTo(&a);
    Exec(stage, a);
    // The final model: the largest component, copied to OUT/sparse/0.
    const std::string largest = LargestModel(dir);
    if (largest.empty()) {
      throw InputError(
          fmt::format("stage global_mapper: no model under {} (see {})", dir, RunningLog(name)));
    }
    const std::string sparse = JoinPaths(output_path, "sparse");
    fs::remove_all(sparse);
    CreateDirs(sparse);
    fs::copy(largest, JoinPaths(sparse, "0"), fs::copy_options::recursive);
  } else if (name == "stock_mapper" || name == "exhaustive_mapper") {
    CreateDirs(JoinPaths(dir, "sparse"));
    const bool exhaustive = name == "exhaustive_mapper";
    const std::string db = CopyDatabase(
        JoinPaths(Dir(exhaustive ? "feature_extractor" : "matches_importer"), "database.db"), name);
    if (exhaustive) {
      std::vector<std::string> m = Colmap("exhaustive_matcher");
      m.insert(m.end(), {"--database_path", db});
      OptionList options;
      options.Set("SiftMatching.use_gpu", "0");
      if (config_.count("exhaustive_matcher")) {
        for (const auto& [n, v] : config_.at("exhaustive_matcher").items()) options.Set(n, v);
      }
      options.AppendTo(&m);
      const auto start = std::chrono::steady_clock::now();
      Exec(stage, m);
      WriteFileAtomically(
          JoinPaths(dir, "matching_seconds.txt"),
          fmt::format(
              "{:.3f}\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()));
    }
    std::vector<std::string> a = Colmap("mapper");
    a.insert(a.end(),
             {"--database_path",
              db,
              "--image_path",
              sequence_,
              "--output_path",
              JoinPaths(dir, "sparse")});
    Append("mapper", &a);
    Exec(stage, a);
  } else if (name == "evaluate") {
    CreateDirs(dir);
    json status = json::object();
    const std::string gt = JoinPaths(sequence_, "groundtruth.txt");
    const std::string control_points = JoinPaths(sequence_, "controlpoints.txt");
    for (const std::string trajectory : {"lio", "pose_slam"}) {
      const std::string estimate = JoinPaths(Dir(trajectory), "trajectory.txt");
      if (FileExists(gt)) {
        std::vector<std::string> a = Lisfm("evaluate");
        a.insert(a.end(),
                 {"--reference_path",
                  gt,
                  "--estimate_path",
                  estimate,
                  "--output_path",
                  JoinPaths(dir, trajectory)});
        Append("evaluate", &a);
        Exec(stage, a);
      }
      if (FileExists(control_points)) {
        // The HILTI score needs non-collinear control points; a sequence whose
        // points do not fix the alignment has no score (the reason is logged).
        std::vector<std::string> a = Lisfm("evaluate");
        a.insert(a.end(),
                 {"--reference_path",
                  control_points,
                  "--reference_type",
                  "control_points",
                  "--estimate_path",
                  estimate,
                  "--output_path",
                  JoinPaths(dir, trajectory + "_hilti")});
        stage->commands.push_back(CommandLine(a));
        const std::string log = JoinPaths(dir, trajectory + "_hilti.log");
        if (RunChild(a, log) != 0) {
          status[trajectory + "_hilti"] = "unavailable: see " + log;
          notes_.push_back(fmt::format("no HILTI score for {} (see {})", trajectory, log));
        }
      }
    }
    if (!FileExists(gt)) status["trajectories"] = "unavailable: no " + gt;
    // Model cameras against the sequence's ground truth (groundtruth.txt at the
    // true capture times with truth/rig.yaml's extrinsics). A model_evaluator
    // that rejects the folder leaves the row "unavailable" with its message.
    std::vector<std::pair<std::string, std::string>> models = {
        {"global_mapper", JoinPaths(output_path, "sparse/0")}};
    if (compare_stock)
      models.emplace_back("stock_mapper", LargestModel(Dir("stock_mapper") + "/sparse"));
    if (compare_exhaustive) {
      models.emplace_back("exhaustive_mapper", LargestModel(Dir("exhaustive_mapper") + "/sparse"));
    }
    for (const auto& [model, path] : models) {
      if (!FileExists(gt)) break;
      if (path.empty()) {
        status[model] = "unavailable: no model";
        continue;
      }
      std::vector<std::string> a = Lisfm("model_evaluator");
      a.insert(a.end(),
               {"--model_path",
                path,
                "--reference_path",
                sequence_,
                "--alignment",
                // Ours is metric (SE(3)); stock COLMAP's scale is arbitrary (Sim(3)).
                model == "global_mapper" ? "se3" : "sim3",
                "--output_path",
                JoinPaths(dir, model + "_cameras.json")});
      Append("model_evaluator", &a);
      stage->commands.push_back(CommandLine(a));
      const std::string log = JoinPaths(dir, model + "_cameras.log");
      if (RunChild(a, log) == 0) {
        status[model] = "done";
      } else {
        std::string last;
        std::ifstream in(log);
        for (std::string line; std::getline(in, line);) {
          if (line.rfind("error:", 0) == 0) last = line;
        }
        status[model] = "unavailable: " + (last.empty() ? "model_evaluator failed" : last);
        notes_.push_back(
            fmt::format("camera errors of {} unavailable ({}; log {})", model, last, log));
      }
    }
    const std::string truth_rig = JoinPaths(sequence_, "truth/rig.yaml");
    if (FileExists(truth_rig)) {
      const json rig = RigErrors(JoinPaths(output_path, "sparse/0"),
                                 ReadRigYaml(JoinPaths(importer, "rig.yaml")),
                                 ReadRigYaml(truth_rig));
      WriteFileAtomically(JoinPaths(dir, "rig.json"), rig.dump(2) + "\n");
    }
    WriteFileAtomically(JoinPaths(dir, "status.json"), status.dump(2) + "\n");
  } else if (name == "report") {
    CreateDirs(dir);
    RunPlots();
    const json report = CollectReport();
    WriteReport(report);
  }
}

void Pipeline::CheckColmap(const std::string& first_stock_stage) {
  colmap_ = FindExecutable(colmap_path);
  if (colmap_.empty()) {
    throw InputError(fmt::format(
        "stage {} needs stock COLMAP, but --colmap_path {} is not an executable{}; install "
        "COLMAP 3.8 (scripts/install_deps.sh) or pass its path with --colmap_path",
        first_stock_stage,
        colmap_path,
        colmap_path.find('/') == std::string::npos ? " on PATH" : ""));
  }
  const std::string log =
      (fs::temp_directory_path() / fmt::format("lisfm_colmap_check_{}.log", getpid())).string();
  fs::remove(log);
  const int code = RunChild({colmap_, "help"}, log);
  const std::string text = ReadFile(log);
  const size_t at = text.find("COLMAP ");
  if (at == std::string::npos) {
    throw InputError(fmt::format(
        "stage {} needs stock COLMAP, but `{} help` (exit code {}) printed no COLMAP version:\n{}",
        first_stock_stage,
        colmap_,
        code,
        [&] {
          const std::string tail = Tail(log, 20);
          fs::remove(log);
          return tail;
        }()));
  }
  colmap_version_ = text.substr(at, text.find_first_of(" \n", at + 7) - at);
  fs::remove(log);
  LogInfo("pipeline: {} is {}", colmap_, colmap_version_);
}

void Pipeline::RunPlots() {
  const std::string script = JoinPaths(scripts_path, "pipeline_plots.py");
  const std::string plots = JoinPaths(output_path, "plots");
  if (!FileExists(script) || access(python_path.c_str(), X_OK) != 0) {
    notes_.push_back(fmt::format(
        "no plots ({} or {} missing); the report is written without them", script, python_path));
    return;
  }
  std::vector<std::string> a = {python_path, script, "--output_dir", plots};
  for (const std::string t : {"lio", "pose_slam"}) {
    const std::string path = JoinPaths(Dir(t), "trajectory.txt");
    if (FileExists(path)) a.insert(a.end(), {"--trajectory", t + "=" + path});
  }
  const std::string gt = JoinPaths(sequence_, "groundtruth.txt");
  if (FileExists(gt)) a.insert(a.end(), {"--groundtruth", gt});
  const std::string model = JoinPaths(output_path, "sparse/0");
  if (DirExists(model)) a.insert(a.end(), {"--model_path", model});
  const std::string log = JoinPaths(Dir("report"), "plots.log");
  if (RunChild(a, log) != 0) {
    notes_.push_back(fmt::format(
        "the plot script failed (matplotlib missing?); report without plots. Log: {}\n{}",
        log,
        Tail(log, 5)));
  }
}

json TrajectoryMetrics(const std::string& dir) {
  json j;
  if (auto m = ReadJson(JoinPaths(dir, "metrics.json"))) {
    j["ate_translation_rmse_m"] = (*m)["ate"]["translation_m"]["rmse"];
    j["ate_rotation_rmse_deg"] = (*m)["ate"]["rotation_deg"]["rmse"];
    j["rpe_translation_rmse_m"] = (*m)["rpe"]["per_frame"]["translation_m"]["rmse"];
    j["rpe_rotation_rmse_deg"] = (*m)["rpe"]["per_frame"]["rotation_deg"]["rmse"];
  }
  if (auto m = ReadJson(JoinPaths(dir + "_hilti", "metrics.json"))) {
    j["hilti2022_score"] = (*m)["hilti2022"]["score"];
    j["control_points_associated"] = (*m)["num_associated"];
  }
  return j;
}

json Pipeline::CollectReport() {
  json report;
  report["input_path"] = input_path;
  report["sequence_path"] = sequence_;
  report["output_path"] = output_path;
  // The stock COLMAP of the run that ran the stock stages (OUT/colmap.json).
  report["colmap"] = ReadJson(JoinPaths(output_path, "colmap.json"))
                         .value_or(json{{"path", colmap_}, {"version", colmap_version_}});
  json stages = json::array();
  json counts_by_stage = json::object();
  const std::string importer = Dir("database_importer");
  for (const StageState& s : stages_) {
    json counts = json::object();
    try {
      if (s.name == "lio") {
        counts["scans"] = CountCsvRows(JoinPaths(Dir("lio"), "scans.csv"));
        counts["keyframes"] = CountCsvRows(JoinPaths(Dir("lio"), "keyframes/keyframes.csv"));
      } else if (s.name == "pose_slam") {
        if (auto m = ReadJson(JoinPaths(Dir("pose_slam"), "pose_slam_summary.json"))) {
          counts["keyframes"] = (*m)["keyframes"];
          counts["pair_candidates"] = (*m)["pairs"]["candidates"];
          counts["pairs_kept"] = (*m)["pairs"]["kept"];
        }
      } else if (s.name == "database_importer") {
        if (auto m = ReadJson(JoinPaths(importer, "importer_summary.json"))) {
          counts["images"] = (*m)["images"];
          counts["rig_frames"] = (*m)["rig_frames"];
          counts["constraints"] = (*m)["constraints"]["written"];
          counts["pairs"] = (*m)["pairs"]["total"];
          counts["covisibility_pairs"] = (*m)["pairs"]["covisibility"];
        }
      } else if (s.name == "feature_extractor" && FileExists(Done(s.name))) {
        const colmap::Database db(JoinPaths(Dir(s.name), "database.db"),
                                  colmap::Database::OpenMode::kReadOnly);
        counts["images"] = db.NumImages();
        counts["features"] = db.SumRowsColumn("keypoints");
      } else if (s.name == "matches_importer" && FileExists(Done(s.name))) {
        const colmap::Database db(JoinPaths(Dir(s.name), "database.db"),
                                  colmap::Database::OpenMode::kReadOnly);
        counts["pairs_listed"] = ListedPairs(JoinPaths(importer, "pairs.txt")).size();
        counts["matched_pairs"] = VerifiedPairs(db).size();
      } else if (s.name == "global_mapper" && FileExists(Done(s.name))) {
        const colmap::Database db(JoinPaths(Dir("matches_importer"), "database.db"),
                                  colmap::Database::OpenMode::kReadOnly);
        counts = ModelCounts(JoinPaths(output_path, "sparse/0"), db.NumImages());
      } else if ((s.name == "stock_mapper" || s.name == "exhaustive_mapper") &&
                 FileExists(Done(s.name))) {
        const colmap::Database db(JoinPaths(Dir(s.name), "database.db"),
                                  colmap::Database::OpenMode::kReadOnly);
        const std::string model = LargestModel(JoinPaths(Dir(s.name), "sparse"));
        if (!model.empty()) counts = ModelCounts(model, db.NumImages());
        if (s.name == "exhaustive_mapper") counts["matched_pairs"] = VerifiedPairs(db).size();
      }
    } catch (const std::exception& e) {
      counts["error"] = e.what();
    }
    json entry = {{"name", s.name}, {"status", s.status}, {"seconds", s.seconds}};
    if (!counts.empty()) entry["counts"] = counts;
    counts_by_stage[s.name] = counts;
    stages.push_back(entry);
  }
  report["stages"] = stages;

  const std::string eval = Dir("evaluate");
  if (FileExists(Done("evaluate"))) {
    json trajectories = json::object();
    for (const std::string t : {"lio", "pose_slam"}) {
      const json j = TrajectoryMetrics(JoinPaths(eval, t));
      if (!j.is_null()) trajectories[t] = j;
    }
    report["trajectories"] = trajectories;
    if (auto rig = ReadJson(JoinPaths(eval, "rig.json"))) report["rig"] = *rig;
  }
  if (FileExists(Done("global_mapper"))) {
    if (auto m = ReadJson(JoinPaths(Dir("global_mapper"), "global_mapper_summary.json"))) {
      const json prior_frame = PriorFrameReport(
          *m, JoinPaths(sequence_, "rig.yaml"), JoinPaths(sequence_, "truth/rig.yaml"));
      if (!prior_frame.is_null()) report["prior_frame"] = prior_frame;
    }
  }
  const auto status = ReadJson(JoinPaths(eval, "status.json")).value_or(json::object());

  // The models side by side: ours, stock mapper on the same matches, stock
  // exhaustive matching + mapper.
  json comparison = json::array();
  const std::vector<std::pair<std::string, std::string>> methods = {
      {"global_mapper", "lisfm global_mapper (pair list)"},
      {"stock_mapper", "colmap mapper (pair list)"},
      {"exhaustive_mapper", "colmap exhaustive_matcher + mapper"}};
  for (const auto& [stage, label] : methods) {
    const auto it = std::find_if(
        stages_.begin(), stages_.end(), [&](const StageState& s) { return s.name == stage; });
    if (it == stages_.end() || !it->enabled) continue;
    json row = {{"method", label}, {"stage", stage}, {"seconds", it->seconds}};
    const json& counts = counts_by_stage[stage];
    for (const char* key :
         {"registered_images", "images", "points", "mean_reprojection_error_px"}) {
      if (counts.contains(key)) row[key] = counts[key];
    }
    if (auto m = ReadJson(JoinPaths(eval, stage + "_cameras.json"))) {
      row["cameras"] = {{"alignment", (*m)["alignment"]},
                        {"scale", (*m)["reference_from_estimate"]["scale"]},
                        {"position_error_m", (*m)["position_error"]},
                        {"rotation_error_deg", (*m)["rotation_error_deg"]}};
    } else if (status.contains(stage)) {
      row["cameras"] = status[stage];
    }
    comparison.push_back(row);
  }
  report["comparison"] = comparison;

  if (counts_by_stage.contains("exhaustive_mapper") && FileExists(Done("exhaustive_mapper"))) {
    const colmap::Database db(JoinPaths(Dir("exhaustive_mapper"), "database.db"),
                              colmap::Database::OpenMode::kReadOnly);
    const auto verified = VerifiedPairs(db);
    const auto listed = ListedPairs(JoinPaths(importer, "pairs.txt"));
    size_t found = 0;
    for (const auto& p : verified) found += listed.count(p);
    report["covisibility_recall"] = {
        {"exhaustive_verified_pairs", verified.size()},
        {"listed", found},
        {"recall", verified.empty() ? 0.0 : static_cast<double>(found) / verified.size()}};
  }
  json plots = json::array();
  for (const char* p : {"trajectories.png", "errors.png", "model.png"}) {
    if (FileExists(JoinPaths(output_path, std::string("plots/") + p))) {
      plots.push_back(std::string("plots/") + p);
    }
  }
  report["plots"] = plots;
  report["colmap_gui"] = CommandLine({"colmap",
                                      "gui",
                                      "--database_path",
                                      JoinPaths(Dir("matches_importer"), "database.db"),
                                      "--image_path",
                                      sequence_,
                                      "--import_path",
                                      JoinPaths(output_path, "sparse/0")});
  return report;
}

std::string Num(const json& j, int decimals) {
  if (!j.is_number()) return "-";
  if (j.is_number_integer()) return std::to_string(j.get<int64_t>());
  const double v = j.get<double>();
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : "-";
}

void Pipeline::WriteReport(const json& report) {
  WriteFileAtomically(JoinPaths(output_path, "report.json"), report.dump(2) + "\n");
  std::string md = "# lisfm pipeline report\n\n";
  md += fmt::format("Input `{}` → `{}`; stock COLMAP `{}` ({}).\n\n",
                    input_path,
                    output_path,
                    report["colmap"]["path"].get<std::string>(),
                    report["colmap"]["version"].get<std::string>());
  md += "## Stages\n\n| stage | status | seconds | counts |\n|---|---|---:|---|\n";
  for (const json& s : report["stages"]) {
    std::string counts;
    if (s.contains("counts")) {
      for (const auto& [k, v] : s["counts"].items()) {
        if (k == "model_path") continue;
        counts += (counts.empty() ? "" : ", ") + k + " " +
                  (v.is_string() ? v.get<std::string>() : Num(v, 3));
      }
    }
    md += fmt::format("| {} | {} | {} | {} |\n",
                      s["name"].get<std::string>(),
                      s["status"].get<std::string>(),
                      Num(s["seconds"], 1),
                      counts);
  }
  if (report.contains("trajectories") && !report["trajectories"].empty()) {
    md +=
        "\n## Trajectories vs ground truth\n\n| trajectory | ATE rmse [m] | ATE rot. rmse "
        "[deg] | RPE/frame [m] | RPE/frame [deg] | HILTI 2022 score |\n"
        "|---|---:|---:|---:|---:|---:|\n";
    for (const auto& [t, j] : report["trajectories"].items()) {
      md += fmt::format("| {} | {} | {} | {} | {} | {} |\n",
                        t,
                        Num(j.value("ate_translation_rmse_m", json()), 4),
                        Num(j.value("ate_rotation_rmse_deg", json()), 3),
                        Num(j.value("rpe_translation_rmse_m", json()), 4),
                        Num(j.value("rpe_rotation_rmse_deg", json()), 3),
                        Num(j.value("hilti2022_score", json()), 1));
    }
  }
  md +=
      "\n## Models side by side\n\n| method | seconds | registered / images | points | "
      "reproj. [px] | alignment | position error mean / max [mm] | rotation error mean / max "
      "[deg] |\n"
      "|---|---:|---:|---:|---:|---|---:|---:|\n";
  for (const json& row : report["comparison"]) {
    std::string position = "-", rotation = "-", alignment = "-";
    if (row.contains("cameras") && row["cameras"].is_object()) {
      const json& c = row["cameras"];
      const auto mm = [](const json& v) {
        return v.is_number() ? fmt::format("{:.2f}", v.get<double>() * 1000) : std::string("-");
      };
      position = mm(c["position_error_m"]["mean"]) + " / " + mm(c["position_error_m"]["max"]);
      rotation =
          Num(c["rotation_error_deg"]["mean"], 4) + " / " + Num(c["rotation_error_deg"]["max"], 4);
      alignment = c.value("alignment", json()) == "sim3"
                      ? "Sim(3), scale " + Num(c.value("scale", json()), 3)
                      : "SE(3)";
    } else if (row.contains("cameras")) {
      position = row["cameras"].get<std::string>();
    }
    md += fmt::format("| {} | {} | {} / {} | {} | {} | {} | {} | {} |\n",
                      row["method"].get<std::string>(),
                      Num(row["seconds"], 1),
                      Num(row.value("registered_images", json()), 0),
                      Num(row.value("images", json()), 0),
                      Num(row.value("points", json()), 0),
                      Num(row.value("mean_reprojection_error_px", json()), 3),
                      alignment,
                      position,
                      rotation);
  }
  md +=
      "\nCamera errors: `lisfm model_evaluator` against the sequence's ground truth (true "
      "capture times, truth/rig.yaml). lisfm's model is metric and aligned by SE(3) (no scale); "
      "stock COLMAP's models have an arbitrary scale and are aligned by Sim(3), whose scale is "
      "shown (1 = metric).\n";
  if (report.contains("covisibility_recall")) {
    const json& r = report["covisibility_recall"];
    md += fmt::format(
        "\nCo-visibility recall: {} of {} pairs verified by exhaustive matching "
        "are on the pair list ({:.1f} %).\n",
        Num(r["listed"], 0),
        Num(r["exhaustive_verified_pairs"], 0),
        100.0 * r["recall"].get<double>());
  }
  if (report.contains("rig") && !report["rig"].empty()) {
    md +=
        "\n## Camera extrinsics (cam_k_from_cam0) vs truth/rig.yaml\n\n| camera | calibration "
        "[deg] | calibration [mm] | refined [deg] | refined [mm] |\n|---|---:|---:|---:|---:|\n";
    for (const json& c : report["rig"]) {
      md += fmt::format("| cam{} | {} | {} | {} | {} |\n",
                        Num(c["camera"], 0),
                        Num(c["calibration_rotation_error_deg"], 4),
                        Num(c["calibration_translation_error_mm"], 2),
                        Num(c["refined_rotation_error_deg"], 4),
                        Num(c["refined_translation_error_mm"], 2));
    }
  }
  if (report.contains("prior_frame")) {
    const json& p = report["prior_frame"];
    const auto vec = [](const json& v, int decimals) {
      std::string s;
      for (const json& x : v) s += (s.empty() ? "" : ", ") + Num(x, decimals);
      return "[" + s + "]";
    };
    const auto row = [&](const std::string& label, const json& pose) {
      return fmt::format("| {} | {} | {} | {} |\n",
                         label,
                         Num(pose["rotation_deg"], 4),
                         vec(pose["rotation_vector_deg"], 4),
                         vec(pose["translation_mm"], 2));
    };
    const json& e = p["estimated"];
    md += fmt::format(
        "\n## LiDAR/IMU frame in the rig frame (rig_from_prior)\n\nThe pose priors and LiDAR "
        "constraints live in lio's IMU frame, which carries the LiDAR extrinsic calibration "
        "error; global_mapper's bundle adjustment estimates that frame in the rig frame "
        "(rotation {}, translation {}; held where the LiDAR constraints do not determine "
        "it).\n\n| | rotation [deg] | rotation vector, IMU axes [deg] | translation [mm] |\n"
        "|---|---:|---:|---:|\n",
        e.value("rotation_refined", false) ? "refined" : "held",
        TranslationRefinedText(e));
    md += row("estimated", e);
    if (p.contains("expected")) {
      md += row("expected from truth/rig.yaml (cam0 and LiDAR calibration errors)", p["expected"]);
      md += row("LiDAR calibration error, imu_from_lidar true · believed⁻¹",
                p["lidar_calibration_error"]);
      md += fmt::format("\nEstimate vs expected: {} deg, {} mm.\n",
                        Num(p["estimated_minus_expected"]["rotation_deg"], 4),
                        Num(p["estimated_minus_expected"]["translation_mm"], 2));
    }
  }
  if (!report["plots"].empty()) {
    md += "\n## Plots\n\n";
    for (const json& p : report["plots"]) {
      md += fmt::format("![{}]({})\n", p.get<std::string>(), p.get<std::string>());
    }
  }
  md += "\n## Open the model\n\n```\n" + report["colmap_gui"].get<std::string>() + "\n```\n";
  WriteFileAtomically(JoinPaths(output_path, "report.md"), md);
}

int Pipeline::Run(int argc, char** argv) {
  // --config_path names the pipeline's own file (stage maps), not options of
  // this command; it is taken out before the option parser sees argv.
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--config_path" && i + 1 < argc) {
      config_path = argv[++i];
    } else if (arg.rfind("--config_path=", 0) == 0) {
      config_path = arg.substr(14);
    } else {
      args.push_back(argv[i]);
    }
  }
  OptionManager options(
      "lisfm pipeline",
      "recording (sequence folder or ROS1 bag) -> lio -> pose_slam -> database_importer -> stock "
      "colmap features + matches on the pair list -> global_mapper -> evaluation and report; "
      "--config_path FILE.yaml holds per-stage options (configs/pipeline_*.yaml)");
  options.AddRequiredString(
      "input_path", &input_path, "sequence folder (with rig.yaml) or ROS1 bag (.bag)");
  options.AddRequiredString("output_path",
                            &output_path,
                            "output folder: one subfolder per stage, sparse/0, report.md/json");
  options.AddString("rig_path",
                    &rig_path,
                    "rig YAML or Kalibr folder for a bag (a sequence folder has its rig.yaml)");
  options.AddString("start_stage",
                    &start_stage,
                    "rerun from this stage (later stages too); earlier ones must be done");
  options.AddString("end_stage", &end_stage, "stop after this stage");
  options.AddBool("overwrite", &overwrite, "rerun stages that are already done");
  options.AddBool("compare_stock",
                  &compare_stock,
                  "also run stock colmap mapper on a copy of the matched database");
  options.AddBool("compare_exhaustive",
                  &compare_exhaustive,
                  "also run stock exhaustive_matcher + mapper (slow for long recordings)");
  options.AddString("colmap_path", &colmap_path, "the colmap executable (name on PATH or path)");
  options.AddString(
      "scripts_path", &scripts_path, "folder of pipeline_plots.py (the source tree's scripts/)");
  options.AddString("python_path", &python_path, "python3 with matplotlib, for the plots");
  options.AddInt("mpi_ranks",
                 &mpi_ranks,
                 "run pose_slam, database_importer and global_mapper under `mpirun "
                 "--oversubscribe --bind-to none -np N` (0: one process); outputs are the same "
                 "for any N",
                 OptionRange::AtLeast(0));
  if (!options.Parse(static_cast<int>(args.size()), args.data())) return 0;

  // Stages: names checked first (usage errors before any file access).
  const auto& names = StageNames();
  const auto index_of = [&](const std::string& stage, const std::string& option) {
    const auto it = std::find(names.begin(), names.end(), stage);
    if (it == names.end()) {
      const std::string near = NearestName(stage, names);
      std::string all;
      for (const auto& n : names) all += (all.empty() ? "" : ", ") + n;
      throw UsageError(fmt::format("--{} {}: unknown stage{}; stages: {}",
                                   option,
                                   stage,
                                   near.empty() ? "" : " (did you mean '" + near + "'?)",
                                   all));
    }
    return static_cast<size_t>(it - names.begin());
  };
  const size_t start_index = start_stage.empty() ? 0 : index_of(start_stage, "start_stage");
  const size_t end_index = end_stage.empty() ? names.size() - 1 : index_of(end_stage, "end_stage");
  if (start_index > end_index) {
    throw UsageError(
        fmt::format("--start_stage {} comes after --end_stage {}", start_stage, end_stage));
  }
  config_ = ReadPipelineConfig(config_path);

  // Input: a sequence folder or a bag.
  if (DirExists(input_path)) {
    if (!FileExists(JoinPaths(input_path, "rig.yaml"))) {
      throw InputError(input_path,
                       "",
                       "expected a sequence folder (with rig.yaml) or a ROS1 bag (.bag); this "
                       "folder has no rig.yaml");
    }
    sequence_ = fs::absolute(input_path).lexically_normal().string();
  } else if (FileExists(input_path)) {
    std::ifstream in(input_path, std::ios::binary);
    char magic[13] = {};
    in.read(magic, 13);
    if (std::string(magic, 13) != "#ROSBAG V2.0\n") {
      throw InputError(input_path,
                       "",
                       "expected a sequence folder (with rig.yaml) or a ROS1 bag (.bag); this "
                       "file is not a ROS1 bag (no '#ROSBAG V2.0' header)");
    }
    bag_input_ = true;
  } else {
    throw InputError(input_path, "", "not found (--input_path: a sequence folder or a ROS1 bag)");
  }
  for (size_t k = 0; k < names.size(); ++k) {
    StageState s;
    s.name = names[k];
    s.enabled = (s.name != "bag_importer" || bag_input_) &&
                (s.name != "stock_mapper" || compare_stock) &&
                (s.name != "exhaustive_mapper" || compare_exhaustive);
    if (!s.enabled) s.status = "disabled";
    stages_.push_back(s);
  }
  if (!start_stage.empty() && !stages_[start_index].enabled) {
    throw UsageError(
        fmt::format("--start_stage {}: that stage does not run for this input and "
                    "these options",
                    start_stage));
  }

  // Which stages run: from start_index (everything from there is rerun) or
  // from the first stage that is not done; up to end_index.
  std::vector<size_t> to_run;
  bool rerun = !start_stage.empty() || overwrite;
  for (size_t k = 0; k <= end_index; ++k) {
    StageState& s = stages_[k];
    if (!s.enabled) continue;
    if (k < start_index) {
      if (!FileExists(Done(s.name))) {
        throw UsageError(
            fmt::format("--start_stage {}: the earlier stage {} is not done ({} "
                        "missing); start from {}",
                        start_stage,
                        s.name,
                        Done(s.name),
                        s.name));
      }
      continue;
    }
    if (!rerun && FileExists(Done(s.name))) continue;
    rerun = true;  // every stage after one that runs runs too
    to_run.push_back(k);
  }
  const std::set<std::string> stock = {
      "feature_extractor", "matches_importer", "stock_mapper", "exhaustive_mapper"};
  for (size_t k : to_run) {
    if (stock.count(stages_[k].name)) {
      CheckColmap(stages_[k].name);
      break;
    }
  }
  // --rig_path is read by a stage (bag_importer); read it now, so that a bad rig
  // fails before the output folder exists.
  if (!rig_path.empty()) {
    if (DirExists(rig_path)) {
      LoadHiltiCalibration(rig_path);
    } else {
      ReadRigYaml(rig_path);
    }
  }
  // The output folder: new, empty, or an earlier pipeline output.
  const std::string marker = JoinPaths(output_path, ".lisfm_pipeline");
  if (FileExists(output_path)) {
    throw UsageError("--output_path " + output_path + " is a file, not a folder");
  }
  if (DirExists(output_path) && !fs::is_empty(output_path) && !FileExists(marker)) {
    throw UsageError("--output_path " + output_path +
                     " is a non-empty folder that lisfm pipeline did not write; choose another");
  }
  CreateDirs(output_path);
  output_path = fs::absolute(output_path).lexically_normal().string();
  WriteFileAtomically(JoinPaths(output_path, ".lisfm_pipeline"), "lisfm pipeline output\n");
  if (bag_input_) sequence_ = Dir("bag_importer");
  self_ = fs::read_symlink("/proc/self/exe").string();

  if (!colmap_.empty()) {
    const json colmap = {{"path", colmap_}, {"version", colmap_version_}};
    WriteFileAtomically(JoinPaths(output_path, "colmap.json"), colmap.dump(2) + "\n");
  }
  // Invalidate the stages that will run and everything after them.
  if (!to_run.empty()) {
    for (size_t k = to_run.front(); k < stages_.size(); ++k) {
      fs::remove(Done(stages_[k].name));
    }
  }
  WriteFileAtomically(JoinPaths(output_path, "pipeline_config.yaml"), [&] {
    std::string y = "# lisfm pipeline: effective options of the last run\n";
    y += "input_path: " + input_path + "\noutput_path: " + output_path + "\n";
    y += "rig_path: \"" + rig_path + "\"\ncolmap_path: " + colmap_path + "\n";
    y += fmt::format("compare_stock: {}\ncompare_exhaustive: {}\nmpi_ranks: {}\n",
                     compare_stock ? 1 : 0,
                     compare_exhaustive ? 1 : 0,
                     mpi_ranks);
    y += "config_path: \"" + config_path + "\"\nstages:\n";
    for (const auto& [key, list] : config_) {
      y += "  " + key + ":\n";
      for (const auto& [n, v] : list.items()) y += "    " + n + ": \"" + v + "\"\n";
    }
    return y;
  }());

  int enabled_count = 0;
  for (const StageState& s : stages_) enabled_count += s.enabled;
  int number = 0;
  const auto total_start = std::chrono::steady_clock::now();
  for (size_t k = 0; k < stages_.size(); ++k) {
    StageState& s = stages_[k];
    if (!s.enabled) continue;
    ++number;
    const std::string label = fmt::format("[{}/{}] {}", number, enabled_count, s.name);
    if (std::find(to_run.begin(), to_run.end(), k) == to_run.end()) {
      if (FileExists(Done(s.name))) {
        s.status = "skipped";
        if (auto done = ReadJson(Done(s.name))) s.seconds = done->value("seconds", 0.0);
        if (k <= end_index) std::cout << label << " done earlier, skipped\n" << std::flush;
      }
      continue;
    }
    if (s.name == "report") {
      // The report lists this stage as done with its own time.
      s.status = "done";
    }
    const auto start = std::chrono::steady_clock::now();
    fs::remove(RunningLog(s.name));
    if (DirExists(Dir(s.name))) fs::remove_all(Dir(s.name));
    Monitor().Start(label);
    try {
      RunStage(&s);
    } catch (const std::exception& e) {
      Monitor().Stop();
      s.status = "failed";
      std::cout << label << " ... failed\n" << std::flush;
      for (const std::string& note : notes_) LogWarning("pipeline: {}: {}", s.name, note);
      throw;
    }
    Monitor().Stop();
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    s.status = "done";
    CreateDirs(Dir(s.name));
    if (FileExists(RunningLog(s.name))) {
      fs::rename(RunningLog(s.name), JoinPaths(Dir(s.name), "stage.log"));
    } else {
      WriteFileAtomically(JoinPaths(Dir(s.name), "stage.log"), "");  // ran no child process
    }
    json done = {{"stage", s.name},
                 {"commands", s.commands},
                 {"seconds", s.seconds},
                 {"finished", NowUtc()}};
    WriteFileAtomically(Done(s.name), done.dump(2) + "\n");
    std::cout << label << fmt::format(" ... {:.1f} s\n", s.seconds) << std::flush;
    for (const std::string& note : notes_) LogWarning("pipeline: {}: {}", s.name, note);
    notes_.clear();
  }
  if (!FileExists(Done("report"))) {
    std::cout << "pipeline: stopped after " << names[end_index] << " (--end_stage); no report\n";
    return 0;
  }

  // The summary table (stage, status, seconds) and where the files are.
  std::cout << fmt::format("\n{:<20}{:<10}{:>10}\n", "stage", "status", "seconds");
  for (const StageState& s : stages_) {
    if (!s.enabled) continue;
    std::cout << fmt::format("{:<20}{:<10}{:>10.1f}\n", s.name, s.status, s.seconds);
  }
  std::cout << fmt::format(
      "{:<30}{:>10.1f}\n",
      "this run",
      std::chrono::duration<double>(std::chrono::steady_clock::now() - total_start).count());
  std::cout << "\nmodel   " << JoinPaths(output_path, "sparse/0") << "\nreport  "
            << JoinPaths(output_path, "report.md") << " (and report.json)\n";
  return 0;
}

}  // namespace

int RunPipeline(int argc, char** argv) {
  Pipeline pipeline;
  return pipeline.Run(argc, argv);
}

}  // namespace lisfm
