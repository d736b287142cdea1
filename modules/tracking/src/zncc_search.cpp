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
#include "simd.hpp"

#ifdef MOSAICLOC_TRACKING_AVX2
#include <immintrin.h>
#endif

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

// sum_{r, c} t[r][c] w[r + dy][c + dx] for every offset (dx, dy) of an rw x rh score map:
// `t` and `w` are 16-bit rows of `stride_t` and `stride_w` values, padded with zeros to whole
// groups of kGroup. Integer arithmetic: every build gives the same sums.
constexpr int kGroup = 16;

void CorrelateRows(const std::int16_t* t, int stride_t, int th, const std::int16_t* w, int stride_w, int rw, int rh,
                   std::int32_t* out) {
  constexpr int kLanes = cv::v_int16x8::nlanes;
  for (int dy = 0; dy < rh; ++dy) {
    for (int dx = 0; dx < rw; ++dx) {
      cv::v_int32x4 acc = cv::v_setzero_s32();
      for (int r = 0; r < th; ++r) {
        const std::int16_t* tr = t + static_cast<std::size_t>(r) * stride_t;
        const std::int16_t* wr = w + static_cast<std::size_t>(r + dy) * stride_w + dx;
        for (int c = 0; c < stride_t; c += kLanes) acc += cv::v_dotprod(cv::v_load(tr + c), cv::v_load(wr + c));
      }
      out[static_cast<std::size_t>(dy) * rw + dx] = cv::v_reduce_sum(acc);
    }
  }
}

