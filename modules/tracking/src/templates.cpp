#include "mosaicloc/tracking/templates.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "area_halve.hpp"
#include "mosaicloc/core/error.hpp"
#include "ranking_map.hpp"
#include "simd.hpp"

#ifdef MOSAICLOC_TRACKING_AVX2
#include <immintrin.h>
#endif

namespace mosaicloc::tracking {
namespace {

// Smallest eigenvalue of [[a, b], [b, c]].
double MinEigen(double a, double b, double c) {
  return 0.5 * (a + c) - std::sqrt(0.25 * (a - c) * (a - c) + b * b);
}

// Grid of cells for `count` templates over a w x h frame: cols x rows with cols * rows >= count,
// cells as square as the frame allows.
cv::Size CellGrid(int count, int width, int height) {
  int best_cols = 1;
  double best_score = 1e300;
  for (int cols = 1; cols <= count; ++cols) {
    const int rows = (count + cols - 1) / cols;
    const double aspect = (static_cast<double>(width) / cols) / (static_cast<double>(height) / rows);
    const double score = std::abs(std::log(aspect)) + 0.5 * (cols * rows - count);
    if (score < best_score) {
      best_score = score;
      best_cols = cols;
    }
  }
  return {best_cols, (count + best_cols - 1) / best_cols};
}

// The structure tensor in integers. cv::Sobel (3x3, scale 1/8) of an 8-bit image is G / 8
// with the integer numerators
//   Gx(i) = (u[i+1] - u[i-1]) + 2 (m[i+1] - m[i-1]) + (d[i+1] - d[i-1]),
//   Gy(i) = (d[i-1] + 2 d[i] + d[i+1]) - (u[i-1] + 2 u[i] + u[i+1])
// (u, m, d the rows above, at and below), |G| <= 1020. Their products summed over a pair of
// pixels fit in int32, and every float OpenCV forms from them on the way to the ranking
// (products, 2x2 area averages, box sums in double) is exact: integer sums give its values
// bit for bit, in one pass instead of a dozen OpenCV calls whose set-up dominates at these
// sizes. The plain and AVX2 builds of each row loop share the per-pixel code below (the AVX2
// one does 16 pixels at a time and hands the rest to it); integer arithmetic makes them agree.

// Three 16-bit rows, each readable one value before index 0 and one after the last.
struct Rows3 {
  const std::int16_t* up;
  const std::int16_t* mid;
  const std::int16_t* down;
};

MOSAICLOC_ALWAYS_INLINE void SobelAt(const Rows3& r, int i, std::int32_t* gx, std::int32_t* gy) {
  *gx = (r.up[i + 1] - r.up[i - 1]) + 2 * (r.mid[i + 1] - r.mid[i - 1]) + (r.down[i + 1] - r.down[i - 1]);
  *gy = (r.down[i - 1] + 2 * r.down[i] + r.down[i + 1]) - (r.up[i - 1] + 2 * r.up[i] + r.up[i + 1]);
}

// Gx^2, Gx Gy and Gy^2 summed over the pixels 2j and 2j + 1.
MOSAICLOC_ALWAYS_INLINE void TensorPair(const Rows3& r, int j, std::int32_t* xx, std::int32_t* xy, std::int32_t* yy) {
  std::int32_t gx0 = 0, gy0 = 0, gx1 = 0, gy1 = 0;
  SobelAt(r, 2 * j, &gx0, &gy0);
  SobelAt(r, 2 * j + 1, &gx1, &gy1);
  xx[j] = gx0 * gx0 + gx1 * gx1;
  xy[j] = gx0 * gy0 + gx1 * gy1;
  yy[j] = gy0 * gy0 + gy1 * gy1;
}

void TensorPairsFrom(const Rows3& r, int begin, int pairs, std::int32_t* xx, std::int32_t* xy, std::int32_t* yy) {
  for (int j = begin; j < pairs; ++j) TensorPair(r, j, xx, xy, yy);
}
void TensorPairs(const Rows3& r, int pairs, std::int32_t* xx, std::int32_t* xy, std::int32_t* yy) {
  TensorPairsFrom(r, 0, pairs, xx, xy, yy);
}
void WidenFrom(const std::uint8_t* in, int begin, int n, std::int16_t* out) {
  for (int i = begin; i < n; ++i) out[i] = in[i];
}
void Widen(const std::uint8_t* in, int n, std::int16_t* out) { WidenFrom(in, 0, n, out); }
void MinEigensFrom(const float* a, const float* b, const float* c, int begin, int n, double* out) {
  for (int i = begin; i < n; ++i) out[i] = MinEigen(a[i], b[i], c[i]);
}
void MinEigens(const float* a, const float* b, const float* c, int n, double* out) {
  MinEigensFrom(a, b, c, 0, n, out);
}

#ifdef MOSAICLOC_TRACKING_AVX2
MOSAICLOC_TARGET_AVX2 MOSAICLOC_ALWAYS_INLINE __m256i Load16(const std::int16_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

MOSAICLOC_TARGET_AVX2 void TensorPairsAvx2(const Rows3& r, int pairs, std::int32_t* xx, std::int32_t* xy,
                                           std::int32_t* yy) {
  int j = 0;
  for (; j + 8 <= pairs; j += 8) {
    const int i = 2 * j;
    const __m256i ul = Load16(r.up + i - 1), uc = Load16(r.up + i), ur = Load16(r.up + i + 1);
    const __m256i ml = Load16(r.mid + i - 1), mr = Load16(r.mid + i + 1);
    const __m256i dl = Load16(r.down + i - 1), dc = Load16(r.down + i), dr = Load16(r.down + i + 1);
    const __m256i gx = _mm256_add_epi16(
        _mm256_add_epi16(_mm256_sub_epi16(ur, ul), _mm256_slli_epi16(_mm256_sub_epi16(mr, ml), 1)),
        _mm256_sub_epi16(dr, dl));
    const __m256i gy = _mm256_sub_epi16(_mm256_add_epi16(_mm256_add_epi16(dl, dr), _mm256_slli_epi16(dc, 1)),
                                        _mm256_add_epi16(_mm256_add_epi16(ul, ur), _mm256_slli_epi16(uc, 1)));
    // madd: lane j of the result is the sum of the products of 16-bit lanes 2j and 2j + 1.
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(xx + j), _mm256_madd_epi16(gx, gx));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(xy + j), _mm256_madd_epi16(gx, gy));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(yy + j), _mm256_madd_epi16(gy, gy));
  }
  TensorPairsFrom(r, j, pairs, xx, xy, yy);
}

