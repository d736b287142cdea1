#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mosaicloc/core/pose2.hpp"

namespace mosaicloc::sim {

/// The guide path a simulated vehicle follows, with its speed profile.
struct RouteOptions {
  /// "straight": one straight run; "loop": a rounded rectangle driven anticlockwise;
  /// "network": a guidepath network with two junctions, a cross aisle and a dead-end spur
  /// the vehicle enters forwards and leaves in reverse (a figure-of-eight tour per lap);
  /// "serpentine": parallel rows joined by half turns, covering an area as a site survey
  /// does, closed by a return leg to the first row.
  std::string name = "loop";
  double straight_length_m = 20.0;
  double loop_width_m = 4.0;
  double loop_height_m = 2.0;
  double corner_radius_m = 0.5;   ///< loop corners and network turns
  double network_scale = 0.5;     ///< network size: 1.0 is a 12 m x 6 m site, 84 m per lap
  int serpentine_rows = 6;        ///< even number of rows
  double serpentine_length_m = 4.0;   ///< length of a row
  double serpentine_spacing_m = 0.5;  ///< distance between rows (twice the turn radius)
  double speed_mps = 1.0;         ///< cruise speed
  double max_accel_mps2 = 1.0;    ///< longitudinal acceleration and braking
  double max_lateral_accel_mps2 = 1.5;  ///< bounds the speed in turns: v <= sqrt(a / curvature)
  double stop_s = 1.0;            ///< dwell where the vehicle stops (spur end, route end)
  /// Length over which the curvature changes at the ends of a bend, m (a clothoid's, as the
  /// guide paths of steered vehicles have: a tricycle's wheel swings at a finite rate). 0: the
  /// curvature steps, as a differential drive may follow. Bends keep their angle; the path
  /// cuts slightly inside them.
  double curvature_transition_m = 0.0;
  /// Path-following error: a smooth lateral deviation with this standard deviation, mm,
  /// different on every lap (its wavelengths do not divide the lap length).
  double lateral_deviation_mm = 3.0;
  /// A vehicle that moves sideways (mecanum) need not face where it goes: its heading is the
  /// path's plus crab_amplitude_deg sin(2 pi s / crab_wavelength_m), s the distance driven. 0:
  /// it faces along the path, as every other kind must.
  double crab_amplitude_deg = 0.0;
  double crab_wavelength_m = 8.0;
  bool Check(std::string* why) const;
};

/// Where the vehicle is at a time.
struct VehicleState {
  core::Pose2 world_from_vehicle;
  double forward_speed_mps = 0.0;  ///< negative when reversing
  double path_distance_m = 0.0;    ///< distance driven so far, always increasing
};

/// A time-parameterized drive along a route: `laps` complete laps (or the straight run
/// that many times its length), starting and ending at rest.
class Drive {
 public:
  /// Throws core::Error (invalid input) for bad options. `seed` drives the lateral deviation.
  Drive(const RouteOptions& options, int laps, std::uint64_t seed);

  double duration_s() const { return duration_s_; }
  double length_m() const;
  double lap_length_m() const { return lap_length_m_; }
  int laps() const { return laps_; }
  double max_speed_mps() const;
  /// State at time t, clamped to [0, duration].
  VehicleState At(double time_s) const;
  /// The route's centre line (no deviation) at driven distance s, for tests and plots.
  core::Pose2 CentreLineAt(double distance_m) const;

  /// Laps needed for `frames` frames at `frame_rate_hz` (at least one).
  static int LapsForFrames(const RouteOptions& options, std::int64_t frames, double frame_rate_hz);

  /// Internal samples of the drive: every 5 mm of path.
  struct Sample {
    double distance_m;   ///< driven distance
    double time_s;
    double speed_mps;    ///< magnitude
    double curvature_per_m;
    int direction;       ///< +1 forward, -1 reverse
    core::Pose2 centre;  ///< centre line pose in the direction of travel
  };

 private:
  struct CentrePoint;
  void SmoothCurvature(std::vector<std::vector<CentrePoint>>* legs) const;
  double LateralDeviationMm(double distance_m) const;
  double LateralDeviationSlope(double distance_m) const;

  RouteOptions options_;
  int laps_ = 1;
  double lap_length_m_ = 0.0;
  double duration_s_ = 0.0;
  std::vector<Sample> samples_;
  struct LegBounds {
    double start_m;
    double end_m;
  };
  std::vector<LegBounds> leg_bounds_;  ///< driven distance where each leg starts and ends
  std::vector<double> deviation_wavelengths_m_;
  std::vector<double> deviation_phases_;
  double deviation_gain_ = 0.0;
};

}  // namespace mosaicloc::sim
