#include "mosaicloc/dataset/evaluation.hpp"

#include <cmath>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/plots.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::dataset {
namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;

core::Timestamp At(double t_s) { return core::Timestamp::FromSeconds(t_s); }

// `laps` laps of a circle of radius 1000 mm around the origin, counter-clockwise, heading along
// the tangent, 40 s per lap sampled every 100 ms (400 samples a lap, 15.7 mm apart); the last
// sample is one step before the start of lap laps + 1, so every position occurs exactly `laps`
// times.
constexpr double kRadiusMm = 1000.0;
constexpr double kLapS = 40.0;
constexpr int kSamplesPerLap = 400;

core::Pose2 CirclePose(double t_s) {
  const double angle = 2.0 * std::numbers::pi * t_s / kLapS;
  return core::Pose2(kRadiusMm * std::cos(angle), kRadiusMm * std::sin(angle), angle + std::numbers::pi / 2);
}

Trajectory Circle(int laps) {
  Trajectory trajectory;
  for (int i = 0; i < laps * kSamplesPerLap; ++i) {
    const double t_s = i * kLapS / kSamplesPerLap;
    trajectory.push_back({At(t_s), CirclePose(t_s)});
  }
  return trajectory;
}

// The same trajectory with each pose changed by `change(time_s, ground truth pose)`.
Trajectory Perturbed(const Trajectory& groundtruth,
                     const std::function<core::Pose2(double, const core::Pose2&)>& change) {
  Trajectory estimate;
  for (const StampedPose& pose : groundtruth) {
    estimate.push_back({pose.time, change(pose.time.seconds(), pose.world_from_vehicle)});
  }
  return estimate;
}

core::Pose2 Shifted(const core::Pose2& pose, double dx_mm, double dy_mm, double dyaw_rad = 0.0) {
  return core::Pose2(pose.x_mm() + dx_mm, pose.y_mm() + dy_mm, pose.yaw_rad() + dyaw_rad);
}

TEST(EvaluationOptions, CheckRejectsNonPositiveValues) {
  std::string why;
  EXPECT_TRUE(EvaluationOptions{}.Check(&why)) << why;
  EvaluationOptions options;
  options.repeatability_radius_mm = -1.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("repeatability_radius_mm"), std::string::npos);
  options = {};
  options.max_gap = core::Duration(0);
  EXPECT_FALSE(options.Check(nullptr));
  options = {};
  options.repeatability_spacing_mm = std::nan("");
  EXPECT_FALSE(options.Check(&why));
  EXPECT_THROW(Evaluate(Circle(1), Circle(1), options), core::Error);
}

// Estimates half-way between the ground truth's samples, each 3 mm off (1.8, -2.4) in its
// own frame.
Trajectory OffsetByThreeMillimetres(const Trajectory& groundtruth) {
  Trajectory estimate;
  for (std::size_t i = 0; i + 1 < groundtruth.size(); ++i) {
    const double t_s = (static_cast<double>(i) + 0.5) * kLapS / kSamplesPerLap;
    estimate.push_back({At(t_s), Shifted(CirclePose(t_s), 1.8, -2.4)});
  }
  return estimate;
}

