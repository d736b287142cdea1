#include "mosaicloc/core/wheel_geometry.hpp"

#include <cmath>

namespace mosaicloc::core {

bool WheelGeometry::Check(std::string* why) const {
  const auto positive = [why](const char* key, double value) {
    if (std::isfinite(value) && value > 0.0) return true;
    *why = std::string(key) + " must be > 0 mm (got " + std::to_string(value) + ")";
    return false;
  };
  if (!positive("left_wheel_radius_mm", left_wheel_radius_mm) ||
      !positive("right_wheel_radius_mm", right_wheel_radius_mm) || !positive("track_width_mm", track_width_mm)) {
    return false;
  }
  if (ticks_per_revolution <= 0) {
    *why = "ticks_per_revolution must be > 0 (got " + std::to_string(ticks_per_revolution) + ")";
    return false;
  }
  return true;
}

void ReadWheelGeometry(YamlMap& map, WheelGeometry* wheels, bool required) {
  const auto read = [&](std::string_view key, auto* value) {
    if (required) {
      map.Required(key, value);
    } else {
      map.Optional(key, value);
    }
  };
  read("left_wheel_radius_mm", &wheels->left_wheel_radius_mm);
  read("right_wheel_radius_mm", &wheels->right_wheel_radius_mm);
  read("track_width_mm", &wheels->track_width_mm);
  read("ticks_per_revolution", &wheels->ticks_per_revolution);
  map.Check(*wheels);
}

}  // namespace mosaicloc::core
