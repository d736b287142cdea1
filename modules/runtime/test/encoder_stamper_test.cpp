#include "mosaicloc/runtime/encoder_stamper.hpp"

#include <chrono>

#include <gtest/gtest.h>

namespace mosaicloc::runtime {
namespace {

using std::chrono::milliseconds;

io::PlcInputs Read(int at_ms, std::int32_t left, std::int32_t right, bool fresh = true) {
  io::PlcInputs in;
  in.time = core::Timestamp() + milliseconds(at_ms);
  in.counts.left_ticks = left;
  in.counts.right_ticks = right;
  in.fresh = fresh;
  return in;
}

EncoderStamperOptions Polling() {
  EncoderStamperOptions options;
  options.polling = true;
  options.counter_period = milliseconds(10);
  options.stationary_after = milliseconds(50);
  options.latency = milliseconds(2);
  return options;
}

TEST(EncoderStamper, AChangeIsDatedWithinTheLastCounterPeriodBeforeTheRead) {
  EncoderStamper stamper(Polling());
  const auto first = stamper.Take(Read(100, 0, 0));
  ASSERT_TRUE(first);
  EXPECT_EQ(first->time, core::Timestamp() + milliseconds(98)) << "a first read is its own time, less the latency";
  // Read 4 ms later: the change happened between the reads, the middle of [100, 104] ms.
  const auto soon = stamper.Take(Read(104, 5, 6));
  ASSERT_TRUE(soon);
  EXPECT_EQ(soon->time, io::CountersChangedAt(core::Timestamp() + milliseconds(100),
                                              core::Timestamp() + milliseconds(104), milliseconds(10)) -
                            milliseconds(2));
  EXPECT_EQ(soon->counts.left_ticks, 5);
  EXPECT_EQ(soon->counts.right_ticks, 6);
  // A late read (60 ms on): within the last 10 ms before it, not back to the previous read.
  const auto late = stamper.Take(Read(164, 9, 9));
  ASSERT_TRUE(late);
  EXPECT_GE(late->time, core::Timestamp() + milliseconds(164 - 10 - 2));
  EXPECT_LE(late->time, core::Timestamp() + milliseconds(164 - 2));
}

TEST(EncoderStamper, StandingStillIsPassedOnOnlyAfterStationaryAfter) {
  EncoderStamper stamper(Polling());
  ASSERT_TRUE(stamper.Take(Read(100, 7, 7)));  // forwarded at 100 ms
  EXPECT_FALSE(stamper.Take(Read(120, 7, 7))) << "20 ms unchanged: could still be moving";
  EXPECT_FALSE(stamper.Take(Read(150, 7, 7)));
  const auto still = stamper.Take(Read(161, 7, 7));
  ASSERT_TRUE(still) << "unchanged for 50 ms after one counter period";
  EXPECT_EQ(still->time, core::Timestamp() + milliseconds(161 - 10 - 2));
  EXPECT_FALSE(stamper.Take(Read(170, 7, 7)));
}

// Counters that stop changing while the vehicle was seen moving fast are a PLC that has not
// updated them (a stalled cycle), not a stop: held as standing still, the filter would keep the
// vehicle in place and then make it jump, and the frames between would be predicted where it
// was not (a live run lost its lock so). They are passed on only after ten times
// stationary_after; a vehicle that slowed down first is passed on as before.
TEST(EncoderStamper, AStallWhileMovingIsNotAStop) {
  EncoderStamper stamper(Polling());
  std::int32_t ticks = 1000;
  int at = 100;
  ASSERT_TRUE(stamper.Take(Read(at, ticks, ticks)));
  for (int i = 0; i < 10; ++i) {  // 128 ticks every 10 ms: about 1.5 m/s
    at += 10;
    ticks += 128;
    ASSERT_TRUE(stamper.Take(Read(at, ticks, ticks)));
  }
  for (int wait = 10; wait < 500; wait += 5) {
    EXPECT_FALSE(stamper.Take(Read(at + wait, ticks, ticks))) << wait << " ms unchanged after moving";
  }
  const auto still = stamper.Take(Read(at + 515, ticks, ticks));
  ASSERT_TRUE(still) << "unchanged for ten times stationary_after";
  // The counters move again, slowly (1 tick every 10 ms), and stand still: passed on after 50 ms.
  at += 515;
  for (int i = 0; i < 5; ++i) {
    at += 10;
    ticks += 1;
    ASSERT_TRUE(stamper.Take(Read(at, ticks, ticks)));
  }
  EXPECT_FALSE(stamper.Take(Read(at + 50, ticks, ticks)));
  EXPECT_TRUE(stamper.Take(Read(at + 61, ticks, ticks))) << "creeping to a stop is a stop";
}

TEST(EncoderStamper, ServedReadsAreTheirOwnTimeAndStaleOnesNothing) {
  EncoderStamperOptions options = Polling();
  options.polling = false;
  EncoderStamper stamper(options);
  ASSERT_TRUE(stamper.Take(Read(100, 1, 1)));
  const auto same = stamper.Take(Read(105, 1, 1));
  ASSERT_TRUE(same) << "the PLC wrote them: that is when they were so";
  EXPECT_EQ(same->time, core::Timestamp() + milliseconds(103));
  EXPECT_FALSE(stamper.Take(Read(110, 2, 2, /*fresh=*/false)));
}

TEST(EncoderStamper, AfterTheLinkWasInvalidTheNextReadIsAFirstOne) {
  EncoderStamper stamper(Polling());
  ASSERT_TRUE(stamper.Take(Read(100, 1, 1)));
  stamper.Forget();
  const auto again = stamper.Take(Read(900, 50, 50));
  ASSERT_TRUE(again);
  EXPECT_EQ(again->time, core::Timestamp() + milliseconds(898)) << "not dated back towards the read before the outage";
}

}  // namespace
}  // namespace mosaicloc::runtime
