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

namespace mosaicloc::dataset {

namespace {

constexpr int kWidthPx = 1000;
constexpr int kHeightPx = 800;
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
// Fractional bits of the fixed-point coordinates given to cv::line and cv::circle.
constexpr int kShift = 4;
constexpr double kShiftScale = 1 << kShift;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kBlack(0, 0, 0);
const cv::Scalar kDarkGrey(70, 70, 70);
const cv::Scalar kGridGrey(228, 228, 228);
const cv::Scalar kTrackGrey(165, 165, 165);
const cv::Scalar kSeriesBlue(180, 90, 20);  // BGR
const cv::Scalar kRmsGreen(60, 150, 40);
const cv::Scalar kP99Orange(20, 120, 230);

// ---------------------------------------------------------------------------------------------
// Text

enum class Align { kStart, kCenter, kEnd };

std::string Ascii(const std::string& text) {
  std::string clean = text;
  for (char& c : clean) {
    if (c < 32 || c > 126) c = '?';
  }
  return clean;
}

// Draws `text` with its box aligned to `anchor` (horizontally: left / centre / right edge;
// vertically: top / middle / baseline).
// With `background`, the text sits on a white box that hides what is under it.
void PutText(cv::Mat& image, const std::string& text, cv::Point anchor, double scale,
             const cv::Scalar& color, Align horizontal, Align vertical, int thickness = 1,
             bool background = false) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(Ascii(text), kFont, scale, thickness, &baseline);
  int x = anchor.x;
  if (horizontal == Align::kCenter) x -= size.width / 2;
  if (horizontal == Align::kEnd) x -= size.width;
  int y = anchor.y;
  if (vertical == Align::kStart) y += size.height;
  if (vertical == Align::kCenter) y += size.height / 2;
  if (background) {
    cv::rectangle(image,
                  cv::Rect(x - 3, y - size.height - 3, size.width + 6, size.height + baseline + 5),
                  kWhite, cv::FILLED);
  }
  cv::putText(image, Ascii(text), {x, y}, kFont, scale, color, thickness, cv::LINE_AA);
}

int TextWidth(const std::string& text, double scale) {
  int baseline = 0;
  return cv::getTextSize(Ascii(text), kFont, scale, 1, &baseline).width;
}

// Text read bottom to top, centred on `center` (dark text on a light background).
void PutVerticalText(cv::Mat& image, const std::string& text, cv::Point center, double scale) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(Ascii(text), kFont, scale, 1, &baseline);
  cv::Mat horizontal(size.height + baseline + 4, size.width + 4, image.type(), kWhite);
  cv::putText(horizontal, Ascii(text), {2, size.height + 2}, kFont, scale, kBlack, 1, cv::LINE_AA);
  cv::Mat vertical;
  cv::rotate(horizontal, vertical, cv::ROTATE_90_COUNTERCLOCKWISE);
  cv::Rect box(center.x - vertical.cols / 2, center.y - vertical.rows / 2, vertical.cols,
               vertical.rows);
  box &= cv::Rect(0, 0, image.cols, image.rows);
  if (box.empty()) return;
  cv::Mat target = image(box);
  cv::min(target, vertical(cv::Rect(0, 0, box.width, box.height)), target);
}

