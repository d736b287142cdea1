#pragma once

#include <cstdint>
#include <optional>
#include <utility>

#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/io/plc_link.hpp"

namespace mosaicloc::runtime {

struct EncoderStamperOptions {
  /// mosaicloc polls the PLC (client role): a read says only that the counters changed since
  /// the previous read. Otherwise the PLC writes them (server role) and the write is the time.
  bool polling = true;
  /// How often the PLC updates its counters (0: unknown): a change is dated within the last
  /// period before the read that saw it.
  core::Duration counter_period{};
  /// Unchanged counters are passed on (the vehicle stands still) once this long has passed
  /// since the last sample, so the filter keeps up with the clock.
  core::Duration stationary_after{};
  /// The PLC's own delay between the wheels turning and its counters saying so.
  core::Duration latency{};
  /// A vehicle whose counters last changed by more than this many ticks a counter period (of
  /// its wheel counters, the steering's aside) was moving too fast to stop within
  /// stationary_after: its counters standing still then are a PLC that has not updated them
  /// (a stalled read, a late cycle), and are passed on only after moving_stop_factor times
  /// stationary_after. Passed on sooner, the filter would hold the vehicle still and then make
  /// it jump, and the frames between would be predicted where it was not.
  std::int64_t moving_ticks_per_period = 2;
  int moving_stop_factor = 10;
};

/// When the wheel counters the PLC reports took their values: the time stamp an encoder
/// sample gets before odometry sees it (design.md section 6). One object per link, fed every
/// fresh, valid read in order.
class EncoderStamper {
 public:
  explicit EncoderStamper(const EncoderStamperOptions& options) : options_(options) {}

  /// The sample a read gives, dated; nothing for a read that is not fresh, or whose
  /// unchanged counters stand still for less than stationary_after.
  std::optional<dataset::EncoderSample> Take(const io::PlcInputs& read);
  /// The link was invalid: the next read is dated as a first one.
  void Forget() { have_ticks_ = false; }

 private:
  EncoderStamperOptions options_;
  bool have_ticks_ = false;  // (not an optional pair: GCC 12 warns wrongly about it)
  core::EncoderCounts last_ticks_;
  core::Timestamp last_read_;
  core::Timestamp last_forwarded_;
  core::Timestamp last_change_;
  bool moving_ = false;  // the last change was faster than moving_ticks_per_period
};

}  // namespace mosaicloc::runtime
