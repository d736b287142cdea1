#include "mosaicloc/dataset/report_plots.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <system_error>
#include <utility>

#include "mosaicloc/dataset/validation.hpp"
#include "plot_canvas.hpp"

namespace mosaicloc::dataset {
namespace {

using plot::Align;
using plot::Axes;
using plot::Range;

constexpr double kInf = std::numeric_limits<double>::infinity();

// Lock states and reasons for a frame without a fix, with their colours (BGR).
cv::Scalar StateColour(int status) {
  switch (status) {
    case 1: return {60, 160, 40};    // tracking: green
    case 2: return {0, 165, 255};    // degraded: orange
    case 3: return {40, 40, 220};    // lost: red
    case 4: return {150, 150, 150};  // off-map: grey
    case 5: return {200, 60, 160};   // searching: purple
    default: return {180, 90, 20};   // none (baseline modes): blue
  }
}

cv::Scalar ReasonColour(const std::string& reason) {
  static const std::map<std::string, cv::Scalar> kColours = {
      {"rejected", {180, 0, 180}},       {"no-match", {0, 0, 200}},        {"ambiguous", {0, 110, 230}},
      {"no-texture", {200, 170, 0}},     {"too-few-inliers", {30, 60, 120}}, {"not-converged", {0, 0, 0}},
      {"off-map", {120, 120, 120}},      {"dead-reckoning", {120, 120, 120}}};
  const auto found = kColours.find(reason);
  return found == kColours.end() ? cv::Scalar(90, 90, 90) : found->second;
}

void Cross(cv::Mat& image, const cv::Point2d& p, double half, const cv::Scalar& colour) {
  plot::Line(image, {p.x - half, p.y - half}, {p.x + half, p.y + half}, colour, 2);
  plot::Line(image, {p.x - half, p.y + half}, {p.x + half, p.y - half}, colour, 2);
}

// The drive's extent in metres, padded, widened to the area's aspect (equal scales).
std::pair<Range, Range> EqualScaleExtent(const std::vector<FrameReport>& reports, const cv::Rect& area) {
  Range x{kInf, -kInf}, y{kInf, -kInf};
  for (const FrameReport& r : reports) {
    x = {std::min(x.lo, r.world_from_vehicle.x_mm() / 1000.0), std::max(x.hi, r.world_from_vehicle.x_mm() / 1000.0)};
    y = {std::min(y.lo, r.world_from_vehicle.y_mm() / 1000.0), std::max(y.hi, r.world_from_vehicle.y_mm() / 1000.0)};
  }
  if (reports.empty()) x = y = {0.0, 1.0};
  const double extent_m = std::max({x.span(), y.span(), 0.1});
  x = plot::Widened({x.lo - 0.06 * extent_m, x.hi + 0.06 * extent_m}, 0.1);
  y = plot::Widened({y.lo - 0.06 * extent_m, y.hi + 0.06 * extent_m}, 0.1);
  const double px_per_m = std::min(area.width / x.span(), area.height / y.span());
  return {plot::Widened(x, area.width / px_per_m), plot::Widened(y, area.height / px_per_m)};
}

// The floor drawn into the axes' plot, lightened so that the drive stands out.
void DrawFloor(Axes& axes, const Range& x, const Range& y, const FloorPicture& floor) {
  if (floor.image.empty()) return;
  cv::Mat& target = axes.plot();
  // Plot pixel (u, v) is world (x.lo + u sx, y.hi - v sy) m; the picture's pixel of a world point
  // is ((X - x0) / px_w, (y1 - Y) / px_h) with X, Y in mm.
  const double sx = x.span() * 1000.0 / target.cols, sy = y.span() * 1000.0 / target.rows;
  const double px_w = (floor.x1_mm - floor.x0_mm) / floor.image.cols;
  const double px_h = (floor.y1_mm - floor.y0_mm) / floor.image.rows;
  const cv::Matx23d plot_to_picture(sx / px_w, 0.0, (x.lo * 1000.0 - floor.x0_mm) / px_w + 0.5 * sx / px_w - 0.5,
                                    0.0, sy / px_h, (floor.y1_mm - y.hi * 1000.0) / px_h + 0.5 * sy / px_h - 0.5);
  cv::Mat grey;
  cv::warpAffine(floor.image, grey, plot_to_picture, target.size(), cv::INTER_AREA | cv::WARP_INVERSE_MAP,
                 cv::BORDER_CONSTANT, cv::Scalar(255));
  cv::Mat light;
  grey.convertTo(light, CV_8UC1, 0.45, 140.0);  // 0..255 to 140..255
  cv::cvtColor(light, target, cv::COLOR_GRAY2BGR);
}

// The world frame's axes at its origin, when in view, and a scale bar at the bottom left.
void DrawWorldAxesAndScale(Axes& axes, const Range& x, const Range& y) {
  cv::Mat& image = axes.plot();
  const double arm_m = plot::NiceStep(0.12 * x.span());
  if (x.lo < 0.0 && 0.0 < x.hi && y.lo < 0.0 && 0.0 < y.hi) {
    const cv::Point2d o = axes.ToPixel(0.0, 0.0);
    const cv::Point2d ax = axes.ToPixel(arm_m, 0.0), ay = axes.ToPixel(0.0, arm_m);
    cv::arrowedLine(image, plot::Fixed(o), plot::Fixed(ax), {30, 30, 200}, 2, cv::LINE_AA, plot::kShift, 0.15);
    cv::arrowedLine(image, plot::Fixed(o), plot::Fixed(ay), {40, 150, 40}, 2, cv::LINE_AA, plot::kShift, 0.15);
    plot::PutText(image, "x", {static_cast<int>(ax.x) + 6, static_cast<int>(ax.y)}, 0.6, {30, 30, 200},
                  Align::kStart, Align::kCenter, 2);
    plot::PutText(image, "y", {static_cast<int>(ay.x), static_cast<int>(ay.y) - 6}, 0.6, {40, 150, 40},
                  Align::kCenter, Align::kEnd, 2);
  }
  const double bar_px = axes.ToPixel(x.lo + arm_m, 0.0).x;
  const int left = 20, base = image.rows - 20;
  cv::rectangle(image, cv::Rect(left - 6, base - 28, static_cast<int>(bar_px) + 12, 40), plot::kWhite, cv::FILLED);
  cv::line(image, {left, base}, {left + static_cast<int>(bar_px), base}, plot::kBlack, 3);
  const double bar_mm = arm_m * 1000.0;
  const std::string label = bar_mm >= 1000.0 ? plot::FormatValue(arm_m) + " m" : plot::FormatValue(bar_mm) + " mm";
  plot::PutText(image, label, {left + static_cast<int>(bar_px) / 2, base - 6}, 0.5, plot::kBlack, Align::kCenter,
                Align::kEnd);
}

// What a map plot colours the frames by.
enum class Colouring { kState, kQuality, kMode };

// The colour of a localizer mode (fixes.csv's mode column), in the order of the PLC's mode
// register: track green, visual odometry blue, dead reckoning orange, searching magenta.
cv::Scalar ModeColour(const std::string& mode) {
  if (mode == "track") return {60, 170, 40};
  if (mode == "visual-odometry") return {200, 110, 20};
  if (mode == "dead-reckoning") return {20, 140, 240};
  if (mode == "searching") return {200, 40, 200};
  return plot::kTrackGrey;
}

cv::Mat MapPlot(const std::vector<FrameReport>& reports, const FloorPicture& floor, const std::string& title,
                Colouring colouring) {
  const bool by_quality = colouring == Colouring::kQuality;
  constexpr int kWidth = 1040, kHeight = 900;  // the legend's 250 px hold "visual-odometry (12345)"
  cv::Mat canvas(kHeight, kWidth, CV_8UC3, plot::kWhite);
  const cv::Rect area(110, 80, kWidth - 110 - 250, kHeight - 80 - 80);
  const auto [x, y] = EqualScaleExtent(reports, area);
  Axes axes(canvas, area, x, y);
  axes.DrawFrame("x [m]", "y [m]", area.width / 90.0, area.height / 90.0);
  DrawFloor(axes, x, y, floor);
  cv::rectangle(canvas, area, plot::kDarkGrey, 1);
  const char* what = colouring == Colouring::kQuality ? " - fixes by quality, over the map"
                     : colouring == Colouring::kMode  ? " - the localizer's mode, over the map"
                                                      : " - lock state, over the map";
  plot::DrawTitle(canvas, title + what, floor.image.empty() ? "no map picture" : "the map's mosaic below");
  if (colouring == Colouring::kMode) {
    std::map<std::string, std::int64_t> modes;
    for (const FrameReport& r : reports) {
      const cv::Point2d p = axes.ToPixel(r.world_from_vehicle.x_mm() / 1000.0, r.world_from_vehicle.y_mm() / 1000.0);
      plot::Dot(axes.plot(), p, 2.5, ModeColour(r.mode));
      ++modes[r.mode.empty() ? std::string("unknown") : r.mode];
    }
    DrawWorldAxesAndScale(axes, x, y);
    const int lx = area.br().x + 16;
    int ly = area.y + 10;
    plot::PutText(canvas, "mode", {lx, ly}, 0.55, plot::kBlack, Align::kStart, Align::kCenter);
    for (const auto& [mode, count] : modes) {
      ly += 24;
      plot::Dot(canvas, {lx + 8.0, static_cast<double>(ly)}, 4.0, ModeColour(mode));
      plot::PutText(canvas, mode + " (" + std::to_string(count) + ")", {lx + 20, ly}, 0.5, plot::kDarkGrey,
                    Align::kStart, Align::kCenter);
    }
    return canvas;
  }

  cv::Mat colormap;
  if (by_quality) {
    cv::Mat ramp(1, 256, CV_8UC1);
    for (int i = 0; i < 256; ++i) ramp.at<uchar>(0, i) = static_cast<uchar>(i);
    cv::applyColorMap(ramp, colormap, cv::COLORMAP_VIRIDIS);
  }
  // Quality from 0.5 (the bottom colour) to 1.
  const auto quality_colour = [&](double quality) {
    const int index = std::clamp(static_cast<int>(std::lround((quality - 0.5) / 0.5 * 255.0)), 0, 255);
    const cv::Vec3b bgr = colormap.at<cv::Vec3b>(0, index);
    return cv::Scalar(bgr[0], bgr[1], bgr[2]);
  };
  std::map<int, std::int64_t> states;
  std::map<std::string, std::int64_t> reasons;
  // Fixes first, the misses on top of them: a reason is never hidden under the track.
  for (const FrameReport& r : reports) {
    if (!r.fixed) continue;
    const cv::Point2d p = axes.ToPixel(r.world_from_vehicle.x_mm() / 1000.0, r.world_from_vehicle.y_mm() / 1000.0);
    plot::Dot(axes.plot(), p, 2.5, by_quality ? quality_colour(r.quality) : StateColour(r.status));
    ++states[r.status];
  }
  for (const FrameReport& r : reports) {
    if (r.fixed) continue;
    const cv::Point2d p = axes.ToPixel(r.world_from_vehicle.x_mm() / 1000.0, r.world_from_vehicle.y_mm() / 1000.0);
    if (by_quality) {
      plot::Dot(axes.plot(), p, 2.0, plot::kTrackGrey);
    } else {
      plot::Dot(axes.plot(), p, 2.0, StateColour(r.status));
      if (r.reason != "off-map") Cross(axes.plot(), p, 4.0, ReasonColour(r.reason));
    }
    ++states[r.status];
    ++reasons[r.reason.empty() ? std::string("unknown") : r.reason];
  }
  DrawWorldAxesAndScale(axes, x, y);

  // Legend, right of the plot.
  const int lx = area.br().x + 16;
  int ly = area.y + 10;
  if (by_quality) {
    plot::PutText(canvas, "fix quality", {lx, ly}, 0.55, plot::kBlack, Align::kStart, Align::kCenter);
    const int bar_top = ly + 20, bar_height = 300;
    for (int i = 0; i < bar_height; ++i) {
      const double q = 1.0 - 0.5 * i / (bar_height - 1.0);
      cv::line(canvas, {lx, bar_top + i}, {lx + 24, bar_top + i}, quality_colour(q), 1);
    }
    for (int k = 0; k <= 5; ++k) {
      const double q = 1.0 - 0.1 * k;
      plot::PutText(canvas, plot::FormatValue(q), {lx + 32, bar_top + static_cast<int>(k * (bar_height - 1) / 5.0)},
                    0.5, plot::kDarkGrey, Align::kStart, Align::kCenter);
    }
    ly = bar_top + bar_height + 30;
    plot::Dot(canvas, {lx + 12.0, static_cast<double>(ly)}, 3.0, plot::kTrackGrey);
    std::int64_t misses = 0;
    for (const auto& [reason, count] : reasons) misses += count;
    plot::PutText(canvas, "no fix (" + std::to_string(misses) + ")", {lx + 24, ly}, 0.5, plot::kDarkGrey,
                  Align::kStart, Align::kCenter);
    return canvas;
  }
  plot::PutText(canvas, "lock state", {lx, ly}, 0.55, plot::kBlack, Align::kStart, Align::kCenter);
  for (const auto& [status, count] : states) {
    ly += 24;
    plot::Dot(canvas, {lx + 8.0, static_cast<double>(ly)}, 4.0, StateColour(status));
    plot::PutText(canvas, std::string(StatusName(status)) + " (" + std::to_string(count) + ")", {lx + 20, ly}, 0.5,
                  plot::kDarkGrey, Align::kStart, Align::kCenter);
  }
  if (reasons.empty()) return canvas;
  ly += 40;
  plot::PutText(canvas, "no fix, why", {lx, ly}, 0.55, plot::kBlack, Align::kStart, Align::kCenter);
  for (const auto& [reason, count] : reasons) {
    ly += 24;
    if (reason == "off-map") {
      plot::Dot(canvas, {lx + 8.0, static_cast<double>(ly)}, 2.0, StateColour(4));
    } else {
      Cross(canvas, {lx + 8.0, static_cast<double>(ly)}, 5.0, ReasonColour(reason));
    }
    plot::PutText(canvas, reason + " (" + std::to_string(count) + ")", {lx + 20, ly}, 0.5, plot::kDarkGrey,
                  Align::kStart, Align::kCenter);
  }
  return canvas;
}

// One panel of the timelines: finite values of each series against time.
struct Series {
  std::vector<double> y;
  cv::Scalar colour;
};

void Panel(cv::Mat& canvas, const cv::Rect& area, const std::vector<double>& t, const std::vector<Series>& series,
           const std::string& label, bool x_label, std::optional<double> bound = std::nullopt) {
  Range yr{kInf, -kInf};
  for (const Series& s : series) {
    for (double v : s.y) {
      if (std::isfinite(v)) yr = {std::min(yr.lo, v), std::max(yr.hi, v)};
    }
  }
  if (bound) yr = {std::min(yr.lo, *bound), std::max(yr.hi, *bound)};
  const bool empty = !std::isfinite(yr.lo);
  if (empty) yr = {0.0, 1.0};
  const double pad = std::max(0.05 * yr.span(), 1e-9);
  yr = plot::Widened({yr.lo - pad, yr.hi + pad}, 1e-6);
  Range xr{0.0, t.empty() ? 1.0 : std::max(t.back(), 1e-3)};
  Axes axes(canvas, area, xr, yr);
  axes.DrawFrame(x_label ? "time [s]" : "", label, 10.0, 3.0);
  if (empty) {
    plot::PutText(axes.plot(), "no values", {area.width / 2, area.height / 2}, 0.6, plot::kDarkGrey, Align::kCenter,
                  Align::kCenter);
    return;
  }
  if (bound) plot::DashedHorizontal(axes, *bound, plot::kP99Orange);
  for (const Series& s : series) {
    std::vector<double> xs, ys;
    for (std::size_t i = 0; i < t.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.y[i])) continue;
      xs.push_back(t[i]);
      ys.push_back(s.y[i]);
    }
    plot::DrawSeries(axes, xs, ys, s.colour);
  }
}