TEST(Evaluate, ConstantOffsetOfThreeMillimetres) {
  const Trajectory groundtruth = Circle(1);
  // Estimates half-way between ground-truth samples: the interpolated reference is exact on a
  // circle.
  const Trajectory estimate = OffsetByThreeMillimetres(groundtruth);
  const Evaluation evaluation = Evaluate(estimate, groundtruth, {});
  const Metrics& metrics = evaluation.metrics;
  ASSERT_EQ(evaluation.samples.size(), estimate.size());
  EXPECT_EQ(metrics.frames, static_cast<std::int64_t>(estimate.size()));
  EXPECT_EQ(metrics.associated, static_cast<std::int64_t>(estimate.size()));
  for (const ErrorSample& sample : evaluation.samples) {
    EXPECT_NEAR(sample.position_error_mm, 3.0, 1e-9);
    EXPECT_NEAR(sample.heading_error_rad, 0.0, 1e-12);
  }
  EXPECT_NEAR(*metrics.position_rms_mm, 3.0, 1e-9);
  EXPECT_NEAR(*metrics.position_p50_mm, 3.0, 1e-9);
  EXPECT_NEAR(*metrics.position_p99_mm, 3.0, 1e-9);
  EXPECT_NEAR(*metrics.position_max_mm, 3.0, 1e-9);
  EXPECT_NEAR(*metrics.final_position_error_mm, 3.0, 1e-9);
  EXPECT_NEAR(*metrics.heading_max_deg, 0.0, 1e-9);
  // Left for the caller.
  EXPECT_FALSE(metrics.fixes || metrics.fix_rate || metrics.lock_losses || metrics.processing_fps ||
               metrics.latency_p50_ms || metrics.latency_p99_ms || metrics.overlap_speed_limit_mps);
  // Ground-truth chord speed: 2 R sin(pi / N) per 0.1 s.
  const double chord_mm = 2.0 * kRadiusMm * std::sin(std::numbers::pi / kSamplesPerLap);
  EXPECT_NEAR(*metrics.max_speed_mps, chord_mm / 0.1 / 1000.0, 1e-9);
  // From the first estimate (t = 0.05 s) to the last (39.85 s): two half-step chords around the
  // 397 chords between the ground-truth samples at 0.1 s ... 39.8 s.
  const double half_chord_mm = 2.0 * kRadiusMm * std::sin(std::numbers::pi / (2 * kSamplesPerLap));
  EXPECT_NEAR(*metrics.path_length_m, (397 * chord_mm + 2 * half_chord_mm) / 1000.0, 1e-9);
}

// A report's metrics: what the caller measured, and the evaluation's figures against the truth.
TEST(Evaluate, WithEvaluationKeepsTheCallersFiguresAndTakesTheTruths) {
  const Trajectory groundtruth = Circle(1);
  const Trajectory estimate = OffsetByThreeMillimetres(groundtruth);
  const Metrics evaluated = Evaluate(estimate, groundtruth, {}).metrics;
  Metrics caller;
  caller.fixes = 7;
  caller.wrong_fixes = 0;
  caller.steering_offset_error_deg = 0.25;
  caller.frames_by_mode["track"] = 12;
  caller.position_rms_mm = 99.0;  // not the caller's to say: the evaluation's wins
  const Metrics merged = WithEvaluation(caller, evaluated);
  EXPECT_EQ(merged.frames, evaluated.frames) << "none of the caller's";
  EXPECT_EQ(merged.fixes, 7);
  EXPECT_EQ(merged.wrong_fixes, 0);
  EXPECT_EQ(merged.steering_offset_error_deg, 0.25);
  EXPECT_EQ(merged.frames_by_mode.at("track"), 12);
  EXPECT_NEAR(*merged.position_rms_mm, 3.0, 1e-9);
  EXPECT_EQ(merged.path_length_m, evaluated.path_length_m);
  EXPECT_EQ(merged.max_speed_mps, evaluated.max_speed_mps);
  caller.frames = 1000;
  EXPECT_EQ(WithEvaluation(caller, evaluated).frames, 1000) << "the caller's frame count stands";
}

TEST(Evaluate, HeadingOffset) {
  const Trajectory groundtruth = Circle(1);
  const Evaluation evaluation = Evaluate(
      Perturbed(groundtruth,
                [](double, const core::Pose2& pose) { return Shifted(pose, 0, 0, -0.02); }),
      groundtruth, {});
  EXPECT_NEAR(*evaluation.metrics.heading_rms_deg, 0.02 * 180.0 / std::numbers::pi, 1e-9);
  EXPECT_NEAR(*evaluation.metrics.heading_max_deg, 0.02 * 180.0 / std::numbers::pi, 1e-9);
  EXPECT_NEAR(evaluation.samples.front().heading_error_rad, -0.02, 1e-12);
  EXPECT_NEAR(*evaluation.metrics.position_max_mm, 0.0, 1e-9);
}

