// Progress reporting for long work. On a terminal (stderr is a tty) it draws a
// single-line bar with rate and ETA as the logging facade's status line, so a
// log message meanwhile clears the bar, prints, and the bar is redrawn below it
// (core/logging.h); otherwise it prints a plain log line at most every
// `min_interval_s` seconds (and at 100 %). Thread-safe: Add() may be called
// from TBB workers.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace lisfm {

class ProgressReporter {
 public:
  // `total` units of work (0 = unknown); `label` prefixes every line.
  ProgressReporter(std::string label, int64_t total, double min_interval_s = 5.0);
  ~ProgressReporter();  // calls Finish() if not done yet

  void Add(int64_t done_units = 1);
  void Finish();

  int64_t done() const { return done_; }
  double ElapsedSeconds() const;

  // For tests: force the plain (non-tty) mode, or the terminal mode.
  void SetPlainMode(bool plain) { tty_ = !plain; }

 private:
  void Print(bool final_line);

  std::string label_;
  int64_t total_;
  double min_interval_s_;
  bool tty_;
  bool finished_ = false;
  std::atomic<int64_t> done_{0};
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_print_;
  std::mutex mutex_;
};

}  // namespace lisfm
