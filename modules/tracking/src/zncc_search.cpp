#include "mosaicloc/tracking/zncc_search.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::tracking {
namespace {

// Vertex of the parabola through (-1, a), (0, b), (1, c), clamped to half a pixel.
double ParabolaVertex(double a, double b, double c) {
  const double denominator = a - 2.0 * b + c;
  if (!(denominator < 0.0)) return 0.0;
  return std::clamp(0.5 * (a - c) / denominator, -0.5, 0.5);
}

struct ScoreMap {
  cv::Mat scores;  // CV_32F
  cv::Point best;
  double peak = -1.0;
};

ScoreMap Match(const cv::Mat& templ, const cv::Mat& window) {
  ScoreMap m;
  cv::matchTemplate(window, templ, m.scores, cv::TM_CCOEFF_NORMED);
  double min_value = 0.0;
  cv::minMaxLoc(m.scores, &min_value, &m.peak, nullptr, &m.best);
  return m;
}

// Best score at least `radius` (Chebyshev) away from `centre`.
double SecondPeak(const cv::Mat& scores, cv::Point centre, int radius) {
  double second = -1.0;
  for (int y = 0; y < scores.rows; ++y) {
    const float* row = scores.ptr<float>(y);
    const bool near_row = std::abs(y - centre.y) < radius;
    for (int x = 0; x < scores.cols; ++x) {
      if (near_row && std::abs(x - centre.x) < radius) continue;
      second = std::max(second, static_cast<double>(row[x]));
    }
  }
  return second;
}

}  // namespace

bool SearchOptions::Check(std::string* why) const {
  if (max_direct_range_px < 2) {
    if (why != nullptr) *why = "max_direct_range_px must be >= 2";
    return false;
  }
  if (!(prefilter_sigma_px >= 0.0 && prefilter_sigma_px <= 5.0)) {
    if (why != nullptr) *why = "prefilter_sigma_px must be in [0, 5]";
    return false;
  }
  if (exclusion_radius_px < 1) {
    if (why != nullptr) *why = "exclusion_radius_px must be >= 1";
    return false;
  }
  return true;
}

SearchPeak SearchZncc(const cv::Mat& raw_templ, const cv::Mat& raw_window, const SearchOptions& options) {
  SearchPeak result;
  if (raw_templ.empty() || raw_window.cols < raw_templ.cols || raw_window.rows < raw_templ.rows) return result;
  cv::Mat templ = raw_templ, window = raw_window;
  if (options.prefilter_sigma_px > 0.0) {
    const double sigma = options.prefilter_sigma_px;
    cv::GaussianBlur(raw_templ, templ, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
    cv::GaussianBlur(raw_window, window, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
  }
  const int range = std::max(window.cols - templ.cols, window.rows - templ.rows) / 2;

  // Coarse levels: halve until the range fits, keeping at least 16 px of template.
  int levels = 1;
  while ((range >> (levels - 1)) > options.max_direct_range_px && (templ.cols >> levels) >= 16 &&
         (templ.rows >> levels) >= 16) {
    ++levels;
  }
  result.levels = levels;

  // `scores` holds ZNCC for template positions origin + (x, y) of the window.
  ScoreMap full;
  cv::Point origin(0, 0);
  double judged_peak = 0.0;  // the peak at the level where `second` was found
  if (levels == 1) {
    full = Match(templ, window);
    result.second = SecondPeak(full.scores, full.best, options.exclusion_radius_px);
    judged_peak = full.peak;
  } else {
    const double f = 1.0 / (1 << (levels - 1));
    cv::Mat small_templ, small_window;
    cv::resize(templ, small_templ, cv::Size(), f, f, cv::INTER_AREA);
    cv::resize(window, small_window, cv::Size(), f, f, cv::INTER_AREA);
    const ScoreMap coarse = Match(small_templ, small_window);
    // Ambiguity is judged at the coarse level, where the whole range was seen.
    result.second = SecondPeak(coarse.scores, coarse.best, options.exclusion_radius_px);
    judged_peak = coarse.peak;
    // Refine at full resolution in a small window around the upsampled peak.
    const int scale = 1 << (levels - 1);
    const int slack = scale + 2;
    const int x0 = std::clamp(coarse.best.x * scale - slack, 0, window.cols - templ.cols);
    const int y0 = std::clamp(coarse.best.y * scale - slack, 0, window.rows - templ.rows);
    const int x1 = std::clamp(coarse.best.x * scale + slack, 0, window.cols - templ.cols);
    const int y1 = std::clamp(coarse.best.y * scale + slack, 0, window.rows - templ.rows);
    origin = {x0, y0};
    full = Match(templ, window(cv::Rect(x0, y0, x1 - x0 + templ.cols, y1 - y0 + templ.rows)));
  }

  const cv::Mat& s = full.scores;
  const cv::Point best = full.best;
  result.peak = full.peak;
  double dx = 0.0, dy = 0.0;
  if (best.x > 0 && best.x + 1 < s.cols) {
    dx = ParabolaVertex(s.at<float>(best.y, best.x - 1), s.at<float>(best), s.at<float>(best.y, best.x + 1));
  }
  if (best.y > 0 && best.y + 1 < s.rows) {
    dy = ParabolaVertex(s.at<float>(best.y - 1, best.x), s.at<float>(best), s.at<float>(best.y + 1, best.x));
  }
  result.offset_px = {origin.x + best.x + dx, origin.y + best.y + dy};
  double ring = 0.0;
  int ring_count = 0;
  for (const cv::Point d : {cv::Point(2, 0), cv::Point(-2, 0), cv::Point(0, 2), cv::Point(0, -2)}) {
    const cv::Point p = best + d;
    if (p.x >= 0 && p.y >= 0 && p.x < s.cols && p.y < s.rows) {
      ring += s.at<float>(p);
      ++ring_count;
    }
  }
  result.sharpness = ring_count > 0 ? result.peak - ring / ring_count : 0.0;
  result.ambiguity = judged_peak > 0.0 ? std::max(result.second, 0.0) / judged_peak : 1.0;
  result.found = std::isfinite(result.peak) && result.peak > 0.0;
  return result;
}

}  // namespace mosaicloc::tracking
