// Helpers for the tests that run the stock `colmap` 3.8 binary (headless, CPU).
// Header for tests only.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace colmap {
namespace test_stock {

inline std::string ColmapBinary() {
  std::string out;
  if (test::RunCommand("command -v colmap", &out) != 0) return "";
  return Trim(out);
}

#define REQUIRE_COLMAP()                                                             \
  do {                                                                               \
    if (::lisfm::colmap::test_stock::ColmapBinary().empty()) GTEST_SKIP() << "stock `colmap` not found in PATH"; \
  } while (0)

// Runs stock COLMAP headless on the CPU.
inline std::string RunColmap(const std::string& args) {
  std::string out;
  const int rc = test::RunCommand("QT_QPA_PLATFORM=offscreen " + ColmapBinary() + " " + args, &out);
  EXPECT_EQ(rc, 0) << "colmap " << args << "\n" << out;
  return out;
}

// The statistic lines of (colmap|lisfm) model_analyzer, "Name: value".
inline std::map<std::string, std::string> AnalyzerLines(const std::string& output) {
  std::map<std::string, std::string> lines;
  for (const std::string& raw : SplitString(output, "\n")) {
    for (const char* key : {"Cameras", "Images", "Registered images", "Points", "Observations",
                            "Mean track length", "Mean observations per image",
                            "Mean reprojection error"}) {
      const std::string prefix = std::string(key) + ": ";
      const size_t at = raw.find(prefix);
      // COLMAP logs with a glog prefix; take the text after "Key: ".
      if (at != std::string::npos && (at == 0 || raw[at - 1] == ' ' || raw[at - 1] == ']')) {
        lines[key] = Trim(raw.substr(at + prefix.size()));
      }
    }
  }
  return lines;
}

// Text model file as (header lines, record lines keyed by their first token).
// COLMAP 3.8 writes records in its hash-map order, so records are compared by id.
struct TextRecords {
  std::vector<std::string> header;
  std::map<std::string, std::string> records;
};
inline TextRecords ParseRecords(const std::string& text, int lines_per_record) {
  TextRecords r;
  const std::vector<std::string> lines = SplitString(text, "\n", false);
  size_t i = 0;
  while (i < lines.size() && !lines[i].empty() && lines[i][0] == '#') r.header.push_back(lines[i++]);
  for (; i + lines_per_record <= lines.size(); i += lines_per_record) {
    std::string record;
    for (int k = 0; k < lines_per_record; ++k) record += lines[i + k] + "\n";
    r.records[lines[i].substr(0, lines[i].find(' '))] = record;
  }
  return r;
}

inline void ExpectSameText(const std::string& ours, const std::string& theirs, int lines_per_record,
                    const std::string& what) {
  const TextRecords a = ParseRecords(ours, lines_per_record);
  const TextRecords b = ParseRecords(theirs, lines_per_record);
  EXPECT_EQ(a.header, b.header) << what;
  ASSERT_EQ(a.records.size(), b.records.size()) << what;
  size_t mismatches = 0;
  for (const auto& [id, record] : a.records) {
    const auto it = b.records.find(id);
    if (it == b.records.end() || it->second != record) {
      if (++mismatches <= 3) {
        ADD_FAILURE() << what << " record " << id << "\nours:   " << record << "colmap: "
                      << (it == b.records.end() ? "(missing)\n" : it->second);
      }
    }
  }
  EXPECT_EQ(mismatches, 0u) << what;
}

}  // namespace test_stock
}  // namespace colmap
}  // namespace lisfm