TEST(Evaluate, HeadingErrorIsWrappedAcrossPi) {
  const Trajectory groundtruth = {{At(0.0), core::Pose2(0, 0, std::numbers::pi - 0.01)},
                                  {At(0.1), core::Pose2(0, 0, std::numbers::pi - 0.01)}};
  const Trajectory estimate = {{At(0.0), core::Pose2(0, 0, -std::numbers::pi + 0.01)}};
  const Evaluation evaluation = Evaluate(estimate, groundtruth, {});
  EXPECT_NEAR(evaluation.samples[0].heading_error_rad, 0.02, 1e-12);
}

TEST(Evaluate, PercentilesInterpolateBetweenClosestRanks) {
  // A straight run along x; estimate i (of 100, in shuffled order of size) is i mm off in y.
  Trajectory groundtruth;
  Trajectory estimate;
  for (int i = 0; i < 100; ++i) {
    const int error_mm = 1 + (i * 37) % 100;  // a permutation of 1..100
    groundtruth.push_back({At(i * 0.01), core::Pose2(i * 5.0, 0.0, 0.0)});
    estimate.push_back({At(i * 0.01), core::Pose2(i * 5.0, error_mm, 0.0)});
  }
  const Metrics metrics = Evaluate(estimate, groundtruth, {}).metrics;
  // h = 99 p: p50 -> between 50 and 51, p99 -> 99 + 0.01.
  EXPECT_NEAR(*metrics.position_p50_mm, 50.5, 1e-9);
  EXPECT_NEAR(*metrics.position_p99_mm, 99.01, 1e-9);
  EXPECT_NEAR(*metrics.position_max_mm, 100.0, 1e-12);
  EXPECT_NEAR(*metrics.position_rms_mm, std::sqrt(338350.0 / 100.0), 1e-9);  // sum i^2 = 338350
  EXPECT_NEAR(*metrics.path_length_m, 0.495, 1e-12);
  // Final error 1 + 99*37 % 100 = 64 mm over 495 mm.
  EXPECT_NEAR(*metrics.drift_percent, 100.0 * 64.0 / 495.0, 1e-9);
  EXPECT_NEAR(*metrics.max_speed_mps, 0.5, 1e-9);
}

TEST(Evaluate, EstimatesOutsideTheGroundTruthOrInGapsAreLeftOut) {
  const Trajectory groundtruth = {{At(1.0), core::Pose2(0, 0, 0)},
                                  {At(1.1), core::Pose2(10, 0, 0)},
                                  {At(2.0), core::Pose2(100, 0, 0)}};
  const Trajectory estimate = {{At(0.5), core::Pose2()},
                               {At(1.05), core::Pose2(5, 1, 0)},
                               {At(1.5), core::Pose2()},
                               {At(2.0), core::Pose2(100, 2, 0)},
                               {At(2.5), core::Pose2()}};
  const Evaluation evaluation = Evaluate(estimate, groundtruth, {});
  EXPECT_EQ(evaluation.metrics.frames, 5);
  ASSERT_EQ(evaluation.samples.size(), 2u);
  EXPECT_EQ(evaluation.samples[0].time, At(1.05));
  EXPECT_NEAR(evaluation.samples[0].position_error_mm, 1.0, 1e-9);
  EXPECT_NEAR(evaluation.samples[1].position_error_mm, 2.0, 1e-9);
  // The 0.9 s ground-truth gap is not a speed.
  EXPECT_NEAR(*evaluation.metrics.max_speed_mps, 0.1, 1e-9);
}

