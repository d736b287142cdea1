#include "binary_erode.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::tracking::detail {

void ErodeBinary(const cv::Mat& mask, const cv::Mat& element, cv::Mat* out) {
  if (mask.type() != CV_8UC1 || element.type() != CV_8UC1 || element.rows % 2 == 0 || element.cols % 2 == 0) {
    core::ThrowInvalidInput("erode: expected an 8-bit mask and an 8-bit element of odd size");
  }
  const int cx = element.cols / 2, cy = element.rows / 2;
  // Each element row's half-width, -1 for an empty row.
  std::vector<int> half(static_cast<std::size_t>(element.rows), -1);
  for (int r = 0; r < element.rows; ++r) {
    const std::uint8_t* e = element.ptr<std::uint8_t>(r);
    int first = -1, last = -1;
    for (int c = 0; c < element.cols; ++c) {
      if (e[c] == 0) continue;
      if (first < 0) first = c;
      if (last >= 0 && last != c - 1) core::ThrowInvalidInput("erode: an element row is not one run");
      last = c;
    }
    if (first < 0) continue;
    if (cx - first != last - cx) core::ThrowInvalidInput("erode: an element row is not centred");
    half[static_cast<std::size_t>(r)] = cx - first;
  }
  const int rows = mask.rows, cols = mask.cols;
  // reach(y, x): the largest w with mask row y set over [x - w, x + w] (outside counts as set),
  // -1 where the pixel itself is not set.
  constexpr std::int16_t kFar = std::numeric_limits<std::int16_t>::max();
  const auto clamp16 = [](int v) { return static_cast<std::int16_t>(std::min<int>(v, kFar)); };
  cv::Mat reach(rows, cols, CV_16SC1);
  std::vector<int> left(static_cast<std::size_t>(cols));
  for (int y = 0; y < rows; ++y) {
    const std::uint8_t* m = mask.ptr<std::uint8_t>(y);
    auto* h = reach.ptr<std::int16_t>(y);
    // Set pixels to the left of x, x included; the run that starts at the border is unbounded.
    int run = kFar;
    for (int x = 0; x < cols; ++x) {
      run = m[x] != 0 ? (run >= kFar ? kFar : run + 1) : 0;
      left[static_cast<std::size_t>(x)] = run;
    }
    run = kFar;
    for (int x = cols - 1; x >= 0; --x) {
      run = m[x] != 0 ? (run >= kFar ? kFar : run + 1) : 0;
      h[x] = clamp16(std::min(left[static_cast<std::size_t>(x)], run) - 1);
    }
  }
  out->create(rows, cols, CV_8UC1);
  // margin[x]: the least, over the element's rows, of how much wider the set run about x is than
  // the row needs; the element fits where it is not negative.
  std::vector<std::int16_t> margin(static_cast<std::size_t>(cols));
  for (int y = 0; y < rows; ++y) {
    std::fill(margin.begin(), margin.end(), kFar);
    std::int16_t* g = margin.data();
    for (int r = 0; r < element.rows; ++r) {
      const auto w = static_cast<std::int16_t>(half[static_cast<std::size_t>(r)]);
      const int yy = y + r - cy;
      if (w < 0 || yy < 0 || yy >= rows) continue;  // outside counts as set
      const auto* h = reach.ptr<std::int16_t>(yy);
      for (int x = 0; x < cols; ++x) g[x] = std::min(g[x], static_cast<std::int16_t>(h[x] - w));
    }
    std::uint8_t* o = out->ptr<std::uint8_t>(y);
    for (int x = 0; x < cols; ++x) o[x] = g[x] >= 0 ? 255 : 0;
  }
}

}  // namespace mosaicloc::tracking::detail
