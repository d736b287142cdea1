#include "mosaicloc/sim/encoders.hpp"

#include <cmath>
#include <numbers>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::sim {

bool EncoderOptions::Check(std::string* why) const {
  if (!(rate_hz > 0.0 && rate_hz <= 10000.0)) {
    *why = "rate_hz must be in (0, 10000]";
    return false;
  }
  for (const double error : {left_radius_error, right_radius_error, track_width_error}) {
    if (!(std::abs(error) < 0.5)) {
      *why = "radius and track width errors must be within +-0.5 (relative)";
      return false;
    }
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

dataset::EncoderSample EncoderModel::Step(core::Timestamp time, const core::Pose2& world_from_vehicle) {
  if (started_) {
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
  // A counter reads whole ticks; it wraps modulo 2^32 like the PLC's int32.
  const auto counter = [](std::int32_t initial, double ticks) {
    const auto whole = static_cast<std::int64_t>(std::floor(ticks));
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(initial) + static_cast<std::uint32_t>(whole));
  };
  return {time, counter(options_.initial_left_ticks, left_ticks_), counter(options_.initial_right_ticks, right_ticks_)};
}

}  // namespace mosaicloc::sim
