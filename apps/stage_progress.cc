#include "apps/stage_progress.h"

#include <fmt/format.h>

#include <regex>

namespace lisfm {

std::optional<StageProgress> ParseStageProgress(const std::string& line) {
  // core/progress.h plain mode: "<label>: <done>/<total> (<pct>%)".
  static const std::regex kLisfm(R"(: ([0-9]+)/([0-9]+) \([0-9.]+%\))");
  // Stock COLMAP: "Processed file [i/N]", "Matching block [i/N]" or "[i/N, j/M]".
  static const std::regex kColmap(R"((Processed file|Matching block) \[([0-9]+)/([0-9]+)[,\]])");
  std::smatch m;
  StageProgress p;
  try {
    if (std::regex_search(line, m, kLisfm)) {
      p.done = std::stoll(m[1].str());
      p.total = std::stoll(m[2].str());
    } else if (std::regex_search(line, m, kColmap)) {
      p.done = std::stoll(m[2].str());
      p.total = std::stoll(m[3].str());
    } else {
      return std::nullopt;
    }
  } catch (const std::out_of_range&) {
    return std::nullopt;
  }
  if (p.total <= 0 || p.done > p.total) return std::nullopt;
  return p;
}

std::string FormatStageStatus(const std::string& label,
                              double elapsed_s,
                              const std::optional<StageProgress>& progress) {
  std::string text = fmt::format("{} {:.0f} s", label, elapsed_s);
  if (progress) {
    text += fmt::format(
        ", {}/{} ({:.0f}%)", progress->done, progress->total, 100.0 * progress->Fraction());
  }
  return text;
}

}  // namespace lisfm
