#include "mosaicloc/sim/route.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::sim {
namespace {

constexpr double kStepM = 0.005;
constexpr double kPi = std::numbers::pi;
// Over 1 m, 8 mm of path-following error fades in turning a 1.2 m tricycle's wheel at most
// about 40 degrees/s at 1 m/s, as a steering motor can.
constexpr double kDeviationRampM = 1.0;

// A piece of path: a line (curvature 0) or an arc, of a length, driven in a direction.
struct Primitive {
  double length_m;
  double curvature_per_m;
  int direction;  // +1 forward, -1 reverse
};

Primitive Line(double length_m, int direction = 1) { return {length_m, 0.0, direction}; }
Primitive Arc(double radius_m, double angle_rad, int direction = 1) {
  return {radius_m * std::abs(angle_rad), (angle_rad > 0 ? 1.0 : -1.0) / radius_m, direction};
}

std::vector<Primitive> LapPrimitives(const RouteOptions& o) {
  std::vector<Primitive> lap;
  if (o.name == "straight") {
    lap.push_back(Line(o.straight_length_m));
  } else if (o.name == "loop") {
    const double r = o.corner_radius_m;
    for (int side = 0; side < 4; ++side) {
      lap.push_back(Line((side % 2 == 0 ? o.loop_width_m : o.loop_height_m) - 2.0 * r));
      lap.push_back(Arc(r, kPi / 2));
    }
  } else if (o.name == "serpentine") {
    const double r = 0.5 * o.serpentine_spacing_m;
    for (int row = 0; row < o.serpentine_rows; ++row) {
      lap.push_back(Line(o.serpentine_length_m));
      // Half turns alternate right and left; after the last row, back up the side.
      if (row + 1 < o.serpentine_rows) lap.push_back(Arc(r, row % 2 == 0 ? -kPi : kPi));
    }
    lap.push_back(Arc(r, -kPi / 2));
    if (o.serpentine_rows > 2) lap.push_back(Line((o.serpentine_rows - 2) * o.serpentine_spacing_m));
    lap.push_back(Arc(r, -kPi / 2));
  } else {  // network: see RouteOptions; unit layout 12 m x 6 m, turns of radius 1 m
    const double k = o.network_scale;
    const auto line = [&](double m, int direction = 1) { lap.push_back(Line(m * k, direction)); };
    const auto left = [&](int direction = 1) { lap.push_back(Arc(k, kPi / 2, direction)); };
    const auto right = [&](int direction = 1) { lap.push_back(Arc(k, -kPi / 2, direction)); };
    // Bottom side, left into the cross aisle, right onto the top side, clockwise round
    // the outer loop, then along the top side into the spur.
    line(4); left(); line(4); right(); line(4); right(); line(4); right(); line(10); right();
    line(4); right(); line(1); left(); line(1.5);
    // Back out of the spur in reverse: the same path, travelled backwards.
    line(1.5, -1); right(-1);
    // Along the top side, right down the cross aisle, left onto the bottom side, and
    // anticlockwise round the outer loop to the start.
    line(3); right(); line(4); left(); line(4); left(); line(4); left(); line(10); left(); line(4); left();
  }
  return lap;
}

}  // namespace

// A point of the centre line, sampled every kStepM.
struct Drive::CentrePoint {
  double s;
  double curvature;     // per m, relative to the direction of travel
  int direction;
  core::Pose2 travel;   // heading along the direction of travel
};

