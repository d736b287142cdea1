#include "mosaicloc/runtime/encoder_stamper.hpp"

namespace mosaicloc::runtime {

std::optional<dataset::EncoderSample> EncoderStamper::Take(const io::PlcInputs& read) {
  if (!read.fresh) return std::nullopt;
  // Polling: the counters changed since the previous read, within the PLC's last counter
  // period (CountersChangedAt); unchanged counters are passed on only once they have stood
  // still for stationary_after. Served: when the PLC wrote them.
  const core::EncoderCounts ticks = read.counts();
  std::optional<core::Timestamp> stamp;
  if (!options_.polling || !have_ticks_) {
    stamp = read.time;
  } else if (ticks != last_ticks_) {
    stamp = io::CountersChangedAt(last_read_, read.time, options_.counter_period);
  } else if (read.time - options_.counter_period - last_forwarded_ >= options_.stationary_after) {
    stamp = read.time - options_.counter_period;
  }
  last_ticks_ = ticks;
  have_ticks_ = true;
  last_read_ = read.time;
  if (!stamp) return std::nullopt;
  last_forwarded_ = *stamp;
  return dataset::EncoderSample{*stamp - options_.latency, read.left_ticks, read.right_ticks, read.drive_ticks,
                                read.steering_ticks};
}

}  // namespace mosaicloc::runtime
