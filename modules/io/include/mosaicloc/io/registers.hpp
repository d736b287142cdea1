#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "mosaicloc/core/wheel_geometry.hpp"

namespace mosaicloc::io {

/// Which 16-bit word of a 32-bit value comes first (at the lower address). Modbus itself
/// says nothing about it: Siemens and most PLCs put the high word first, some put it last.
enum class WordOrder { kHighFirst, kLowFirst };
inline constexpr WordOrder kWordOrders[] = {WordOrder::kHighFirst, WordOrder::kLowFirst};
/// "high_first" or "low_first", as the run configuration names them.
const char* ToString(WordOrder order);

/// One value in the PLC's holding registers: where it is and how it is encoded.
/// `scale` is the engineering unit per count (tick, mm or rad): a fix x of 1234.56 mm with
/// scale 0.01 is written as the count 123456.
struct RegisterField {
  std::string name;     ///< for messages, e.g. "fix_x"
  int address = 0;      ///< 0-based holding register
  int width_bits = 16;  ///< 16 or 32
  bool is_signed = false;
  double scale = 1.0;
  WordOrder word_order = WordOrder::kHighFirst;

  int words() const { return width_bits / 16; }
  /// Smallest and largest count the field can hold.
  std::int64_t MinCount() const;
  std::int64_t MaxCount() const;
  /// "fix_x (registers 100-101)".
  std::string Describe() const;
};

/// The PLC register map (design.md section 6). Inputs are written by the PLC, outputs by
/// mosaicloc.
struct RegisterMap {
  /// Which counters the PLC provides: a differential drive's left and right wheel counters, a
  /// tricycle's drive wheel counter and steering encoder, or a mecanum vehicle's four wheel
  /// counters. Only the kind's are read (and checked).
  core::DriveKind kind = core::DriveKind::kDifferential;
  // Inputs.
  RegisterField left_ticks{"left_ticks", 0, 32, true, 1.0};
  RegisterField right_ticks{"right_ticks", 2, 32, true, 1.0};
  RegisterField drive_ticks{"drive_ticks", 0, 32, true, 1.0};
  /// The steering angle's absolute encoder (a count of steering_ticks_per_revolution; not a
  /// counter that wraps): 16 bits hold a 16-bit encoder's count, signed or not as the PLC has it.
  RegisterField steering_ticks{"steering_ticks", 2, 32, true, 1.0};
  RegisterField front_left_ticks{"front_left_ticks", 0, 32, true, 1.0};
  RegisterField front_right_ticks{"front_right_ticks", 2, 32, true, 1.0};
  RegisterField rear_left_ticks{"rear_left_ticks", 8, 32, true, 1.0};
  RegisterField rear_right_ticks{"rear_right_ticks", 10, 32, true, 1.0};
  RegisterField plc_heartbeat{"plc_heartbeat", 4, 16, false, 1.0};
  RegisterField fix_request{"fix_request", 5, 16, false, 1.0};
  /// The PLC adds 1 when the vehicle's pose is unknown (moved while switched off, put down
  /// elsewhere): mosaicloc relocalizes without trusting its estimate.
  RegisterField relocalize_request{"relocalize_request", 6, 16, false, 1.0};
  // Outputs.
  RegisterField fix_x{"fix_x", 100, 32, true, 0.01};    ///< mm per count
  RegisterField fix_y{"fix_y", 102, 32, true, 0.01};    ///< mm per count
  RegisterField fix_yaw{"fix_yaw", 104, 32, true, 1e-6};  ///< rad per count
  RegisterField fix_status{"fix_status", 106, 16, false, 1.0};
  RegisterField fix_quality{"fix_quality", 107, 16, false, 1.0};
  RegisterField fix_request_echo{"fix_request_echo", 108, 16, false, 1.0};
  RegisterField heartbeat{"heartbeat", 109, 16, false, 1.0};
  /// What the localizer does (localizer::Mode): 0 none yet, 1 track, 2 visual odometry,
  /// 3 dead reckoning, 4 searching.
  RegisterField fix_mode{"fix_mode", 110, 16, false, 1.0};

  /// The kind's counters: (left_ticks, right_ticks), (drive_ticks, steering_ticks) or
  /// (front_left_ticks, front_right_ticks, rear_left_ticks, rear_right_ticks).
  std::vector<const RegisterField*> Counters() const;
  /// The values of those in a reading (a mecanum vehicle's front wheels are its left_ticks and
  /// right_ticks).
  std::vector<std::int32_t> CounterValues(const core::EncoderCounts& counts) const;
  std::vector<const RegisterField*> Inputs() const;
  std::vector<const RegisterField*> Outputs() const;
  /// Every field is valid, no two overlap, and the counters, heartbeats and status have
  /// scale 1. The reason names the field and its registers.
  bool Check(std::string* why) const;
};

/// A run of consecutive registers read or written in one Modbus request.
struct RegisterSpan {
  int address = 0;
  int count = 0;
  std::vector<const RegisterField*> fields;
  /// "holding registers 0-6 (left_ticks, right_ticks, plc_heartbeat, fix_request, relocalize_request)".
  std::string Describe() const;
};

/// Groups fields into as few requests as possible: fields whose registers touch or are at
/// most `max_gap` registers apart share a span (reading a gap is harmless; writing one is
/// not, so writes use max_gap = 0). Spans never exceed `max_count` registers (125 is the
/// Modbus limit for a read).
std::vector<RegisterSpan> GroupIntoSpans(std::vector<const RegisterField*> fields, int max_gap, int max_count = 120);

/// The count stored in a field, from its words (the field's first word at words[0]).
std::int64_t DecodeCount(const RegisterField& field, const std::uint16_t* words);
/// Stores a count in the field's words. A count outside the field's range is clamped to it,
/// and the function returns false.
bool EncodeCount(const RegisterField& field, std::int64_t count, std::uint16_t* words);

/// Unsigned 32-bit value from two words, explicitly (libmodbus' MODBUS_GET_INT32_FROM_INT16
/// shifts a signed int).
constexpr std::uint32_t JoinWords(std::uint16_t high, std::uint16_t low) {
  return (static_cast<std::uint32_t>(high) << 16U) | static_cast<std::uint32_t>(low);
}
constexpr std::uint16_t HighWord(std::uint32_t value) { return static_cast<std::uint16_t>(value >> 16U); }
constexpr std::uint16_t LowWord(std::uint32_t value) { return static_cast<std::uint16_t>(value & 0xFFFFU); }

/// Extends a counter that wraps at its field's width to 64 bits, assuming it moves less than
/// half its range between two readings. A 16-bit PLC counter wraps every 16 wheel turns of
/// a 4096-tick encoder; this keeps odometry continuous through it.
class CounterUnwrapper {
 public:
  explicit CounterUnwrapper(int width_bits) : width_bits_(width_bits) {}
  std::int64_t Update(std::int64_t count);
  /// The next reading starts afresh (after a reconnection, a PLC restart).
  void Reset() { last_.reset(); }

 private:
  int width_bits_;
  std::optional<std::int64_t> last_;
  std::int64_t extended_ = 0;
};

}  // namespace mosaicloc::io
