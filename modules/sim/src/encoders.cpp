#include "mosaicloc/sim/encoders.hpp"

#include <algorithm>
#include <cmath>
#include <utility>
#include <numbers>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::sim {

bool EncoderOptions::Check(std::string* why) const {
  if (!(rate_hz > 0.0 && rate_hz <= 10000.0)) {
    *why = "rate_hz must be in (0, 10000]";
    return false;
  }
  for (const double error : {left_radius_error, right_radius_error, track_width_error, drive_radius_error,
                             wheelbase_error, mecanum_radius_error}) {
    if (!(std::abs(error) < 0.5)) {
      *why = "radius, track width and wheelbase errors must be within +-0.5 (relative)";
      return false;
    }
  }
  if (!(std::abs(steering_offset_error_deg) <= 10.0) || !(steering_backlash_deg >= 0.0 && steering_backlash_deg <= 5.0)) {
    *why = "steering_offset_error_deg must be within +-10 and steering_backlash_deg in [0, 5]";
    return false;
  }
  if (!(lateral_slip >= 0.0 && lateral_slip < 0.5)) {
    *why = "lateral_slip must be in [0, 0.5)";
    return false;
  }
  if (!(slip_std >= 0.0 && slip_std < 0.5)) {
    *why = "slip_std must be in [0, 0.5)";
    return false;
  }
  // The wheels last, so that a complaint about these fields is not hidden by one of theirs.
  return nominal.Check(why);
}

EncoderModel::EncoderModel(const EncoderOptions& options, std::uint64_t seed)
    : options_(options), rng_(seed ^ 0xe4c0de45ULL) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("encoders: " + why);
}

namespace {

// The steered wheel's angle and its travel for an arc of the fixed axle's centre (forward ds mm,
// turn dtheta rad) on wheelbase l: the wheel, l ahead, rolls hypot(ds, l dtheta) at
// atan(l dtheta / ds), the other way round when reversing. Nothing for no motion.
std::optional<std::pair<double, double>> SteeredWheel(const Eigen::Vector3d& twist, double l) {
  const double ds = twist.x(), lateral = l * twist.z();
  if (!(std::hypot(ds, lateral) > 1e-9)) return std::nullopt;
  const double sign = ds < 0.0 ? -1.0 : 1.0;
  return std::make_pair(std::atan2(sign * lateral, sign * ds), sign * std::hypot(ds, lateral));
}

}  // namespace

