#include "mosaicloc/core/timestamp.hpp"

#include <gtest/gtest.h>

namespace mosaicloc::core {
namespace {

TEST(Timestamp, ArithmeticAndConversion) {
  const Timestamp t = Timestamp::FromNanoseconds(1'700'000'000'123'456'789);
  EXPECT_EQ(t.nanoseconds(), 1'700'000'000'123'456'789);
  const Timestamp later = t + std::chrono::milliseconds(33);
  EXPECT_EQ((later - t).count(), 33'000'000);
  EXPECT_LT(t, later);
  EXPECT_DOUBLE_EQ(ToSeconds(later - t), 0.033);
  EXPECT_EQ(Timestamp::FromSeconds(1.5).nanoseconds(), 1'500'000'000);
  EXPECT_EQ(Timestamp::FromSeconds(-0.25).nanoseconds(), -250'000'000);
  EXPECT_EQ(FromSeconds(1e-9).count(), 1);
  EXPECT_EQ((later - std::chrono::milliseconds(33)), t);
}

TEST(Timestamp, SecondsRoundTripKeepsNanosecondsOverAnHour) {
  for (std::int64_t ns : {0LL, 1LL, 999'999'999LL, 3'600'000'000'001LL}) {
    const Timestamp t = Timestamp::FromNanoseconds(ns);
    EXPECT_EQ(Timestamp::FromSeconds(t.seconds()).nanoseconds(), ns);
  }
}

}  // namespace
}  // namespace mosaicloc::core