TEST(Evaluate, NonOverlappingTimeRangesThrowWithBothRanges) {
  const Trajectory groundtruth = Circle(1);
  Trajectory late;
  for (const StampedPose& pose : groundtruth)
    late.push_back({pose.time + std::chrono::seconds(100), pose.world_from_vehicle});
  try {
    Evaluate(late, groundtruth, {});
    FAIL() << "no error";
  } catch (const core::Error& error) {
    const std::string message = error.what();
    EXPECT_EQ(error.kind(), core::ErrorKind::kInvalidInput);
    EXPECT_NE(message.find("estimate spans [100.000000000 s, 139.900000000 s]"), std::string::npos)
        << message;
    EXPECT_NE(message.find("ground truth spans [0.000000000 s, 39.900000000 s]"), std::string::npos)
        << message;
    EXPECT_NE(message.find("do not overlap"), std::string::npos) << message;
  }
  // Overlapping ranges, but every estimate inside a gap longer than max_gap.
  const Trajectory sparse = {{At(0.0), core::Pose2()}, {At(10.0), core::Pose2()}};
  const Trajectory between = {{At(5.0), core::Pose2()}};
  try {
    Evaluate(between, sparse, {});
    FAIL() << "no error";
  } catch (const core::Error& error) {
    EXPECT_NE(std::string(error.what()).find("gap longer than max_gap"), std::string::npos)
        << error.what();
  }
  EXPECT_THROW(Evaluate({}, groundtruth, {}), core::Error);
  EXPECT_THROW(Evaluate(groundtruth, {}, {}), core::Error);
}

TEST(Repeatability, FixedErrorPerPlaceIsPerfectlyRepeatable) {
  const Trajectory groundtruth = Circle(3);
  // The error depends on the place only, as with a map that is slightly wrong.
  const Trajectory estimate = Perturbed(groundtruth, [](double, const core::Pose2& pose) {
    return Shifted(pose, 2.0 * std::sin(pose.x_mm() / 300.0), 1.5 * std::cos(pose.y_mm() / 200.0),
                   0.001);
  });
  const Metrics metrics = Evaluate(estimate, groundtruth, {}).metrics;
  ASSERT_TRUE(metrics.repeatability_mm.has_value());
  EXPECT_LT(*metrics.repeatability_mm, 1e-9);
  EXPECT_GT(*metrics.position_max_mm, 1.0);
  // A place every 100 mm of the 6283 mm lap, give or take the 15.7 mm sampling.
  EXPECT_GE(*metrics.repeatability_places, 50);
  EXPECT_LE(*metrics.repeatability_places, 70);
}

TEST(Repeatability, DriftingEstimateMatchesTheHandComputedSpread) {
  const Trajectory groundtruth = Circle(3);
  // Error c t along x: a place's visits, one lap T apart, have errors c (t0 + k T), k = 0, 1, 2,
  // deviating from their mean by c T (-1, 0, 1): RMS = c T sqrt(2/3) at every place.
  constexpr double kDriftMmPerS = 0.1;
  const Trajectory estimate = Perturbed(groundtruth, [](double t_s, const core::Pose2& pose) {
    return Shifted(pose, kDriftMmPerS * t_s, 0.0);
  });
  const Metrics metrics = Evaluate(estimate, groundtruth, {}).metrics;
  ASSERT_TRUE(metrics.repeatability_mm.has_value());
  EXPECT_NEAR(*metrics.repeatability_mm, kDriftMmPerS * kLapS * std::sqrt(2.0 / 3.0), 1e-9);
}

TEST(Repeatability, TwoPassesGiveHalfTheDifference) {
  const Trajectory groundtruth = Circle(2);
  // Second lap 0.6 mm off in y: every place has errors 0 and 0.6, each 0.3 from the mean.
  const Trajectory estimate = Perturbed(groundtruth, [](double t_s, const core::Pose2& pose) {
    return Shifted(pose, 0.0, t_s >= kLapS ? 0.6 : 0.0);
  });
  EXPECT_NEAR(*Evaluate(estimate, groundtruth, {}).metrics.repeatability_mm, 0.3, 1e-9);
}

