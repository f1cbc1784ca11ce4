#include "core/time.h"

#include <gtest/gtest.h>

namespace lisfm {
namespace {

TEST(Time, ParsesDecimalSecondsExactly) {
  TimestampNs t = 0;
  ASSERT_TRUE(ParseSecondsToNs("1646307131.123456789", &t));
  EXPECT_EQ(t, 1646307131123456789LL);
  ASSERT_TRUE(ParseSecondsToNs("12.5", &t));
  EXPECT_EQ(t, 12500000000LL);
  ASSERT_TRUE(ParseSecondsToNs("7", &t));
  EXPECT_EQ(t, 7000000000LL);
  ASSERT_TRUE(ParseSecondsToNs("-0.25", &t));
  EXPECT_EQ(t, -250000000LL);
  // A 10th decimal rounds.
  ASSERT_TRUE(ParseSecondsToNs("1.0000000006", &t));
  EXPECT_EQ(t, 1000000001LL);
  ASSERT_TRUE(ParseSecondsToNs("1e3", &t));
  EXPECT_EQ(t, 1000LL * kNsPerSecond);
}

TEST(Time, RejectsGarbage) {
  TimestampNs t = 0;
  EXPECT_FALSE(ParseSecondsToNs("", &t));
  EXPECT_FALSE(ParseSecondsToNs("abc", &t));
  EXPECT_FALSE(ParseSecondsToNs("1.5x", &t));
  EXPECT_FALSE(ParseSecondsToNs(".", &t));
}

TEST(Time, FormatRoundTrips) {
  for (TimestampNs t : {0LL, 1LL, 999999999LL, 1646307131123456789LL, -1500000000LL}) {
    TimestampNs back = 0;
    ASSERT_TRUE(ParseSecondsToNs(FormatNsAsSeconds(t), &back)) << FormatNsAsSeconds(t);
    EXPECT_EQ(back, t);
  }
  EXPECT_EQ(FormatNsAsSeconds(1500000000LL), "1.500000000");
  EXPECT_EQ(FormatNsAsSeconds(-1500000000LL), "-1.500000000");
}

TEST(Time, SecondsToNsRounds) {
  EXPECT_EQ(SecondsToNs(1.5), 1500000000LL);
  EXPECT_EQ(SecondsToNs(-0.5), -500000000LL);
  EXPECT_DOUBLE_EQ(NsToSeconds(2500000000LL), 2.5);
}

}  // namespace
}  // namespace lisfm