// Each leg's curvature averaged over curvature_transition_m around every point (a bend's
// step becomes a linear ramp, a clothoid) and its centre line integrated again from the leg's
// start; the next leg starts where this one now ends.
void Drive::SmoothCurvature(std::vector<std::vector<CentrePoint>>* legs) const {
  const double half_window = 0.5 * options_.curvature_transition_m;
  core::Pose2 start = legs->front().front().travel;
  for (auto& leg : *legs) {
    // Prefix sums of curvature times step length: the window's mean in O(1) per point.
    std::vector<double> turned(leg.size(), 0.0);
    for (std::size_t i = 1; i < leg.size(); ++i) turned[i] = turned[i - 1] + leg[i].curvature * (leg[i].s - leg[i - 1].s);
    const auto turned_at = [&](double s) {
      s = std::clamp(s, leg.front().s, leg.back().s);
      const auto upper = std::upper_bound(leg.begin(), leg.end(), s, [](double v, const CentrePoint& p) { return v < p.s; });
      if (upper == leg.end()) return turned.back();
      const std::size_t j = static_cast<std::size_t>(upper - leg.begin());
      return turned[j - 1] + leg[j].curvature * (s - leg[j - 1].s);
    };
    std::vector<double> smoothed(leg.size());
    for (std::size_t i = 0; i < leg.size(); ++i) {
      const double from = std::max(leg.front().s, leg[i].s - half_window);
      const double to = std::min(leg.back().s, leg[i].s + half_window);
      smoothed[i] = to > from ? (turned_at(to) - turned_at(from)) / (to - from) : leg[i].curvature;
    }
    leg.front().travel = start;
    for (std::size_t i = 1; i < leg.size(); ++i) {
      const double step = leg[i].s - leg[i - 1].s;
      const double k = 0.5 * (smoothed[i - 1] + smoothed[i]);
      leg[i].travel = leg[i - 1].travel * core::Pose2::Exp({step * 1000.0, 0.0, step * k});
    }
    for (std::size_t i = 0; i < leg.size(); ++i) leg[i].curvature = smoothed[i];
    // Stop and reverse: the vehicle keeps its heading, the travel heading turns round.
    start = leg.back().travel * core::Pose2(0.0, 0.0, kPi);
  }
}

bool RouteOptions::Check(std::string* why) const {
  if (name != "straight" && name != "loop" && name != "network" && name != "serpentine") {
    *why = "route must be straight, loop, network or serpentine, got '" + name + "'";
    return false;
  }
  if (serpentine_rows < 2 || serpentine_rows % 2 != 0 || !(serpentine_length_m > 0.0) || !(serpentine_spacing_m > 0.0)) {
    *why = "serpentine_rows must be even and >= 2, serpentine_length_m and serpentine_spacing_m > 0";
    return false;
  }
  if (!(speed_mps > 0.0 && speed_mps <= 30.0)) {
    *why = "speed_mps must be in (0, 30]";
    return false;
  }
  if (!(max_accel_mps2 > 0.0) || !(max_lateral_accel_mps2 > 0.0) || !(stop_s >= 0.0)) {
    *why = "max_accel_mps2 and max_lateral_accel_mps2 must be > 0, stop_s >= 0";
    return false;
  }
  if (!(corner_radius_m > 0.0) || !(loop_width_m > 2.0 * corner_radius_m) || !(loop_height_m > 2.0 * corner_radius_m)) {
    *why = "loop_width_m and loop_height_m must exceed twice corner_radius_m (> 0)";
    return false;
  }
  if (!(straight_length_m > 0.0)) {
    *why = "straight_length_m must be > 0";
    return false;
  }
  if (!(network_scale >= 0.05 && network_scale <= 100.0)) {
    *why = "network_scale must be in [0.05, 100]";
    return false;
  }
  if (serpentine_rows > 10000) {
    *why = "serpentine_rows must be at most 10000";
    return false;
  }
  if (!(curvature_transition_m >= 0.0 && curvature_transition_m <= 10.0)) {
    *why = "curvature_transition_m must be in [0, 10]";
    return false;
  }
  if (!(crab_amplitude_deg >= 0.0 && crab_amplitude_deg <= 90.0) || !(crab_wavelength_m >= 0.5)) {
    *why = "crab_amplitude_deg must be in [0, 90] and crab_wavelength_m >= 0.5";
    return false;
  }
  if (!(lateral_deviation_mm >= 0.0 && lateral_deviation_mm < 100.0)) {
    *why = "lateral_deviation_mm must be in [0, 100)";
    return false;
  }
  return true;
}

