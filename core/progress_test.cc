#include "core/progress.h"

#include <gtest/gtest.h>

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
