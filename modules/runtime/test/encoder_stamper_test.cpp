#include "mosaicloc/runtime/encoder_stamper.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

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

namespace mosaicloc::runtime {
namespace {

// A PLC that updates its counters every `period_us` from `phase_us` on, read by polls whose
// period varies as the PLC thread varies it.
struct PlcModel {
  int period_us = 10000;
  int phase_us = 3700;
  // The share of reads whose answer comes 2 to 9 ms after the request (the PLC thread not
  // scheduled in time); the others take 0.2 ms. The PLC takes the values it answers with at a
  // random instant of the round trip.
  double slow_answers = 0.0;
  // False: the reads say only the middle of their round trip, as if it took no time.
  bool round_trips_known = true;
  // How much each update moves the counters (128: about 1.5 m/s on the simulator's wheels).
  int ticks_per_update = 1;
  // The share of updates the PLC makes visible 3 to 8 ms after their instant (a scan that ran
  // long); the others at once.
  double late_updates = 0.0;
};
// The stamps' error, in microseconds, over the changes after the first `settle` (RMS and
// largest).
struct StampErrors {
  double rms_us = 0.0, max_us = 0.0;
  double left_out = 0.0;  // share of the reads that saw a change and gave no sample
  std::int64_t late = 0;  // changes the stamper found made visible late
};
// The PLC thread's poll periods: 0.75 to 1.25 times the cycle, at random.
double PollSpread(std::minstd_rand& random) {
  return 0.75 + 0.5 * std::uniform_real_distribution<double>(0.0, 1.0)(random);
}

StampErrors StampErrorUs(bool phase_lock, const PlcModel& plc, int settle = 200) {
  EncoderStamperOptions options;
  options.polling = true;
  options.counter_period = std::chrono::microseconds(10000);
  options.stationary_after = std::chrono::milliseconds(50);
  options.phase_lock = phase_lock;
  EncoderStamper stamper(options);
  std::minstd_rand random(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  // When each update becomes visible, after its instant (in order: a late one is less than a
  // period late).
  std::minstd_rand late_random(11);
  std::vector<std::int64_t> late_us(4000, 0);
  for (std::int64_t& late : late_us) {
    if (unit(late_random) < plc.late_updates) late = 3000 + static_cast<std::int64_t>(5000.0 * unit(late_random));
  }
  const auto visible_updates = [&](std::int64_t at_us) -> std::int64_t {
    if (at_us < plc.phase_us) return 0;
    std::int64_t updates = (at_us - plc.phase_us) / plc.period_us + 1;
    if (at_us < plc.phase_us + (updates - 1) * plc.period_us + late_us[static_cast<std::size_t>(updates)]) --updates;
    return updates;
  };
  StampErrors errors;
  double sum2 = 0.0;
  int changes = 0;
  std::int64_t read_us = 0, seen_updates = 0;
  int changed_reads = 0, left_out = 0;
  for (int cycle = 1; cycle < 2000; ++cycle) {
    read_us += static_cast<std::int64_t>(5000.0 * PollSpread(random));
    const std::int64_t trip_us =
        unit(random) < plc.slow_answers ? 2000 + static_cast<std::int64_t>(7000.0 * unit(random)) : 200;
    const std::int64_t held_us = read_us + static_cast<std::int64_t>(static_cast<double>(trip_us) * unit(random));
    // The counters hold the updates so far: each update changes them.
    const std::int64_t updates = visible_updates(held_us);
    io::PlcInputs in;
    in.time = core::Timestamp() + std::chrono::microseconds(read_us + trip_us / 2);
    if (plc.round_trips_known) in.round_trip = std::chrono::microseconds(trip_us);
    read_us += trip_us;
    in.counts.left_ticks = static_cast<std::int32_t>(updates * plc.ticks_per_update);
    in.fresh = true;
    const auto sample = stamper.Take(in);
    if (updates != seen_updates) {
      ++changed_reads;
      if (!sample) ++left_out;
    }
    seen_updates = updates;
    if (!sample || updates == 0 || sample->counts.left_ticks != in.counts.left_ticks) continue;
    const std::int64_t changed_us = plc.phase_us + (updates - 1) * plc.period_us;
    if (++changes > settle) {
      const double error = static_cast<double>((sample->time - core::Timestamp()).count()) / 1e3 -
                           static_cast<double>(changed_us);
      sum2 += error * error;
      errors.max_us = std::max(errors.max_us, std::abs(error));
    }
  }
  errors.rms_us = std::sqrt(sum2 / std::max(1, changes - settle));
  errors.left_out = static_cast<double>(left_out) / std::max(1, changed_reads);
  errors.late = stamper.late_changes();
  return errors;
}

TEST(EncoderStamper, ReadsAtVaryingPhasesFindWhenInItsCycleThePlcUpdates) {
  for (const int phase_us : {3700, 9100}) {
    // Each change dated at the middle of its poll interval: up to half a poll off.
    const StampErrors middle = StampErrorUs(false, {.phase_us = phase_us});
    const StampErrors locked = StampErrorUs(true, {.phase_us = phase_us});
    std::printf("phase %d us: middle of the interval rms %.0f max %.0f us; locked rms %.0f max %.0f us, %.1f %% left out\n",
                phase_us, middle.rms_us, middle.max_us, locked.rms_us, locked.max_us, 100.0 * locked.left_out);
    EXPECT_GT(middle.rms_us, 1000.0);
    EXPECT_LT(locked.rms_us, 0.3 * middle.rms_us);
    EXPECT_LT(locked.max_us, 0.5 * middle.max_us);
    EXPECT_LT(locked.left_out, 0.02);
  }
}

TEST(EncoderStamper, APlcOffItsConfiguredPeriodIsNeverDatedOutsideTheReads) {
  // A PLC cycling every 10.5 ms where 10 are configured: the phase slips by 0.5 ms a period;
  // no stamp leaves the interval its reads give (the longest poll, 6.25 ms, and two round
  // trips at most). One
  // 0.5 % off is followed.
  EXPECT_LT(StampErrorUs(true, {.period_us = 10500, .phase_us = 1200}).max_us, 6250.0 + 2 * 200.0 + 1.0);
  const StampErrors slow = StampErrorUs(true, {.period_us = 10050, .phase_us = 1200});
  std::printf("PLC period 10.05 ms: rms %.0f max %.0f us\n", slow.rms_us, slow.max_us);
  EXPECT_LT(slow.rms_us, 0.5 * StampErrorUs(false, {.period_us = 10050, .phase_us = 1200}).rms_us);
}

TEST(EncoderStamper, ALateAnswerDoesNotPutAChangeAPeriodOff) {
  // One read in ten answered 2 to 9 ms late: dated by the middle of the round trip alone,
  // changes land a whole period off; by the interval from one request to the next answer, and
  // the cycle learnt from the prompt answers, none does.
  const StampErrors blind = StampErrorUs(true, {.slow_answers = 0.1, .round_trips_known = false});
  const StampErrors known = StampErrorUs(true, {.slow_answers = 0.1});
  std::printf("slow answers: round trips ignored rms %.0f max %.0f us; known rms %.0f max %.0f us, %.1f %% left out\n",
              blind.rms_us, blind.max_us, known.rms_us, known.max_us, 100.0 * known.left_out);
  EXPECT_GT(blind.max_us, 5000.0);
  EXPECT_LT(known.max_us, 2500.0);
  EXPECT_LT(known.rms_us, 0.5 * blind.rms_us);
  EXPECT_LT(known.left_out, 0.15);
}

TEST(EncoderStamper, CountersMadeVisibleLateAreDatedByTheWheelsTravel) {
  // One update in ten made visible 3 to 8 ms after its instant, at 128 ticks an update: a read
  // between the instant and the values appearing comes back with the old ones, so the interval
  // from that request to the next answer holds only the next cycle's instant, and dated by it
  // the values are a whole period late. The travel of one cycle says they are the cycle's
  // before.
  const StampErrors counted = StampErrorUs(true, {.ticks_per_update = 128, .late_updates = 0.1});
  const StampErrors single = StampErrorUs(true, {.ticks_per_update = 1, .late_updates = 0.1});
  const StampErrors prompt = StampErrorUs(true, {.ticks_per_update = 128});
  std::printf("late updates: by the interval rms %.0f max %.0f us; by the travel rms %.0f max %.0f us, %.1f %% left out; "
              "none late rms %.0f max %.0f us\n",
              single.rms_us, single.max_us, counted.rms_us, counted.max_us, 100.0 * counted.left_out, prompt.rms_us,
              prompt.max_us);
  EXPECT_GT(single.max_us, 8000.0) << "a tick an update: the travel cannot tell one cycle from two";
  EXPECT_LT(counted.max_us, 2500.0);
  EXPECT_LT(counted.rms_us, 0.5 * single.rms_us);
  EXPECT_LT(counted.left_out, 0.02);
  EXPECT_LT(prompt.max_us, 2500.0);
  // Counted, for the run's summary: about one update in ten of ~2000 is seen before it was
  // visible and then found late; none where all come on time.
  EXPECT_GT(counted.late, 20);
  EXPECT_LT(counted.late, 250);
  EXPECT_EQ(prompt.late, 0);
  // With slow answers besides, still none a period off.
  EXPECT_LT(StampErrorUs(true, {.slow_answers = 0.1, .ticks_per_update = 128, .late_updates = 0.1}).max_us, 2500.0);
}

// A PLC updating its counters every 10 ms by `ticks[k]` at update k (the last entry repeated),
// polled every 7.5 to 12.5 ms: how long after the last change the stamper first passes the
// counters on unchanged (standing still), in ms; -1 when it does not within a second.
double StandingStillAfterMs(const std::vector<std::int64_t>& ticks) {
  EncoderStamper stamper(Polling());
  std::minstd_rand random(5);
  std::int64_t read_us = 0;
  const std::int64_t last_change_us = 3700 + static_cast<std::int64_t>(ticks.size() - 1) * 10000;
  while (read_us < last_change_us + 1000000) {
    read_us += static_cast<std::int64_t>(10000.0 * PollSpread(random));
    const std::int64_t updates = read_us < 3700 ? 0 : std::min<std::int64_t>((read_us - 3700) / 10000 + 1, ticks.size());
    std::int64_t count = 0;
    for (std::int64_t k = 0; k < updates; ++k) count += ticks[static_cast<std::size_t>(k)];
    io::PlcInputs in;
    in.time = core::Timestamp() + std::chrono::microseconds(read_us + 100);
    in.round_trip = std::chrono::microseconds(200);
    in.counts.left_ticks = static_cast<std::int32_t>(count);
    in.counts.right_ticks = static_cast<std::int32_t>(count);
    const auto sample = stamper.Take(in);
    if (sample && read_us > last_change_us + 10000 && sample->counts.left_ticks == count) {
      return static_cast<double>(read_us - last_change_us) / 1e3;
    }
  }
  return -1.0;
}

TEST(EncoderStamper, AVehicleBrakingToAStopStandsStillAfterStationaryAfterAStallAfterTenTimesThat) {
  // 11 ticks a cycle (about 100 mm/s on the simulator's wheels), then braking at 3 m/s^2 (about
  // 3 ticks a cycle less each cycle) to a stop: the last change, 5 ticks, is above the moving
  // threshold, but slowing at that rate the vehicle stands within the next cycle.
  std::vector<std::int64_t> braking(100, 11);
  braking.insert(braking.end(), {8, 5, 0});
  const double stop = StandingStillAfterMs(braking);
  // The same cruise with the counters frozen (a PLC that stopped updating them): held.
  std::vector<std::int64_t> stalled(100, 11);
  stalled.push_back(0);
  const double stall = StandingStillAfterMs(stalled);
  // Braking from 1.5 m/s at 3 m/s^2 (162 ticks, 3 less a cycle): fifty cycles from a stop,
  // so counters that freeze on the way are a stall.
  std::vector<std::int64_t> fast(100, 162);
  fast.insert(fast.end(), {159, 156, 0});
  const double fast_stall = StandingStillAfterMs(fast);
  // A coarse encoder at a steady 10 ticks a cycle on a PLC whose cycle jitters (11, 9, 11, ...),
  // frozen after a 9: one fall is no braking.
  std::vector<std::int64_t> jittery;
  for (int i = 0; i < 50; ++i) jittery.insert(jittery.end(), {11, 9});
  jittery.push_back(0);
  const double jittery_stall = StandingStillAfterMs(jittery);
  std::printf("standing still passed on after: a stop from a creep %.1f ms, a stall %.1f ms, a stall while braking "
              "at speed %.1f ms, a stall of a jittery cycle %.1f ms\n", stop, stall, fast_stall, jittery_stall);
  EXPECT_GT(jittery_stall, 500.0);
  EXPECT_GT(stop, 50.0);
  EXPECT_LT(stop, 85.0) << "stationary_after (50 ms) after the last cycle, and a poll";
  EXPECT_GT(stall, 500.0);
  EXPECT_GT(fast_stall, 500.0);
}

}  // namespace
}  // namespace mosaicloc::runtime
