#include "core/progress.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "core/logging.h"

namespace lisfm {
namespace {

// Captured stderr is a file, not a terminal: the reporter is in plain mode.
TEST(ProgressReporter, PlainModePrintsPeriodicAndFinalLines) {
  SetLogLevel(LogLevel::kInfo);
  testing::internal::CaptureStderr();
  {
    ProgressReporter progress("work", 10, /*min_interval_s=*/0.0);
    for (int i = 0; i < 10; ++i) progress.Add();
    EXPECT_EQ(progress.done(), 10);
  }  // the destructor finishes
  const std::string out = testing::internal::GetCapturedStderr();
  SetLogLevel(LogLevel::kWarning);
  EXPECT_NE(out.find("work: 10/10 (100.0%)"), std::string::npos) << out;
  EXPECT_NE(out.find("done"), std::string::npos) << out;
  // No terminal control characters in plain mode (logs stay readable in CI).
  EXPECT_EQ(out.find('\r'), std::string::npos);
}

// On a terminal a log line never prints into the bar: the bar's line is
// cleared first, the message printed, and the bar drawn again after it.
TEST(ProgressReporter, LogLinesClearAndRedrawTheBar) {
  SetLogLevel(LogLevel::kInfo);
  testing::internal::CaptureStderr();
  {
    ProgressReporter progress("work", 10);
    progress.SetPlainMode(false);
    std::this_thread::sleep_for(std::chrono::milliseconds(150));  // past the redraw interval
    progress.Add();
    LogWarning("a message while the bar is shown");
    progress.Finish();
  }
  const std::string out = testing::internal::GetCapturedStderr();
  SetLogLevel(LogLevel::kWarning);
  const std::string bar = "work [###...........................] 1/10";
  const std::string clear = "\r\033[2K";
  const size_t message = out.find("a message while the bar is shown");
  ASSERT_NE(message, std::string::npos) << out;
  // Drawn before the message, and its line cleared between the bar and the message.
  const size_t drawn = out.rfind(bar, message);
  ASSERT_NE(drawn, std::string::npos) << out;
  const size_t cleared = out.rfind(clear, message);
  ASSERT_NE(cleared, std::string::npos) << out;
  EXPECT_GT(cleared, drawn) << out;
  // The message is a line of its own, and the bar comes back after it.
  const size_t end_of_message = out.find('\n', message);
  ASSERT_NE(end_of_message, std::string::npos);
  EXPECT_EQ(out.compare(end_of_message + 1, bar.size(), bar), 0) << out;
  // Finish() ends the bar's line.
  EXPECT_EQ(out.back(), '\n');
}

TEST(ProgressReporter, ThreadSafeCounting) {
  SetLogLevel(LogLevel::kWarning);
  ProgressReporter progress("threads", 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 1000; ++i) progress.Add();
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(progress.done(), 4000);
  progress.Finish();
  progress.Finish();  // idempotent
}

}  // namespace
}  // namespace lisfm