void CreateDirectory(const std::filesystem::path& directory) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec) core::ThrowRuntime(directory.string() + ": cannot create the report directory (" + ec.message() + ")");
}

}  // namespace

void WriteMapPlots(const std::filesystem::path& directory, const std::vector<FrameReport>& reports,
                   const FloorPicture& floor, const std::string& title) {
  CreateDirectory(directory);
  plot::SavePng(directory / "map_state.png", MapPlot(reports, floor, title, Colouring::kState));
  plot::SavePng(directory / "map_quality.png", MapPlot(reports, floor, title, Colouring::kQuality));
  if (std::any_of(reports.begin(), reports.end(), [](const FrameReport& r) { return !r.mode.empty(); })) {
    plot::SavePng(directory / "map_mode.png", MapPlot(reports, floor, title, Colouring::kMode));
  }
}

void WriteTimelines(const std::filesystem::path& directory, const std::vector<TimelineSample>& samples,
                    const std::string& title, core::DriveKind kind) {
  CreateDirectory(directory);
  const bool height = std::any_of(samples.begin(), samples.end(),
                                  [](const TimelineSample& s) { return std::isfinite(s.height_mm); });
  const int panels = height ? 7 : 6;
  constexpr int kWidth = 1000, kPanel = 190, kTop = 70;
  cv::Mat canvas(kTop + panels * kPanel + 50, kWidth, CV_8UC3, plot::kWhite);
  plot::PutText(canvas, title + " - timelines", {kWidth / 2, 12}, 0.75, plot::kBlack, Align::kCenter, Align::kStart, 2);
  std::vector<double> t;
  std::vector<Series> quality(1), sigma(1), nis(1), speed(1), latency(1), wheels(2), heights(1);
  const cv::Scalar blue = plot::kSeriesBlue, green = plot::kRmsGreen;
  quality[0].colour = sigma[0].colour = nis[0].colour = speed[0].colour = latency[0].colour = heights[0].colour = blue;
  wheels[0].colour = blue;
  wheels[1].colour = green;
  for (const TimelineSample& s : samples) {
    t.push_back(s.seconds);
    quality[0].y.push_back(s.quality);
    sigma[0].y.push_back(s.sigma_mm > 0.0 ? std::log10(s.sigma_mm) : plot::kNaN);
    nis[0].y.push_back(s.nis > 0.0 ? std::log10(s.nis) : plot::kNaN);
    speed[0].y.push_back(s.speed_mps);
    latency[0].y.push_back(s.latency_ms);
    wheels[0].y.push_back(s.calibration_first);
    wheels[1].y.push_back(s.calibration_second);
    heights[0].y.push_back(s.height_mm);
  }
  int k = 0;
  const auto area = [&] { return cv::Rect(110, kTop + kPanel * k + 10, kWidth - 110 - 40, kPanel - 45); };
  Panel(canvas, area(), t, quality, "fix quality", false);
  ++k;
  Panel(canvas, area(), t, sigma, "log10 sigma [mm]", false);
  ++k;
  Panel(canvas, area(), t, nis, "log10 NIS", false, std::log10(kNis95Bound3Dof));
  ++k;
  Panel(canvas, area(), t, speed, "speed [m/s]", false);
  ++k;
  Panel(canvas, area(), t, latency, "latency [ms]", false);
  ++k;
  const bool tricycle = kind == core::DriveKind::kTricycle;
  const bool mecanum = kind == core::DriveKind::kMecanum;
  Panel(canvas, area(), t, wheels, tricycle ? "calibration [% / deg]" : "wheel scale [%]", !height);
  if (height) {
    ++k;
    Panel(canvas, area(), t, heights, "camera height [mm]", true);
  }
  plot::PutText(canvas,
                tricycle  ? "NIS: dashed, the 95 % bound (3 dof); drive wheel scale [%] blue, steering offset [deg] green"
                : mecanum ? "NIS: dashed, the 95 % bound (3 dof); scale: wheels blue, sideways green"
                          : "NIS: dashed, the 95 % bound (3 dof); wheel scale: left blue, right green",
                {kWidth / 2, 46}, 0.5, plot::kDarkGrey, Align::kCenter, Align::kStart);
  plot::SavePng(directory / "timelines.png", canvas);
}

}  // namespace mosaicloc::dataset
