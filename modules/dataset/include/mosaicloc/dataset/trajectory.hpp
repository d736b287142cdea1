#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"

namespace mosaicloc::dataset {

/// One pose of a trajectory: the vehicle in the world frame (design.md section 3) at `time`.
struct StampedPose {
  core::Timestamp time;
  core::Pose2 world_from_vehicle;
};

/// Poses sorted by strictly increasing time.
using Trajectory = std::vector<StampedPose>;

/// Largest accepted | |q| - 1 | of a TUM quaternion (files written with 4 decimals pass).
inline constexpr double kTumQuaternionNormTolerance = 1e-3;
/// Largest accepted tilt of a TUM rotation away from a rotation about z, in radians (0.57 deg).
inline constexpr double kTumMaxTiltRad = 1e-2;

/// Reads a TUM trajectory: one pose per line, "timestamp_s x_m y_m z_m qx qy qz qw" separated
/// by spaces or tabs; blank lines and lines starting with '#' are skipped. Seconds and metres
/// become nanoseconds (exact, see ParseSeconds) and millimetres. z is ignored (the floor is the
/// plane); the quaternion, normalized, must be a rotation about z within kTumMaxTiltRad and its
/// yaw is 2 atan2(qz, qw).
/// Every line is validated: exactly 8 fields, each a finite number, a unit quaternion within
/// kTumQuaternionNormTolerance, a rotation about z, timestamps strictly increasing.
/// Throws core::Error (invalid input) "file:line: reason" on the first bad line, and
/// "file: ..." when the file cannot be opened or holds no pose.
Trajectory ReadTum(const std::filesystem::path& file);

/// Writes a TUM trajectory (z = 0, qx = qy = 0, qw >= 0) that ReadTum reads back to the
/// nanosecond and to 1e-6 mm: timestamps and metres with 9 decimals, the quaternion with 12.
/// The file is written under a temporary name in the same directory, then renamed, so readers
/// see the old file or the complete new one. Throws core::Error (invalid input) if the
/// trajectory is not sorted by strictly increasing time, (runtime) if writing fails.
void WriteTum(const std::filesystem::path& file, const Trajectory& trajectory);

/// Pose at time t by geodesic interpolation (core::Interpolate) between the two samples that
/// bracket t, exact for motion with constant speed and curvature. A sample at exactly t is
/// returned as is. Nothing if the trajectory is empty, t is outside [first, last] time, or
/// the bracketing samples are more than max_gap apart.
std::optional<core::Pose2> PoseAt(const Trajectory& trajectory, core::Timestamp t,
                                  core::Duration max_gap);

/// The TUM text of a time: seconds with exactly 9 decimals ("1700000000.123456789",
/// "-0.500000000"), computed on integers so no nanosecond is lost.
std::string FormatSeconds(core::Timestamp time);

/// Parses decimal seconds ("12", "-0.5", "1700000000.123456789", "1.7e9") on the digits, not
/// through a double, rounding to the nearest nanosecond (halves away from zero). Nothing if
/// the text is not a number or is out of the int64 nanosecond range (about ±292 years).
std::optional<core::Timestamp> ParseSeconds(std::string_view text);

}  // namespace mosaicloc::dataset
