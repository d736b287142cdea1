#pragma once

// Drawing for the report's PNG plots (plots.cpp, report_plots.cpp): text, axes with nice ticks,
// series that stay cheap for a million samples, atomic PNG files. Internal to the module.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"

namespace mosaicloc::dataset::plot {

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

inline std::string Ascii(const std::string& text) {
  std::string clean = text;
  for (char& c : clean) {
    if (c < 32 || c > 126) c = '?';
  }
  return clean;
}

// Draws `text` with its box aligned to `anchor` (horizontally: left / centre / right edge;
// vertically: top / middle / baseline).
// With `background`, the text sits on a white box that hides what is under it.
inline void PutText(cv::Mat& image, const std::string& text, cv::Point anchor, double scale,
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

inline int TextWidth(const std::string& text, double scale) {
  int baseline = 0;
  return cv::getTextSize(Ascii(text), kFont, scale, 1, &baseline).width;
}

// Text read bottom to top, centred on `center` (dark text on a light background).
inline void PutVerticalText(cv::Mat& image, const std::string& text, cv::Point center, double scale) {
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
inline std::string FormatValue(double value) {
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
inline Range Widened(Range range, double min_span) {
  if (!std::isfinite(range.lo) || !std::isfinite(range.hi)) return {0.0, min_span};
  if (range.span() >= min_span) return range;
  const double center = 0.5 * (range.lo + range.hi);
  return {center - 0.5 * min_span, center + 0.5 * min_span};
}

// The "nice" step 1, 2 or 5 x 10^k nearest to `rough` (Heckbert, "Nice numbers for graph
// labels", Graphics Gems, 1990); 1 for a rough step that is not finite and positive.
inline double NiceStep(double rough) {
  if (!std::isfinite(rough) || rough <= 0.0) return 1.0;
  const double magnitude = std::pow(10.0, std::floor(std::log10(rough)));
  const double fraction = rough / magnitude;
  const double nice = fraction < 1.5 ? 1.0 : fraction < 3.0 ? 2.0 : fraction < 7.0 ? 5.0 : 10.0;
  return nice * magnitude;
}

inline double TickStep(Range range, double target_ticks) {
  return NiceStep(range.span() / std::max(1.0, target_ticks));
}

// The range rounded outwards to multiples of its tick step.
inline Range NiceBounds(Range range, double target_ticks) {
  const double step = TickStep(range, target_ticks);
  return {std::floor(range.lo / step + 1e-9) * step, std::ceil(range.hi / step - 1e-9) * step};
}

struct Ticks {
  std::vector<double> values;
  int decimals = 0;
};

inline Ticks MakeTicks(Range range, double target_ticks) {
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

inline std::string TickLabel(double value, int decimals) {
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

inline cv::Point Fixed(const cv::Point2d& p) {
  return {static_cast<int>(std::lround(p.x * kShiftScale)),
          static_cast<int>(std::lround(p.y * kShiftScale))};
}

inline void Line(cv::Mat& image, const cv::Point2d& a, const cv::Point2d& b, const cv::Scalar& color,
          int thickness) {
  cv::line(image, Fixed(a), Fixed(b), color, thickness, cv::LINE_AA, kShift);
}

inline void Dot(cv::Mat& image, const cv::Point2d& center, double radius, const cv::Scalar& color) {
  cv::circle(image, Fixed(center), static_cast<int>(std::lround(radius * kShiftScale)), color,
             cv::FILLED, cv::LINE_AA, kShift);
}

inline void DashedHorizontal(Axes& axes, double y, const cv::Scalar& color) {
  const double py = axes.ToPixel(0.0, y).y;
  for (int x = 0; x < axes.area().width; x += 14) {
    Line(axes.plot(), {static_cast<double>(x), py},
         {std::min(x + 8.0, axes.area().width - 1.0), py}, color, 2);
  }
}

// Curves are broken where consecutive samples are further apart in time than this many typical
// (median) sampling intervals, so a lost estimate shows as a gap instead of a straight line.
constexpr double kBreakIntervals = 10.0;

inline double BreakGap(const std::vector<double>& times) {
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
inline void DrawSeries(Axes& axes, const std::vector<double>& x, const std::vector<double>& y,
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

inline void DrawTitle(cv::Mat& canvas, const std::string& title, const std::string& subtitle) {
  PutText(canvas, title, {kWidthPx / 2, 12}, 0.75, kBlack, Align::kCenter, Align::kStart, 2);
  PutText(canvas, subtitle, {kWidthPx / 2, 44}, 0.55, kDarkGrey, Align::kCenter, Align::kStart);
}

inline void DrawNoData(Axes& axes) {
  PutText(axes.plot(), "no estimate was compared with the ground truth",
          {axes.area().width / 2, axes.area().height / 2}, 0.7, kDarkGrey, Align::kCenter,
          Align::kCenter);
}

inline void SavePng(const std::filesystem::path& file, const cv::Mat& image) {
  std::vector<uchar> png;
  if (!cv::imencode(".png", image, png))
    core::ThrowRuntime(file.string() + ": PNG encoding failed");
  core::WriteFileAtomically(
      file, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}


}  // namespace mosaicloc::dataset::plot