dataset::EncoderSample EncoderModel::Step(core::Timestamp time, const core::Pose2& world_from_vehicle,
                                          const std::optional<core::Pose2>& moving_on) {
  // A counter reads whole ticks; it wraps modulo 2^32 like the PLC's int32.
  const auto counter = [](std::int32_t initial, double ticks) {
    const auto whole = static_cast<std::int64_t>(std::floor(ticks));
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(initial) + static_cast<std::uint32_t>(whole));
  };
  const core::WheelGeometry& nominal = options_.nominal;
  if (nominal.kind == core::DriveKind::kTricycle) {
    const double l = nominal.wheelbase_mm * (1.0 + options_.wheelbase_error);
    if (started_) {
      // The arc just driven: the drive wheel's travel (the steered wheel's path length).
      if (const auto wheel = SteeredWheel(core::Between(last_pose_, world_from_vehicle).Log(), l)) {
        wheel_rad_ = wheel->first;
        std::normal_distribution<double> slip(0.0, options_.slip_std);
        const double radius = nominal.drive_wheel_radius_mm * (1.0 + options_.drive_radius_error);
        drive_ticks_ += wheel->second * (1.0 + slip(rng_)) / (2.0 * std::numbers::pi * radius) *
                        static_cast<double>(nominal.ticks_per_revolution);
      }
    } else {
      gear_rad_ = wheel_rad_ = 0.0;
    }
    // The angle at this instant: the one the vehicle moves on with.
    if (moving_on) {
      if (const auto wheel = SteeredWheel(core::Between(world_from_vehicle, *moving_on).Log(), l)) wheel_rad_ = wheel->first;
    }
    started_ = true;
    last_pose_ = world_from_vehicle;
    // The encoder's side of the gear stays where it is unless the wheel pulls it beyond the play.
    const double half_play = 0.5 * options_.steering_backlash_deg * std::numbers::pi / 180.0;
    gear_rad_ = std::clamp(gear_rad_, wheel_rad_ - half_play, wheel_rad_ + half_play);
    const double zero_rad = (nominal.steering_offset_deg + options_.steering_offset_error_deg) * std::numbers::pi / 180.0;
    dataset::EncoderSample sample;
    sample.time = time;
    sample.counts.drive_ticks = counter(options_.initial_drive_ticks, drive_ticks_);
    sample.counts.steering_ticks = static_cast<std::int32_t>(std::lround(
        (gear_rad_ - zero_rad) / (2.0 * std::numbers::pi) * static_cast<double>(nominal.steering_ticks_per_revolution)));
    return sample;
  }
  if (started_ && nominal.kind == core::DriveKind::kMecanum) {
    // The motion between the two poses (dx, dy, dtheta); the wheels turn as the kinematics
    // on the true geometry ask (WheelTravel), their sideways share 1 / (1 - lateral_slip)
    // times the motion's.
    const Eigen::Vector3d twist = core::Between(last_pose_, world_from_vehicle).Log();
    const double l = 0.5 * (nominal.track_width_mm * (1.0 + options_.track_width_error) +
                            nominal.wheelbase_mm * (1.0 + options_.wheelbase_error));
    const double dx = twist.x(), dy = twist.y() / (1.0 - options_.lateral_slip), turn = l * twist.z();
    const double radius = nominal.mecanum_wheel_radius_mm * (1.0 + options_.mecanum_radius_error);
    const double ticks_per_mm = static_cast<double>(nominal.ticks_per_revolution) / (2.0 * std::numbers::pi * radius);
    std::normal_distribution<double> slip(0.0, options_.slip_std);
    left_ticks_ += (dx - dy - turn) * (1.0 + slip(rng_)) * ticks_per_mm;
    right_ticks_ += (dx + dy + turn) * (1.0 + slip(rng_)) * ticks_per_mm;
    rear_left_ticks_ += (dx + dy - turn) * (1.0 + slip(rng_)) * ticks_per_mm;
    rear_right_ticks_ += (dx - dy + turn) * (1.0 + slip(rng_)) * ticks_per_mm;
  } else if (started_) {
    // The arc between the two poses: forward travel ds and rotation dtheta; each wheel
    // travels ds -+ dtheta * b / 2 on the true track width b.
    const Eigen::Vector3d twist = core::Between(last_pose_, world_from_vehicle).Log();
    const double b = options_.nominal.track_width_mm * (1.0 + options_.track_width_error);
    std::normal_distribution<double> slip(0.0, options_.slip_std);
    const double left_mm = (twist.x() - 0.5 * b * twist.z()) * (1.0 + slip(rng_));
    const double right_mm = (twist.x() + 0.5 * b * twist.z()) * (1.0 + slip(rng_));
    const double ticks_per_rev = static_cast<double>(options_.nominal.ticks_per_revolution);
    const double left_radius = options_.nominal.left_wheel_radius_mm * (1.0 + options_.left_radius_error);
    const double right_radius = options_.nominal.right_wheel_radius_mm * (1.0 + options_.right_radius_error);
    left_ticks_ += left_mm / (2.0 * std::numbers::pi * left_radius) * ticks_per_rev;
    right_ticks_ += right_mm / (2.0 * std::numbers::pi * right_radius) * ticks_per_rev;
  }
  started_ = true;
  last_pose_ = world_from_vehicle;
  dataset::EncoderSample sample;
  sample.time = time;
  sample.counts.left_ticks = counter(options_.initial_left_ticks, left_ticks_);
  sample.counts.right_ticks = counter(options_.initial_right_ticks, right_ticks_);
  if (nominal.kind == core::DriveKind::kMecanum) {
    sample.counts.rear_left_ticks = counter(options_.initial_rear_left_ticks, rear_left_ticks_);
    sample.counts.rear_right_ticks = counter(options_.initial_rear_right_ticks, rear_right_ticks_);
  }
  return sample;
}

}  // namespace mosaicloc::sim
