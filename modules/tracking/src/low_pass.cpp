#include "low_pass.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::tracking::detail {
namespace {

constexpr int kMaxRadius = 15;  // sigma <= 5 px (the options' limit)

// The kernel is symmetric, k[i] = k[2R - i]: each output is
//   k[R] p[x + R] + sum_{i < R} k[i] (p[x + i] + p[x + 2R - i]),
// half the multiplications. With R fixed at compile time the tap loop unrolls and the loop
// over x vectorizes.
template <int R>
void FilterRow(const float* __restrict p, const std::array<float, R + 1>& k, float* __restrict out, int n) {
  for (int x = 0; x < n; ++x) {
    float s = k[R] * p[x + R];
    for (int i = 0; i < R; ++i) s += k[i] * (p[x + i] + p[x + 2 * R - i]);
    out[x] = s;
  }
}

template <int R>
void FilterColumns(const std::array<const float*, 2 * R + 1>& rows, const std::array<float, R + 1>& k,
                   float* __restrict out, int n) {
  for (int x = 0; x < n; ++x) {
    float s = k[R] * rows[R][x];
    for (int i = 0; i < R; ++i) s += k[i] * (rows[i][x] + rows[2 * R - i][x]);
    out[x] = s;
  }
}

template <int R>
void Filter(const cv::Mat& src, cv::Mat& dst, double sigma_px) {
  // The kernel of the last sigma, per thread: the tracker filters with one or two sigmas.
  thread_local double kernel_sigma = -1.0;
  thread_local std::array<float, R + 1> k{};
  if (sigma_px != kernel_sigma) {
    const cv::Mat kernel = cv::getGaussianKernel(2 * R + 1, sigma_px, CV_64F);
    for (int i = 0; i <= R; ++i) k[static_cast<std::size_t>(i)] = static_cast<float>(kernel.at<double>(i));
    kernel_sigma = sigma_px;
  }
  const int cols = src.cols, rows = src.rows;
  // Per-thread buffers: the tracker filters several windows a frame.
  thread_local std::vector<float> padded, horizontal, line;
  padded.resize(static_cast<std::size_t>(cols + 2 * R));
  horizontal.resize(static_cast<std::size_t>(cols) * rows);
  line.resize(static_cast<std::size_t>(cols));
  for (int y = 0; y < rows; ++y) {
    const std::uint8_t* s = src.ptr<std::uint8_t>(y);
    float* p = padded.data();
    for (int i = 0; i < R; ++i) {
      p[i] = s[0];
      p[R + cols + i] = s[cols - 1];
    }
    for (int x = 0; x < cols; ++x) p[R + x] = s[x];
    FilterRow<R>(p, k, horizontal.data() + static_cast<std::size_t>(y) * cols, cols);
  }
  for (int y = 0; y < rows; ++y) {
    std::array<const float*, 2 * R + 1> taps{};
    for (int i = 0; i <= 2 * R; ++i) {
      const int from = std::clamp(y - R + i, 0, rows - 1);
      taps[static_cast<std::size_t>(i)] = horizontal.data() + static_cast<std::size_t>(from) * cols;
    }
    if (dst.depth() == CV_32F) {
      FilterColumns<R>(taps, k, dst.ptr<float>(y), cols);
      continue;
    }
    FilterColumns<R>(taps, k, line.data(), cols);
    std::uint8_t* out = dst.ptr<std::uint8_t>(y);
    const float* v = line.data();
    // The kernel is positive and sums to 1, so v is in [0, 255] up to float rounding.
    for (int x = 0; x < cols; ++x) out[x] = static_cast<std::uint8_t>(std::min(v[x] + 0.5F, 255.0F));
  }
}

template <int R>
void Dispatch(const cv::Mat& src, cv::Mat& dst, double sigma_px, int radius) {
  if constexpr (R <= kMaxRadius) {
    if (radius == R) {
      Filter<R>(src, dst, sigma_px);
    } else {
      Dispatch<R + 1>(src, dst, sigma_px, radius);
    }
  }
}

}  // namespace

int LowPassRadius(double sigma_px) { return sigma_px > 0.0 ? static_cast<int>(std::ceil(3.0 * sigma_px)) : 0; }

void GaussianLowPass(const cv::Mat& src, cv::Mat& dst, double sigma_px, int depth) {
  if (src.empty() || src.type() != CV_8UC1) core::ThrowInvalidInput("low-pass: expected a non-empty 8-bit grey image");
  if (depth != CV_8U && depth != CV_32F) core::ThrowInvalidInput("low-pass: the result is 8-bit or float");
  const int radius = LowPassRadius(sigma_px);
  if (radius > kMaxRadius) core::ThrowInvalidInput("low-pass: sigma must be <= 5 px");
  if (dst.data == src.data) dst.release();
  dst.create(src.size(), CV_MAKETYPE(depth, 1));
  if (radius == 0) {
    src.convertTo(dst, depth);
    return;
  }
  Dispatch<1>(src, dst, sigma_px, radius);
}

cv::Mat ScratchImage(cv::Mat& store, cv::Size size, int type) {
  if (store.type() != type || store.cols < size.width || store.rows < size.height) {
    store.create(std::max(store.type() == type ? store.rows : 0, size.height),
                 std::max(store.type() == type ? store.cols : 0, size.width), type);
  }
  return store(cv::Rect(0, 0, size.width, size.height));
}

}  // namespace mosaicloc::tracking::detail
