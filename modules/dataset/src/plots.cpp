#include "mosaicloc/dataset/plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string_view>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "plot_canvas.hpp"

namespace mosaicloc::dataset {

using namespace plot;  // NOLINT: the drawing vocabulary of every plot here

namespace {

// ---------------------------------------------------------------------------------------------
// The three plots

std::vector<double> SecondsSinceStart(const std::vector<ErrorSample>& samples) {
  std::vector<double> seconds;
  seconds.reserve(samples.size());
  for (const ErrorSample& sample : samples) {
    seconds.push_back(core::ToSeconds(sample.time - samples.front().time));
  }
  return seconds;
}

const cv::Rect kTimePlotArea(110, 80, kWidthPx - 110 - 40, kHeightPx - 80 - 80);

cv::Mat ErrorPlot(const Evaluation& evaluation, const std::string& title, bool position) {
  cv::Mat canvas(kHeightPx, kWidthPx, CV_8UC3, kWhite);
  const std::vector<ErrorSample>& samples = evaluation.samples;
  const Metrics& metrics = evaluation.metrics;
  std::vector<double> seconds = SecondsSinceStart(samples);
  std::vector<double> errors;
  errors.reserve(samples.size());
  for (const ErrorSample& sample : samples) {
    errors.push_back(position ? sample.position_error_mm : sample.heading_error_rad * 180.0 / std::numbers::pi);
  }
  constexpr int kXTicks = 10;
  constexpr int kYTicks = 8;
  const Range x{0.0, !seconds.empty() && seconds.back() > 0.0 ? seconds.back() : 1.0};
  Range y{0.0, 1.0};
  if (!errors.empty()) {
    double lo = 0.0;
    double hi = 0.0;
    for (double error : errors) {
      if (std::isfinite(error)) {
        lo = std::min(lo, error);
        hi = std::max(hi, error);
      }
    }
    // At least 1 um or 1e-4 deg high, so that errors all (nearly) zero still give an axis.
    y = position ? Range{0.0, std::max(hi * 1.05, 1e-3)} : Widened({lo * 1.05, hi * 1.05}, 1e-4);
    y = NiceBounds(y, kYTicks);
  }
  Axes axes(canvas, kTimePlotArea, x, y);
  axes.DrawFrame("time since the first estimate [s]",
                 position ? "position error [mm]" : "heading error [deg]", kXTicks, kYTicks);
  std::string subtitle;
  if (position) {
    DrawTitle(canvas, title + " - position error",
              "RMS " + FormatValue(metrics.position_rms_mm.value_or(kNaN)) + " mm   p50 " +
                  FormatValue(metrics.position_p50_mm.value_or(kNaN)) + " mm   p99 " +
                  FormatValue(metrics.position_p99_mm.value_or(kNaN)) + " mm   max " +
                  FormatValue(metrics.position_max_mm.value_or(kNaN)) + " mm   (" +
                  std::to_string(samples.size()) + " estimates)");
  } else {
    DrawTitle(canvas, title + " - heading error",
              "estimate - ground truth:   RMS " +
                  FormatValue(metrics.heading_rms_deg.value_or(kNaN)) + " deg   max |error| " +
                  FormatValue(metrics.heading_max_deg.value_or(kNaN)) + " deg   (" +
                  std::to_string(samples.size()) + " estimates)");
  }
  if (samples.empty()) {
    DrawNoData(axes);
    return canvas;
  }
  if (!position && y.lo < 0.0) {
    Line(axes.plot(), axes.ToPixel(x.lo, 0.0), axes.ToPixel(x.hi, 0.0), kDarkGrey, 1);
  }
  DrawSeries(axes, seconds, errors, kSeriesBlue);
  if (position) {
    const auto label = [&](double value, const std::string& name, const cv::Scalar& color) {
      DashedHorizontal(axes, value, color);
      const double py = axes.ToPixel(0.0, value).y;
      PutText(axes.plot(), name + " " + FormatValue(value) + " mm",
              {axes.area().width - 8, static_cast<int>(py) - 7}, 0.5, color, Align::kEnd,
              Align::kEnd, 1, true);
    };
    if (metrics.position_rms_mm) label(*metrics.position_rms_mm, "RMS", kRmsGreen);
    if (metrics.position_p99_mm) label(*metrics.position_p99_mm, "p99", kP99Orange);
  }
  return canvas;
}

cv::Mat TrajectoryPlot(const Evaluation& evaluation, const std::string& title) {
  cv::Mat canvas(kHeightPx, kWidthPx, CV_8UC3, kWhite);
  const std::vector<ErrorSample>& samples = evaluation.samples;
  const cv::Rect area(110, 80, kWidthPx - 110 - 170, kHeightPx - 80 - 80);

  // Data extent in metres, padded, then widened along one axis so both have the same scale.
  Range x{0.0, 1.0};
  Range y{0.0, 1.0};
  std::vector<double> errors_mm;
  if (!samples.empty()) {
    x = {std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
    y = x;
    for (const ErrorSample& sample : samples) {
      for (const core::Pose2* pose : {&sample.groundtruth, &sample.estimate}) {
        x = {std::min(x.lo, pose->x_mm() / 1000.0), std::max(x.hi, pose->x_mm() / 1000.0)};
        y = {std::min(y.lo, pose->y_mm() / 1000.0), std::max(y.hi, pose->y_mm() / 1000.0)};
      }
      if (std::isfinite(sample.position_error_mm)) errors_mm.push_back(sample.position_error_mm);
    }
    const double extent_m = std::max({x.span(), y.span(), 0.1});
    x = Widened({x.lo - 0.05 * extent_m, x.hi + 0.05 * extent_m}, 0.1);
    y = Widened({y.lo - 0.05 * extent_m, y.hi + 0.05 * extent_m}, 0.1);
  }
  const double px_per_m = std::min(area.width / x.span(), area.height / y.span());
  x = Widened(x, area.width / px_per_m);
  y = Widened(y, area.height / px_per_m);

  Axes axes(canvas, area, x, y);
  // Equal scales and tick counts proportional to the sides give both axes the same step.
  constexpr double kPxPerTick = 90.0;
  axes.DrawFrame("x [m]", "y [m]", area.width / kPxPerTick, area.height / kPxPerTick);
  DrawTitle(canvas, title + " - trajectory (top view)", "");
  // Legend, in the subtitle line.
  const int legend_y = 54;
  cv::line(canvas, {300, legend_y}, {330, legend_y}, kTrackGrey, 2, cv::LINE_AA);
  PutText(canvas, "ground truth", {338, legend_y}, 0.55, kDarkGrey, Align::kStart, Align::kCenter);
  cv::Mat ramp(1, 256, CV_8UC1);
  for (int i = 0; i < 256; ++i) ramp.at<uchar>(0, i) = static_cast<uchar>(i);
  cv::Mat colormap;
  cv::applyColorMap(ramp, colormap, cv::COLORMAP_VIRIDIS);
  const auto colour = [&](double fraction) {
    const int index = std::clamp(static_cast<int>(std::lround(fraction * 255.0)), 0, 255);
    const cv::Vec3b bgr = colormap.at<cv::Vec3b>(0, index);
    return cv::Scalar(bgr[0], bgr[1], bgr[2]);
  };
  for (int k = 0; k < 3; ++k)
    Dot(canvas, {480.0 + 10 * k, static_cast<double>(legend_y)}, 3.0, colour(0.2 + 0.3 * k));
  PutText(canvas, "estimate, coloured by position error", {512, legend_y}, 0.55, kDarkGrey,
          Align::kStart, Align::kCenter);

  // Colour bar. A few outliers would turn everything else the bottom colour: when the largest
  // error exceeds kClipRatio times the 99th percentile, the scale stops at 1.5 p99 and larger
  // errors take the top colour.
  constexpr int kBarTicks = 6;
  constexpr double kClipRatio = 3.0;
  double max_error_mm = 0.0;
  double colour_top_mm = 1.0;
  if (!errors_mm.empty()) {
    const auto p99 = errors_mm.begin() +
                     static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(errors_mm.size() - 1));
    std::nth_element(errors_mm.begin(), p99, errors_mm.end());
    max_error_mm = *std::max_element(p99, errors_mm.end());
    colour_top_mm = max_error_mm > kClipRatio * *p99 ? 1.5 * *p99 : max_error_mm;
    if (colour_top_mm <= 0.0) colour_top_mm = max_error_mm > 0.0 ? max_error_mm : 1.0;
  }
  const Range bar_range = NiceBounds({0.0, colour_top_mm}, kBarTicks);
  const cv::Rect bar(area.br().x + 30, area.y, 22, area.height);
  for (int row = 0; row < bar.height; ++row) {
    const double fraction = 1.0 - (row + 0.5) / bar.height;
    cv::line(canvas, {bar.x, bar.y + row}, {bar.br().x - 1, bar.y + row}, colour(fraction), 1);
  }
  cv::rectangle(canvas, bar, kDarkGrey, 1);
  const Ticks bar_ticks = MakeTicks(bar_range, kBarTicks);
  for (double value : bar_ticks.values) {
    const int py =
        bar.br().y - 1 - static_cast<int>(std::lround(value / bar_range.span() * (bar.height - 1)));
    cv::line(canvas, {bar.br().x, py}, {bar.br().x + 5, py}, kDarkGrey, 1);
    PutText(canvas, TickLabel(value, bar_ticks.decimals), {bar.br().x + 9, py}, 0.5, kDarkGrey,
            Align::kStart, Align::kCenter);
  }
  PutVerticalText(canvas, "position error [mm]", {bar.br().x + 75, bar.y + bar.height / 2}, 0.6);
  if (max_error_mm > bar_range.hi) {
    PutText(canvas, "max " + FormatValue(max_error_mm), {bar.x, bar.y - 8}, 0.45, kDarkGrey,
            Align::kStart, Align::kEnd);
  }

  if (samples.empty()) {
    DrawNoData(axes);
    return canvas;
  }
  const auto pixel = [&](const core::Pose2& pose) {
    return axes.ToPixel(pose.x_mm() / 1000.0, pose.y_mm() / 1000.0);
  };
  // Ground truth: one segment per pixel moved, broken at time gaps.
  const std::vector<double> seconds = SecondsSinceStart(samples);
  const double break_gap = BreakGap(seconds);
  cv::Point2d last_drawn = pixel(samples.front().groundtruth);
  for (std::size_t i = 1; i < samples.size(); ++i) {
    const cv::Point2d p = pixel(samples[i].groundtruth);
    if (seconds[i] - seconds[i - 1] > break_gap) {
      last_drawn = p;
      continue;
    }
    if (std::abs(p.x - last_drawn.x) < 1.0 && std::abs(p.y - last_drawn.y) < 1.0 &&
        i + 1 < samples.size())
      continue;
    Line(axes.plot(), last_drawn, p, kTrackGrey, 1);
    last_drawn = p;
  }
  // Estimates: the largest error per pixel, drawn in increasing error so the worst are on top.
  cv::Mat1f worst(axes.plot().rows, axes.plot().cols, -1.0f);
  for (const ErrorSample& sample : samples) {
    const cv::Point2d p = pixel(sample.estimate);
    const int col = static_cast<int>(std::floor(p.x));
    const int row = static_cast<int>(std::floor(p.y));
    if (col < 0 || row < 0 || col >= worst.cols || row >= worst.rows) continue;
    worst(row, col) = std::max(worst(row, col), static_cast<float>(sample.position_error_mm));
  }
  std::vector<std::pair<float, cv::Point>> dots;
  for (int row = 0; row < worst.rows; ++row) {
    for (int col = 0; col < worst.cols; ++col) {
      if (worst(row, col) >= 0.0f) dots.push_back({worst(row, col), {col, row}});
    }
  }
  std::sort(dots.begin(), dots.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  const double dot_radius = dots.size() > 2000 ? 1.5 : 3.0;
  for (const auto& [error_mm, at] : dots) {
    Dot(axes.plot(), {at.x + 0.5, at.y + 0.5}, dot_radius, colour(error_mm / bar_range.hi));
  }
  const cv::Point2d start = pixel(samples.front().groundtruth);
  cv::circle(axes.plot(), Fixed(start), static_cast<int>(7 * kShiftScale), kBlack, 2, cv::LINE_AA,
             kShift);
  PutText(axes.plot(), "start", {static_cast<int>(start.x) + 10, static_cast<int>(start.y) - 8},
          0.5, kBlack, Align::kStart, Align::kEnd);
  return canvas;
}

}  // namespace

void WritePlots(const std::filesystem::path& directory, const Evaluation& evaluation,
                const std::string& title) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec)
    core::ThrowRuntime(directory.string() + ": cannot create the plot directory: " + ec.message());
  SavePng(directory / "trajectory.png", TrajectoryPlot(evaluation, title));
  SavePng(directory / "position_error.png", ErrorPlot(evaluation, title, true));
  SavePng(directory / "heading_error.png", ErrorPlot(evaluation, title, false));
}