MOSAICLOC_TARGET_AVX2 void WidenAvx2(const std::uint8_t* in, int n, std::int16_t* out) {
  int i = 0;
  for (; i + 16 <= n; i += 16) {
    const __m128i bytes = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + i));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + i), _mm256_cvtepu8_epi16(bytes));
  }
  WidenFrom(in, i, n, out);
}

// MinEigen four at a time: the same IEEE operations in the same order (sqrt is exact in both).
MOSAICLOC_TARGET_AVX2 void MinEigensAvx2(const float* a, const float* b, const float* c, int n, double* out) {
  const __m256d half = _mm256_set1_pd(0.5), quarter = _mm256_set1_pd(0.25);
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    const __m256d va = _mm256_cvtps_pd(_mm_loadu_ps(a + i));
    const __m256d vb = _mm256_cvtps_pd(_mm_loadu_ps(b + i));
    const __m256d vc = _mm256_cvtps_pd(_mm_loadu_ps(c + i));
    const __m256d d = _mm256_sub_pd(va, vc);
    const __m256d root = _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_mul_pd(quarter, d), d), _mm256_mul_pd(vb, vb)));
    _mm256_storeu_pd(out + i, _mm256_sub_pd(_mm256_mul_pd(half, _mm256_add_pd(va, vc)), root));
  }
  MinEigensFrom(a, b, c, i, n, out);
}
#endif

