#include "mosaicloc/runtime/encoder_stamper.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>

#include "mosaicloc/estimation/odometry.hpp"

namespace mosaicloc::runtime {

core::Timestamp EncoderStamper::ChangedAt(core::Timestamp read) {
  const core::Duration period = options_.counter_period;
  if (!options_.phase_lock || period <= core::Duration::zero()) {
    return io::CountersChangedAt(last_read_, read, period);
  }
  // The change happened after the previous read and within the last period before this one.
  const core::Timestamp from = std::max(last_read_, read - period), to = read;
  const core::Timestamp middle = from + (to - from) / 2;
  if (changes_seen_ == 0) {
    changed_ = middle;
  } else {
    // The last change moved on by the whole periods that put it nearest this one's middle,
    // then drawn towards that middle by the running mean's weight.
    const double periods = std::round(core::ToSeconds(middle - changed_) / core::ToSeconds(period));
    const core::Timestamp predicted = changed_ + core::FromSeconds(periods * core::ToSeconds(period));
    const double gain = std::max(options_.phase_gain, 1.0 / static_cast<double>(changes_seen_ + 1));
    const core::Timestamp previous = changed_;
    changed_ = predicted + core::FromSeconds(gain * core::ToSeconds(middle - predicted));
    // The PLC changes its counters at most once a period: two changes dated closer than half
    // a period would make a wheel seem to race between them.
    changed_ = std::clamp(std::max(changed_, previous + period / 2), from, to);
  }
  ++changes_seen_;
  return changed_;
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
    stamp = ChangedAt(read.time);
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
    const auto moved = [](std::int32_t before, std::int32_t after) {
      return std::abs(static_cast<std::int64_t>(estimation::TickDelta(before, after)));
    };
    const std::int64_t step = std::max({moved(last_ticks_.left_ticks, ticks.left_ticks),
                                        moved(last_ticks_.right_ticks, ticks.right_ticks),
                                        moved(last_ticks_.drive_ticks, ticks.drive_ticks),
                                        moved(last_ticks_.rear_left_ticks, ticks.rear_left_ticks),
                                        moved(last_ticks_.rear_right_ticks, ticks.rear_right_ticks)});
    const core::Duration period = std::max<core::Duration>(options_.counter_period, std::chrono::milliseconds(1));
    const double periods = std::max(1.0, core::ToSeconds(read.time - last_change_) / core::ToSeconds(period));
    moving_ = static_cast<double>(step) / periods > static_cast<double>(options_.moving_ticks_per_period);
    last_change_ = read.time;
  }
  last_ticks_ = ticks;
  have_ticks_ = true;
  last_read_ = read.time;
  if (!stamp) return std::nullopt;
  last_forwarded_ = *stamp;
  return dataset::EncoderSample{*stamp - options_.latency, read.counts};
}

}  // namespace mosaicloc::runtime
