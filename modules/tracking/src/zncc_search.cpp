#include "mosaicloc/tracking/zncc_search.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

#include "low_pass.hpp"
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

// Largest score map computed directly, and the largest template (its products summed in
// int32: 32768 x 255^2 < 2^31).
constexpr int kMaxDirectScores = 40 * 40;
constexpr int kMaxDirectTemplatePixels = 32768;

// TM_CCOEFF_NORMED by direct summation, for the small score maps of a search around a
// prediction, where OpenCV's DFT-based correlation spends most of its time setting up. With
// n template pixels, at each offset over the window patch W under the template T:
//   zncc = (n sum TW - sum T sum W) / sqrt((n sum T^2 - (sum T)^2) (n sum W^2 - (sum W)^2)),
// sum TW by 16-bit dot products, sum W and sum W^2 from integral images. A patch without
// variance scores as OpenCV scores it (0, or +-1 within its rounding margin).
cv::Mat DirectZncc(const cv::Mat& templ, const cv::Mat& window) {
  const int tw = templ.cols, th = templ.rows;
  const int rw = window.cols - tw + 1, rh = window.rows - th + 1;
  // Rows padded to whole SIMD vectors with zeros (they add nothing to the dot products).
  constexpr int kLanes = cv::v_int16x8::nlanes;
  const int padded = (tw + kLanes - 1) / kLanes * kLanes;
  const int window_padded = window.cols + padded;
  thread_local std::vector<std::int16_t> t16, w16;
  t16.assign(static_cast<std::size_t>(padded) * th, 0);
  w16.assign(static_cast<std::size_t>(window_padded) * window.rows, 0);
  double sum_t = 0.0, sum_tt = 0.0;
  for (int r = 0; r < th; ++r) {
    const std::uint8_t* row = templ.ptr<std::uint8_t>(r);
    for (int c = 0; c < tw; ++c) {
      t16[static_cast<std::size_t>(r) * padded + c] = row[c];
      sum_t += row[c];
      sum_tt += static_cast<double>(row[c]) * row[c];
    }
  }
  for (int r = 0; r < window.rows; ++r) {
    const std::uint8_t* row = window.ptr<std::uint8_t>(r);
    std::int16_t* out = &w16[static_cast<std::size_t>(r) * window_padded];
    for (int c = 0; c < window.cols; ++c) out[c] = row[c];
  }
  // sum TW at an offset: one vector accumulator over the whole template, reduced once.
  const auto dot = [&](int dx, int dy) {
    cv::v_int32x4 acc = cv::v_setzero_s32();
    for (int r = 0; r < th; ++r) {
      const std::int16_t* t = &t16[static_cast<std::size_t>(r) * padded];
      const std::int16_t* w = &w16[static_cast<std::size_t>(r + dy) * window_padded + dx];
      for (int c = 0; c < padded; c += kLanes) acc += cv::v_dotprod(cv::v_load(t + c), cv::v_load(w + c));
    }
    return cv::v_reduce_sum(acc);
  };
  cv::Mat sum, sq_sum;
  cv::integral(window, sum, sq_sum, CV_32S, CV_64F);
  const double n = static_cast<double>(tw) * th;
  const double t_norm = std::sqrt(std::max(n * sum_tt - sum_t * sum_t, 0.0));
  cv::Mat scores(rh, rw, CV_32F);
  for (int y = 0; y < rh; ++y) {
    const std::int32_t* s0 = sum.ptr<std::int32_t>(y);
    const std::int32_t* s1 = sum.ptr<std::int32_t>(y + th);
    const double* q0 = sq_sum.ptr<double>(y);
    const double* q1 = sq_sum.ptr<double>(y + th);
    float* out = scores.ptr<float>(y);
    for (int x = 0; x < rw; ++x) {
      const double sum_w = static_cast<double>(s1[x + tw] - s1[x] - s0[x + tw] + s0[x]);
      const double sum_ww = q1[x + tw] - q1[x] - q0[x + tw] + q0[x];
      const double numerator = n * dot(x, y) - sum_t * sum_w;
      const double denominator = std::sqrt(std::max(n * sum_ww - sum_w * sum_w, 0.0)) * t_norm;
      double score = 0.0;
      if (std::abs(numerator) < denominator) {
        score = numerator / denominator;
      } else if (std::abs(numerator) < 1.125 * denominator) {
        score = numerator > 0.0 ? 1.0 : -1.0;
      }
      out[x] = static_cast<float>(score);
    }
  }
  return scores;
}

ScoreMap Match(const cv::Mat& templ, const cv::Mat& window) {
  ScoreMap m;
  const int score_pixels = (window.cols - templ.cols + 1) * (window.rows - templ.rows + 1);
  if (score_pixels <= kMaxDirectScores && templ.total() <= static_cast<std::size_t>(kMaxDirectTemplatePixels)) {
    m.scores = DirectZncc(templ, window);
  } else {
    cv::matchTemplate(window, templ, m.scores, cv::TM_CCOEFF_NORMED);
  }
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
  // Filtered into buffers of their own (kept per thread): a header copy of the inputs would
  // share their pixels, and blurring into it would blur the caller's images.
  std::vector<cv::Mat> templ(1), window(1);
  if (options.prefilter_sigma_px > 0.0) {
    const double sigma = options.prefilter_sigma_px;
    thread_local cv::Mat templ_store, window_store;
    templ[0] = detail::ScratchImage(templ_store, raw_templ.size(), CV_8UC1);
    window[0] = detail::ScratchImage(window_store, raw_window.size(), CV_8UC1);
    detail::GaussianLowPass(raw_templ, templ[0], sigma, CV_8U);
    detail::GaussianLowPass(raw_window, window[0], sigma, CV_8U);
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