void WriteHeightPlot(const std::filesystem::path& directory, const HeightSeries& series, const std::string& title,
                     double error_rms_mm) {
  cv::Mat canvas(kHeightPx, kWidthPx, CV_8UC3, kWhite);
  constexpr int kXTicks = 10;
  constexpr int kYTicks = 8;
  const Range x{0.0, !series.seconds.empty() && series.seconds.back() > 0.0 ? series.seconds.back() : 1.0};
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (const std::vector<double>* values : {&series.estimate_mm, &series.truth_mm}) {
    for (double v : *values) {
      if (std::isfinite(v)) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
    }
  }
  // At least 0.1 mm high, so that a constant height still gives an axis.
  const Range y = NiceBounds(std::isfinite(lo) ? Widened({lo, hi}, 0.1) : Range{0.0, 1.0}, kYTicks);
  Axes axes(canvas, kTimePlotArea, x, y);
  axes.DrawFrame("time since the first frame [s]", "camera height over the floor [mm]", kXTicks, kYTicks);
  DrawTitle(canvas, title + " - camera height",
            "truth (grey) and estimate (blue): RMS " + FormatValue(error_rms_mm) + " mm at the fixes   (" +
                std::to_string(series.seconds.size()) + " frames)");
  DrawSeries(axes, series.seconds, series.truth_mm, kTrackGrey);
  DrawSeries(axes, series.seconds, series.estimate_mm, kSeriesBlue);
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  SavePng(directory / "height.png", canvas);
}

}  // namespace mosaicloc::dataset
