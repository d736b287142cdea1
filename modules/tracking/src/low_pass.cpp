#include "low_pass.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "simd.hpp"

namespace mosaicloc::tracking::detail {
namespace {

constexpr int kMaxRadius = 15;  // sigma <= 5 px (the options' limit)

// The kernel is symmetric, k[i] = k[2R - i]: each output is
//   k[R] p[x + R] + sum_{i < R} k[i] (p[x + i] + p[x + 2R - i]),
// half the multiplications. With R fixed at compile time the tap loop unrolls and the loop
// over x vectorizes. The horizontal pass computes its rows in whole blocks of kBlock outputs
// (a row of the buffer is rounded up to a multiple of kBlock) and the vertical pass computes
// a row's last partial block whole: no output goes through the scalar remainder loop, which at
// the tracker's 50-130 px windows cost a good part of the vector loop's time.
constexpr int kBlock = 8;

int RoundUpToBlock(int n) { return (n + kBlock - 1) / kBlock * kBlock; }

// n outputs, a multiple of kBlock (so the vector loop leaves no remainder); p holds n + 2R values.
template <int R>
MOSAICLOC_ALWAYS_INLINE void FilterRow(const float* __restrict p, const std::array<float, R + 1>& k,
                                       float* __restrict out, int n) {
  for (int x = 0; x < n; ++x) {
    float s = k[R] * p[x + R];
    for (int i = 0; i < R; ++i) s += k[i] * (p[x + i] + p[x + 2 * R - i]);
    out[x] = s;
  }
}

template <int R>
MOSAICLOC_ALWAYS_INLINE void FilterColumnsBlock(const std::array<const float*, 2 * R + 1>& rows, int x0,
                                                const std::array<float, R + 1>& k, float* __restrict out) {
  for (int x = 0; x < kBlock; ++x) {
    float s = k[R] * rows[R][x0 + x];
    for (int i = 0; i < R; ++i) s += k[i] * (rows[i][x0 + x] + rows[2 * R - i][x0 + x]);
    out[x] = s;
  }
}

// n outputs; the rows hold RoundUpToBlock(n) values each. A last partial block is computed
// whole into a local block and only its first outputs are kept.
template <int R>
MOSAICLOC_ALWAYS_INLINE void FilterColumns(const std::array<const float*, 2 * R + 1>& rows,
                                           const std::array<float, R + 1>& k, float* __restrict out, int n) {
  const int whole = n / kBlock * kBlock;
  for (int x = 0; x < whole; ++x) {
    float s = k[R] * rows[R][x];
    for (int i = 0; i < R; ++i) s += k[i] * (rows[i][x] + rows[2 * R - i][x]);
    out[x] = s;
  }
  if (whole < n) {
    alignas(32) float tail[kBlock];
    FilterColumnsBlock<R>(rows, whole, k, tail);
    for (int x = whole; x < n; ++x) out[x] = tail[x - whole];
  }
}

// Per-thread buffers: the tracker filters several windows a frame.
struct Buffers {
  std::vector<std::uint8_t> bytes;
  std::vector<float> padded, horizontal, line;
};

// The conversion of a padded row to float runs over a multiple of this many pixels: the
// vector loop converts 32 bytes at a time, and its scalar remainder cost more than the rest.
constexpr int kConvertBlock = 32;

// Output pixel (x, y) of `dst` is the filtered src pixel (rect.x + x, rect.y + y); src's own
// edges are replicated. Only the src rows and columns within R of `rect` are read.
template <int R>
MOSAICLOC_ALWAYS_INLINE void FilterBody(const cv::Mat& src, const cv::Rect& rect, cv::Mat& dst,
                                        const std::array<float, R + 1>& k, Buffers& b) {
  const int cols = rect.width;
  // Rows of the horizontal pass are computed, and stored, in whole blocks: `stride` outputs.
  const int stride = RoundUpToBlock(cols);
  const int first = std::max(rect.y - R, 0), last = std::min(rect.y + rect.height - 1 + R, src.rows - 1);
  // Only ever grown: resizing down and up again zero-fills the regrown part on every call.
  const auto grow = [](auto& v, std::size_t size) {
    if (v.size() < size) v.resize(size);
  };
  const int converted = (stride + 2 * R + kConvertBlock - 1) / kConvertBlock * kConvertBlock;
  grow(b.bytes, static_cast<std::size_t>(converted));
  grow(b.padded, static_cast<std::size_t>(converted));
  grow(b.horizontal, static_cast<std::size_t>(stride) * static_cast<std::size_t>(last - first + 1));
  grow(b.line, static_cast<std::size_t>(stride));
  // Padded row i is src column rect.x - R + i, clamped to the image; the values past
  // cols + 2R only feed outputs past cols, which are never read out.
  const int left = std::clamp(R - rect.x, 0, cols + 2 * R);
  const int right = std::clamp(src.cols - (rect.x - R), left, cols + 2 * R);
  const int shift = rect.x - R;
  for (int y = first; y <= last; ++y) {
    const std::uint8_t* s = src.ptr<std::uint8_t>(y);
    std::uint8_t* q = b.bytes.data();
    std::memset(q, s[0], static_cast<std::size_t>(left));
    std::memcpy(q + left, s + left + shift, static_cast<std::size_t>(right - left));
    std::memset(q + right, q[right - 1], static_cast<std::size_t>(converted - right));
    float* p = b.padded.data();
    for (int i = 0; i < converted; ++i) p[i] = q[i];
    FilterRow<R>(p, k, b.horizontal.data() + static_cast<std::size_t>(y - first) * stride, stride);
  }
  for (int y = 0; y < rect.height; ++y) {
    std::array<const float*, 2 * R + 1> taps{};
    const int top = rect.y + y - R;
    if (top >= first && top + 2 * R <= last) {
      // Away from the image's top and bottom (nearly every row): consecutive rows, no clamps.
      const float* base = b.horizontal.data() + static_cast<std::size_t>(top - first) * stride;
      for (int i = 0; i <= 2 * R; ++i) taps[static_cast<std::size_t>(i)] = base + static_cast<std::size_t>(i) * stride;
    } else {
      for (int i = 0; i <= 2 * R; ++i) {
        const int from = std::clamp(top + i, first, last);
        taps[static_cast<std::size_t>(i)] = b.horizontal.data() + static_cast<std::size_t>(from - first) * stride;
      }
    }
    if (dst.depth() == CV_32F) {
      FilterColumns<R>(taps, k, dst.ptr<float>(y), cols);
      continue;
    }
    FilterColumns<R>(taps, k, b.line.data(), cols);
    std::uint8_t* out = dst.ptr<std::uint8_t>(y);
    const float* v = b.line.data();
    // The kernel is positive and sums to 1, so v is in [0, 255] up to float rounding.
    for (int x = 0; x < cols; ++x) out[x] = static_cast<std::uint8_t>(std::min(v[x] + 0.5F, 255.0F));
  }
}

template <int R>
void FilterBaseline(const cv::Mat& src, const cv::Rect& rect, cv::Mat& dst, const std::array<float, R + 1>& k,
                    Buffers& b) {
  FilterBody<R>(src, rect, dst, k, b);
}

#ifdef MOSAICLOC_TRACKING_AVX2
template <int R>
MOSAICLOC_TARGET_AVX2 void FilterAvx2(const cv::Mat& src, const cv::Rect& rect, cv::Mat& dst,
                                      const std::array<float, R + 1>& k, Buffers& b) {
  FilterBody<R>(src, rect, dst, k, b);
}
#endif

template <int R>
void Filter(const cv::Mat& src, const cv::Rect& rect, cv::Mat& dst, double sigma_px) {
  // The kernel of the last sigma, per thread: the tracker filters with one or two sigmas.
  thread_local double kernel_sigma = -1.0;
  thread_local std::array<float, R + 1> k{};
  if (sigma_px != kernel_sigma) {
    const cv::Mat kernel = cv::getGaussianKernel(2 * R + 1, sigma_px, CV_64F);
    for (int i = 0; i <= R; ++i) k[static_cast<std::size_t>(i)] = static_cast<float>(kernel.at<double>(i));
    kernel_sigma = sigma_px;
  }
  thread_local Buffers buffers;
#ifdef MOSAICLOC_TRACKING_AVX2
  if (UseAvx2()) {
    FilterAvx2<R>(src, rect, dst, k, buffers);
    return;
  }
#endif
  FilterBaseline<R>(src, rect, dst, k, buffers);
}

template <int R>
void Dispatch(const cv::Mat& src, const cv::Rect& rect, cv::Mat& dst, double sigma_px, int radius) {
  if constexpr (R <= kMaxRadius) {
    if (radius == R) {
      Filter<R>(src, rect, dst, sigma_px);
    } else {
      Dispatch<R + 1>(src, rect, dst, sigma_px, radius);
    }
  }
}

}  // namespace

int LowPassRadius(double sigma_px) { return sigma_px > 0.0 ? static_cast<int>(std::ceil(3.0 * sigma_px)) : 0; }

void GaussianLowPass(const cv::Mat& src, cv::Mat& dst, double sigma_px, int depth) {
  GaussianLowPassRect(src, cv::Rect(0, 0, src.cols, src.rows), dst, sigma_px, depth);
}

void GaussianLowPassRect(const cv::Mat& src, const cv::Rect& rect, cv::Mat& dst, double sigma_px, int depth) {
  if (src.empty() || src.type() != CV_8UC1) core::ThrowInvalidInput("low-pass: expected a non-empty 8-bit grey image");
  if (depth != CV_8U && depth != CV_32F) core::ThrowInvalidInput("low-pass: the result is 8-bit or float");
  if (rect.width <= 0 || rect.height <= 0 || (rect & cv::Rect(0, 0, src.cols, src.rows)) != rect) {
    core::ThrowInvalidInput("low-pass: the rectangle is not inside the image");
  }
  const int radius = LowPassRadius(sigma_px);
  if (radius > kMaxRadius) core::ThrowInvalidInput("low-pass: sigma must be <= 5 px");
  if (dst.data == src.data) dst.release();
  dst.create(rect.size(), CV_MAKETYPE(depth, 1));
  if (radius == 0) {
    src(rect).convertTo(dst, depth);
    return;
  }
  Dispatch<1>(src, rect, dst, sigma_px, radius);
}

cv::Mat ScratchImage(cv::Mat& store, cv::Size size, int type) {
  if (store.type() != type || store.cols < size.width || store.rows < size.height) {
    store.create(std::max(store.type() == type ? store.rows : 0, size.height),
                 std::max(store.type() == type ? store.cols : 0, size.width), type);
  }
  return store(cv::Rect(0, 0, size.width, size.height));
}

}  // namespace mosaicloc::tracking::detail
