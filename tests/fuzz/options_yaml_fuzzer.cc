// Fuzz target options_yaml: a --config_path YAML file through
// OptionManager::Parse, with options of every kind a command registers
// (bool, int, int64, uint64, double with ranges, string, choice, enum, a
// required string, an alias, an ordering between two options, a custom check).
// A bad config file is an InputError; a value the checks refuse is the
// UsageError every command reports with exit code 2 -- both are clean
// rejections here.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/errors.h"
#include "core/logging.h"
#include "core/options.h"
#include "tests/fuzz/fuzz_util.h"

namespace {

enum class Mode { kFast, kExact };

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = lisfm::fuzz::WriteScratchFile("config.yaml", data, size);
  bool flag = false;
  int iterations = 10;
  int64_t stamp_ns = 0;
  uint64_t seed = 1;
  double min_range = 0.5, max_range = 100, ratio = 0.5;
  std::string output_path = "out", method = "point_to_plane", input_path;
  Mode mode = Mode::kFast;
  lisfm::OptionManager options("lisfm fuzz", "config file fuzzing");
  options.AddBool("Section.flag", &flag, "a flag");
  options.AddInt("Icp.max_iterations", &iterations, "iterations", lisfm::OptionRange::AtLeast(1));
  options.AddInt64("start_ns", &stamp_ns, "stamp (ns)", lisfm::OptionRange::AtLeast(0));
  options.AddUint64("seed", &seed, "random seed");
  options.AddDouble("Lidar.min_range", &min_range, "m", lisfm::OptionRange::GreaterThan(0));
  options.AddDouble("Lidar.max_range", &max_range, "m", lisfm::OptionRange::GreaterThan(0));
  options.AddDouble("ratio", &ratio, "ratio", lisfm::OptionRange::Between(0, 1).Or(-1));
  options.AddString("output_path", &output_path, "output folder");
  options.AddChoice("Icp.method", &method, {"point_to_plane", "bayesian"}, "method");
  options.AddEnum<Mode>("mode", &mode, {{"fast", Mode::kFast}, {"exact", Mode::kExact}}, "mode");
  options.AddRequiredString("input_path", &input_path, "input");
  options.AddAlias("Icp.iterations", "Icp.max_iterations");
  options.RequireLess("Lidar.min_range", "Lidar.max_range");
  options.AddCheck("output_path",
                   [&] { return output_path.empty() ? std::string("not empty") : std::string(); });
  std::string argv0 = "fuzz", flag_name = "--config_path";
  char* argv[] = {argv0.data(), flag_name.data(), const_cast<char*>(path.c_str()), nullptr};
  try {
    options.Parse(3, argv);
  } catch (const lisfm::InputError&) {
    // A clean rejection of a bad config file.
  } catch (const lisfm::UsageError&) {
    // A clean rejection of a value the option checks refuse.
  }
  lisfm::SetLogLevel(lisfm::LogLevel::kOff);  // a config file may say `verbose: 1`
  return 0;
}
