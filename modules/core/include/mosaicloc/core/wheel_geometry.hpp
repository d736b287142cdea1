#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mosaicloc/core/yaml.hpp"

namespace mosaicloc::core {

/// How a vehicle's wheels move it, and so what its two encoder counters count.
enum class DriveKind {
  /// Two driven wheels on one axle, each with an encoder (counters: left, right). The vehicle
  /// frame's origin is midway between the wheels' contact points.
  kDifferential,
  /// One steered, driven wheel ahead of a fixed axle, as tugs and forklifts are (counters: the
  /// drive wheel's encoder, the steering angle's absolute encoder). The origin is the fixed
  /// axle's centre, the one point that never slides sideways.
  kTricycle,
  /// Four mecanum wheels, each driven and with an encoder (counters: front left, front right,
  /// rear left, rear right), rollers at 45 degrees in the X arrangement seen from above: the
  /// vehicle moves sideways as well as forwards and turns. The origin is the centre of the
  /// four contact points.
  kMecanum,
};
inline constexpr DriveKind kDriveKinds[] = {DriveKind::kDifferential, DriveKind::kTricycle, DriveKind::kMecanum};
/// "differential", "tricycle" or "mecanum", as files name them.
const char* ToString(DriveKind kind);

/// A vehicle's wheels as calibrated: what turns encoder counts into motion. The one definition
/// the dataset header, odometry, the simulator and vehicle calibration share. Only the fields
/// of `kind` are used (and read from files).
struct WheelGeometry {
  DriveKind kind = DriveKind::kDifferential;
  // Differential drive.
  double left_wheel_radius_mm = 75.0;
  double right_wheel_radius_mm = 75.0;
  /// Distance between the left and right wheels' contact points (differential, mecanum).
  double track_width_mm = 500.0;
  /// Of each wheel's encoder (the tricycle's drive wheel's).
  std::int64_t ticks_per_revolution = 4096;
  // Tricycle.
  double drive_wheel_radius_mm = 100.0;
  /// Tricycle: from the fixed axle's centre to the steered wheel's contact point. Mecanum: from
  /// the rear axle to the front axle.
  double wheelbase_mm = 1000.0;
  /// Counts of the steering encoder per turn (an absolute encoder: count 0 is its zero).
  std::int64_t steering_ticks_per_revolution = 65536;
  /// The steering angle at count 0, degrees, positive to the left: the wheel points straight
  /// ahead at count -offset. Calibrated; the filter learns what is left of its error.
  double steering_offset_deg = 0.0;
  // Mecanum (track_width_mm, wheelbase_mm and ticks_per_revolution as above).
  double mecanum_wheel_radius_mm = 76.0;  ///< the four wheels' (their rollers' envelope)

  /// The kind's radii and lengths > 0 and finite, counts per turn >= 1, the steering offset
  /// within +-45 degrees.
  bool Check(std::string* why) const;
  /// The steering angle, radians, of a steering encoder count (tricycle).
  double SteeringRad(std::int32_t steering_ticks) const;
  /// The distance a wheel of `radius_mm` rolls for `ticks` counts.
  double TicksToMm(double radius_mm, std::int64_t ticks) const;
};

/// One reading of a vehicle's encoder counters as the PLC counts them (int32, may wrap); only
/// those of its kind are used: left and right (differential), drive and steering (tricycle),
/// left and right for the front wheels and the two rear ones (mecanum).
struct EncoderCounts {
  std::int32_t left_ticks = 0;
  std::int32_t right_ticks = 0;
  std::int32_t drive_ticks = 0;
  std::int32_t steering_ticks = 0;
  std::int32_t rear_left_ticks = 0;
  std::int32_t rear_right_ticks = 0;
  bool operator==(const EncoderCounts&) const = default;
};

/// The counters of a vehicle of `kind` in a reading, in the order the PLC's registers list them
/// (differential: left, right; tricycle: drive, steering; mecanum: front left, front right,
/// rear left, rear right).
std::vector<std::int32_t> CountersOf(DriveKind kind, const EncoderCounts& counts);

/// Reads a mapping (a dataset header's or a configuration's `vehicle:`) into *wheels: `kind`
/// (optional, differential when absent), then the keys of that kind, then Check(): every key
/// of the kind required, or each optional over what *wheels holds. A key of the other kind is
/// a problem (left unread).
void ReadWheelGeometry(YamlMap& map, WheelGeometry* wheels, bool required);

}  // namespace mosaicloc::core
