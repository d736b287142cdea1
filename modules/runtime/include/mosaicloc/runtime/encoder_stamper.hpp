#pragma once

#include <chrono>
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
  /// A vehicle whose cycles' travel fell twice in a row, so that slowing as it last did it
  /// stands within stationary_after, is braking to a stop, not moving: it is passed on as standing still after
  /// stationary_after. (Held half a second, every stop from a creep had its frames wait for
  /// odometry, and its fixes were written as degraded until then.)
  std::int64_t moving_ticks_per_period = 2;
  int moving_stop_factor = 10;
  /// Polling with counter_period known: the PLC updates its counters on a regular cycle, so
  /// when in that cycle they change is learnt from the changes seen. Each change lies in the
  /// interval between two reads; with reads at varying phases (the PLC thread varies its poll
  /// period) the middles of those intervals scatter evenly around the true instant, and their
  /// running mean (moved on by whole periods, the newest weighted at least phase_gain, so a
  /// PLC clock that drifts is followed) dates each change, never outside its own interval.
  /// A read's interval runs from the previous request's sending to this one's answer (the PLC
  /// answered with values it held at some instant of the round trip, PlcInputs::round_trip).
  /// A read whose interval may hold two of the cycle's instants (a slow answer, a late poll)
  /// is left out, once in a row at most: the next read carries its travel.
  /// Moving (a cycle's travel at least kTravelTicks), the wheels' travel since the last dated
  /// change says how many cycles passed, and so which cycle's values a read holds, also where
  /// the PLC made them visible late (after a request that went out after the cycle's instant
  /// and came back with the old values): dated by the interval alone, such values were put a
  /// whole period late, and the pose written back was a period's travel behind the vehicle.
  /// Off: each change is dated at the middle of its interval.
  bool phase_lock = true;
  double phase_gain = 1.0 / 16.0;
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
  /// Changes the travel dated before the interval their reads give: counter updates the PLC
  /// made visible late.
  std::int64_t late_changes() const { return late_changes_; }
  /// The link was invalid: the next read is dated as a first one.
  void Forget() {
    have_ticks_ = false;
    changes_seen_ = 0;
    cycle_ticks_ = 0.0;
    previous_cycle_ticks_ = 0.0;
    earlier_cycle_ticks_ = 0.0;
    skipped_ = false;
  }

  /// A cycle's travel (ticks of the fastest wheel) from which the travel dates a change, and
  /// the most cycles it dates across.
  static constexpr double kTravelTicks = 8.0;
  static constexpr double kTravelCycles = 4.0;

 private:
  // When counters seen changed at `read` took their values (phase_lock); nothing when the
  // read cannot tell which of two cycles its values are from.
  std::optional<core::Timestamp> ChangedAt(const io::PlcInputs& read);
  // The cycle instant whose values a change of `moved` ticks since the last dated change
  // holds, when the travel tells it; within a period before `from`, not after `to`.
  std::optional<core::Timestamp> CycleByTravel(std::int64_t moved, core::Timestamp from, core::Timestamp to) const;
  // The last dated cycles' travel says the vehicle is braking to a stop within stationary_after.
  bool Stopping() const;
  static constexpr int kPhaseSettled = 16;  // changes seen before the cycle is trusted

  EncoderStamperOptions options_;
  bool have_ticks_ = false;  // (not an optional pair: GCC 12 warns wrongly about it)
  core::EncoderCounts last_ticks_;
  core::Timestamp last_read_;
  core::Timestamp last_sent_;  // when the previous read's request went out
  core::Timestamp last_forwarded_;
  core::Timestamp last_change_;
  bool moving_ = false;  // the last change was faster than moving_ticks_per_period
  // When the last change seen happened, as learnt from the reads and the cycle (phase_lock),
  // and from how many changes.
  core::Timestamp changed_;
  core::EncoderCounts dated_ticks_;  // the counters of that change
  double cycle_ticks_ = 0.0;         // the fastest wheel's ticks a cycle, at that change (0: unknown)
  double previous_cycle_ticks_ = 0.0;  // the same at the dated change before
  double earlier_cycle_ticks_ = 0.0;   // and at the one before that
  int changes_seen_ = 0;
  bool skipped_ = false;  // the last changed read was left out
  std::int64_t late_changes_ = 0;
};

}  // namespace mosaicloc::runtime
