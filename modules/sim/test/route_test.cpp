#include "mosaicloc/sim/route.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::sim {
namespace {

RouteOptions Route(const std::string& name) {
  RouteOptions options;
  options.name = name;
  return options;
}

TEST(Drive, LoopLapsCloseAndDeviationStaysSmall) {
  RouteOptions options = Route("loop");
  options.lateral_deviation_mm = 0.0;
  const Drive drive(options, 3, 1);
  // Perimeter of a rounded rectangle: 2 (W - 2R) + 2 (H - 2R) + 2 pi R.
  const double perimeter = 2 * 3.0 + 2 * 1.0 + 2 * std::numbers::pi * 0.5;
  EXPECT_NEAR(drive.lap_length_m(), perimeter, 1e-9);
  EXPECT_NEAR(drive.length_m(), 3 * perimeter, 1e-6);
  const core::Pose2 start = drive.At(0.0).world_from_vehicle;
  const core::Pose2 end = drive.At(drive.duration_s()).world_from_vehicle;
  EXPECT_LT(core::Distance(start, end), 1e-6);
  EXPECT_LT(std::abs(core::YawDifference(start, end)), 1e-9);
}

TEST(Drive, NetworkLapClosesReversesInTheSpurAndHasJunctions) {
  RouteOptions options = Route("network");
  options.lateral_deviation_mm = 0.0;
  const Drive drive(options, 2, 1);
  EXPECT_NEAR(drive.lap_length_m(), 0.5 * (63.0 + 14.0 * std::numbers::pi / 2.0), 1e-6);
  const core::Pose2 start = drive.At(0.0).world_from_vehicle;
  const core::Pose2 end = drive.At(drive.duration_s()).world_from_vehicle;
  EXPECT_LT(core::Distance(start, end), 1e-5);
  // Somewhere the vehicle drives backwards, and it comes to rest between legs.
  bool reversed = false;
  for (double t = 0.0; t < drive.duration_s(); t += 0.05) {
    reversed = reversed || drive.At(t).forward_speed_mps < -0.1;
  }
  EXPECT_TRUE(reversed);
  // The spur end at (3, 8.5) m in the unit layout, scaled by 0.5, relative to the start (1, 0).
  bool at_spur_end = false;
  for (double t = 0.0; t < drive.duration_s(); t += 0.02) {
    const core::Pose2 pose = drive.At(t).world_from_vehicle;
    if (std::hypot(pose.x_mm() - 1000.0, pose.y_mm() - 4250.0) < 5.0) at_spur_end = true;
  }
  EXPECT_TRUE(at_spur_end);
}

TEST(Drive, SerpentineCoversRowsAndCloses) {
  RouteOptions options = Route("serpentine");
  options.lateral_deviation_mm = 0.0;
  const Drive drive(options, 2, 1);
  // 6 rows of 4 m, 5 half turns and two quarter turns of radius 0.25 m, 2 m back up the side.
  EXPECT_NEAR(drive.lap_length_m(), 6 * 4.0 + 6 * std::numbers::pi * 0.25 + 2.0, 1e-9);
  const core::Pose2 start = drive.At(0.0).world_from_vehicle;
  EXPECT_LT(core::Distance(start, drive.At(drive.duration_s()).world_from_vehicle), 1e-5);
  // The rows lie 0.5 m apart: y reaches -2.5 m.
  double min_y = 0.0;
  for (double t = 0.0; t < drive.duration_s(); t += 0.05) min_y = std::min(min_y, drive.At(t).world_from_vehicle.y_mm());
  EXPECT_NEAR(min_y, -2500.0, 1.0);
}

TEST(Drive, SpeedProfileRespectsLimits) {
  RouteOptions options = Route("loop");
  options.speed_mps = 2.0;
  options.loop_width_m = 8.0;  // long enough straights to reach cruise speed
  const Drive drive(options, 2, 3);
  EXPECT_NEAR(drive.max_speed_mps(), 2.0, 1e-9);
  double previous_speed = 0.0;
  const double dt = 0.01;
  for (double t = 0.0; t < drive.duration_s(); t += dt) {
    const VehicleState state = drive.At(t);
    EXPECT_LE(std::abs(state.forward_speed_mps), 2.0 + 1e-9);
    // Longitudinal acceleration within the limit (with sampling slack).
    EXPECT_LE(std::abs(state.forward_speed_mps - previous_speed) / dt, options.max_accel_mps2 * 1.05 + 1e-6);
    previous_speed = state.forward_speed_mps;
  }
  // Starts and ends at rest.
  EXPECT_EQ(drive.At(0.0).forward_speed_mps, 0.0);
  EXPECT_NEAR(drive.At(drive.duration_s()).forward_speed_mps, 0.0, 1e-9);
}

TEST(Drive, LateralDeviationDiffersBetweenLapsAndMatchesItsSize) {
  RouteOptions options = Route("loop");
  options.lateral_deviation_mm = 3.0;
  RouteOptions centre = options;
  centre.lateral_deviation_mm = 0.0;
  const Drive drive(options, 4, 9);
  const Drive reference(centre, 4, 9);
  double sum2 = 0.0;
  int n = 0;
  double lap_difference = 0.0;
  for (double t = 5.0; t < drive.duration_s() - 20.0; t += 0.1) {
    const double offset = core::Distance(drive.At(t).world_from_vehicle, reference.At(t).world_from_vehicle);
    sum2 += offset * offset;
    ++n;
  }
  // Same place one lap later: the deviation is not the same.
  const double lap_s = 11.2;  // roughly one lap at 1 m/s
  for (double t = 5.0; t < 10.0; t += 0.1) {
    const auto here = reference.At(t);
    // find the time one lap later with the same path distance
    double lo = t, hi = t + 2 * lap_s;
    for (int i = 0; i < 60; ++i) {
      const double mid = 0.5 * (lo + hi);
      (reference.At(mid).path_distance_m < here.path_distance_m + reference.lap_length_m() ? lo : hi) = mid;
    }
    lap_difference = std::max(lap_difference, core::Distance(drive.At(t).world_from_vehicle, drive.At(lo).world_from_vehicle));
  }
  const double rms = std::sqrt(sum2 / n);
  EXPECT_GT(rms, 1.5);
  EXPECT_LT(rms, 5.0);
  EXPECT_GT(lap_difference, 0.5);
}

// With a transition the curvature ramps into and out of each bend, so a tricycle's wheel
// never has to swing at once; every bend keeps its angle, the path cutting slightly inside.
TEST(Drive, CurvatureTransitionsEaseTheBendsAndKeepTheirAngles) {
  RouteOptions sharp = Route("loop");
  sharp.lateral_deviation_mm = 0.0;
  RouteOptions eased = sharp;
  eased.curvature_transition_m = 0.4;
  const Drive a(sharp, 1, 1), b(eased, 1, 1);
  // Curvature from the heading change over 10 mm of path, all along the lap.
  const auto curvature_at = [](const Drive& d, double s) {
    return core::WrapAngle(d.CentreLineAt(s + 0.005).yaw_rad() - d.CentreLineAt(s - 0.005).yaw_rad()) / 0.01;
  };
  double sharp_jump = 0.0, eased_jump = 0.0;
  for (double s = 0.02; s < a.lap_length_m() - 0.03; s += 0.01) {
    sharp_jump = std::max(sharp_jump, std::abs(curvature_at(a, s + 0.01) - curvature_at(a, s)));
    eased_jump = std::max(eased_jump, std::abs(curvature_at(b, s + 0.01) - curvature_at(b, s)));
  }
  EXPECT_GT(sharp_jump, 1.5);   // 1/0.5 m in one step
  EXPECT_LT(eased_jump, 0.1);   // 2 /m over 0.4 m: 0.05 per 10 mm
  // The same quarter turns: past the first bend the heading is the same.
  EXPECT_NEAR(core::WrapAngle(a.CentreLineAt(4.3).yaw_rad() - b.CentreLineAt(4.3).yaw_rad()), 0.0, 1e-4);
  // The eased path stays within a few centimetres of the sharp one, and the lap closes.
  double apart = 0.0;
  for (double s = 0.0; s < a.lap_length_m(); s += 0.05) apart = std::max(apart, core::Distance(a.CentreLineAt(s), b.CentreLineAt(s)));
  EXPECT_LT(apart, 30.0);
  EXPECT_LT(core::Distance(b.CentreLineAt(0.0), b.CentreLineAt(b.lap_length_m())), 15.0);
  RouteOptions bad = eased;
  bad.curvature_transition_m = -1.0;
  EXPECT_THROW(Drive(bad, 1, 1), core::Error);
}

// The path-following error fades in and out at each end of a leg without a step in the
// path's curvature, for any seed: a tricycle's steered wheel would have to swing at once
// (10 degrees within one encoder sample, with an envelope whose second derivative jumps).
TEST(Drive, LateralDeviationKeepsTheCurvatureContinuous) {
  RouteOptions options = Route("straight");
  options.straight_length_m = 3.0;
  options.lateral_deviation_mm = 8.0;
  double largest = 0.0, jump = 0.0;
  for (std::uint64_t seed = 1; seed <= 12; ++seed) {
    const Drive drive(options, 1, seed);
    // Heading against path distance, densely; curvature over 10 mm windows.
    std::vector<std::pair<double, double>> heading;  // (distance m, yaw rad)
    for (double t = 0.0; t < drive.duration_s(); t += 0.0005) {
      const VehicleState state = drive.At(t);
      if (heading.empty() || state.path_distance_m >= heading.back().first + 0.01) {
        heading.emplace_back(state.path_distance_m, state.world_from_vehicle.yaw_rad());
      }
    }
    ASSERT_GT(heading.size(), 250u);
    double previous = 0.0;
    for (std::size_t i = 1; i < heading.size(); ++i) {
      const double curvature = core::WrapAngle(heading[i].second - heading[i - 1].second) /
                               (heading[i].first - heading[i - 1].first);
      largest = std::max(largest, std::abs(curvature));
      if (i > 1) jump = std::max(jump, std::abs(curvature - previous));
      previous = curvature;
    }
  }
  EXPECT_GT(largest, 0.02);  // the deviation does bend the path
  EXPECT_LT(jump, 0.03);     // but never in a step (a cubic smoothstep steps by 0.08 /m)
}

TEST(Drive, LapsForFramesCoversTheFrames) {
  const RouteOptions options = Route("straight");
  const int laps = Drive::LapsForFrames(options, 3000, 30.0);
  const Drive drive(options, laps, 1);
  EXPECT_GE(drive.duration_s(), 3000 / 30.0);
}

TEST(Drive, RejectsBadOptions) {
  RouteOptions options = Route("circle");
  EXPECT_THROW(Drive(options, 1, 1), core::Error);
  options = Route("loop");
  options.corner_radius_m = 3.0;
  EXPECT_THROW(Drive(options, 1, 1), core::Error);
}

}  // namespace
}  // namespace mosaicloc::sim
