#pragma once

#include <chrono>
#include <compare>
#include <cstdint>
#include <string>

namespace mosaicloc::core {

using Duration = std::chrono::nanoseconds;

/// A point in time as int64 nanoseconds since an epoch the source chooses (the dataset's
/// recording start, the monotonic clock, ...). Only differences between timestamps of the
/// same source are meaningful.
class Timestamp {
 public:
  constexpr Timestamp() = default;
  static constexpr Timestamp FromNanoseconds(std::int64_t ns) { return Timestamp(ns); }
  /// Rounds to the nearest nanosecond.
  static Timestamp FromSeconds(double seconds);

  constexpr std::int64_t nanoseconds() const { return ns_; }
  constexpr double seconds() const { return static_cast<double>(ns_) * 1e-9; }

  constexpr auto operator<=>(const Timestamp&) const = default;
  constexpr Timestamp operator+(Duration d) const { return Timestamp(ns_ + d.count()); }
  constexpr Timestamp operator-(Duration d) const { return Timestamp(ns_ - d.count()); }
  constexpr Duration operator-(Timestamp other) const { return Duration(ns_ - other.ns_); }

 private:
  constexpr explicit Timestamp(std::int64_t ns) : ns_(ns) {}
  std::int64_t ns_ = 0;
};

/// Duration in seconds as a double.
constexpr double ToSeconds(Duration d) { return static_cast<double>(d.count()) * 1e-9; }
/// Seconds to a duration, rounded to the nearest nanosecond.
Duration FromSeconds(double seconds);

}  // namespace mosaicloc::core