// Three significant digits, without exponent notation.
std::string FormatValue(double value) {
  if (!std::isfinite(value)) return "n/a";
  if (value == 0.0) return "0";
  const int decimals =
      std::clamp(2 - static_cast<int>(std::floor(std::log10(std::abs(value)))), 0, 6);
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

// ---------------------------------------------------------------------------------------------
// Axes

struct Range {
  double lo = 0.0;
  double hi = 1.0;
  double span() const { return hi - lo; }
};

// A range at least `min_span` wide, centred on the original when it was narrower.
Range Widened(Range range, double min_span) {
  if (!std::isfinite(range.lo) || !std::isfinite(range.hi)) return {0.0, min_span};
  if (range.span() >= min_span) return range;
  const double center = 0.5 * (range.lo + range.hi);
  return {center - 0.5 * min_span, center + 0.5 * min_span};
}

// The "nice" step 1, 2 or 5 x 10^k nearest to `rough` (Heckbert, "Nice numbers for graph
// labels", Graphics Gems, 1990); 1 for a rough step that is not finite and positive.
double NiceStep(double rough) {
  if (!std::isfinite(rough) || rough <= 0.0) return 1.0;
  const double magnitude = std::pow(10.0, std::floor(std::log10(rough)));
  const double fraction = rough / magnitude;
  const double nice = fraction < 1.5 ? 1.0 : fraction < 3.0 ? 2.0 : fraction < 7.0 ? 5.0 : 10.0;
  return nice * magnitude;
}

double TickStep(Range range, double target_ticks) {
  return NiceStep(range.span() / std::max(1.0, target_ticks));
}

// The range rounded outwards to multiples of its tick step.
Range NiceBounds(Range range, double target_ticks) {
  const double step = TickStep(range, target_ticks);
  return {std::floor(range.lo / step + 1e-9) * step, std::ceil(range.hi / step - 1e-9) * step};
}

struct Ticks {
  std::vector<double> values;
  int decimals = 0;
};

Ticks MakeTicks(Range range, double target_ticks) {
  const double step = TickStep(range, target_ticks);
  Ticks ticks;
  if (!std::isfinite(range.lo) || !std::isfinite(range.hi)) return ticks;
  ticks.decimals = std::max(0, -static_cast<int>(std::floor(std::log10(step) + 1e-9)));
  const auto first = static_cast<long long>(std::ceil(range.lo / step - 1e-9));
  constexpr int kMaxTicks = 100;
  for (long long k = first;
       static_cast<double>(k) * step <= range.hi + step * 1e-9 && ticks.values.size() < kMaxTicks;
       ++k) {
    ticks.values.push_back(static_cast<double>(k) * step);
  }
  return ticks;
}

std::string TickLabel(double value, int decimals) {
  if (std::abs(value) < 0.5 * std::pow(10.0, -decimals)) value = 0.0;  // no "-0.0"
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

// A rectangle of the canvas mapping data coordinates linearly to pixels (y up). Data are drawn
// into plot(), a view of that rectangle, so OpenCV clips them at the frame.
class Axes {
 public:
  Axes(cv::Mat& canvas, cv::Rect area, Range x, Range y)
      : canvas_(canvas), area_(area), x_(x), y_(y), plot_(canvas(area)) {}

  cv::Mat& plot() { return plot_; }
  const cv::Rect& area() const { return area_; }

  // Position in plot() pixels, fractional.
  cv::Point2d ToPixel(double x, double y) const {
    return {(x - x_.lo) / x_.span() * area_.width, (y_.hi - y) / y_.span() * area_.height};
  }

  // Grid lines at the tick values, the frame, tick labels and axis labels.
  void DrawFrame(const std::string& x_label, const std::string& y_label, double x_ticks,
                 double y_ticks) {
    const Ticks xt = MakeTicks(x_, x_ticks);
    const Ticks yt = MakeTicks(y_, y_ticks);
    for (double value : xt.values) {
      const int px = area_.x + static_cast<int>(std::lround(ToPixel(value, 0.0).x));
      cv::line(canvas_, {px, area_.y}, {px, area_.br().y - 1}, kGridGrey, 1);
      cv::line(canvas_, {px, area_.br().y}, {px, area_.br().y + 6}, kDarkGrey, 1);
      PutText(canvas_, TickLabel(value, xt.decimals), {px, area_.br().y + 10}, 0.5, kDarkGrey,
              Align::kCenter, Align::kStart);
    }
    int widest_label_px = 0;
    for (double value : yt.values) {
      widest_label_px = std::max(widest_label_px, TextWidth(TickLabel(value, yt.decimals), 0.5));
      const int py = area_.y + static_cast<int>(std::lround(ToPixel(0.0, value).y));
      cv::line(canvas_, {area_.x, py}, {area_.br().x - 1, py}, kGridGrey, 1);
      cv::line(canvas_, {area_.x - 6, py}, {area_.x, py}, kDarkGrey, 1);
      PutText(canvas_, TickLabel(value, yt.decimals), {area_.x - 10, py}, 0.5, kDarkGrey,
              Align::kEnd, Align::kCenter);
    }
    cv::rectangle(canvas_, area_, kDarkGrey, 1);
    PutText(canvas_, x_label, {area_.x + area_.width / 2, area_.br().y + 38}, 0.6, kBlack,
            Align::kCenter, Align::kStart);
    PutVerticalText(canvas_, y_label,
                    {std::max(12, area_.x - 10 - widest_label_px - 20), area_.y + area_.height / 2},
                    0.6);
  }

 private:
  cv::Mat& canvas_;
  cv::Rect area_;
  Range x_;
  Range y_;
  cv::Mat plot_;
};

cv::Point Fixed(const cv::Point2d& p) {
  return {static_cast<int>(std::lround(p.x * kShiftScale)),
          static_cast<int>(std::lround(p.y * kShiftScale))};
}

void Line(cv::Mat& image, const cv::Point2d& a, const cv::Point2d& b, const cv::Scalar& color,
          int thickness) {
  cv::line(image, Fixed(a), Fixed(b), color, thickness, cv::LINE_AA, kShift);
}

void Dot(cv::Mat& image, const cv::Point2d& center, double radius, const cv::Scalar& color) {
  cv::circle(image, Fixed(center), static_cast<int>(std::lround(radius * kShiftScale)), color,
             cv::FILLED, cv::LINE_AA, kShift);
}

void DashedHorizontal(Axes& axes, double y, const cv::Scalar& color) {
  const double py = axes.ToPixel(0.0, y).y;
  for (int x = 0; x < axes.area().width; x += 14) {
    Line(axes.plot(), {static_cast<double>(x), py},
         {std::min(x + 8.0, axes.area().width - 1.0), py}, color, 2);
  }
}

// Curves are broken where consecutive samples are further apart in time than this many typical
// (median) sampling intervals, so a lost estimate shows as a gap instead of a straight line.
constexpr double kBreakIntervals = 10.0;

double BreakGap(const std::vector<double>& times) {
  if (times.size() < 2) return std::numeric_limits<double>::infinity();
  std::vector<double> intervals;
  intervals.reserve(times.size() - 1);
  for (std::size_t i = 1; i < times.size(); ++i) intervals.push_back(times[i] - times[i - 1]);
  std::nth_element(intervals.begin(),
                   intervals.begin() + static_cast<std::ptrdiff_t>(intervals.size() / 2),
                   intervals.end());
  return kBreakIntervals * intervals[intervals.size() / 2];
}

// y(x) as a line. With many more samples than pixel columns each column is drawn as the
// min-max envelope of its samples, so a million samples cost a few thousand line segments.
void DrawSeries(Axes& axes, const std::vector<double>& x, const std::vector<double>& y,
                const cv::Scalar& color) {
  const std::size_t n = x.size();
  if (n == 0) return;
  const double break_gap = BreakGap(x);
  cv::Mat& plot = axes.plot();
  const auto width = static_cast<std::size_t>(plot.cols);
  if (n <= 2 * width) {
    for (std::size_t i = 0; i < n; ++i) {
      const cv::Point2d p = axes.ToPixel(x[i], y[i]);
      const bool joined_before = i > 0 && x[i] - x[i - 1] <= break_gap;
      const bool joined_after = i + 1 < n && x[i + 1] - x[i] <= break_gap;
      if (joined_before) Line(plot, axes.ToPixel(x[i - 1], y[i - 1]), p, color, 2);
      if (n <= 100 || (!joined_before && !joined_after)) Dot(plot, p, 3.0, color);
    }
    return;
  }
  struct Column {
    double first_y, last_y, min_y, max_y, first_x, last_x;
    bool used = false;
  };
  std::vector<Column> columns(width);
  for (std::size_t i = 0; i < n; ++i) {
    const cv::Point2d p = axes.ToPixel(x[i], y[i]);
    const auto c = static_cast<std::size_t>(std::clamp(p.x, 0.0, static_cast<double>(width - 1)));
    Column& column = columns[c];
    if (!column.used) {
      column = {p.y, p.y, p.y, p.y, x[i], x[i], true};
    } else {
      column.last_y = p.y;
      column.last_x = x[i];
      column.min_y = std::min(column.min_y, p.y);
      column.max_y = std::max(column.max_y, p.y);
    }
  }
  const Column* previous = nullptr;
  for (std::size_t c = 0; c < width; ++c) {
    const Column& column = columns[c];
    if (!column.used) continue;
    const double px = static_cast<double>(c) + 0.5;
    Line(plot, {px, column.min_y}, {px, column.max_y}, color, 1);
    if (previous != nullptr && column.first_x - previous->last_x <= break_gap) {
      const double previous_px = static_cast<double>(previous - columns.data()) + 0.5;
      Line(plot, {previous_px, previous->last_y}, {px, column.first_y}, color, 1);
    }
    previous = &column;
  }
}

void DrawTitle(cv::Mat& canvas, const std::string& title, const std::string& subtitle) {
  PutText(canvas, title, {kWidthPx / 2, 12}, 0.75, kBlack, Align::kCenter, Align::kStart, 2);
  PutText(canvas, subtitle, {kWidthPx / 2, 44}, 0.55, kDarkGrey, Align::kCenter, Align::kStart);
}

void DrawNoData(Axes& axes) {
  PutText(axes.plot(), "no estimate was compared with the ground truth",
          {axes.area().width / 2, axes.area().height / 2}, 0.7, kDarkGrey, Align::kCenter,
          Align::kCenter);
}

void SavePng(const std::filesystem::path& file, const cv::Mat& image) {
  std::vector<uchar> png;
  if (!cv::imencode(".png", image, png))
    core::ThrowRuntime(file.string() + ": PNG encoding failed");
  core::WriteFileAtomically(
      file, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

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
