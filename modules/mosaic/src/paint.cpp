#include "paint.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#if defined(__x86_64__)
#include <immintrin.h>
#define MOSAICLOC_PAINT_AVX2 1
#endif

namespace mosaicloc::mosaic::internal {
namespace {

// The cubic convolution kernel at fractional offset x, with Keys' A = -0.5 (Catmull-Rom): the
// one value of A for which interpolation reproduces a linear ramp exactly. OpenCV's -0.75
// samples a ramp at x + 0.5 phi (1 - phi) (1 - 2 phi) instead (up to 0.048 px), a shift that
// averages out over the frames painting a pixel only where they land at spread phases; where
// a drive's yaw holds still they land at one phase, and the map's texture was shifted by up to
// 0.03 px, swinging every 166 mm: a rotation of 1.5e-4 rad to the tracker, whose fixes the
// filter's gate then refused.
constexpr float kA = -0.5f;
// Weights below this (pixels) paint nothing: a position computed in float that should lie
// exactly on the zero of the tent must not mark a pixel mapped.
constexpr float kMinWeight = 1e-3f;
void Cubic(float x, float k[4]) {
  k[0] = ((kA * (x + 1.f) - 5.f * kA) * (x + 1.f) + 8.f * kA) * (x + 1.f) - 4.f * kA;
  k[1] = ((kA + 2.f) * x - (kA + 3.f)) * x * x + 1.f;
  k[2] = ((kA + 2.f) * (1.f - x) - (kA + 3.f)) * (1.f - x) * (1.f - x) + 1.f;
  k[3] = 1.f - k[0] - k[1] - k[2];
}

void PaintPixel(const PaintSource& source, float u, float v, float* pair, bool best_view) {
  const float weight = std::min(std::min(u + 1.f, static_cast<float>(source.width) - u),
                                std::min(v + 1.f, static_cast<float>(source.height) - v));
  if (!(weight > kMinWeight)) return;
  const float fu = std::floor(u), fv = std::floor(v);
  float kx[4], ky[4];
  Cubic(u - fu, kx);
  Cubic(v - fv, ky);
  // -1 < u < width: taps at columns floor(u) - 1 >= -2 .. floor(u) + 2 <= width + 1, inside
  // the border.
  const std::uint8_t* p =
      source.pixel00 + (static_cast<std::ptrdiff_t>(fv) - 1) * source.stride + (static_cast<std::ptrdiff_t>(fu) - 1);
  float value = 0.f;
  for (int j = 0; j < 4; ++j, p += source.stride) {
    value += ky[j] * (kx[0] * p[0] + kx[1] * p[1] + kx[2] * p[2] + kx[3] * p[3]);
  }
  if (!best_view) {
    pair[0] += value * weight;
    pair[1] += weight;
  } else if (weight > pair[1]) {
    pair[0] = value;
    pair[1] = weight;
  }
}

#ifdef MOSAICLOC_PAINT_AVX2
#define MOSAICLOC_AVX2_FMA __attribute__((target("avx2,fma")))

MOSAICLOC_AVX2_FMA inline void CubicAvx2(__m256 x, __m256 k[4]) {
  const __m256 a = _mm256_set1_ps(kA);
  const __m256 one = _mm256_set1_ps(1.f);
  const __m256 a2 = _mm256_set1_ps(kA + 2.f);
  const __m256 a3 = _mm256_set1_ps(kA + 3.f);
  const __m256 x1 = _mm256_add_ps(x, one);
  const __m256 t = _mm256_sub_ps(one, x);
  k[0] = _mm256_fmsub_ps(_mm256_fmadd_ps(_mm256_fmsub_ps(a, x1, _mm256_set1_ps(5.f * kA)), x1, _mm256_set1_ps(8.f * kA)),
                         x1, _mm256_set1_ps(4.f * kA));
  k[1] = _mm256_fmadd_ps(_mm256_mul_ps(_mm256_fmsub_ps(a2, x, a3), x), x, one);
  k[2] = _mm256_fmadd_ps(_mm256_mul_ps(_mm256_fmsub_ps(a2, t, a3), t), t, one);
  k[3] = _mm256_sub_ps(_mm256_sub_ps(_mm256_sub_ps(one, k[0]), k[1]), k[2]);
}

// Eight pixels at a time: one 32-bit load per tap row gives its four horizontal taps.
MOSAICLOC_AVX2_FMA int PaintRowAvx2(const PaintSource& source, float u0, float v0, float du, float dv, int count,
                                    float* accumulator, bool best_view) {
  const __m256 lane = _mm256_setr_ps(0.f, 1.f, 2.f, 3.f, 4.f, 5.f, 6.f, 7.f);
  const __m256 one = _mm256_set1_ps(1.f);
  const __m256 right = _mm256_set1_ps(static_cast<float>(source.width));
  const __m256 bottom = _mm256_set1_ps(static_cast<float>(source.height));
  const __m256i bytes = _mm256_set1_epi32(0xff);
  const int stride = static_cast<int>(source.stride);
  int i = 0;
  for (; i + 8 <= count; i += 8) {
    const __m256 x = _mm256_add_ps(_mm256_set1_ps(static_cast<float>(i)), lane);
    __m256 u = _mm256_fmadd_ps(x, _mm256_set1_ps(du), _mm256_set1_ps(u0));
    __m256 v = _mm256_fmadd_ps(x, _mm256_set1_ps(dv), _mm256_set1_ps(v0));
    __m256 weight = _mm256_min_ps(_mm256_min_ps(_mm256_add_ps(u, one), _mm256_sub_ps(right, u)),
                                  _mm256_min_ps(_mm256_add_ps(v, one), _mm256_sub_ps(bottom, v)));
    const __m256 inside = _mm256_cmp_ps(weight, _mm256_set1_ps(kMinWeight), _CMP_GT_OQ);
    if (_mm256_movemask_ps(inside) == 0) continue;
    weight = _mm256_and_ps(weight, inside);
    u = _mm256_and_ps(u, inside);  // lanes outside the frame read pixel (0, 0) and paint 0
    v = _mm256_and_ps(v, inside);
    const __m256 fu = _mm256_floor_ps(u), fv = _mm256_floor_ps(v);
    __m256 kx[4], ky[4];
    CubicAvx2(_mm256_sub_ps(u, fu), kx);
    CubicAvx2(_mm256_sub_ps(v, fv), ky);
    const __m256i offset = _mm256_add_epi32(
        _mm256_mullo_epi32(_mm256_sub_epi32(_mm256_cvttps_epi32(fv), _mm256_set1_epi32(1)), _mm256_set1_epi32(stride)),
        _mm256_sub_epi32(_mm256_cvttps_epi32(fu), _mm256_set1_epi32(1)));
    alignas(32) int offsets[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(offsets), offset);
    __m256 value = _mm256_setzero_ps();
    for (int j = 0; j < 4; ++j) {
      int quads[8];
      for (int k = 0; k < 8; ++k) std::memcpy(&quads[k], source.pixel00 + offsets[k] + j * stride, 4);
      const __m256i q = _mm256_setr_epi32(quads[0], quads[1], quads[2], quads[3], quads[4], quads[5], quads[6], quads[7]);
      __m256 row = _mm256_mul_ps(kx[0], _mm256_cvtepi32_ps(_mm256_and_si256(q, bytes)));
      row = _mm256_fmadd_ps(kx[1], _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(q, 8), bytes)), row);
      row = _mm256_fmadd_ps(kx[2], _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(q, 16), bytes)), row);
      row = _mm256_fmadd_ps(kx[3], _mm256_cvtepi32_ps(_mm256_srli_epi32(q, 24)), row);
      value = _mm256_fmadd_ps(ky[j], row, value);
    }
    // Interleave (a, b) of the eight pixels as the accumulator stores them.
    const __m256 a = best_view ? value : _mm256_mul_ps(value, weight);
    const __m256 low = _mm256_unpacklo_ps(a, weight);   // pixels 0 1 | 4 5
    const __m256 high = _mm256_unpackhi_ps(a, weight);  // pixels 2 3 | 6 7
    const __m256 first = _mm256_permute2f128_ps(low, high, 0x20);
    const __m256 second = _mm256_permute2f128_ps(low, high, 0x31);
    float* pair = accumulator + 2 * i;
    const __m256 old_first = _mm256_loadu_ps(pair);
    const __m256 old_second = _mm256_loadu_ps(pair + 8);
    if (!best_view) {
      _mm256_storeu_ps(pair, _mm256_add_ps(old_first, first));
      _mm256_storeu_ps(pair + 8, _mm256_add_ps(old_second, second));
    } else {
      // Replace a pair where its weight (odd element) is larger.
      const __m256 take_first = _mm256_permute_ps(_mm256_cmp_ps(first, old_first, _CMP_GT_OQ), 0xF5);
      const __m256 take_second = _mm256_permute_ps(_mm256_cmp_ps(second, old_second, _CMP_GT_OQ), 0xF5);
      _mm256_storeu_ps(pair, _mm256_blendv_ps(old_first, first, take_first));
      _mm256_storeu_ps(pair + 8, _mm256_blendv_ps(old_second, second, take_second));
    }
  }
  return i;
}

bool HaveAvx2Fma() {
  static const bool have = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return have;
}
#endif

}  // namespace

void PaintRow(const PaintSource& source, double u0, double v0, double du, double dv, int count, float* accumulator,
              bool best_view) {
  int i = 0;
#ifdef MOSAICLOC_PAINT_AVX2
  if (HaveAvx2Fma()) {
    i = PaintRowAvx2(source, static_cast<float>(u0), static_cast<float>(v0), static_cast<float>(du),
                     static_cast<float>(dv), count, accumulator, best_view);
  }
#endif
  for (; i < count; ++i) {
    PaintPixel(source, static_cast<float>(u0 + du * i), static_cast<float>(v0 + dv * i), accumulator + 2 * i, best_view);
  }
}

void PaintRowProjective(const PaintSource& source, double u0, double v0, double w0, double du, double dv, double dw,
                        int count, float* accumulator, bool best_view) {
  for (int i = 0; i < count; ++i) {
    const double w = w0 + dw * i;
    if (!(w > 0.0)) continue;
    PaintPixel(source, static_cast<float>((u0 + du * i) / w), static_cast<float>((v0 + dv * i) / w),
               accumulator + 2 * i, best_view);
  }
}

}  // namespace mosaicloc::mosaic::internal
