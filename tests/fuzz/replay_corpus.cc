// Replays the fuzzing corpus in the normal build: every file of
// <corpus>/<target>/ goes through the LLVMFuzzerTestOneInput of fuzz target
// <target> (linked here as LisfmFuzz_<target>), so each seed and each former
// crash input is a regression test of the real readers in every CI run and
// under the sanitizer build.
//
//   tests_fuzz_replay_corpus <corpus folder> [target...]
//
// Exit 0 when every input was handled (a target returns after a clean
// InputError); a crash, a sanitizer report or an escaping exception ends the
// process with that input named on stderr. Exit 1 when the folder and the
// target list disagree (a folder without a target, a target without seeds).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include "tests/fuzz/fuzz_util.h"

#define LISFM_FUZZ_TARGET(name) extern "C" int LisfmFuzz_##name(const uint8_t* data, size_t size);
#include <lisfm_fuzz_targets.inc>
#undef LISFM_FUZZ_TARGET

namespace {

namespace fs = std::filesystem;
using FuzzFunction = int (*)(const uint8_t*, size_t);

const std::map<std::string, FuzzFunction>& Targets() {
#define LISFM_FUZZ_TARGET(name) {#name, &LisfmFuzz_##name},
  static const std::map<std::string, FuzzFunction> targets = {
#include <lisfm_fuzz_targets.inc>
  };
#undef LISFM_FUZZ_TARGET
  return targets;
}

std::vector<uint8_t> ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s <corpus folder> [target...]\n", argv[0]);
    return 2;
  }
  LLVMFuzzerInitialize(&argc, &argv);
  const fs::path corpus = argv[1];
  std::vector<std::string> names;
  for (int i = 2; i < argc; ++i) names.push_back(argv[i]);
  if (names.empty()) {
    for (const auto& [name, function] : Targets()) names.push_back(name);
    for (const fs::directory_entry& entry : fs::directory_iterator(corpus)) {
      if (entry.is_directory() && Targets().count(entry.path().filename().string()) == 0) {
        std::fprintf(stderr, "error: %s: no fuzz target of this name\n", entry.path().c_str());
        return 1;
      }
    }
  }
  size_t num_inputs = 0;
  for (const std::string& name : names) {
    const auto target = Targets().find(name);
    if (target == Targets().end()) {
      std::fprintf(stderr, "error: no fuzz target '%s'\n", name.c_str());
      return 1;
    }
    const fs::path folder = corpus / name;
    std::vector<fs::path> files;
    if (fs::is_directory(folder)) {
      for (const fs::directory_entry& entry : fs::directory_iterator(folder)) {
        if (entry.is_regular_file()) files.push_back(entry.path());
      }
    }
    if (files.empty()) {
      std::fprintf(
          stderr, "error: %s: no seed inputs for fuzz target '%s'\n", folder.c_str(), name.c_str());
      return 1;
    }
    std::sort(files.begin(), files.end());
    for (const fs::path& file : files) {
      const std::vector<uint8_t> bytes = ReadBytes(file);
      static const uint8_t kNoByte = 0;  // libFuzzer never passes a null pointer
      try {
        target->second(bytes.empty() ? &kNoByte : bytes.data(), bytes.size());
      } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s: escaped %s: %s\n", file.c_str(), name.c_str(), e.what());
        return 1;
      }
      ++num_inputs;
    }
    std::printf("%-22s %4zu inputs\n", name.c_str(), files.size());
  }
  std::printf("replayed %zu inputs of %zu targets\n", num_inputs, names.size());
  return 0;
}