Drive::Drive(const RouteOptions& options, int laps, std::uint64_t seed) : options_(options), laps_(laps) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("route: " + why);
  if (laps_ < 1) core::ThrowInvalidInput("route: laps must be >= 1");

  const std::vector<Primitive> lap = LapPrimitives(options_);
  lap_length_m_ = 0.0;
  for (const auto& p : lap) lap_length_m_ += p.length_m;

  // Centre line, sampled every kStepM, split into legs where the direction changes.
  std::vector<std::vector<CentrePoint>> legs(1);
  core::Pose2 travel = core::Pose2::Identity();
  double s = 0.0;
  int direction = lap.front().direction;
  legs.back().push_back({0.0, lap.front().curvature_per_m, direction, travel});
  for (int l = 0; l < laps_; ++l) {
    for (const auto& p : lap) {
      if (p.direction != direction) {
        // Stop and reverse: the vehicle keeps its heading, the travel heading turns round.
        direction = p.direction;
        travel = travel * core::Pose2(0.0, 0.0, kPi);
        legs.emplace_back();
        legs.back().push_back({s, p.curvature_per_m, direction, travel});
      }
      // Travelled backwards, a turn bends the other way relative to the travel heading.
      const double curvature = p.curvature_per_m * p.direction;
      const int steps = std::max(1, static_cast<int>(std::ceil(p.length_m / kStepM)));
      const double step = p.length_m / steps;
      const core::Pose2 increment = core::Pose2::Exp({step * 1000.0, 0.0, step * curvature});
      for (int i = 0; i < steps; ++i) {
        travel = travel * increment;
        s += step;
        legs.back().push_back({s, curvature, direction, travel});
      }
    }
  }

  if (options_.curvature_transition_m > 0.0) SmoothCurvature(&legs);

  // Speed profile per leg: cruise speed, curvature limit, accelerate from and brake to rest.
  double time = options_.stop_s;
  for (const auto& leg : legs) {
    std::vector<double> v(leg.size());
    for (std::size_t i = 0; i < leg.size(); ++i) {
      const double k = std::abs(leg[i].curvature);
      v[i] = k > 0.0 ? std::min(options_.speed_mps, std::sqrt(options_.max_lateral_accel_mps2 / k)) : options_.speed_mps;
    }
    v.front() = 0.0;
    v.back() = 0.0;
    for (std::size_t i = 1; i < leg.size(); ++i) {
      const double ds = leg[i].s - leg[i - 1].s;
      v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + 2.0 * options_.max_accel_mps2 * ds));
    }
    for (std::size_t i = leg.size() - 1; i-- > 0;) {
      const double ds = leg[i + 1].s - leg[i].s;
      v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + 2.0 * options_.max_accel_mps2 * ds));
    }
    for (std::size_t i = 0; i < leg.size(); ++i) {
      if (i > 0) time += 2.0 * (leg[i].s - leg[i - 1].s) / (v[i - 1] + v[i]);
      const int dir = leg[i].direction;
      const core::Pose2 centre = dir > 0 ? leg[i].travel : leg[i].travel * core::Pose2(0.0, 0.0, kPi);
      samples_.push_back({leg[i].s, time, v[i], leg[i].curvature, dir, centre});
    }
    time += options_.stop_s;
  }
  duration_s_ = time;

  std::mt19937_64 rng(seed ^ 0x5eedf00dULL);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const double base_m : {2.3, 5.7, 13.1}) {
    deviation_wavelengths_m_.push_back(base_m * (0.9 + 0.2 * unit(rng)));
    deviation_phases_.push_back(2.0 * kPi * unit(rng));
  }
  // A sum of n unit sinusoids has standard deviation sqrt(n / 2).
  deviation_gain_ = options_.lateral_deviation_mm / std::sqrt(0.5 * static_cast<double>(deviation_wavelengths_m_.size()));

  // Legs start and end where the deviation is smoothly zero, so reversals do not jump.
  leg_bounds_.clear();
  double leg_start = samples_.front().distance_m;
  for (std::size_t i = 1; i <= samples_.size(); ++i) {
    if (i == samples_.size() || samples_[i].direction != samples_[i - 1].direction ||
        samples_[i].distance_m == samples_[i - 1].distance_m) {
      leg_bounds_.push_back({leg_start, samples_[i - 1].distance_m});
      if (i < samples_.size()) leg_start = samples_[i].distance_m;
    }
  }
}

double Drive::length_m() const { return samples_.back().distance_m; }

double Drive::max_speed_mps() const {
  double best = 0.0;
  for (const auto& sample : samples_) best = std::max(best, sample.speed_mps);
  return best;
}

double Drive::LateralDeviationMm(double distance_m) const {
  double sum = 0.0;
  for (std::size_t i = 0; i < deviation_wavelengths_m_.size(); ++i) {
    sum += std::sin(2.0 * kPi * distance_m / deviation_wavelengths_m_[i] + deviation_phases_[i]);
  }
  return deviation_gain_ * sum;
}

double Drive::LateralDeviationSlope(double distance_m) const {
  double sum = 0.0;  // d(deviation)/d(distance), mm per m
  for (std::size_t i = 0; i < deviation_wavelengths_m_.size(); ++i) {
    const double w = 2.0 * kPi / deviation_wavelengths_m_[i];
    sum += w * std::cos(w * distance_m + deviation_phases_[i]);
  }
  return deviation_gain_ * sum;
}

