#pragma once

#include <cstdint>
#include <optional>
#include <random>
#include <string>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/dataset.hpp"

namespace mosaicloc::sim {

/// A vehicle's encoders (nominal.kind: a differential drive's two wheels, a tricycle's drive
/// wheel and steering angle, or a mecanum vehicle's four wheels): the true geometry differs from the calibrated one the dataset
/// records, wheels slip, counts are quantized to whole ticks and kept as int32 PLC counters
/// that wrap.
struct EncoderOptions {
  double rate_hz = 100.0;
  dataset::VehicleInfo nominal;         ///< calibrated geometry, written to dataset.yaml
  // Differential drive.
  double left_radius_error = 0.003;     ///< true radius = nominal * (1 + error)
  double right_radius_error = 0.001;
  double track_width_error = 0.002;
  // Tricycle.
  double drive_radius_error = 0.003;    ///< true radius = nominal * (1 + error)
  double wheelbase_error = 0.001;       ///< true wheelbase = nominal * (1 + error)
  /// The true steering angle at count 0 is the calibrated one plus this, degrees.
  double steering_offset_error_deg = 0.2;
  /// Play in the steering gear between the encoder and the wheel, degrees: the wheel lags the
  /// encoder by up to half of it, on the side it last turned from.
  double steering_backlash_deg = 0.05;
  // Mecanum (track_width_error and wheelbase_error as above).
  double mecanum_radius_error = 0.003;  ///< the four wheels' true radius = nominal * (1 + error)
  /// The rollers slip when they carry the vehicle sideways: it moves (1 - lateral_slip) times
  /// the sideways distance its wheels' turns imply.
  double lateral_slip = 0.03;
  double slip_std = 0.002;              ///< relative wheel travel noise per sample
  /// Counter values at the start. Close to the int32 maximum so that every dataset
  /// exercises the wrap-around.
  std::int32_t initial_left_ticks = 2147483647 - 200000;
  std::int32_t initial_right_ticks = 2147483647 - 100000;
  std::int32_t initial_drive_ticks = 2147483647 - 150000;
  // A mecanum vehicle's rear wheels (its front ones start at initial_left_ticks, initial_right_ticks).
  std::int32_t initial_rear_left_ticks = -2147483647 + 120000;
  std::int32_t initial_rear_right_ticks = 2147483647 - 50000;
  bool Check(std::string* why) const;
};

/// How much later `moving_on` is taken for EncoderModel::Step, s: short enough that the
/// steering angle is the instant's.
inline constexpr double kSteeringInstantS = 1e-3;

class EncoderModel {
 public:
  /// Throws core::Error (invalid input) for bad options.
  EncoderModel(const EncoderOptions& options, std::uint64_t seed);

  /// Advances the true vehicle from its previous pose to `world_from_vehicle` (a short arc)
  /// and returns the counters read at that moment. A tricycle's steering encoder reads the
  /// wheel's angle at that instant: the one that moves the vehicle on to `moving_on` (its pose
  /// a moment later; without it, the angle of the arc just driven).
  dataset::EncoderSample Step(core::Timestamp time, const core::Pose2& world_from_vehicle,
                              const std::optional<core::Pose2>& moving_on = std::nullopt);

 private:
  EncoderOptions options_;
  std::mt19937_64 rng_;
  bool started_ = false;
  core::Pose2 last_pose_;
  double left_ticks_ = 0.0;   ///< exact (fractional) counts since start
  double right_ticks_ = 0.0;
  double drive_ticks_ = 0.0;
  double rear_left_ticks_ = 0.0;
  double rear_right_ticks_ = 0.0;
  double wheel_rad_ = 0.0;    ///< the tricycle's true steering angle
  double gear_rad_ = 0.0;     ///< where its steering encoder stands (backlash)
};

}  // namespace mosaicloc::sim
