// Progress of a `lisfm pipeline` stage read from its child's log lines.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace lisfm {

// `done` of `total` units (total > 0, done <= total is not enforced).
struct StageProgress {
  int64_t done = 0;
  int64_t total = 0;
  double Fraction() const { return total > 0 ? static_cast<double>(done) / total : 0.0; }
};

// The progress counter in one log line, or nullopt when it has none. Recognised:
// core/progress.h plain lines ("label: 120/500 (24.0%) 31.2/s"), and stock
// COLMAP's "Processed file [3/12]" and "Matching block [2/9]" /
// "Matching block [1/4, 2/4]" (the first counter). Counters with total 0 or
// done > total are rejected.
std::optional<StageProgress> ParseStageProgress(const std::string& line);

// One status text: "LABEL 12 s" plus ", 120/500 (24%)" when a counter is known.
std::string FormatStageStatus(const std::string& label,
                              double elapsed_s,
                              const std::optional<StageProgress>& progress);

}  // namespace lisfm
