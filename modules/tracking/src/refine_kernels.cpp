#include "refine_kernels.hpp"

#include "simd.hpp"

#ifdef MOSAICLOC_TRACKING_AVX2
#include <immintrin.h>
#endif

namespace mosaicloc::tracking::detail {
namespace {

// Partial sums in four lanes: lane l takes the terms k = 4j + l of the first n - n % 4, the
// lanes are combined as (l0 + l1) + (l2 + l3), and the last n % 4 terms follow in order. The
// plain and AVX2 builds both sum in this order, so they agree bit for bit; four independent
// chains also keep the additions' latency off the critical path.
struct Lanes {
  double v[4] = {0.0, 0.0, 0.0, 0.0};
  double Total() const { return (v[0] + v[1]) + (v[2] + v[3]); }
};

// The bilinear sample of the float raster `pixels` (row stride `stride`, point (x, y) at
// pixel (x - offset_x, y - offset_y)) at the template point (bx, by) + (tx, ty), in double
// precision; the point is known to be inside.
MOSAICLOC_ALWAYS_INLINE double SampleAt(double bx, double by, double tx, double ty, const float* pixels,
                                        std::ptrdiff_t stride, int offset_x, int offset_y) {
  const double x = bx + tx, y = by + ty;
  const int ix = static_cast<int>(x), iy = static_cast<int>(y);  // x, y > 0 by the margin
  const float* p0 = pixels + static_cast<std::ptrdiff_t>(iy - offset_y) * stride + (ix - offset_x);
  const float* p1 = p0 + stride;
  const double fx = x - ix, fy = y - iy;
  const double top = p0[0] + fx * (p0[1] - p0[0]);
  const double bottom = p1[0] + fx * (p1[1] - p1[0]);
  return top + fy * (bottom - top);
}

// Adds the samples k0 <= k < n to the sums one after the other.
MOSAICLOC_ALWAYS_INLINE void AddSamples(const double* base_x, const double* base_y, const double* jac_x,
                                        const double* jac_y, const double* templ, std::size_t k0, std::size_t n,
                                        double tx, double ty, const float* pixels, std::ptrdiff_t stride,
                                        int offset_x, int offset_y, SampleSums* s) {
  for (std::size_t k = k0; k < n; ++k) {
    const double v = SampleAt(base_x[k], base_y[k], tx, ty, pixels, stride, offset_x, offset_y);
    s->sm += v;
    s->smm += v * v;
    s->sjxm += jac_x[k] * v;
    s->sjym += jac_y[k] * v;
    s->smt += v * templ[k];
  }
}

// The samples v_k of the template's points (x_k, y_k) + t, every one of them inside, and the
// five sums over them, in the lane order above.
void SumSamples(const double* base_x, const double* base_y, const double* jac_x, const double* jac_y,
                const double* templ, std::size_t n, double tx, double ty, const float* pixels, std::ptrdiff_t stride,
                int offset_x, int offset_y, SampleSums* sums) {
  Lanes m, mm, jxm, jym, mt;
  std::size_t k = 0;
  for (; k + 4 <= n; k += 4) {
    for (int l = 0; l < 4; ++l) {
      const double v = SampleAt(base_x[k + l], base_y[k + l], tx, ty, pixels, stride, offset_x, offset_y);
      m.v[l] += v;
      mm.v[l] += v * v;
      jxm.v[l] += jac_x[k + l] * v;
      jym.v[l] += jac_y[k + l] * v;
      mt.v[l] += v * templ[k + l];
    }
  }
  SampleSums s{m.Total(), mm.Total(), jxm.Total(), jym.Total(), mt.Total()};
  AddSamples(base_x, base_y, jac_x, jac_y, templ, k, n, tx, ty, pixels, stride, offset_x, offset_y, &s);
  *sums = s;
}

#ifdef MOSAICLOC_TRACKING_AVX2
MOSAICLOC_TARGET_AVX2 MOSAICLOC_ALWAYS_INLINE double LaneTotal(__m256d v) {
  alignas(32) double l[4];
  _mm256_store_pd(l, v);
  return (l[0] + l[1]) + (l[2] + l[3]);
}

// SumSamples four samples at a time: the same operations on each sample, one lane each.
MOSAICLOC_TARGET_AVX2 void SumSamplesAvx2(const double* base_x, const double* base_y, const double* jac_x,
                                          const double* jac_y, const double* templ, std::size_t n, double tx,
                                          double ty, const float* pixels, std::ptrdiff_t stride, int offset_x,
                                          int offset_y, SampleSums* sums) {
  const __m256d vtx = _mm256_set1_pd(tx), vty = _mm256_set1_pd(ty);
  const __m128i vstride = _mm_set1_epi32(static_cast<int>(stride));
  const __m128i shift = _mm_set1_epi32(static_cast<int>(offset_y * stride + offset_x));
  __m256d m = _mm256_setzero_pd(), mm = m, jxm = m, jym = m, mt = m;
  std::size_t k = 0;
  for (; k + 4 <= n; k += 4) {
    const __m256d x = _mm256_add_pd(_mm256_loadu_pd(base_x + k), vtx);
    const __m256d y = _mm256_add_pd(_mm256_loadu_pd(base_y + k), vty);
    const __m128i ix = _mm256_cvttpd_epi32(x), iy = _mm256_cvttpd_epi32(y);
    const __m256d fx = _mm256_sub_pd(x, _mm256_cvtepi32_pd(ix));
    const __m256d fy = _mm256_sub_pd(y, _mm256_cvtepi32_pd(iy));
    alignas(16) int at[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(at),
                    _mm_sub_epi32(_mm_add_epi32(_mm_mullo_epi32(iy, vstride), ix), shift));
    // (p00, p01) of samples 0 and 1, 2 and 3; the same one row down.
    __m128 top01 = _mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(pixels + at[0]));
    top01 = _mm_loadh_pi(top01, reinterpret_cast<const __m64*>(pixels + at[1]));
    __m128 top23 = _mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(pixels + at[2]));
    top23 = _mm_loadh_pi(top23, reinterpret_cast<const __m64*>(pixels + at[3]));
    __m128 bottom01 = _mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(pixels + at[0] + stride));
    bottom01 = _mm_loadh_pi(bottom01, reinterpret_cast<const __m64*>(pixels + at[1] + stride));
    __m128 bottom23 = _mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(pixels + at[2] + stride));
    bottom23 = _mm_loadh_pi(bottom23, reinterpret_cast<const __m64*>(pixels + at[3] + stride));
    const __m128 p00 = _mm_shuffle_ps(top01, top23, _MM_SHUFFLE(2, 0, 2, 0));
    const __m128 p01 = _mm_shuffle_ps(top01, top23, _MM_SHUFFLE(3, 1, 3, 1));
    const __m128 p10 = _mm_shuffle_ps(bottom01, bottom23, _MM_SHUFFLE(2, 0, 2, 0));
    const __m128 p11 = _mm_shuffle_ps(bottom01, bottom23, _MM_SHUFFLE(3, 1, 3, 1));
    const __m256d top = _mm256_add_pd(_mm256_cvtps_pd(p00), _mm256_mul_pd(fx, _mm256_cvtps_pd(_mm_sub_ps(p01, p00))));
    const __m256d bottom =
        _mm256_add_pd(_mm256_cvtps_pd(p10), _mm256_mul_pd(fx, _mm256_cvtps_pd(_mm_sub_ps(p11, p10))));
    const __m256d v = _mm256_add_pd(top, _mm256_mul_pd(fy, _mm256_sub_pd(bottom, top)));
    m = _mm256_add_pd(m, v);
    mm = _mm256_add_pd(mm, _mm256_mul_pd(v, v));
    jxm = _mm256_add_pd(jxm, _mm256_mul_pd(_mm256_loadu_pd(jac_x + k), v));
    jym = _mm256_add_pd(jym, _mm256_mul_pd(_mm256_loadu_pd(jac_y + k), v));
    mt = _mm256_add_pd(mt, _mm256_mul_pd(v, _mm256_loadu_pd(templ + k)));
  }
  SampleSums s{LaneTotal(m), LaneTotal(mm), LaneTotal(jxm), LaneTotal(jym), LaneTotal(mt)};
  AddSamples(base_x, base_y, jac_x, jac_y, templ, k, n, tx, ty, pixels, stride, offset_x, offset_y, &s);
  *sums = s;
}
#endif

