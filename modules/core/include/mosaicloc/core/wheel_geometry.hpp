#pragma once

#include <cstdint>
#include <string>

#include "mosaicloc/core/yaml.hpp"

namespace mosaicloc::core {

/// A differential-drive vehicle's wheels as calibrated: what turns encoder ticks into motion.
/// The one definition the dataset header, odometry, the simulator and vehicle calibration share.
struct WheelGeometry {
  double left_wheel_radius_mm = 75.0;
  double right_wheel_radius_mm = 75.0;
  double track_width_mm = 500.0;  ///< distance between the wheel contact points
  std::int64_t ticks_per_revolution = 4096;
  /// Radii and track width > 0 and finite, ticks_per_revolution >= 1.
  bool Check(std::string* why) const;
};

/// Reads the four keys of a mapping (a dataset header's or a configuration's `vehicle:`)
/// into *wheels, then Check(): every key required, or each optional over what *wheels holds.
void ReadWheelGeometry(YamlMap& map, WheelGeometry* wheels, bool required);

}  // namespace mosaicloc::core