TEST(Repeatability, StraightRunHasNone) {
  Trajectory groundtruth;
  for (int i = 0; i < 1000; ++i)
    groundtruth.push_back({At(i * 0.01), core::Pose2(i * 3.0, 0.0, 0.0)});
  const Metrics metrics = Evaluate(groundtruth, groundtruth, {}).metrics;
  EXPECT_FALSE(metrics.repeatability_mm.has_value());
  EXPECT_EQ(metrics.repeatability_places, 0);
}

TEST(Repeatability, StoppingAtAPlaceIsOneVisit) {
  // Out 500 mm along x, a long stop at the end, back: each place is visited once each way,
  // the turning point once however long the stop.
  Trajectory groundtruth;
  double t_s = 0.0;
  for (int i = 0; i <= 100; ++i)
    groundtruth.push_back({At(t_s += 0.01), core::Pose2(i * 5.0, 0, 0)});
  for (int i = 0; i < 50; ++i) groundtruth.push_back({At(t_s += 0.01), core::Pose2(500.0, 0, 0)});
  for (int i = 99; i >= 0; --i)
    groundtruth.push_back({At(t_s += 0.01), core::Pose2(i * 5.0, 0, std::numbers::pi)});
  // Error +1 mm in y going out, -1 mm coming back, 5 mm while stopped.
  Trajectory estimate;
  for (std::size_t i = 0; i < groundtruth.size(); ++i) {
    const double dy = i <= 100 ? 1.0 : i < 151 ? 5.0 : -1.0;
    estimate.push_back({groundtruth[i].time, Shifted(groundtruth[i].world_from_vehicle, 0.0, dy)});
  }
  const Metrics metrics = Evaluate(estimate, groundtruth, {}).metrics;
  // Places at x = 0, 100, ..., 400 mm: errors +1 and -1 -> deviation 1. The place at 500 mm: the
  // outward run ends in the stop (its nearest sample, the first at 500 mm, has +1), the way back
  // starts 5 mm away inside the radius, so the stop and the return are one visit: one visit only.
  ASSERT_TRUE(metrics.repeatability_mm.has_value());
  EXPECT_NEAR(*metrics.repeatability_mm, 1.0, 1e-9);
  EXPECT_EQ(metrics.repeatability_places, 5);
}

TEST(Evaluate, LargeTrajectoryIsQuick) {
  // 10 laps at 20 000 samples a lap: must not be quadratic (no timing asserted).
  Trajectory groundtruth;
  for (int i = 0; i < 200'000; ++i) {
    const double t_s = i * 0.002;
    groundtruth.push_back({At(t_s), CirclePose(t_s)});
  }
  const Metrics metrics = Evaluate(groundtruth, groundtruth, {}).metrics;
  ASSERT_TRUE(metrics.repeatability_mm.has_value());
  EXPECT_NEAR(*metrics.repeatability_mm, 0.0, 1e-9);
}

const std::vector<std::string> kDesignKeys = {
    "frames",          "fixes",           "fix_rate",         "lock_losses",
    "wrong_fixes",     "max_wrong_fix_mm",
    "position_rms_mm", "position_p50_mm", "position_p99_mm",  "position_max_mm",
    "heading_rms_deg", "heading_max_deg", "repeatability_mm", "processing_fps",
    "latency_p50_ms",  "latency_p99_ms",  "max_speed_mps",    "overlap_speed_limit_mps"};

