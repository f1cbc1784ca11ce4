#include "core/progress.h"

#include <unistd.h>

#include <algorithm>

#include "core/logging.h"

namespace lisfm {

ProgressReporter::ProgressReporter(std::string label,
                                   int64_t total,
                                   double min_interval_s)
    : label_(std::move(label)),
      total_(total),
      min_interval_s_(min_interval_s),
      tty_(isatty(STDERR_FILENO) != 0 && GetLogLevel() <= LogLevel::kInfo),
      start_(std::chrono::steady_clock::now()),
      last_print_(start_) {}

ProgressReporter::~ProgressReporter() {
  try {
    Finish();
  } catch (...) {
  }
}

double ProgressReporter::ElapsedSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_)
      .count();
}

void ProgressReporter::Add(int64_t done_units) {
  done_ += done_units;
  const auto now = std::chrono::steady_clock::now();
  const double since = std::chrono::duration<double>(now - last_print_).count();
  const double interval = tty_ ? 0.1 : min_interval_s_;
  if (since < interval) return;
  std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() || finished_) return;
  last_print_ = now;
  Print(false);
}

void ProgressReporter::Finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return;
  finished_ = true;
  Print(true);
}

void ProgressReporter::Print(bool final_line) {
  if (GetLogLevel() > LogLevel::kInfo) return;
  const int64_t done = done_;
  const double elapsed = ElapsedSeconds();
  const double rate = elapsed > 0 ? done / elapsed : 0.0;
  if (tty_) {
    constexpr int kWidth = 30;
    std::string bar;
    double frac = total_ > 0 ? std::min(1.0, static_cast<double>(done) / total_) : 0;
    const int filled = static_cast<int>(frac * kWidth);
    bar.assign(filled, '#');
    bar.append(kWidth - filled, '.');
    const double eta = (rate > 0 && total_ > 0) ? (total_ - done) / rate : 0.0;
    const std::string text =
        total_ > 0 ? fmt::format("{} [{}] {}/{} {:5.1f}% {:.1f}/s eta {:.0f}s", label_, bar,
                                 done, total_, 100.0 * frac, rate, eta)
                   : fmt::format("{} {} done {:.1f}/s", label_, done, rate);
    // Through the logging facade, so that log lines never print inside the bar.
    if (final_line) {
      EndStatusLine(text);
    } else {
      ShowStatusLine(text);
    }
  } else {
    if (total_ > 0) {
      LogInfo("{}: {}/{} ({:.1f}%) {:.1f}/s{}", label_, done, total_,
              100.0 * done / total_, rate, final_line ? " done" : "");
    } else {
      LogInfo("{}: {} {:.1f}/s{}", label_, done, rate, final_line ? " done" : "");
    }
  }
}

}  // namespace lisfm
