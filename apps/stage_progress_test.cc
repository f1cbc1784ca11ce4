#include "apps/stage_progress.h"

#include <gtest/gtest.h>

namespace lisfm {
namespace {

TEST(StageProgress, ReadsLisfmPlainProgressLines) {
  const auto p = ParseStageProgress("[I 10:33:47.120] lio: 120/500 (24.0%) 31.2/s");
  ASSERT_TRUE(p.has_value());
  EXPECT_EQ(p->done, 120);
  EXPECT_EQ(p->total, 500);
  EXPECT_DOUBLE_EQ(p->Fraction(), 0.24);
  const auto last = ParseStageProgress("[I 10:33:49.000] pose_slam: 7/7 (100.0%) 3.5/s done");
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->done, 7);
  EXPECT_EQ(last->total, 7);
}

TEST(StageProgress, ReadsStockColmapCounters) {
  const auto file = ParseStageProgress("Processed file [3/12]");
  ASSERT_TRUE(file.has_value());
  EXPECT_EQ(file->done, 3);
  EXPECT_EQ(file->total, 12);
  const auto block = ParseStageProgress("Matching block [2/9]");
  ASSERT_TRUE(block.has_value());
  EXPECT_EQ(block->done, 2);
  EXPECT_EQ(block->total, 9);
  const auto pair = ParseStageProgress("Matching block [1/4, 3/4]");
  ASSERT_TRUE(pair.has_value());
  EXPECT_EQ(pair->done, 1);
  EXPECT_EQ(pair->total, 4);
}

TEST(StageProgress, IgnoresLinesWithoutACounter) {
  EXPECT_FALSE(ParseStageProgress("").has_value());
  EXPECT_FALSE(ParseStageProgress("[I 10:33:47.120] lio: 120 31.2/s").has_value());
  EXPECT_FALSE(ParseStageProgress("Registering image #5 (3)").has_value());
  EXPECT_FALSE(ParseStageProgress("Elapsed time: 0.012 [minutes]").has_value());
  EXPECT_FALSE(ParseStageProgress("lio: 3/0 (0.0%)").has_value());
  EXPECT_FALSE(ParseStageProgress("Processed file [13/12]").has_value());
}

TEST(StageProgress, FormatsTheStatusText) {
  EXPECT_EQ(FormatStageStatus("[2/8] lio", 12.4, std::nullopt), "[2/8] lio 12 s");
  EXPECT_EQ(FormatStageStatus("[2/8] lio", 12.4, StageProgress{120, 500}),
            "[2/8] lio 12 s, 120/500 (24%)");
}

}  // namespace
}  // namespace lisfm
