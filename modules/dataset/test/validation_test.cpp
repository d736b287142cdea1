#include "mosaicloc/dataset/validation.hpp"

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/html_report.hpp"
#include "mosaicloc/dataset/report_plots.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::dataset {
namespace {

using core::Pose2;
using core::Timestamp;

FrameReport Row(double t_s, double x_mm, int status, bool fixed, std::optional<double> nis, const std::string& reason) {
  FrameReport r;
  r.time = Timestamp::FromSeconds(t_s);
  r.world_from_vehicle = Pose2(x_mm, 0.0, 0.0);
  r.status = status;
  r.fixed = fixed;
  r.quality = fixed ? 0.9 : 0.0;
  r.nis = nis;
  r.reason = reason;
  return r;
}

// Counts per state and reason, the speeds of the estimate, and the NIS against its 95 % bound.
TEST(TruthFreeFigures, CountsStatesReasonsSpeedsAndNis) {
  std::vector<FrameReport> reports = {Row(0.0, 0.0, 1, true, 1.0, ""), Row(0.1, 100.0, 1, true, 2.0, ""),
                                      Row(0.2, 200.0, 2, false, 20.0, "rejected"),
                                      Row(0.3, 300.0, 4, false, std::nullopt, "off-map"),
                                      Row(0.4, 400.0, 1, true, 9.0, "")};
  for (FrameReport& r : reports) r.mode = "track";
  reports[3].mode = "visual-odometry";
  Trajectory estimate;
  for (const FrameReport& r : reports) estimate.push_back({r.time, r.world_from_vehicle});
  const std::vector<Eigen::Vector3d> innovations = {{1.0, -1.0, 0.0}, {-1.0, 1.0, 0.0}};
  Metrics metrics;
  AddTruthFreeFigures(reports, estimate, innovations, &metrics);
  EXPECT_NEAR(*metrics.estimate_path_length_m, 0.4, 1e-9);
  EXPECT_NEAR(*metrics.estimate_speed_mean_mps, 1.0, 1e-9);
  EXPECT_NEAR(*metrics.estimate_speed_p99_mps, 1.0, 1e-9);
  EXPECT_EQ(metrics.frames_by_state.at("tracking"), 3);
  EXPECT_EQ(metrics.frames_by_state.at("degraded"), 1);
  EXPECT_EQ(metrics.frames_by_state.at("off-map"), 1);
  EXPECT_EQ(metrics.fixes_by_state.at("tracking"), 3);
  EXPECT_EQ(metrics.fixes_by_state.count("degraded"), 0U);
  EXPECT_EQ(metrics.no_fix_reasons.at("rejected"), 1);
  EXPECT_EQ(metrics.frames_by_mode.at("track"), 4);
  EXPECT_EQ(metrics.frames_by_mode.at("visual-odometry"), 1);
  EXPECT_EQ(metrics.fixes_by_mode.at("track"), 3);
  EXPECT_EQ(metrics.fixes_by_mode.count("visual-odometry"), 0U) << "a frame off the map has no fix";
  EXPECT_EQ(*metrics.mode_switches, 2);
  EXPECT_EQ(metrics.no_fix_reasons.at("off-map"), 1);
  // Four judged fixes (the rejected one included); 1 and 2 inside 7.81, 20 and 9 outside.
  EXPECT_EQ(*metrics.nis_fixes, 4);
  EXPECT_NEAR(*metrics.nis_inside_95_share, 0.5, 1e-12);
  EXPECT_NEAR(*metrics.nis_mean, 8.0, 1e-12);
  EXPECT_NEAR(metrics.innovation_sigma_ratio->x(), std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(metrics.innovation_sigma_ratio->z(), 0.0, 1e-12);
}

// The places the truth-based repeatability finds along the truth, found along any path; the
// spread of error vectors is Evaluate's.
TEST(RevisitedPlaces, ThreePassesOfALineShareTheFirstPassPlaces) {
  std::vector<Eigen::Vector2d> path;
  for (int pass = 0; pass < 3; ++pass) {
    for (int i = 0; i <= 50; ++i) path.emplace_back(pass % 2 == 0 ? 10.0 * i : 500.0 - 10.0 * i, 0.5 * pass);
  }
  const auto places = RevisitedPlaces(path, EvaluationOptions{});
  ASSERT_EQ(places.size(), 6U);  // every 100 mm along 500 mm
  // Where the path turns back, the passes before and after the turn are one visit.
  for (std::size_t k = 0; k < places.size(); ++k) {
    EXPECT_EQ(places[k].size(), k == 0 || k == 5 ? 2U : 3U) << "place " << k;
  }
  // Two visits with errors 0 and (0.02, 0) mm: each 0.01 mm from their mean.
  const auto spread = SpreadAtPlaces({{Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(0.02, 0.0)}, {Eigen::Vector2d(1, 1)}});
  ASSERT_TRUE(spread);
  EXPECT_NEAR(spread->rms_mm, 0.01, 1e-12);
  EXPECT_EQ(spread->places, 1);
  EXPECT_EQ(spread->visits, 2);
  EXPECT_FALSE(SpreadAtPlaces({{Eigen::Vector2d(1, 1)}}));
}

// index.html holds the summary, every figure, the plots present, and escapes what it shows.
TEST(HtmlReport, ShowsTheSummaryThePlotsAndTheConfigurationEscaped) {
  test::ScratchDir scratch;
  Metrics metrics;
  metrics.frames = 5;
  metrics.wrong_fixes = 1;
  metrics.no_fix_reasons = {{"off-map", 2}};
  WriteMetricsJson(scratch.path() / "metrics.json", metrics);
  std::vector<FrameReport> reports = {Row(0.0, 0.0, 1, true, 1.0, ""), Row(0.1, 100.0, 3, false, {}, "no-match")};
  WriteMapPlots(scratch.path(), reports, FloorPicture{}, "test");
  HtmlReportInputs inputs;
  inputs.title = "a <test>";
  inputs.configuration = "tracker: {a: \"<b>\"}";
  WriteHtmlReport(scratch.path(), inputs);
  std::ifstream in(scratch.path() / "index.html");
  std::stringstream html;
  html << in.rdbuf();
  const std::string page = html.str();
  EXPECT_NE(page.find("<title>a &lt;test&gt;</title>"), std::string::npos);
  EXPECT_NE(page.find("id=\"summary\""), std::string::npos);
  EXPECT_NE(page.find("class=\"v bad\">1<"), std::string::npos) << "a wrong fix stands out";
  EXPECT_NE(page.find("off-map 2"), std::string::npos);
  EXPECT_NE(page.find("src=\"map_state.png\""), std::string::npos);
  EXPECT_EQ(page.find("src=\"timelines.png\""), std::string::npos) << "only plots that exist";
  EXPECT_NE(page.find("&quot;&lt;b&gt;&quot;"), std::string::npos);
  EXPECT_EQ(page.find("http"), std::string::npos) << "nothing from the network";
  std::filesystem::remove(scratch.path() / "metrics.json");
  EXPECT_THROW(WriteHtmlReport(scratch.path(), inputs), core::Error);
}

// Timelines of a drive with unknowns (no fix, no NIS, no wheel scales) and of no frame at all
// are drawn, not refused; the map plots take a drive without a picture of the floor.
TEST(ReportPlots, DrawWhatIsKnownAndSayWhatIsNot) {
  test::ScratchDir scratch;
  std::vector<TimelineSample> samples(3);
  for (int i = 0; i < 3; ++i) {
    samples[i].seconds = 0.1 * i;
    samples[i].quality = i == 1 ? std::numeric_limits<double>::quiet_NaN() : 0.95;
    samples[i].nis = std::numeric_limits<double>::quiet_NaN();
    samples[i].calibration_first = samples[i].calibration_second = std::numeric_limits<double>::quiet_NaN();
    samples[i].height_mm = std::numeric_limits<double>::quiet_NaN();
  }
  WriteTimelines(scratch.path(), samples, "unknowns");
  EXPECT_GT(std::filesystem::file_size(scratch.path() / "timelines.png"), 1000U);
  WriteTimelines(scratch.path() / "empty", {}, "empty");
  EXPECT_TRUE(std::filesystem::exists(scratch.path() / "empty" / "timelines.png"));
  WriteMapPlots(scratch.path() / "empty", {}, FloorPicture{}, "empty");
  EXPECT_TRUE(std::filesystem::exists(scratch.path() / "empty" / "map_quality.png"));
}

}  // namespace
}  // namespace mosaicloc::dataset
