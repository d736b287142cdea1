#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/sim/floor.hpp"

namespace mosaicloc::sim {

/// How a floor looks now against when it was mapped: changes on the floor itself (not the
/// lens), each with an amount, all drawn from `seed` so that a map can be made before and a
/// drive after. All zero: the floor as it was.
struct FloorChangeOptions {
  std::uint64_t seed = 1;
  /// Grime: the share of the floor (0..1) under a film that darkens it and flattens its
  /// texture, in smooth patches about 150 mm across; `grime_strength` (0..1) at their heart.
  double grime_fraction = 0.0;
  double grime_strength = 0.5;
  /// Stains: dark or light blotches 20 to 200 mm across, this many per square metre.
  double stains_per_m2 = 0.0;
  /// Tyre marks along the wheel paths (Simulate: the drive's route): their darkness at
  /// the centre of a mark (0..1, 0: none) and a mark's width, mm.
  double tyre_marks = 0.0;
  double tyre_mark_width_mm = 60.0;
  /// The distance between the marks of a lane's two wheel paths, mm (0: the drive's own
  /// track; a narrower vehicle's marks run under the camera).
  double tyre_track_width_mm = 0.0;
  /// A wet patch: a disc (centre, radius; radius 0: none) darker and flatter by `wet_strength`.
  double wet_x_mm = 0.0;
  double wet_y_mm = 0.0;
  double wet_radius_mm = 0.0;
  double wet_strength = 0.5;
  /// A replaced tile: a square (centre, side; side 0: none) of new floor of the same kind.
  double tile_x_mm = 0.0;
  double tile_y_mm = 0.0;
  double tile_size_mm = 0.0;
  /// A painted lane line from (x0, y0) to (x1, y1), `lane_width_mm` wide (0: none), of grey
  /// level `lane_dn`.
  double lane_x0_mm = 0.0;
  double lane_y0_mm = 0.0;
  double lane_x1_mm = 0.0;
  double lane_y1_mm = 0.0;
  double lane_width_mm = 0.0;
  double lane_dn = 230.0;
  bool any() const;
  bool Check(std::string* why) const;
};

/// `base` as changed by `options`. `wheel_paths`: polylines of the wheels' contact points, mm,
/// along which tyre marks are laid. Texels keep the Floor contract: the same value whatever
/// window renders them.
std::unique_ptr<Floor> ChangedFloor(std::unique_ptr<Floor> base, const FloorChangeOptions& options,
                                    std::vector<std::vector<Eigen::Vector2d>> wheel_paths = {});

}  // namespace mosaicloc::sim
