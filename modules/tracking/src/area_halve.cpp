#include "area_halve.hpp"

#include <cstdint>

#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "simd.hpp"

#ifdef MOSAICLOC_TRACKING_AVX2
#include <immintrin.h>
#endif

namespace mosaicloc::tracking::detail {
namespace {

MOSAICLOC_ALWAYS_INLINE std::uint8_t AreaAt(const std::uint8_t* a, const std::uint8_t* b, int j) {
  return static_cast<std::uint8_t>((a[2 * j] + a[2 * j + 1] + b[2 * j] + b[2 * j + 1] + 2) >> 2);
}

void HalveRowFrom(const std::uint8_t* a, const std::uint8_t* b, int begin, int n, std::uint8_t* out) {
  for (int j = begin; j < n; ++j) out[j] = AreaAt(a, b, j);
}

void HalveRow(const std::uint8_t* a, const std::uint8_t* b, int n, std::uint8_t* out) { HalveRowFrom(a, b, 0, n, out); }

#ifdef MOSAICLOC_TRACKING_AVX2
MOSAICLOC_TARGET_AVX2 MOSAICLOC_ALWAYS_INLINE __m256i PairSums(const std::uint8_t* a, const std::uint8_t* b) {
  // maddubs with ones: 16-bit lane j is the sum of bytes 2j and 2j + 1 (at most 510).
  const __m256i ones = _mm256_set1_epi8(1);
  return _mm256_add_epi16(_mm256_maddubs_epi16(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(a)), ones),
                          _mm256_maddubs_epi16(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(b)), ones));
}

MOSAICLOC_TARGET_AVX2 void HalveRowAvx2(const std::uint8_t* a, const std::uint8_t* b, int n, std::uint8_t* out) {
  const __m256i two = _mm256_set1_epi16(2);
  int j = 0;
  for (; j + 32 <= n; j += 32) {
    const __m256i low = _mm256_srli_epi16(_mm256_add_epi16(PairSums(a + 2 * j, b + 2 * j), two), 2);
    const __m256i high = _mm256_srli_epi16(_mm256_add_epi16(PairSums(a + 2 * j + 32, b + 2 * j + 32), two), 2);
    // packus interleaves the 128-bit halves of its operands; the permute puts them in order.
    const __m256i packed = _mm256_permute4x64_epi64(_mm256_packus_epi16(low, high), _MM_SHUFFLE(3, 1, 2, 0));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + j), packed);
  }
  HalveRowFrom(a, b, j, n, out);
}
#endif

}  // namespace

void HalveImage(const cv::Mat& src, cv::Mat& dst) {
  if (src.type() != CV_8UC1 || src.cols < 2 || src.rows < 2) {
    core::ThrowInvalidInput("halve: expected an 8-bit grey image of at least 2x2 pixels");
  }
  if (src.cols % 2 != 0 || src.rows % 2 != 0) {
    cv::resize(src, dst, cv::Size(src.cols / 2, src.rows / 2), 0, 0, cv::INTER_AREA);
    return;
  }
  dst.create(src.rows / 2, src.cols / 2, CV_8UC1);
  auto* halve_row = &HalveRow;
#ifdef MOSAICLOC_TRACKING_AVX2
  if (UseAvx2()) halve_row = &HalveRowAvx2;
#endif
  for (int y = 0; y < dst.rows; ++y) {
    halve_row(src.ptr<std::uint8_t>(2 * y), src.ptr<std::uint8_t>(2 * y + 1), dst.cols, dst.ptr<std::uint8_t>(y));
  }
}

}  // namespace mosaicloc::tracking::detail
