// Shared helpers of the end-to-end MPI tests: the Open MPI environment a root CI
// and an oversubscribed 2-core machine need, and output files reduced to what must
// be byte-identical between a single-process run and runs under mpirun.
#pragma once

#include <cstdlib>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace test {

// Sets the Open MPI variables (root allowed, oversubscription: 3 ranks on 2 cores)
// and returns whether `mpirun` runs.
inline bool PrepareMpirun() {
  setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  setenv("OMPI_MCA_rmaps_base_oversubscribe", "1", 1);
  std::string out;
  return RunCommand("mpirun --version", &out) == 0;
}

// A JSON summary without its timings (keys containing "seconds", at any depth).
inline std::string JsonWithoutSeconds(const std::string& path) {
  nlohmann::json j = nlohmann::json::parse(ReadFile(path));
  std::function<void(nlohmann::json&)> strip = [&](nlohmann::json& node) {
    if (node.is_array()) {
      for (auto& value : node) strip(value);
      return;
    }
    if (!node.is_object()) return;
    std::vector<std::string> timing;
    for (auto& [key, value] : node.items()) {
      if (key.find("seconds") != std::string::npos) timing.push_back(key);
    }
    for (const std::string& key : timing) node.erase(key);
    for (auto& [key, value] : node.items()) strip(value);
  };
  strip(j);
  return j.dump(1);
}

// A config file without its output_path line (the output folders differ).
inline std::string ConfigWithoutOutputPath(const std::string& path) {
  std::string out;
  for (const std::string& line : SplitString(ReadFile(path), "\n")) {
    if (line.rfind("output_path:", 0) != 0) out += line + "\n";
  }
  return out;
}

}  // namespace test
}  // namespace lisfm