#ifdef MOSAICLOC_TRACKING_AVX2
MOSAICLOC_TARGET_AVX2 MOSAICLOC_ALWAYS_INLINE std::int32_t SumLanes(__m256i acc) {
  const __m128i half = _mm_add_epi32(_mm256_castsi256_si128(acc), _mm256_extracti128_si256(acc, 1));
  const __m128i pairs = _mm_add_epi32(half, _mm_shuffle_epi32(half, _MM_SHUFFLE(1, 0, 3, 2)));
  const __m128i total = _mm_add_epi32(pairs, _mm_shuffle_epi32(pairs, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(total);
}

MOSAICLOC_TARGET_AVX2 MOSAICLOC_ALWAYS_INLINE __m256i LoadRow16(const std::int16_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

// The lane sums of eight accumulators, in order: out[i] = sum of the lanes of acc[i].
MOSAICLOC_TARGET_AVX2 MOSAICLOC_ALWAYS_INLINE void StoreSums8(const __m256i* acc, std::int32_t* out) {
  const __m256i h01 = _mm256_hadd_epi32(acc[0], acc[1]), h23 = _mm256_hadd_epi32(acc[2], acc[3]);
  const __m256i h45 = _mm256_hadd_epi32(acc[4], acc[5]), h67 = _mm256_hadd_epi32(acc[6], acc[7]);
  // Per 128-bit half: the partial sums of accumulators 0-3 and 4-7.
  const __m256i h0123 = _mm256_hadd_epi32(h01, h23), h4567 = _mm256_hadd_epi32(h45, h67);
  const __m256i sums = _mm256_add_epi32(_mm256_permute2x128_si256(h0123, h4567, 0x20),
                                        _mm256_permute2x128_si256(h0123, h4567, 0x31));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), sums);
}

// Eight (then four) neighbouring offsets at a time share each load of the template, and the
// loop overhead. Integer sums: the order of the additions does not matter.
MOSAICLOC_TARGET_AVX2 void CorrelateRowsAvx2(const std::int16_t* t, int stride_t, int th, const std::int16_t* w,
                                             int stride_w, int rw, int rh, std::int32_t* out) {
  for (int dy = 0; dy < rh; ++dy) {
    int dx = 0;
    for (; dx + 8 <= rw; dx += 8) {
      __m256i acc[8];
      for (__m256i& a : acc) a = _mm256_setzero_si256();
      for (int r = 0; r < th; ++r) {
        const std::int16_t* tr = t + static_cast<std::size_t>(r) * stride_t;
        const std::int16_t* wr = w + static_cast<std::size_t>(r + dy) * stride_w + dx;
        for (int c = 0; c < stride_t; c += kGroup) {
          const __m256i a = LoadRow16(tr + c);
          for (int i = 0; i < 8; ++i) acc[i] = _mm256_add_epi32(acc[i], _mm256_madd_epi16(a, LoadRow16(wr + c + i)));
        }
      }
      StoreSums8(acc, out + static_cast<std::size_t>(dy) * rw + dx);
    }
    for (; dx + 4 <= rw; dx += 4) {
      __m256i acc0 = _mm256_setzero_si256(), acc1 = acc0, acc2 = acc0, acc3 = acc0;
      for (int r = 0; r < th; ++r) {
        const std::int16_t* tr = t + static_cast<std::size_t>(r) * stride_t;
        const std::int16_t* wr = w + static_cast<std::size_t>(r + dy) * stride_w + dx;
        for (int c = 0; c < stride_t; c += kGroup) {
          const __m256i a = LoadRow16(tr + c);
          acc0 = _mm256_add_epi32(acc0, _mm256_madd_epi16(a, LoadRow16(wr + c)));
          acc1 = _mm256_add_epi32(acc1, _mm256_madd_epi16(a, LoadRow16(wr + c + 1)));
          acc2 = _mm256_add_epi32(acc2, _mm256_madd_epi16(a, LoadRow16(wr + c + 2)));
          acc3 = _mm256_add_epi32(acc3, _mm256_madd_epi16(a, LoadRow16(wr + c + 3)));
        }
      }
      std::int32_t* o = out + static_cast<std::size_t>(dy) * rw + dx;
      o[0] = SumLanes(acc0);
      o[1] = SumLanes(acc1);
      o[2] = SumLanes(acc2);
      o[3] = SumLanes(acc3);
    }
    for (; dx < rw; ++dx) {
      __m256i acc = _mm256_setzero_si256();
      for (int r = 0; r < th; ++r) {
        const std::int16_t* tr = t + static_cast<std::size_t>(r) * stride_t;
        const std::int16_t* wr = w + static_cast<std::size_t>(r + dy) * stride_w + dx;
        for (int c = 0; c < stride_t; c += kGroup) acc = _mm256_add_epi32(acc, _mm256_madd_epi16(LoadRow16(tr + c), LoadRow16(wr + c)));
      }
      out[static_cast<std::size_t>(dy) * rw + dx] = SumLanes(acc);
    }
  }
}
#endif

// TM_CCOEFF_NORMED by direct summation, for the small score maps of a search around a
// prediction, where OpenCV's DFT-based correlation spends most of its time setting up. With
// n template pixels, at each offset over the window patch W under the template T:
//   zncc = (n sum TW - sum T sum W) / sqrt((n sum T^2 - (sum T)^2) (n sum W^2 - (sum W)^2)),
// sum TW by 16-bit dot products, sum W and sum W^2 as exact integers from column sums. A
// patch without variance scores as OpenCV scores it (0, or +-1 within its rounding margin).
cv::Mat DirectZncc(const cv::Mat& templ, const cv::Mat& window) {
  const int tw = templ.cols, th = templ.rows;
  const int rw = window.cols - tw + 1, rh = window.rows - th + 1;
  // Rows padded to whole vector groups with zeros (they add nothing to the dot products).
  const int padded = (tw + kGroup - 1) / kGroup * kGroup;
  const int window_padded = window.cols + padded;
  // Per-thread buffers, only ever grown; every value read is written below.
  thread_local std::vector<std::int16_t> t16, w16;
  thread_local std::vector<std::int32_t> dots;
  thread_local std::vector<std::int64_t> column_sum, column_sq;
  const auto grow = [](auto& v, std::size_t size) {
    if (v.size() < size) v.resize(size);
  };
  grow(t16, static_cast<std::size_t>(padded) * th);
  grow(w16, static_cast<std::size_t>(window_padded) * window.rows);
  grow(dots, static_cast<std::size_t>(rw) * rh);
  grow(column_sum, static_cast<std::size_t>(window.cols));
  grow(column_sq, static_cast<std::size_t>(window.cols));
  // Integer sums (exact, and the loop vectorizes; as doubles they were exact too).
  std::int64_t sum_t_int = 0, sum_tt_int = 0;
  for (int r = 0; r < th; ++r) {
    const std::uint8_t* row = templ.ptr<std::uint8_t>(r);
    std::int16_t* out = &t16[static_cast<std::size_t>(r) * padded];
    std::int32_t row_sum = 0, row_sq = 0;  // at most 32768 255^2 < 2^31
    for (int c = 0; c < tw; ++c) {
      out[c] = row[c];
      row_sum += row[c];
      row_sq += row[c] * row[c];
    }
    sum_t_int += row_sum;
    sum_tt_int += row_sq;
    std::fill(out + tw, out + padded, std::int16_t{0});
  }
  const double sum_t = static_cast<double>(sum_t_int), sum_tt = static_cast<double>(sum_tt_int);
  for (int r = 0; r < window.rows; ++r) {
    const std::uint8_t* row = window.ptr<std::uint8_t>(r);
    std::int16_t* out = &w16[static_cast<std::size_t>(r) * window_padded];
    for (int c = 0; c < window.cols; ++c) out[c] = row[c];
    std::fill(out + window.cols, out + window_padded, std::int16_t{0});
  }
#ifdef MOSAICLOC_TRACKING_AVX2
  if (detail::UseAvx2()) {
    CorrelateRowsAvx2(t16.data(), padded, th, w16.data(), window_padded, rw, rh, dots.data());
  } else
#endif
  {
    CorrelateRows(t16.data(), padded, th, w16.data(), window_padded, rw, rh, dots.data());
  }
  const double n = static_cast<double>(tw) * th;
  const double t_norm = std::sqrt(std::max(n * sum_tt - sum_t * sum_t, 0.0));
  cv::Mat scores(rh, rw, CV_32F);
  // Column sums over the th window rows under the template, moved down a row at a time.
  std::fill(column_sum.begin(), column_sum.begin() + window.cols, 0);
  std::fill(column_sq.begin(), column_sq.begin() + window.cols, 0);
  for (int r = 0; r < th; ++r) {
    const std::uint8_t* row = window.ptr<std::uint8_t>(r);
    for (int c = 0; c < window.cols; ++c) {
      column_sum[c] += row[c];
      column_sq[c] += row[c] * row[c];
    }
  }
  for (int y = 0; y < rh; ++y) {
    if (y > 0) {
      const std::uint8_t* leaving = window.ptr<std::uint8_t>(y - 1);
      const std::uint8_t* entering = window.ptr<std::uint8_t>(y + th - 1);
      for (int c = 0; c < window.cols; ++c) {
        column_sum[c] += entering[c] - leaving[c];
        column_sq[c] += entering[c] * entering[c] - leaving[c] * leaving[c];
      }
    }
    std::int64_t box_sum = 0, box_sq = 0;
    for (int c = 0; c < tw; ++c) {
      box_sum += column_sum[c];
      box_sq += column_sq[c];
    }
    float* out = scores.ptr<float>(y);
    for (int x = 0; x < rw; ++x) {
      if (x > 0) {
        box_sum += column_sum[x + tw - 1] - column_sum[x - 1];
        box_sq += column_sq[x + tw - 1] - column_sq[x - 1];
      }
      const double sum_w = static_cast<double>(box_sum);
      const double sum_ww = static_cast<double>(box_sq);
      const double dot = static_cast<double>(dots[static_cast<std::size_t>(y) * rw + x]);
      const double numerator = n * dot - sum_t * sum_w;
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