// The samples k0 <= k < n of MomentsBody, added to the lanes' totals one after the other.
MOSAICLOC_ALWAYS_INLINE void MomentsTail(const double* t, std::size_t k0, std::size_t n, double a, double b,
                                         double* sum, double* sum_sq) {
  for (std::size_t k = k0; k < n; ++k) {
    a += t[k];
    b += t[k] * t[k];
  }
  *sum = a;
  *sum_sq = b;
}

// The template's set-up sums, in the lane order of SumSamples. The AVX2 builds below do the
// same operations on each lane, so the builds agree.
MOSAICLOC_ALWAYS_INLINE void MomentsBody(const double* t, std::size_t n, double* sum, double* sum_sq) {
  Lanes s, q;
  std::size_t k = 0;
  for (; k + 4 <= n; k += 4) {
    for (int l = 0; l < 4; ++l) {
      s.v[l] += t[k + l];
      q.v[l] += t[k + l] * t[k + l];
    }
  }
  MomentsTail(t, k, n, s.Total(), q.Total(), sum, sum_sq);
}


// The samples k0 <= k < n of NormaliseBody, added to the sums one after the other.
MOSAICLOC_ALWAYS_INLINE void NormaliseTail(double* templ, double* jac_x, double* jac_y, std::size_t k0,
                                           std::size_t n, double mean, double inv, NormalisedSums* s) {
  for (std::size_t k = k0; k < n; ++k) {
    const double t = (templ[k] - mean) * inv, jx = jac_x[k] * inv, jy = jac_y[k] * inv;
    templ[k] = t;
    jac_x[k] = jx;
    jac_y[k] = jy;
    s->jxjx += jx * jx;
    s->jxjy += jx * jy;
    s->jyjy += jy * jy;
    s->jx += jx;
    s->jy += jy;
    s->jxt += jx * t;
    s->jyt += jy * t;
  }
}

