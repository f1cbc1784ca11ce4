#include "core/time.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

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

// Stamps outside the int64 nanosecond range (+-9223372036.854775807 s) are
// rejected in every notation instead of wrapping.
TEST(Time, RejectsStampsOutsideTheNanosecondRange) {
  TimestampNs t = 0;
  for (const char* text : {"1e10", "-1e10", "1e300", "9.3e9", "inf", "nan", "9223372037",
                           "9223372036.9", "-9223372036.9", "99999999999"}) {
    EXPECT_FALSE(ParseSecondsToNs(text, &t)) << text << " -> " << t;
  }
  ASSERT_TRUE(ParseSecondsToNs("9223372036.854775807", &t));
  EXPECT_EQ(t, INT64_MAX);
  ASSERT_TRUE(ParseSecondsToNs("1e9", &t));
  EXPECT_EQ(t, 1000000000LL * kNsPerSecond);
  EXPECT_TRUE(IsRepresentableAsNs(9.2e9));
  EXPECT_FALSE(IsRepresentableAsNs(1e10));
  EXPECT_FALSE(IsRepresentableAsNs(std::nan("")));
  EXPECT_THROW(SecondsToNs(1e10), InternalError);
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
