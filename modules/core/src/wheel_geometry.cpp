#include "mosaicloc/core/wheel_geometry.hpp"

#include <cmath>
#include <numbers>

namespace mosaicloc::core {

std::vector<std::int32_t> CountersOf(DriveKind kind, const EncoderCounts& counts) {
  if (kind == DriveKind::kTricycle) return {counts.drive_ticks, counts.steering_ticks};
  if (kind == DriveKind::kMecanum) {
    return {counts.left_ticks, counts.right_ticks, counts.rear_left_ticks, counts.rear_right_ticks};
  }
  return {counts.left_ticks, counts.right_ticks};
}

const char* ToString(DriveKind kind) {
  switch (kind) {
    case DriveKind::kDifferential: return "differential";
    case DriveKind::kTricycle: return "tricycle";
    case DriveKind::kMecanum: return "mecanum";
  }
  return "unknown";
}

bool WheelGeometry::Check(std::string* why) const {
  const auto positive = [why](const char* key, double value) {
    if (std::isfinite(value) && value > 0.0) return true;
    *why = std::string(key) + " must be > 0 mm (got " + std::to_string(value) + ")";
    return false;
  };
  const auto counts = [why](const char* key, std::int64_t value) {
    if (value > 0) return true;
    *why = std::string(key) + " must be > 0 (got " + std::to_string(value) + ")";
    return false;
  };
  if (kind == DriveKind::kTricycle) {
    if (!positive("drive_wheel_radius_mm", drive_wheel_radius_mm) || !positive("wheelbase_mm", wheelbase_mm) ||
        !counts("ticks_per_revolution", ticks_per_revolution) ||
        !counts("steering_ticks_per_revolution", steering_ticks_per_revolution)) {
      return false;
    }
    if (!(std::abs(steering_offset_deg) <= 45.0)) {
      *why = "steering_offset_deg must be within +-45 (got " + std::to_string(steering_offset_deg) + ")";
      return false;
    }
    return true;
  }
  if (kind == DriveKind::kMecanum) {
    return positive("mecanum_wheel_radius_mm", mecanum_wheel_radius_mm) && positive("track_width_mm", track_width_mm) &&
           positive("wheelbase_mm", wheelbase_mm) && counts("ticks_per_revolution", ticks_per_revolution);
  }
  return positive("left_wheel_radius_mm", left_wheel_radius_mm) &&
         positive("right_wheel_radius_mm", right_wheel_radius_mm) && positive("track_width_mm", track_width_mm) &&
         counts("ticks_per_revolution", ticks_per_revolution);
}

double WheelGeometry::SteeringRad(std::int32_t steering_ticks) const {
  return 2.0 * std::numbers::pi * static_cast<double>(steering_ticks) /
             static_cast<double>(steering_ticks_per_revolution) +
         steering_offset_deg * std::numbers::pi / 180.0;
}

double WheelGeometry::TicksToMm(double radius_mm, std::int64_t ticks) const {
  return 2.0 * std::numbers::pi * radius_mm * static_cast<double>(ticks) / static_cast<double>(ticks_per_revolution);
}

void ReadWheelGeometry(YamlMap& map, WheelGeometry* wheels, bool required) {
  const auto read = [&](std::string_view key, auto* value) {
    if (required) {
      map.Required(key, value);
    } else {
      map.Optional(key, value);
    }
  };
  map.OptionalEnum("kind", &wheels->kind, kDriveKinds);
  if (wheels->kind == DriveKind::kTricycle) {
    read("drive_wheel_radius_mm", &wheels->drive_wheel_radius_mm);
    read("wheelbase_mm", &wheels->wheelbase_mm);
    read("ticks_per_revolution", &wheels->ticks_per_revolution);
    read("steering_ticks_per_revolution", &wheels->steering_ticks_per_revolution);
    read("steering_offset_deg", &wheels->steering_offset_deg);
  } else if (wheels->kind == DriveKind::kMecanum) {
    read("mecanum_wheel_radius_mm", &wheels->mecanum_wheel_radius_mm);
    read("track_width_mm", &wheels->track_width_mm);
    read("wheelbase_mm", &wheels->wheelbase_mm);
    read("ticks_per_revolution", &wheels->ticks_per_revolution);
  } else {
    read("left_wheel_radius_mm", &wheels->left_wheel_radius_mm);
    read("right_wheel_radius_mm", &wheels->right_wheel_radius_mm);
    read("track_width_mm", &wheels->track_width_mm);
    read("ticks_per_revolution", &wheels->ticks_per_revolution);
  }
  map.Check(*wheels);
}

}  // namespace mosaicloc::core