VehicleState Drive::At(double time_s) const {
  const double t = std::clamp(time_s, samples_.front().time_s, samples_.back().time_s);
  auto upper = std::upper_bound(samples_.begin(), samples_.end(), t,
                                [](double value, const Sample& sample) { return value < sample.time_s; });
  if (upper == samples_.end()) upper = std::prev(samples_.end());
  if (upper == samples_.begin()) upper = std::next(samples_.begin());
  const Sample& a = *std::prev(upper);
  const Sample& b = *upper;

  double distance = a.distance_m;
  double speed = 0.0;
  core::Pose2 centre = a.centre;
  const double ds = b.distance_m - a.distance_m;
  if (ds > 0.0 && b.direction == a.direction && t >= a.time_s) {
    // Constant acceleration between samples.
    const double accel = (b.speed_mps * b.speed_mps - a.speed_mps * a.speed_mps) / (2.0 * ds);
    const double tau = t - a.time_s;
    const double travelled = std::clamp(a.speed_mps * tau + 0.5 * accel * tau * tau, 0.0, ds);
    distance = a.distance_m + travelled;
    speed = a.speed_mps + accel * tau;
    centre = core::Interpolate(a.centre, b.centre, travelled / ds);
  } else if (t >= b.time_s) {
    distance = b.distance_m;
    centre = b.centre;
  }

  // Deviation envelope over kDeviationRampM from each end of the leg: the quintic smoothstep,
  // whose first and second derivatives vanish at both ends, so the path's curvature (and a
  // steered wheel's angle) stays continuous where the deviation fades in and out.
  const int direction = a.direction;
  auto leg = std::upper_bound(leg_bounds_.begin(), leg_bounds_.end(), distance,
                              [](double value, const LegBounds& bounds) { return value < bounds.start_m; });
  if (leg != leg_bounds_.begin()) --leg;
  // At a reversal two legs share the distance: both envelopes are zero there.
  const double from_end = std::min(distance - leg->start_m, leg->end_m - distance);
  const double x = std::clamp(from_end / kDeviationRampM, 0.0, 1.0);
  const double envelope = x * x * x * (10.0 + x * (-15.0 + 6.0 * x));
  const double envelope_slope = (from_end > 0.0 && from_end < kDeviationRampM)
                                    ? 30.0 * x * x * (1.0 - x) * (1.0 - x) / kDeviationRampM
                                    : 0.0;
  const double sign = (distance - leg->start_m) < (leg->end_m - distance) ? 1.0 : -1.0;
  const double deviation_mm = envelope * LateralDeviationMm(distance);
  const double slope_mm_per_m =
      envelope * LateralDeviationSlope(distance) + sign * envelope_slope * LateralDeviationMm(distance);
  // The vehicle's x axis points against the travel direction when reversing.
  const double heading_rad = std::atan(direction * slope_mm_per_m * 1e-3) +
                            options_.crab_amplitude_deg * std::numbers::pi / 180.0 *
                                std::sin(2.0 * std::numbers::pi * distance / options_.crab_wavelength_m);

  VehicleState state;
  state.world_from_vehicle = centre * core::Pose2(0.0, deviation_mm, heading_rad);
  state.forward_speed_mps = direction * speed;
  state.path_distance_m = distance;
  return state;
}

core::Pose2 Drive::CentreLineAt(double distance_m) const {
  const auto upper = std::lower_bound(samples_.begin(), samples_.end(), distance_m,
                                      [](const Sample& sample, double value) { return sample.distance_m < value; });
  if (upper == samples_.begin()) return samples_.front().centre;
  if (upper == samples_.end()) return samples_.back().centre;
  const Sample& a = *std::prev(upper);
  const Sample& b = *upper;
  const double ds = b.distance_m - a.distance_m;
  return ds > 0.0 ? core::Interpolate(a.centre, b.centre, (distance_m - a.distance_m) / ds) : b.centre;
}

int Drive::LapsForFrames(const RouteOptions& options, std::int64_t frames, double frame_rate_hz) {
  const Drive one(options, 1, 0);
  const double needed_s = static_cast<double>(frames) / frame_rate_hz;
  // Each further lap adds its cruise time; the first one includes the start and end stops.
  const double per_lap_s = std::max(one.duration_s() - 2.0 * options.stop_s, 1e-3);
  return std::max(1, static_cast<int>(std::ceil((needed_s - 2.0 * options.stop_s) / per_lap_s)) + 1);
}

}  // namespace mosaicloc::sim
