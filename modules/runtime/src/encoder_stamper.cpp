#include "mosaicloc/runtime/encoder_stamper.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>

#include "mosaicloc/estimation/odometry.hpp"

namespace mosaicloc::runtime {
namespace {

// How far the wheels turned from `before` to `after`: the largest change of a wheel counter
// (the steering's absolute count aside), in ticks.
std::int64_t WheelTicksMoved(const core::EncoderCounts& before, const core::EncoderCounts& after) {
  const auto moved = [](std::int32_t from, std::int32_t to) {
    return std::abs(static_cast<std::int64_t>(estimation::TickDelta(from, to)));
  };
  return std::max({moved(before.left_ticks, after.left_ticks), moved(before.right_ticks, after.right_ticks),
                   moved(before.drive_ticks, after.drive_ticks), moved(before.rear_left_ticks, after.rear_left_ticks),
                   moved(before.rear_right_ticks, after.rear_right_ticks)});
}

}  // namespace

std::optional<core::Timestamp> EncoderStamper::ChangedAt(const io::PlcInputs& read) {
  const core::Duration period = options_.counter_period;
  if (!options_.phase_lock || period <= core::Duration::zero()) {
    return io::CountersChangedAt(last_read_, read.time, period);
  }
  // The PLC took the values it answered with at some instant of the request's round trip:
  // the change happened after the previous request went out, before this one's answer came
  // back, and within the last period before this request went out (moving, the counters
  // change every period). Dated by the middle of the read alone, a late answer (a PLC thread
  // not scheduled in time) put the change a whole period off.
  const core::Timestamp sent = read.time - read.round_trip / 2, answered = read.time + read.round_trip / 2;
  const core::Timestamp from = std::max(last_sent_, sent - period), to = answered;
  const core::Timestamp middle = from + (to - from) / 2;
  const core::Duration slack = period / 10;  // how far the cycle may be off between two changes
  const std::int64_t moved = WheelTicksMoved(dated_ticks_, read.counts);
  const core::Timestamp previous = changed_;
  if (changes_seen_ == 0) {
    changed_ = middle;
  } else if (const std::optional<core::Timestamp> cycle = CycleByTravel(moved, from, to)) {
    // Moving, the wheels' travel says which cycle the values are from. Where that instant
    // lies before the interval, the PLC made the values visible late (after a request that
    // went out after the instant and came back with the old ones): the interval says nothing
    // of the cycle's phase then, and does not move it.
    changed_ = std::min(*cycle, to);
    if (*cycle < from - slack) ++late_changes_;
    if (*cycle >= from - slack && read.round_trip <= period / 4) {
      const double gain = std::max(options_.phase_gain, 1.0 / static_cast<double>(changes_seen_ + 1));
      changed_ = std::clamp(*cycle + core::FromSeconds(gain * core::ToSeconds(middle - *cycle)), from, to);
    }
  } else {
    // The last change moved on by the whole periods that put it nearest this one's middle,
    // then drawn towards that middle by the running mean's weight. A read whose round trip
    // took more than a quarter period says little about the instant: it is dated by the
    // cycle alone and does not move it.
    const double periods = std::round(core::ToSeconds(middle - changed_) / core::ToSeconds(period));
    const core::Timestamp predicted = changed_ + core::FromSeconds(periods * core::ToSeconds(period));
    // A slow answer's interval can hold two of the cycle's instants (give or take a tenth of a
    // period the cycle may be off): the values may be those of either. Such a read gives no
    // sample, once in a row at most, so a link that is always slow still gives samples; its
    // values and request still bound the next change, and the counters being cumulative, the
    // next sample carries its travel.
    if (changes_seen_ >= kPhaseSettled && !skipped_) {
      int possible = 0;
      for (const core::Timestamp instant : {predicted - period, predicted, predicted + period}) {
        if (instant > from - slack && instant < to + slack) ++possible;
      }
      if (possible >= 2) {
        skipped_ = true;
        return std::nullopt;
      }
    }
    const double gain = read.round_trip > period / 4
                            ? 0.0
                            : std::max(options_.phase_gain, 1.0 / static_cast<double>(changes_seen_ + 1));
    changed_ = predicted + core::FromSeconds(gain * core::ToSeconds(middle - predicted));
    // The PLC changes its counters at most once a period: two changes dated closer than half
    // a period would make a wheel seem to race between them.
    changed_ = std::clamp(std::max(changed_, previous + period / 2), from, to);
  }
  // The travel a cycle brings, from the whole cycles between this change and the last dated
  // one: what the next change's travel is measured against.
  if (changes_seen_ > 0) {
    const double cycles = std::round(core::ToSeconds(changed_ - previous) / core::ToSeconds(period));
    earlier_cycle_ticks_ = previous_cycle_ticks_;
    previous_cycle_ticks_ = cycle_ticks_;
    cycle_ticks_ = cycles >= 1.0 ? static_cast<double>(moved) / cycles : 0.0;
  }
  dated_ticks_ = read.counts;
  ++changes_seen_;
  skipped_ = false;
  return changed_;
}

std::optional<core::Timestamp> EncoderStamper::CycleByTravel(std::int64_t moved, core::Timestamp from,
                                                             core::Timestamp to) const {
  const core::Duration period = options_.counter_period;
  if (changes_seen_ < kPhaseSettled || cycle_ticks_ < kTravelTicks) return std::nullopt;
  const double cycles = static_cast<double>(moved) / cycle_ticks_;
  const double whole = std::round(cycles);
  // A cycle's travel changes by a few per cent at most while the vehicle accelerates; further
  // from a whole number of cycles than this, the travel does not tell which.
  if (whole < 1.0 || whole > kTravelCycles || std::abs(cycles - whole) > 0.3) return std::nullopt;
  const core::Timestamp instant = changed_ + core::FromSeconds(whole * core::ToSeconds(period));
  // Never after the answer that saw it, and made visible at most a period late.
  if (instant > to + period / 10 || instant < from - period) return std::nullopt;
  return instant;
}

bool EncoderStamper::Stopping() const {
  // The travel of the last dated cycles, each counted in whole cycles of the learnt phase (not
  // over the reads' jittered spacing), fell twice in a row (once may be a PLC cycle's jitter on
  // a coarse encoder: 11 ticks, then 9, at a steady 10), and slowing as it last did, the
  // vehicle stands within stationary_after.
  if (changes_seen_ < kPhaseSettled || !(cycle_ticks_ > 0.0) || !(previous_cycle_ticks_ > cycle_ticks_) ||
      !(earlier_cycle_ticks_ > previous_cycle_ticks_)) {
    return false;
  }
  const double cycles_to_stop = cycle_ticks_ / (previous_cycle_ticks_ - cycle_ticks_);
  return cycles_to_stop * core::ToSeconds(options_.counter_period) <= core::ToSeconds(options_.stationary_after);
}

std::optional<dataset::EncoderSample> EncoderStamper::Take(const io::PlcInputs& read) {
  if (!read.fresh) return std::nullopt;
  // Polling: the counters changed since the previous read, within the PLC's last counter
  // period (CountersChangedAt); unchanged counters are passed on only once they have stood
  // still for stationary_after (a vehicle seen moving: moving_stop_factor times that). Served:
  // when the PLC wrote them.
  const core::EncoderCounts ticks = read.counts;
  std::optional<core::Timestamp> stamp;
  if (!options_.polling || !have_ticks_) {
    stamp = read.time;
  } else if (ticks != last_ticks_) {
    stamp = ChangedAt(read);  // nothing: the values are held back, but they bound the next change
  } else {
    const core::Duration still_for = moving_ ? options_.moving_stop_factor * options_.stationary_after
                                             : options_.stationary_after;
    if (read.time - options_.counter_period - last_forwarded_ >= still_for) stamp = read.time - options_.counter_period;
  }
  if (!have_ticks_) {
    moving_ = false;
    last_change_ = read.time;
  } else if (ticks != last_ticks_) {
    // How fast the wheel counters moved since their last change, in ticks a counter period.
    const std::int64_t step = WheelTicksMoved(last_ticks_, ticks);
    const core::Duration period = std::max<core::Duration>(options_.counter_period, std::chrono::milliseconds(1));
    const double periods = std::max(1.0, core::ToSeconds(read.time - last_change_) / core::ToSeconds(period));
    moving_ = static_cast<double>(step) / periods > static_cast<double>(options_.moving_ticks_per_period) &&
              !Stopping();
    last_change_ = read.time;
  }
  last_ticks_ = ticks;
  have_ticks_ = true;
  last_read_ = read.time;
  last_sent_ = read.time - read.round_trip / 2;
  if (!stamp) return std::nullopt;
  last_forwarded_ = *stamp;
  return dataset::EncoderSample{*stamp - options_.latency, read.counts};
}

}  // namespace mosaicloc::runtime