TEST(MetricsJson, HasEveryDesignKeyWithNullsWhereUnknown) {
  test::ScratchDir dir;
  Trajectory groundtruth;
  for (int i = 0; i < 100; ++i)
    groundtruth.push_back({At(i * 0.01), core::Pose2(i * 3.0, 0.0, 0.0)});
  Metrics metrics = Evaluate(groundtruth, groundtruth, {}).metrics;
  metrics.fixes = 97;
  metrics.fix_rate = 0.97;
  const auto file = dir / "metrics.json";
  WriteMetricsJson(file, metrics);
  const nlohmann::json json = nlohmann::json::parse(test::ReadFile(file));
  ASSERT_TRUE(json.is_object());
  for (const std::string& key : kDesignKeys) EXPECT_TRUE(json.contains(key)) << key;
  for (const char* key : {"associated", "final_position_error_mm", "path_length_m", "drift_percent",
                          "repeatability_places", "fix_error_rms_mm", "off_map_frames", "off_map_max_error_mm", "reentries",
                          "reentry_frames_to_fix_max", "reentry_first_fix_error_max_mm", "relocalizations",
                          "reanchorings"}) {
    EXPECT_TRUE(json.contains(key)) << key;
  }
  EXPECT_EQ(json["frames"].get<std::int64_t>(), 100);
  EXPECT_EQ(json["fixes"].get<std::int64_t>(), 97);
  EXPECT_DOUBLE_EQ(json["fix_rate"].get<double>(), 0.97);
  EXPECT_DOUBLE_EQ(json["position_max_mm"].get<double>(), 0.0);
  EXPECT_NEAR(json["max_speed_mps"].get<double>(), 0.3, 1e-9);
  for (const char* key : {"lock_losses", "wrong_fixes", "max_wrong_fix_mm", "repeatability_mm", "processing_fps",
                          "latency_p50_ms", "latency_p99_ms", "overlap_speed_limit_mps"}) {
    EXPECT_TRUE(json[key].is_null()) << key;
  }
  // An empty Metrics is all nulls.
  WriteMetricsJson(file, Metrics{});
  const nlohmann::json empty = nlohmann::json::parse(test::ReadFile(file));
  for (const std::string& key : kDesignKeys) EXPECT_TRUE(empty.at(key).is_null()) << key;
}

void ExpectPlots(const std::filesystem::path& directory) {
  for (const char* name : {"trajectory.png", "position_error.png", "heading_error.png"}) {
    const cv::Mat image = cv::imread((directory / name).string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty()) << name;
    EXPECT_EQ(image.cols, 1000) << name;
    EXPECT_EQ(image.rows, 800) << name;
    // Mostly white background, with something drawn on it.
    const cv::Scalar mean = cv::mean(image);
    EXPECT_GT(mean[0], 200.0) << name;
    EXPECT_LT(mean[0], 254.0) << name;
  }
}

TEST(Plots, WritesThreeReadablePngs) {
  test::ScratchDir dir;
  const Trajectory groundtruth = Circle(2);
  const Trajectory estimate = Perturbed(groundtruth, [](double t_s, const core::Pose2& pose) {
    return Shifted(pose, 0.05 * std::sin(t_s), 0.02 * t_s / kLapS, 1e-4 * std::cos(t_s / 3.0));
  });
  WritePlots(dir / "report", Evaluate(estimate, groundtruth, {}), "circle, 2 laps");
  ExpectPlots(dir / "report");
  int entries = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir / "report"))
    ++entries;
  EXPECT_EQ(entries, 3);  // no temporary left behind
}

TEST(Plots, DegenerateInputsDoNotBreak) {
  test::ScratchDir dir;
  // One sample, zero extent, zero errors.
  const Trajectory single = {{At(3.0), core::Pose2(5.0, 5.0, 0.0)}};
  WritePlots(dir / "single", Evaluate(single, single, {}), "single");
  ExpectPlots(dir / "single");
  // A vehicle standing still with all errors zero.
  Trajectory still;
  for (int i = 0; i < 50; ++i) still.push_back({At(i * 0.1), core::Pose2(1.0, 2.0, 0.5)});
  WritePlots(dir / "still", Evaluate(still, still, {}), "still");
  ExpectPlots(dir / "still");
  // Nothing at all.
  WritePlots(dir / "empty", Evaluation{}, "empty");
  ExpectPlots(dir / "empty");
}

}  // namespace
}  // namespace mosaicloc::dataset