// T <- (T - mean) / sd, J <- J / sd (as products with 1 / sd), and the sums over them.
MOSAICLOC_ALWAYS_INLINE void NormaliseBody(double* __restrict templ, double* __restrict jac_x,
                                           double* __restrict jac_y, std::size_t n, double mean, double sd,
                                           NormalisedSums* out) {
  const double inv = 1.0 / sd;
  Lanes xx, xy, yy, x, y, xt, yt;
  std::size_t k = 0;
  for (; k + 4 <= n; k += 4) {
    for (int l = 0; l < 4; ++l) {
      const double t = (templ[k + l] - mean) * inv, jx = jac_x[k + l] * inv, jy = jac_y[k + l] * inv;
      templ[k + l] = t;
      jac_x[k + l] = jx;
      jac_y[k + l] = jy;
      xx.v[l] += jx * jx;
      xy.v[l] += jx * jy;
      yy.v[l] += jy * jy;
      x.v[l] += jx;
      y.v[l] += jy;
      xt.v[l] += jx * t;
      yt.v[l] += jy * t;
    }
  }
  NormalisedSums s{xx.Total(), xy.Total(), yy.Total(), x.Total(), y.Total(), xt.Total(), yt.Total()};
  NormaliseTail(templ, jac_x, jac_y, k, n, mean, inv, &s);
  *out = s;
}

void Moments(const double* t, std::size_t n, double* sum, double* sum_sq) { MomentsBody(t, n, sum, sum_sq); }
void Normalise(double* templ, double* jac_x, double* jac_y, std::size_t n, double mean, double sd,
               NormalisedSums* out) {
  NormaliseBody(templ, jac_x, jac_y, n, mean, sd, out);
}
#ifdef MOSAICLOC_TRACKING_AVX2
// The bodies above, one lane per vector element: the compiler's own vectorization of them
// shuffled the four lanes through memory and cost several times as much.
MOSAICLOC_TARGET_AVX2 void MomentsAvx2(const double* t, std::size_t n, double* sum, double* sum_sq) {
  __m256d s = _mm256_setzero_pd(), q = s;
  std::size_t k = 0;
  for (; k + 4 <= n; k += 4) {
    const __m256d v = _mm256_loadu_pd(t + k);
    s = _mm256_add_pd(s, v);
    q = _mm256_add_pd(q, _mm256_mul_pd(v, v));
  }
  MomentsTail(t, k, n, LaneTotal(s), LaneTotal(q), sum, sum_sq);
}

MOSAICLOC_TARGET_AVX2 void NormaliseAvx2(double* templ, double* jac_x, double* jac_y, std::size_t n, double mean,
                                         double sd, NormalisedSums* out) {
  const double inv = 1.0 / sd;
  const __m256d vinv = _mm256_set1_pd(inv), vmean = _mm256_set1_pd(mean);
  __m256d xx = _mm256_setzero_pd(), xy = xx, yy = xx, x = xx, y = xx, xt = xx, yt = xx;
  std::size_t k = 0;
  for (; k + 4 <= n; k += 4) {
    const __m256d t = _mm256_mul_pd(_mm256_sub_pd(_mm256_loadu_pd(templ + k), vmean), vinv);
    const __m256d jx = _mm256_mul_pd(_mm256_loadu_pd(jac_x + k), vinv);
    const __m256d jy = _mm256_mul_pd(_mm256_loadu_pd(jac_y + k), vinv);
    _mm256_storeu_pd(templ + k, t);
    _mm256_storeu_pd(jac_x + k, jx);
    _mm256_storeu_pd(jac_y + k, jy);
    xx = _mm256_add_pd(xx, _mm256_mul_pd(jx, jx));
    xy = _mm256_add_pd(xy, _mm256_mul_pd(jx, jy));
    yy = _mm256_add_pd(yy, _mm256_mul_pd(jy, jy));
    x = _mm256_add_pd(x, jx);
    y = _mm256_add_pd(y, jy);
    xt = _mm256_add_pd(xt, _mm256_mul_pd(jx, t));
    yt = _mm256_add_pd(yt, _mm256_mul_pd(jy, t));
  }
  NormalisedSums s{LaneTotal(xx), LaneTotal(xy), LaneTotal(yy), LaneTotal(x),
                   LaneTotal(y),  LaneTotal(xt), LaneTotal(yt)};
  NormaliseTail(templ, jac_x, jac_y, k, n, mean, inv, &s);
  *out = s;
}
#endif

}  // namespace

RefineKernels ChooseRefineKernels() {
  RefineKernels k{&Moments, &Normalise, &SumSamples};
#ifdef MOSAICLOC_TRACKING_AVX2
  if (UseAvx2()) k = {&MomentsAvx2, &NormaliseAvx2, &SumSamplesAvx2};
#endif
  return k;
}

}  // namespace mosaicloc::tracking::detail
