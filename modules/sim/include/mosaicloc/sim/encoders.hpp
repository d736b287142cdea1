#pragma once

#include <cstdint>
#include <random>
#include <string>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/dataset.hpp"

namespace mosaicloc::sim {

/// Wheel encoders of a differential-drive vehicle: the true geometry differs from the
/// calibrated one the dataset records, wheels slip, counts are quantized to whole ticks
/// and kept as int32 PLC counters that wrap.
struct EncoderOptions {
  double rate_hz = 100.0;
  dataset::VehicleInfo nominal;         ///< calibrated geometry, written to dataset.yaml
  double left_radius_error = 0.003;     ///< true radius = nominal * (1 + error)
  double right_radius_error = 0.001;
  double track_width_error = 0.002;
  double slip_std = 0.002;              ///< relative wheel travel noise per sample
  /// Counter values at the start. Close to the int32 maximum so that every dataset
  /// exercises the wrap-around.
  std::int32_t initial_left_ticks = 2147483647 - 200000;
  std::int32_t initial_right_ticks = 2147483647 - 100000;
  bool Check(std::string* why) const;
};

class EncoderModel {
 public:
  /// Throws core::Error (invalid input) for bad options.
  EncoderModel(const EncoderOptions& options, std::uint64_t seed);

  /// Advances the true vehicle from its previous pose to `world_from_vehicle` (a short arc)
  /// and returns the counters read at that moment.
  dataset::EncoderSample Step(core::Timestamp time, const core::Pose2& world_from_vehicle);

 private:
  EncoderOptions options_;
  std::mt19937_64 rng_;
  bool started_ = false;
  core::Pose2 last_pose_;
  double left_ticks_ = 0.0;   ///< exact (fractional) counts since start
  double right_ticks_ = 0.0;
};

}  // namespace mosaicloc::sim
