#include "mosaicloc/tracking/zncc_search.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

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

// Best local maximum (3x3) at least `radius` (Chebyshev) away from `centre`: a broad main
// lobe is not a second place, a separate bump is.
double SecondPeak(const cv::Mat& scores, cv::Point centre, int radius) {
  cv::Mat dilated;
  cv::dilate(scores, dilated, cv::Mat());
  double second = -1.0;
  for (int y = 0; y < scores.rows; ++y) {
    const float* row = scores.ptr<float>(y);
    const float* top = dilated.ptr<float>(y);
    const bool near_row = std::abs(y - centre.y) < radius;
    for (int x = 0; x < scores.cols; ++x) {
      if (row[x] < top[x] || (near_row && std::abs(x - centre.x) < radius)) continue;
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
  // Pyramid by 2x2 area averaging: level k pixel i covers level-0 pixels [2^k i, 2^k (i + 1)),
  // so a template offset scales exactly by 2^k between levels.
  // Fresh buffers: a header copy of the inputs would share their pixels, and blurring into
  // it would blur the caller's images.
  std::vector<cv::Mat> templ(1), window(1);
  if (options.prefilter_sigma_px > 0.0) {
    const double sigma = options.prefilter_sigma_px;
    cv::GaussianBlur(raw_templ, templ[0], cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
    cv::GaussianBlur(raw_window, window[0], cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
  } else {
    templ[0] = raw_templ;
    window[0] = raw_window;
  }
  const int range = std::max(raw_window.cols - raw_templ.cols, raw_window.rows - raw_templ.rows) / 2;
  const auto can_halve = [&](int level) {
    return (raw_templ.cols >> (level + 1)) >= 16 && (raw_templ.rows >> (level + 1)) >= 16;
  };
  constexpr int finest = 0;
  int coarsest = finest;
  while ((range >> coarsest) > options.max_direct_range_px && can_halve(coarsest)) ++coarsest;
  for (int level = 1; level <= coarsest; ++level) {
    cv::Mat t, w;
    cv::resize(templ.back(), t, cv::Size(templ.back().cols / 2, templ.back().rows / 2), 0, 0, cv::INTER_AREA);
    cv::resize(window.back(), w, cv::Size(window.back().cols / 2, window.back().rows / 2), 0, 0, cv::INTER_AREA);
    templ.push_back(t);
    window.push_back(w);
  }
  result.coarsest_level = coarsest;

  // The whole range at the coarsest level; ambiguity is judged there.
  ScoreMap at = Match(templ[static_cast<std::size_t>(coarsest)], window[static_cast<std::size_t>(coarsest)]);
  cv::Point origin(0, 0);  // `at.scores` holds positions origin + (x, y) of the level's window
  result.second = SecondPeak(at.scores, at.best, options.exclusion_radius_px);
  const double judged_peak = at.peak;
  for (int level = coarsest - 1; level >= finest; --level) {
    const cv::Mat& t = templ[static_cast<std::size_t>(level)];
    const cv::Mat& w = window[static_cast<std::size_t>(level)];
    const cv::Point guess = 2 * (origin + at.best);
    const int x0 = std::clamp(guess.x - 2, 0, w.cols - t.cols), x1 = std::clamp(guess.x + 3, 0, w.cols - t.cols);
    const int y0 = std::clamp(guess.y - 2, 0, w.rows - t.rows), y1 = std::clamp(guess.y + 3, 0, w.rows - t.rows);
    origin = {x0, y0};
    at = Match(t, w(cv::Rect(x0, y0, x1 - x0 + t.cols, y1 - y0 + t.rows)));
  }

  const cv::Mat& s = at.scores;
  const cv::Point best = at.best;
  result.peak = at.peak;
  double dx = 0.0, dy = 0.0;
  if (best.x > 0 && best.x + 1 < s.cols) {
    dx = ParabolaVertex(s.at<float>(best.y, best.x - 1), s.at<float>(best), s.at<float>(best.y, best.x + 1));
  }
  if (best.y > 0 && best.y + 1 < s.rows) {
    dy = ParabolaVertex(s.at<float>(best.y - 1, best.x), s.at<float>(best), s.at<float>(best.y + 1, best.x));
  }
  result.offset_px = Eigen::Vector2d(origin.x + best.x + dx, origin.y + best.y + dy);
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