struct Kernels {
  void (*tensor_pairs)(const Rows3&, int, std::int32_t*, std::int32_t*, std::int32_t*) = &TensorPairs;
  void (*widen)(const std::uint8_t*, int, std::int16_t*) = &Widen;
  void (*min_eigen)(const float*, const float*, const float*, int, double*) = &MinEigens;
};

Kernels ChooseKernels() {
  Kernels k;
#ifdef MOSAICLOC_TRACKING_AVX2
  if (detail::UseAvx2()) {
    k.tensor_pairs = &TensorPairsAvx2;
    k.widen = &WidenAvx2;
    k.min_eigen = &MinEigensAvx2;
  }
#endif
  return k;
}

template <typename T>
T* Grown(std::vector<T>& v, std::size_t size) {
  if (v.size() < size) v.resize(size);
  return v.data();
}

}  // namespace

namespace detail {

void RankingMap(const cv::Mat& half, int k, cv::Mat* eigen) {
  const Kernels kernels = ChooseKernels();
  const int qw = half.cols / 2, qh = half.rows / 2, cw = qw / 2, ch = qh / 2;
  // Per-thread buffers, only ever grown: this runs every frame.
  thread_local cv::Mat quarter_image;
  thread_local std::vector<std::int16_t> quarter_store;
  thread_local std::vector<std::int32_t> pair_store, cell_store, column_store;
  thread_local std::vector<float> mean_store;
  thread_local std::vector<double> box_store;
  // Quarter-resolution rows with one reflected (BORDER_REFLECT_101) column on either side.
  const std::size_t stride = static_cast<std::size_t>(qw) + 2;
  std::int16_t* quarter = Grown(quarter_store, stride * static_cast<std::size_t>(qh));
  detail::HalveImage(half, quarter_image);
  for (int y = 0; y < qh; ++y) {
    std::int16_t* q = quarter + static_cast<std::size_t>(y) * stride + 1;
    kernels.widen(quarter_image.ptr<std::uint8_t>(y), qw, q);
    q[-1] = q[1];
    q[qw] = q[qw - 2];
  }
  const auto row = [&](int y) -> const std::int16_t* {
    y = y < 0 ? -y : y >= qh ? 2 * qh - 2 - y : y;
    return quarter + static_cast<std::size_t>(y) * stride + 1;
  };
  // Cell sums of Gx^2, Gx Gy, Gy^2 (channels 0, 1, 2): at most 4 1020^2 < 2^22.
  const std::size_t plane = static_cast<std::size_t>(cw) * static_cast<std::size_t>(ch);
  std::int32_t* cells = Grown(cell_store, 3 * plane);
  std::int32_t* pairs = Grown(pair_store, 6 * static_cast<std::size_t>(cw));
  for (int cy = 0; cy < ch; ++cy) {
    for (int r = 0; r < 2; ++r) {
      const int y = 2 * cy + r;
      std::int32_t* p = pairs + 3 * r * cw;
      kernels.tensor_pairs({row(y - 1), row(y), row(y + 1)}, cw, p, p + cw, p + 2 * cw);
    }
    for (int c = 0; c < 3; ++c) {
      const std::int32_t* top = pairs + c * cw;
      const std::int32_t* bottom = pairs + (3 + c) * cw;
      std::int32_t* out = cells + c * plane + static_cast<std::size_t>(cy) * cw;
      for (int x = 0; x < cw; ++x) out[x] = top[x] + bottom[x];
    }
  }
  // Box sums: down the columns, a running sum moved a row at a time (k cells, < 2^29 for the
  // largest template); then along the row, a running int64 sum over the column sums with the
  // last one repeated k - 1 times past the edge. All exact.
  const double scale = 1.0 / (k * k);
  const std::size_t line = static_cast<std::size_t>(cw + k);
  std::int32_t* columns = Grown(column_store, 3 * line);
  float* means = Grown(mean_store, 3 * static_cast<std::size_t>(cw));
  double* box = Grown(box_store, static_cast<std::size_t>(cw));
  for (int c = 0; c < 3; ++c) {
    std::int32_t* column = columns + c * line;
    const std::int32_t* cell = cells + c * plane;
    std::fill(column, column + cw, 0);
    for (int r = 0; r < k; ++r) {
      const std::int32_t* from = cell + static_cast<std::size_t>(std::min(r, ch - 1)) * cw;
      for (int x = 0; x < cw; ++x) column[x] += from[x];
    }
  }
  eigen->create(ch, cw, CV_64F);
  for (int sy = 0; sy < ch; ++sy) {
    for (int c = 0; c < 3; ++c) {
      std::int32_t* column = columns + c * line;
      std::fill(column + cw, column + cw + k, column[cw - 1]);
      // The running sum alone is serial; the conversions after it vectorize.
      std::int64_t sum = 0;
      for (int j = 0; j < k; ++j) sum += column[j];
      for (int x = 0; x < cw; ++x) {
        box[x] = static_cast<double>(sum);
        sum += column[x + k] - column[x];
      }
      float* mean = means + c * cw;
      for (int x = 0; x < cw; ++x) mean[x] = static_cast<float>(box[x] / 256.0 * scale);
      // Down a row: the row leaving the window out, the one entering it in.
      const std::int32_t* cell = cells + c * plane;
      const std::int32_t* leaving = cell + static_cast<std::size_t>(sy) * cw;
      const std::int32_t* entering = cell + static_cast<std::size_t>(std::min(sy + k, ch - 1)) * cw;
      for (int x = 0; x < cw; ++x) column[x] += entering[x] - leaving[x];
    }
    kernels.min_eigen(means, means + cw, means + 2 * cw, cw, eigen->ptr<double>(sy));
  }
}

void RankingMapOpenCv(const cv::Mat& half, int k, cv::Mat* eigen) {
  cv::Mat quarter, gx, gy, product, sxx, sxy, syy, mxx, mxy, myy;
  cv::resize(half, quarter, cv::Size(half.cols / 2, half.rows / 2), 0, 0, cv::INTER_AREA);
  cv::Sobel(quarter, gx, CV_32F, 1, 0, 3, 0.125);
  cv::Sobel(quarter, gy, CV_32F, 0, 1, 3, 0.125);
  const cv::Size cells(quarter.cols / 2, quarter.rows / 2);
  cv::multiply(gx, gx, product);
  cv::resize(product, sxx, cells, 0, 0, cv::INTER_AREA);
  cv::multiply(gx, gy, product);
  cv::resize(product, sxy, cells, 0, 0, cv::INTER_AREA);
  cv::multiply(gy, gy, product);
  cv::resize(product, syy, cells, 0, 0, cv::INTER_AREA);
  cv::boxFilter(sxx, mxx, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
  cv::boxFilter(sxy, mxy, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
  cv::boxFilter(syy, myy, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
  eigen->create(cells, CV_64F);
  for (int y = 0; y < cells.height; ++y) {
    for (int x = 0; x < cells.width; ++x) {
      eigen->at<double>(y, x) = MinEigen(mxx.at<float>(y, x), mxy.at<float>(y, x), myy.at<float>(y, x));
    }
  }
}

}  // namespace detail

const char* ToString(TemplateMode mode) {
  switch (mode) {
    case TemplateMode::kSpread: return "spread";
    case TemplateMode::kTiled: return "tiled";
  }
  return "unknown";
}

bool TemplateOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (mode == TemplateMode::kSpread && (count < 1 || count > 64)) return fail("count must be in [1, 64]");
  if (mode == TemplateMode::kSpread && (size_px < 8 || size_px > 1024)) return fail("size_px must be in [8, 1024]");
  if (mode == TemplateMode::kTiled && (tile_cols < 1 || tile_rows < 1 || tile_cols * tile_rows > 256)) {
    return fail("tile_cols and tile_rows must be >= 1 and their product <= 256");
  }
  if (border_px < 1) return fail("border_px must be >= 1");
  if (!(min_texture >= 0.0)) return fail("min_texture must be >= 0");
  return true;
}

double TextureStrength(const cv::Mat& region) {
  if (region.empty() || region.type() != CV_8UC1) core::ThrowInvalidInput("texture: expected an 8-bit grey region");
  // The gradients of cv::Sobel on the region: inside a larger image it reads the image's own
  // pixels around the region, and reflects (BORDER_REFLECT_101) at the image's edges.
  cv::Size whole;
  cv::Point offset;
  region.locateROI(whole, offset);
  const auto reflect = [](int i, int n) { return n == 1 ? 0 : i < 0 ? -i : i >= n ? 2 * n - 2 - i : i; };
  const int w = region.cols, h = region.rows;
  const Kernels kernels = ChooseKernels();
  thread_local std::vector<std::int16_t> rows_store;
  thread_local std::vector<std::int32_t> pair_store;
  const std::size_t stride = static_cast<std::size_t>(w) + 2;
  std::int16_t* rows = Grown(rows_store, stride * static_cast<std::size_t>(h + 2));
  const bool inside = offset.x >= 1 && offset.x + w + 1 <= whole.width;
  for (int r = -1; r <= h; ++r) {
    // Column 0 of the image row the region's row r reads.
    const std::uint8_t* source = region.ptr<std::uint8_t>(0) +
                                 static_cast<std::ptrdiff_t>(reflect(offset.y + r, whole.height) - offset.y) *
                                     static_cast<std::ptrdiff_t>(region.step[0]) -
                                 offset.x;
    std::int16_t* out = rows + static_cast<std::size_t>(r + 1) * stride;
    if (inside) {
      kernels.widen(source + offset.x - 1, w + 2, out);
    } else {
      for (int c = -1; c <= w; ++c) out[c + 1] = source[reflect(offset.x + c, whole.width)];
    }
  }
  const int pairs = w / 2;
  std::int32_t* p = Grown(pair_store, 3 * static_cast<std::size_t>(pairs) + 3);
  std::int64_t sxx = 0, sxy = 0, syy = 0;
  for (int y = 0; y < h; ++y) {
    const auto at = [&](int r) { return rows + static_cast<std::size_t>(r + 1) * stride + 1; };
    const Rows3 r3{at(y - 1), at(y), at(y + 1)};
    kernels.tensor_pairs(r3, pairs, p, p + pairs, p + 2 * pairs);
    for (int j = 0; j < pairs; ++j) {
      sxx += p[j];
      sxy += p[pairs + j];
      syy += p[2 * pairs + j];
    }
    if (w % 2 == 1) {
      std::int32_t gx = 0, gy = 0;
      SobelAt(r3, w - 1, &gx, &gy);
      sxx += gx * gx;
      sxy += gx * gy;
      syy += gy * gy;
    }
  }
  // gx = Gx / 8: the mean of gx^2 is sum Gx^2 / 64 / n.
  const double n = static_cast<double>(region.total());
  return MinEigen(static_cast<double>(sxx) / 64.0 / n, static_cast<double>(sxy) / 64.0 / n,
                  static_cast<double>(syy) / 64.0 / n);
}

std::vector<TemplateSpot> SelectTemplates(const cv::Mat& frame, const TemplateOptions& options) {
  cv::Mat half;
  if (frame.type() == CV_8UC1 && frame.cols >= 2 && frame.rows >= 2) detail::HalveImage(frame, half);
  return SelectTemplates(frame, half, options);
}

std::vector<TemplateSpot> SelectTemplates(const cv::Mat& frame, const cv::Mat& half, const TemplateOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("template options: " + why);
  if (frame.empty() || frame.type() != CV_8UC1) core::ThrowInvalidInput("templates: expected an 8-bit grey frame");
  if (half.type() != CV_8UC1 || half.cols != frame.cols / 2 || half.rows != frame.rows / 2) {
    core::ThrowInvalidInput("templates: the half-resolution frame does not match the frame");
  }
  // Rectangles start on even pixels and have even sizes, so they map exactly onto the
  // half-resolution frame the coarse search uses.
  const int b = (options.border_px + 1) & ~1;
  const auto texture_of = [&half](const cv::Rect& rect) {
    return TextureStrength(half(cv::Rect(rect.x / 2, rect.y / 2, rect.width / 2, rect.height / 2)));
  };
  std::vector<TemplateSpot> spots;
  if (options.mode == TemplateMode::kTiled) {
    const int w = ((frame.cols - 2 * b) / options.tile_cols) & ~1;
    const int h = ((frame.rows - 2 * b) / options.tile_rows) & ~1;
    if (w < 16 || h < 16) core::ThrowInvalidInput("templates: the frame is too small for the tile grid");
    for (int r = 0; r < options.tile_rows; ++r) {
      for (int c = 0; c < options.tile_cols; ++c) {
        const cv::Rect rect(b + c * w, b + r * h, w, h);
        const double texture = texture_of(rect);
        if (texture >= options.min_texture) spots.push_back({rect, texture});
      }
    }
    return spots;
  }

  const int s = options.size_px & ~1;
  if (s + 2 * b > frame.cols || s + 2 * b > frame.rows) {
    core::ThrowInvalidInput("templates: size_px " + std::to_string(s) + " does not fit in a " +
                            std::to_string(frame.cols) + "x" + std::to_string(frame.rows) + " frame");
  }
  // Structure tensor of the frame at quarter resolution (enough to rank windows; the
  // threshold below is checked at half resolution), box-averaged over template-size windows
  // at an eighth of the frame's resolution: the tensor of a window is the mean of its cells.
  constexpr int kCell = 2;  // quarter-resolution pixels per cell = 8 frame pixels
  const int k = std::max(1, s / (4 * kCell));
  thread_local cv::Mat eigen;  // reused frame to frame
  if (half.cols % 4 == 0 && half.rows % 4 == 0) {
    detail::RankingMap(half, k, &eigen);
  } else {
    detail::RankingMapOpenCv(half, k, &eigen);
  }
  const cv::Size cells = eigen.size();

  constexpr int kStep = 4 * kCell;  // frame pixels between candidate corners
  const cv::Size grid = CellGrid(options.count, frame.cols, frame.rows);
  const int max_x = (frame.cols - b - s) & ~1;
  const int max_y = (frame.rows - b - s) & ~1;
  for (int gr = 0; gr < grid.height; ++gr) {
    for (int gc = 0; gc < grid.width; ++gc) {
      if (gr * grid.width + gc >= options.count) break;
      // Template corners whose centre lies in this cell.
      const int cx0 = gc * frame.cols / grid.width, cx1 = (gc + 1) * frame.cols / grid.width;
      const int cy0 = gr * frame.rows / grid.height, cy1 = (gr + 1) * frame.rows / grid.height;
      const int x_lo = std::clamp(cx0 - s / 2, b, max_x), x_hi = std::clamp(cx1 - s / 2, b, max_x);
      const int y_lo = std::clamp(cy0 - s / 2, b, max_y), y_hi = std::clamp(cy1 - s / 2, b, max_y);
      // Neighbouring cells share their boundary corners: a window more than half covered by
      // one already chosen adds no geometry (a frame textured in one spot would otherwise give
      // the same window from every cell, and a pose whose yaw nothing determines).
      const auto taken = [&spots, s](int x, int y) {
        const cv::Rect candidate(x, y, s, s);
        for (const TemplateSpot& spot : spots) {
          if ((candidate & spot.rect).area() * 2 > candidate.area()) return true;
        }
        return false;
      };
      double best = -1.0;
      cv::Point best_at(-1, -1);
      for (int y = y_lo; y <= y_hi; y += kStep) {
        for (int x = x_lo; x <= x_hi; x += kStep) {
          const int sx = std::min(x / kStep, cells.width - 1), sy = std::min(y / kStep, cells.height - 1);
          const double e = eigen.at<double>(sy, sx);
          if (e > best && !taken(x & ~1, y & ~1)) {
            best = e;
            best_at = {x & ~1, y & ~1};
          }
        }
      }
      if (best_at.x < 0) continue;  // every window of the cell is taken
      const cv::Rect rect(best_at.x, best_at.y, s, s);
      const double texture = texture_of(rect);
      if (texture >= options.min_texture) spots.push_back({rect, texture});
    }
  }
  return spots;
}

}  // namespace mosaicloc::tracking
