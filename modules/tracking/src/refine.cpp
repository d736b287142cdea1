#include "mosaicloc/tracking/refine.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include <Eigen/LU>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "low_pass.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "render_window.hpp"
#include "simd.hpp"
#include "visp_refine.hpp"

#ifdef MOSAICLOC_TRACKING_AVX2
#include <immintrin.h>
#endif

namespace mosaicloc::tracking {
namespace {

using Affine = Eigen::Matrix<double, 2, 3>;

// The raster block holding every point frame_to_raster maps `rect` to: columns
// [col0, col1] and rows [row0, row1].
struct RasterBounds {
  std::int64_t col0 = 0, row0 = 0, col1 = 0, row1 = 0;
};

RasterBounds BoundsOf(const Affine& frame_to_raster, const cv::Rect& rect) {
  double min_x = 1e300, min_y = 1e300, max_x = -1e300, max_y = -1e300;
  for (const int x : {rect.x, rect.x + rect.width - 1}) {
    for (const int y : {rect.y, rect.y + rect.height - 1}) {
      const Eigen::Vector2d r = ApplyAffine(frame_to_raster, Eigen::Vector2d(x, y));
      min_x = std::min(min_x, r.x());
      min_y = std::min(min_y, r.y());
      max_x = std::max(max_x, r.x());
      max_y = std::max(max_y, r.y());
    }
  }
  return {static_cast<std::int64_t>(std::floor(min_x)), static_cast<std::int64_t>(std::floor(min_y)),
          static_cast<std::int64_t>(std::ceil(max_x)), static_cast<std::int64_t>(std::ceil(max_y))};
}

// The bounds plus `margin` px on every side, into `store` (see ReferenceRaster::Region).
void FetchRegion(const ReferenceRaster& reference, const RasterBounds& bounds, int margin, cv::Mat& store,
                 mosaic::RasterPatch* patch) {
  reference.Region(bounds.col0 - margin, bounds.row0 - margin, static_cast<int>(bounds.col1 - bounds.col0 + 1 + 2 * margin),
                   static_cast<int>(bounds.row1 - bounds.row0 + 1 + 2 * margin), store, patch);
}

// Bilinear sample of an image of T at (x, y); false when a source pixel is outside or unknown.
template <typename T>
inline bool Sample(const cv::Mat& image, const cv::Mat& mask, bool all_known, double x, double y, double* value) {
  const double fx0 = std::floor(x), fy0 = std::floor(y);
  const int ix = static_cast<int>(fx0), iy = static_cast<int>(fy0);
  if (ix < 0 || iy < 0 || ix + 1 >= image.cols || iy + 1 >= image.rows) return false;
  const T* p = image.ptr<T>(iy) + ix;
  const T* q = image.ptr<T>(iy + 1) + ix;
  if (!all_known) {
    const std::uint8_t* m = mask.ptr<std::uint8_t>(iy) + ix;
    const std::uint8_t* n = m + mask.step[0];
    if ((m[0] & m[1] & n[0] & n[1]) == 0) return false;
  }
  const double fx = x - fx0, fy = y - fy0;
  *value = (1.0 - fy) * ((1.0 - fx) * p[0] + fx * p[1]) + fy * ((1.0 - fx) * q[0] + fx * q[1]);
  return true;
}

// Inverse-compositional Gauss-Newton on the translation t of the template in the raster,
// with ZNCC normalisation of both sides:
//   min_t sum_k ( N[M](A x_k + b + t) - N[T](x_k) )^2,   N[f] = (f - mean f) / std f,
// where M is the raster, T the frame, x_k the template's pixels and [A | b] the current
// frame -> raster map. At the optimum M(A x + b + t) ~ T(x), so grad M ~ grad T A^-1:
// the Jacobian and the 2x2 Gauss-Newton matrix come from the template once (Baker and
// Matthews, "Lucas-Kanade 20 years on", 2004, section 3.2), and each iteration costs one
// bilinear sample per pixel. The normalisation makes the cost blind to gain and offset.
// Running sums of one Gauss-Newton iteration over the samples v_k = M(x_k + t):
// sum v, sum v^2, sum Jx v, sum Jy v, sum v T.
struct SampleSums {
  double sm = 0.0, smm = 0.0, sjxm = 0.0, sjym = 0.0, smt = 0.0;
};

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

// Sums over the normalised template T and Jacobian J: J J^T (three entries), J and J T.
struct NormalisedSums {
  double jxjx = 0.0, jxjy = 0.0, jyjy = 0.0, jx = 0.0, jy = 0.0, jxt = 0.0, jyt = 0.0;
};

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

struct TemplateKernels {
  void (*moments)(const double*, std::size_t, double*, double*) = &Moments;
  void (*normalise)(double*, double*, double*, std::size_t, double, double, NormalisedSums*) = &Normalise;
};

TemplateKernels ChooseTemplateKernels() {
  TemplateKernels k;
#ifdef MOSAICLOC_TRACKING_AVX2
  if (detail::UseAvx2()) {
    k.moments = &MomentsAvx2;
    k.normalise = &NormaliseAvx2;
  }
#endif
  return k;
}

// The low-passed reference around one template. Sample positions are raster coordinates
// relative to `origin` (the corner of the largest block the refinement may need); the block
// actually fetched may be smaller and starts `offset` px further in.
struct FilteredRaster {
  mosaic::RasterPatch region;
  cv::Mat raster;  // CV_32F, the size of region.image
  cv::Mat mask;    // region.mask eroded by the kernel radius (when not all mapped)
  int offset_x = 0, offset_y = 0;
  // Positions whose bilinear samples read only filtered pixels that do not depend on where
  // the block ends: lo <= x < hi.
  double lo_x = 0.0, lo_y = 0.0, hi_x = 0.0, hi_y = 0.0;
  bool whole = false;  // the largest block, filtered to its edges (every position may be tried)
};

// Fetches and filters the block `margin` px around `bounds`; the largest is `full_margin`.
// Filtered pixels at least the kernel radius R inside the block equal those of any larger
// block, so a smaller block gives the same samples wherever it is valid; only the largest is
// filtered to its edges (replicated), as every sample it may be asked for must be defined.
void LoadRaster(const ReferenceRaster& reference, const RasterBounds& bounds, int margin, int full_margin,
                double sigma_px, FilteredRaster* out) {
  const int radius = detail::LowPassRadius(sigma_px);
  // Per-thread pixels: several templates are refined every frame.
  thread_local cv::Mat region_store;
  FetchRegion(reference, bounds, margin, region_store, &out->region);
  out->offset_x = out->offset_y = full_margin - margin;
  out->whole = margin == full_margin;
  const cv::Mat& image = out->region.image;
  // Per-thread buffer: several templates are refined every frame.
  thread_local cv::Mat raster_store;
  out->raster = detail::ScratchImage(raster_store, image.size(), CV_32FC1);
  if (out->whole) {
    detail::GaussianLowPass(image, out->raster, sigma_px, CV_32F);
  } else {
    const cv::Rect interior(radius, radius, image.cols - 2 * radius, image.rows - 2 * radius);
    cv::Mat target = out->raster(interior);
    detail::GaussianLowPassRect(image, interior, target, sigma_px, CV_32F);
  }
  out->lo_x = out->offset_x + radius;
  out->lo_y = out->offset_y + radius;
  out->hi_x = out->offset_x + image.cols - 1 - radius;
  out->hi_y = out->offset_y + image.rows - 1 - radius;
  out->mask = out->region.mask;
  if (radius > 0 && !out->region.all_mapped) {
    const cv::Size k(2 * radius + 1, 2 * radius + 1);
    cv::erode(out->region.mask, out->mask, cv::getStructuringElement(cv::MORPH_RECT, k));
  }
}

// Inverse-compositional Gauss-Newton on the translation t of the template in the raster,
// with ZNCC normalisation of both sides:
//   min_t sum_k ( N[M](A x_k + b + t) - N[T](x_k) )^2,   N[f] = (f - mean f) / std f,
// where M is the raster, T the frame, x_k the template's pixels and [A | b] the current
// frame -> raster map. At the optimum M(A x + b + t) ~ T(x), so grad M ~ grad T A^-1:
// the Jacobian and the 2x2 Gauss-Newton matrix come from the template once (Baker and
// Matthews, "Lucas-Kanade 20 years on", 2004, section 3.2), and each iteration costs one
// bilinear sample per pixel. The normalisation makes the cost blind to gain and offset.
RefinedMatch RefineDirect(const cv::Mat& frame, const cv::Rect& rect, const ReferenceRaster& reference,
                          const Affine& frame_to_raster, const RefineOptions& options) {
  RefinedMatch match;
  const cv::Rect inner = rect & cv::Rect(1, 1, frame.cols - 2, frame.rows - 2);
  const int blur_radius = detail::LowPassRadius(options.prefilter_sigma_px);
  // The block every sample of a shift up to max_shift_px falls in; a refinement that stays
  // within a few pixels of its start (nearly all) needs only the smaller one.
  const int full_margin = static_cast<int>(std::ceil(options.max_shift_px)) + 2 + blur_radius;
  constexpr int kSlackPx = 2;
  const int margin = std::min(full_margin, blur_radius + 1 + kSlackPx);
  const RasterBounds bounds = BoundsOf(frame_to_raster, inner);

  // Both sides low-pass filtered alike: real floors carry detail up to the pixel scale, where
  // bilinear interpolation is a poor model of the image between samples and would bias the
  // sub-pixel estimate. The mask shrinks by the kernel radius so no unknown pixel leaks in.
  // The template's gradient needs the filtered frame on `inner` and one pixel around it.
  const cv::Rect gradient_rect(inner.x - 1, inner.y - 1, inner.width + 2, inner.height + 2);
  // Per-thread buffer: several templates are refined every frame.
  thread_local cv::Mat templ_store;
  cv::Mat templ_source = detail::ScratchImage(templ_store, gradient_rect.size(), CV_32FC1);
  detail::GaussianLowPassRect(frame, gradient_rect, templ_source, options.prefilter_sigma_px, CV_32F);
  FilteredRaster filtered;
  LoadRaster(reference, bounds, margin, full_margin, options.prefilter_sigma_px, &filtered);

  const Eigen::Matrix2d a = frame_to_raster.leftCols<2>();
  const Eigen::Matrix2d a_inv = a.inverse();
  const Eigen::Vector2d b = frame_to_raster.col(2) - Eigen::Vector2d(static_cast<double>(bounds.col0 - full_margin),
                                                                      static_cast<double>(bounds.row0 - full_margin));
  const int step = options.sampling;
  // Per-thread buffers, only ever grown.
  thread_local std::vector<double> base_x, base_y, templ, jac_x, jac_y;
  const std::size_t capacity = static_cast<std::size_t>((inner.width / step + 1) * (inner.height / step + 1));
  for (auto* v : {&base_x, &base_y, &templ, &jac_x, &jac_y}) {
    if (v->size() < capacity) v->resize(capacity);
  }
  // The template's sample grid: columns x0, x0 + step, ..., x1 and rows y0, ..., y1.
  const int x0 = inner.x, x1 = inner.x + (inner.width - 1) / step * step;
  const int y0 = inner.y, y1 = inner.y + (inner.height - 1) / step * step;
  // Raster position of grid point (x, y): a00 x + (a01 y + b0), a10 x + (a11 y + b1). Each is
  // monotonic in x and y in floating point too, so the grid's corners bound all of them.
  const auto raster_at = [&](int x, int y) {
    return Eigen::Vector2d(a(0, 0) * x + (a(0, 1) * y + b.x()), a(1, 0) * x + (a(1, 1) * y + b.y()));
  };
  double min_x = 1e300, min_y = 1e300, max_x = -1e300, max_y = -1e300;
  for (const int x : {x0, x1}) {
    for (const int y : {y0, y1}) {
      const Eigen::Vector2d r = raster_at(x, y);
      min_x = std::min(min_x, r.x());
      min_y = std::min(min_y, r.y());
      max_x = std::max(max_x, r.x());
      max_y = std::max(max_y, r.y());
    }
  }
  std::size_t n = 0;
  for (int y = y0; y <= y1; y += step) {
    const float* row = templ_source.ptr<float>(y - gradient_rect.y) - gradient_rect.x;
    const float* up = templ_source.ptr<float>(y - 1 - gradient_rect.y) - gradient_rect.x;
    const float* down = templ_source.ptr<float>(y + 1 - gradient_rect.y) - gradient_rect.x;
    const double row_x = a(0, 1) * y + b.x(), row_y = a(1, 1) * y + b.y();
    for (int x = x0; x <= x1; x += step, ++n) {
      const double gx = 0.5 * (row[x + 1] - row[x - 1]);
      const double gy = 0.5 * (down[x] - up[x]);
      base_x[n] = a(0, 0) * x + row_x;
      base_y[n] = a(1, 0) * x + row_y;
      templ[n] = row[x];
      jac_x[n] = gx * a_inv(0, 0) + gy * a_inv(1, 0);
      jac_y[n] = gx * a_inv(0, 1) + gy * a_inv(1, 1);
    }
  }
  const TemplateKernels kernels = ChooseTemplateKernels();
  double sum = 0.0, sum_sq = 0.0;
  kernels.moments(templ.data(), n, &sum, &sum_sq);
  const double mean_t = sum / static_cast<double>(n);
  const double std_t = std::sqrt(std::max(sum_sq / static_cast<double>(n) - mean_t * mean_t, 1e-12));
  // With the template normalised (sum T = 0, sum T^2 = n) and e_k = (M_k - mu) / sigma - T_k:
  //   sum_k J_k e_k = (sum_k J_k M_k - mu sum_k J_k) / sigma - sum_k J_k T_k,
  //   sum_k e_k^2  = 2 n - 2 sum_k M_k T_k / sigma,
  // so one pass of five running sums per iteration does it, with no per-pixel storage.
  // Off-map samples (only near the map's edge) take the general path with their own sums.
  NormalisedSums normalised;
  kernels.normalise(templ.data(), jac_x.data(), jac_y.data(), n, mean_t, std_t, &normalised);
  Eigen::Matrix2d hessian;
  hessian(0, 0) = normalised.jxjx;
  hessian(0, 1) = normalised.jxjy;
  hessian(1, 1) = normalised.jyjy;
  const double sum_jx = normalised.jx, sum_jy = normalised.jy, sum_jxt = normalised.jxt, sum_jyt = normalised.jyt;
  hessian(1, 0) = hessian(0, 1);
  if (!(hessian.determinant() > 1e-12)) {
    match.failure = RefineFailure::kDiverged;
    match.detail = "no texture: the template has no gradient";
    return match;
  }
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  double sum_e2 = 0.0;
  std::size_t used = 0;
  bool converged = false;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    match.iterations = iteration + 1;
    // All samples of this iteration within the filtered block, or the largest block.
    const bool within = min_x + t.x() >= filtered.lo_x && min_y + t.y() >= filtered.lo_y &&
                        max_x + t.x() < filtered.hi_x && max_y + t.y() < filtered.hi_y;
    if (!within && !filtered.whole) {
      LoadRaster(reference, bounds, full_margin, full_margin, options.prefilter_sigma_px, &filtered);
    }
    const float* pixels = filtered.raster.ptr<float>(0);
    const std::size_t stride = filtered.raster.step1();
    const int max_col = filtered.raster.cols - 2, max_row = filtered.raster.rows - 2;
    const int offset_x = filtered.offset_x, offset_y = filtered.offset_y;
    const bool all_known = filtered.region.all_mapped;
    double sm = 0.0, smm = 0.0, sjxm = 0.0, sjym = 0.0, smt = 0.0;
    double pjx = sum_jx, pjy = sum_jy, pjxt = sum_jxt, pjyt = sum_jyt, stt = static_cast<double>(n), st = 0.0;
    Eigen::Matrix2d h = hessian;
    used = 0;
    if (within && all_known) {
      // Every sample inside and known: no per-sample test.
      SampleSums sums;
      auto* sum_samples = &SumSamples;
#ifdef MOSAICLOC_TRACKING_AVX2
      if (detail::UseAvx2()) sum_samples = &SumSamplesAvx2;
#endif
      sum_samples(base_x.data(), base_y.data(), jac_x.data(), jac_y.data(), templ.data(), n, t.x(), t.y(), pixels,
          static_cast<std::ptrdiff_t>(stride), offset_x, offset_y, &sums);
      sm = sums.sm;
      smm = sums.smm;
      sjxm = sums.sjxm;
      sjym = sums.sjym;
      smt = sums.smt;
      used = n;
    } else {
      for (std::size_t k = 0; k < n; ++k) {
        const double x = base_x[k] + t.x(), y = base_y[k] + t.y();
        const int ix = static_cast<int>(x) - offset_x, iy = static_cast<int>(y) - offset_y;
        bool ok = ix >= 0 && iy >= 0 && ix <= max_col && iy <= max_row;
        if (ok && !all_known) {
          const std::uint8_t* m0 = filtered.mask.ptr<std::uint8_t>(iy) + ix;
          const std::uint8_t* m1 = filtered.mask.ptr<std::uint8_t>(iy + 1) + ix;
          ok = (m0[0] & m0[1] & m1[0] & m1[1]) != 0;
        }
        if (!ok) {
          // Take this sample out of the precomputed sums.
          pjx -= jac_x[k];
          pjy -= jac_y[k];
          pjxt -= jac_x[k] * templ[k];
          pjyt -= jac_y[k] * templ[k];
          stt -= templ[k] * templ[k];
          st -= templ[k];
          h(0, 0) -= jac_x[k] * jac_x[k];
          h(0, 1) -= jac_x[k] * jac_y[k];
          h(1, 1) -= jac_y[k] * jac_y[k];
          continue;
        }
        const float* p0 = pixels + static_cast<std::size_t>(iy) * stride + ix;
        const float* p1 = p0 + stride;
        const double fx = x - (ix + offset_x), fy = y - (iy + offset_y);
        const double top = p0[0] + fx * (p0[1] - p0[0]);
        const double bottom = p1[0] + fx * (p1[1] - p1[0]);
        const double v = top + fy * (bottom - top);
        sm += v;
        smm += v * v;
        sjxm += jac_x[k] * v;
        sjym += jac_y[k] * v;
        smt += v * templ[k];
        ++used;
      }
    }
    if (static_cast<double>(used) < options.min_mapped_fraction * static_cast<double>(n)) {
      match.failure = RefineFailure::kOffMap;
      return match;
    }
    h(1, 0) = h(0, 1);
    const double count = static_cast<double>(used);
    const double mean_m = sm / count;
    const double std_m = std::sqrt(std::max(smm / count - mean_m * mean_m, 1e-12));
    const Eigen::Vector2d gradient((sjxm - mean_m * pjx) / std_m - pjxt, (sjym - mean_m * pjy) / std_m - pjyt);
    // sum e^2 over the used samples; st, stt correct for samples left out (their T is not
    // re-normalised: near the edge the score is slightly pessimistic, never the position).
    sum_e2 = std::max(0.0, count + stt - 2.0 * (smt - mean_m * st) / std_m);
    const Eigen::Vector2d delta = -(h.inverse() * gradient);
    t += delta;
    if (!t.allFinite() || t.norm() > options.max_shift_px) {
      match.failure = RefineFailure::kDiverged;
      return match;
    }
    if (delta.norm() < options.tolerance_px) {
      converged = true;
      break;
    }
  }
  if (!converged) {
    match.failure = RefineFailure::kNotConverged;
    return match;
  }
  const double dof = std::max(1.0, static_cast<double>(used) - 2.0);
  match.covariance_px2 = (sum_e2 / dof) * hessian.inverse();
  match.zncc = 1.0 - sum_e2 / (2.0 * static_cast<double>(used));
  const Eigen::Vector2d centre(rect.x + 0.5 * (rect.width - 1), rect.y + 0.5 * (rect.height - 1));
  match.centre_raster = ApplyAffine(frame_to_raster, centre) + t;
  return match;
}

// ZNCC between the template `rect` of the frame and the window sampled bilinearly at the
// template's pixels + shift (window pixel = frame pixel - origin + shift), both low-passed by
// `sigma` like the direct method's images, so the scores of all methods compare.
double SubPixelZncc(const cv::Mat& frame, const cv::Rect& rect, const cv::Mat& window, const cv::Point& origin,
                    const Eigen::Vector2d& shift, double sigma) {
  cv::Mat templ, win;
  detail::GaussianLowPass(frame(rect), templ, sigma, CV_32F);
  detail::GaussianLowPass(window, win, sigma, CV_32F);
  double st = 0.0, sm = 0.0, stt = 0.0, smm = 0.0, stm = 0.0;
  int n = 0;
  const cv::Mat no_mask;
  for (int y = 0; y < rect.height; ++y) {
    for (int x = 0; x < rect.width; ++x) {
      double m = 0.0;
      if (!Sample<float>(win, no_mask, true, rect.x - origin.x + x + shift.x(), rect.y - origin.y + y + shift.y(),
                         &m)) {
        continue;
      }
      const double t = templ.at<float>(y, x);
      st += t;
      sm += m;
      stt += t * t;
      smm += m * m;
      stm += t * m;
      ++n;
    }
  }
  if (n < 2) return 0.0;
  const double var_t = stt / n - (st / n) * (st / n), var_m = smm / n - (sm / n) * (sm / n);
  if (var_t <= 0.0 || var_m <= 0.0) return 0.0;
  return (stm / n - (st / n) * (sm / n)) / std::sqrt(var_t * var_m);
}

// ViSP's headers do not compile as C++20; the part that uses them is a C++17 island
// (visp_refine.cpp) behind a plain interface.
RefinedMatch RefineVisp(const cv::Mat& frame, const cv::Rect& rect, const ReferenceRaster& reference,
                        const Affine& frame_to_raster, const RefineOptions& options) {
  RefinedMatch match;
  constexpr int kBorder = 2;
  const cv::Rect crop_rect = cv::Rect(rect.x - kBorder, rect.y - kBorder, rect.width + 2 * kBorder,
                                      rect.height + 2 * kBorder) &
                             cv::Rect(0, 0, frame.cols, frame.rows);
  const int pad = static_cast<int>(std::ceil(options.max_shift_px)) + kBorder + 2;
  const cv::Point origin(rect.x - pad, rect.y - pad);
  cv::Mat mask;
  const cv::Mat window =
      RenderWindow(reference, frame_to_raster, origin, cv::Size(rect.width + 2 * pad, rect.height + 2 * pad), &mask);
  const double mapped = static_cast<double>(cv::countNonZero(mask)) / static_cast<double>(mask.total());
  if (mapped < options.min_mapped_fraction) {
    match.failure = RefineFailure::kOffMap;
    return match;
  }
  detail::VispRequest request;
  request.ssd = options.method == RefineMethod::kVispSsd;
  request.warp = options.warp == RefineWarp::kTranslation ? detail::VispWarp::kTranslation
                 : options.warp == RefineWarp::kSrt       ? detail::VispWarp::kSrt
                                                          : detail::VispWarp::kHomography;
  request.sampling = options.sampling;
  request.max_iterations = options.max_iterations;
  request.pyramid_levels = options.visp_pyramid_levels;
  request.zone = cv::Rect(rect.x - crop_rect.x, rect.y - crop_rect.y, rect.width, rect.height);
  request.start_u = crop_rect.x - origin.x;
  request.start_v = crop_rect.y - origin.y;
  const detail::VispAnswer answer = detail::TrackWithVisp(frame(crop_rect), window, request);
  match.iterations = answer.iterations;
  if (!answer.ok) {
    match.failure = answer.diverged ? RefineFailure::kDiverged : RefineFailure::kVispError;
    match.detail = answer.message;
    return match;
  }
  // Where the template's centre went, relative to where it was predicted.
  const Eigen::Vector2d moved(answer.centre_u - (request.zone.x + 0.5 * (rect.width - 1) + request.start_u),
                              answer.centre_v - (request.zone.y + 0.5 * (rect.height - 1) + request.start_v));
  if (!moved.allFinite() || moved.norm() > options.max_shift_px) {
    match.failure = RefineFailure::kDiverged;
    return match;
  }
  const Eigen::Vector2d centre(rect.x + 0.5 * (rect.width - 1), rect.y + 0.5 * (rect.height - 1));
  match.centre_raster = ApplyAffine(frame_to_raster, centre + moved);
  match.rotation_rad = answer.rotation_rad;
  // Score: our own ZNCC at the solution (ViSP has no public cost getter for its ZNCC trackers).
  match.zncc = SubPixelZncc(frame, rect, window, origin, moved, options.prefilter_sigma_px);
  // ViSP exposes no information matrix: take an isotropic 0.02 px floor grown by the
  // residual (1 - ZNCC), so weaker matches weigh less, and express it in raster px.
  const double sigma_frame_px = 0.02 + 0.5 * std::max(0.0, 1.0 - match.zncc);
  const double raster_px2_per_frame_px2 = std::abs(frame_to_raster.leftCols<2>().determinant());
  match.covariance_px2 = Eigen::Matrix2d::Identity() * (sigma_frame_px * sigma_frame_px * raster_px2_per_frame_px2);
  return match;
}

// Pixel x of a RenderRows row starting at block point `row_start`, bilinear in double
// precision; its four pixels lie in the block.
MOSAICLOC_ALWAYS_INLINE std::uint8_t KnownSample(const std::uint8_t* pixels, std::size_t stride,
                                                 const Eigen::Matrix2d& a, const Eigen::Vector2d& row_start, int x) {
  const double rx = row_start.x() + a(0, 0) * x, ry = row_start.y() + a(1, 0) * x;
  // rx, ry >= 0: truncation is the floor (std::floor is a library call without SSE4.1).
  const auto ix = static_cast<std::size_t>(rx), iy = static_cast<std::size_t>(ry);
  const std::uint8_t* p = pixels + iy * stride + ix;
  const std::uint8_t* q = p + stride;
  const double fx = rx - static_cast<double>(ix), fy = ry - static_cast<double>(iy);
  const double v = (1.0 - fy) * ((1.0 - fx) * p[0] + fx * p[1]) + fy * ((1.0 - fx) * q[0] + fx * q[1]);
  return static_cast<std::uint8_t>(v + 0.5);
}

// The inside of RenderWindow: every sample's four pixels in the block and known. Pixel (x, y)
// of `out` shows block point a (origin + (x, y)) + b, bilinear in double precision.
void RenderRows(const std::uint8_t* pixels, std::size_t stride, const Eigen::Matrix2d& a, const Eigen::Vector2d& b,
                const cv::Point& origin, const cv::Size& size, cv::Mat* out) {
  for (int y = 0; y < size.height; ++y) {
    auto* o = out->ptr<std::uint8_t>(y);
    const Eigen::Vector2d row_start = a * Eigen::Vector2d(origin.x, origin.y + y) + b;
    for (int x = 0; x < size.width; ++x) {
      o[x] = KnownSample(pixels, stride, a, row_start, x);
    }
  }
}

#ifdef MOSAICLOC_TRACKING_AVX2
// RenderRows four pixels at a time, the same operations on each.
MOSAICLOC_TARGET_AVX2 void RenderRowsAvx2(const std::uint8_t* pixels, std::size_t stride, const Eigen::Matrix2d& a,
                                          const Eigen::Vector2d& b, const cv::Point& origin, const cv::Size& size,
                                          cv::Mat* out) {
  const __m256d ax = _mm256_set1_pd(a(0, 0)), ay = _mm256_set1_pd(a(1, 0));
  const __m256d one = _mm256_set1_pd(1.0), half = _mm256_set1_pd(0.5);
  const __m128i vstride = _mm_set1_epi32(static_cast<int>(stride));
  const __m128i low_byte = _mm_set1_epi32(0xFF);
  for (int y = 0; y < size.height; ++y) {
    auto* o = out->ptr<std::uint8_t>(y);
    const Eigen::Vector2d row_start = a * Eigen::Vector2d(origin.x, origin.y + y) + b;
    const __m256d sx = _mm256_set1_pd(row_start.x()), sy = _mm256_set1_pd(row_start.y());
    int x = 0;
    for (; x + 4 <= size.width; x += 4) {
      const __m256d xs = _mm256_setr_pd(x, x + 1, x + 2, x + 3);
      const __m256d rx = _mm256_add_pd(sx, _mm256_mul_pd(ax, xs));
      const __m256d ry = _mm256_add_pd(sy, _mm256_mul_pd(ay, xs));
      const __m128i ix = _mm256_cvttpd_epi32(rx), iy = _mm256_cvttpd_epi32(ry);
      const __m256d fx = _mm256_sub_pd(rx, _mm256_cvtepi32_pd(ix));
      const __m256d fy = _mm256_sub_pd(ry, _mm256_cvtepi32_pd(iy));
      alignas(16) int at[4];
      _mm_store_si128(reinterpret_cast<__m128i*>(at), _mm_add_epi32(_mm_mullo_epi32(iy, vstride), ix));
      std::uint16_t top[4], bottom[4];
      for (int i = 0; i < 4; ++i) {
        std::memcpy(&top[i], pixels + at[i], 2);
        std::memcpy(&bottom[i], pixels + at[i] + stride, 2);
      }
      const __m128i t = _mm_setr_epi32(top[0], top[1], top[2], top[3]);
      const __m128i u = _mm_setr_epi32(bottom[0], bottom[1], bottom[2], bottom[3]);
      const __m256d p0 = _mm256_cvtepi32_pd(_mm_and_si128(t, low_byte));
      const __m256d p1 = _mm256_cvtepi32_pd(_mm_srli_epi32(t, 8));
      const __m256d q0 = _mm256_cvtepi32_pd(_mm_and_si128(u, low_byte));
      const __m256d q1 = _mm256_cvtepi32_pd(_mm_srli_epi32(u, 8));
      const __m256d gx = _mm256_sub_pd(one, fx), gy = _mm256_sub_pd(one, fy);
      const __m256d upper = _mm256_add_pd(_mm256_mul_pd(gx, p0), _mm256_mul_pd(fx, p1));
      const __m256d lower = _mm256_add_pd(_mm256_mul_pd(gx, q0), _mm256_mul_pd(fx, q1));
      const __m256d v = _mm256_add_pd(_mm256_mul_pd(gy, upper), _mm256_mul_pd(fy, lower));
      const __m128i value = _mm256_cvttpd_epi32(_mm256_add_pd(v, half));
      const __m128i bytes = _mm_packus_epi16(_mm_packs_epi32(value, value), _mm_setzero_si128());
      const int four = _mm_cvtsi128_si32(bytes);
      std::memcpy(o + x, &four, 4);
    }
    for (; x < size.width; ++x) {
      o[x] = KnownSample(pixels, stride, a, row_start, x);
    }
  }
}
#endif

}  // namespace

bool RefineOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (max_iterations < 1 || max_iterations > 1000) return fail("max_iterations must be in [1, 1000]");
  if (!(tolerance_px > 0.0)) return fail("tolerance_px must be > 0");
  if (!(max_shift_px > 0.0 && max_shift_px <= 64.0)) return fail("max_shift_px must be in (0, 64]");
  if (sampling < 1 || sampling > 8) return fail("sampling must be in [1, 8]");
  if (visp_pyramid_levels < 1 || visp_pyramid_levels > 4) return fail("visp_pyramid_levels must be in [1, 4]");
  if (!(prefilter_sigma_px >= 0.0 && prefilter_sigma_px <= 5.0)) return fail("prefilter_sigma_px must be in [0, 5]");
  if (!(min_mapped_fraction > 0.0 && min_mapped_fraction <= 1.0)) return fail("min_mapped_fraction must be in (0, 1]");
  if (method == RefineMethod::kDirect && warp != RefineWarp::kTranslation) {
    return fail("warp must be translation for the direct method, which estimates a translation only");
  }
  return true;
}

const char* ToString(RefineMethod method) {
  switch (method) {
    case RefineMethod::kDirect: return "direct";
    case RefineMethod::kVispSsd: return "visp-ssd";
    case RefineMethod::kVispZncc: return "visp-zncc";
  }
  return "unknown";
}

const char* ToString(RefineWarp warp) {
  switch (warp) {
    case RefineWarp::kTranslation: return "translation";
    case RefineWarp::kSrt: return "srt";
    case RefineWarp::kHomography: return "homography";
  }
  return "unknown";
}

const char* ToString(RefineFailure failure) {
  switch (failure) {
    case RefineFailure::kNone: return "ok";
    case RefineFailure::kOffMap: return "off map";
    case RefineFailure::kDiverged: return "diverged";
    case RefineFailure::kNotConverged: return "not converged";
    case RefineFailure::kVispError: return "ViSP error";
  }
  return "unknown";
}

cv::Mat RenderWindow(const ReferenceRaster& reference, const Affine& frame_to_raster, const cv::Point& origin,
                     const cv::Size& size, cv::Mat* mask) {
  bool all_known = false;
  cv::Mat out = detail::RenderWindowKnown(reference, frame_to_raster, origin, size, mask, &all_known);
  if (all_known && mask != nullptr) {
    mask->create(size, CV_8UC1);
    mask->setTo(cv::Scalar(255));
  }
  return out;
}

cv::Mat detail::RenderWindowKnown(const ReferenceRaster& reference, const Affine& frame_to_raster,
                                  const cv::Point& origin, const cv::Size& size, cv::Mat* mask, bool* all_known) {
  *all_known = false;
  const cv::Rect rect(origin, size);
  // Per-thread pixels: several windows are rendered every frame.
  thread_local cv::Mat region_store;
  thread_local mosaic::RasterPatch region;
  FetchRegion(reference, BoundsOf(frame_to_raster, rect), 2, region_store, &region);
  const Eigen::Matrix2d a = frame_to_raster.leftCols<2>();
  const Eigen::Vector2d b = frame_to_raster.col(2) - Eigen::Vector2d(static_cast<double>(region.col0),
                                                                      static_cast<double>(region.row0));
  cv::Mat out(size, CV_8UC1);
  // Every sample inside the block and every block pixel known (the usual case, away from the
  // map's edge): the same arithmetic as Sample without its per-pixel checks. The sample
  // positions are an affine image of the window, so they lie within the hull of its corners.
  bool inside = region.all_mapped;
  for (const int x : {0, size.width - 1}) {
    for (const int y : {0, size.height - 1}) {
      const Eigen::Vector2d r = a * Eigen::Vector2d(origin.x + x, origin.y + y) + b;
      inside = inside && r.x() >= 0.0 && r.y() >= 0.0 && r.x() < region.image.cols - 1.0 &&
               r.y() < region.image.rows - 1.0;
    }
  }
  if (inside) {
    const std::uint8_t* pixels = region.image.ptr<std::uint8_t>(0);
    const std::size_t stride = region.image.step[0];
    auto* render_rows = &RenderRows;
#ifdef MOSAICLOC_TRACKING_AVX2
    if (detail::UseAvx2()) render_rows = &RenderRowsAvx2;
#endif
    render_rows(pixels, stride, a, b, origin, size, &out);
    *all_known = true;
    return out;
  }
  if (mask != nullptr) mask->create(size, CV_8UC1);
  for (int y = 0; y < size.height; ++y) {
    auto* o = out.ptr<std::uint8_t>(y);
    std::uint8_t* m = mask != nullptr ? mask->ptr<std::uint8_t>(y) : nullptr;
    const Eigen::Vector2d row_start = a * Eigen::Vector2d(origin.x, origin.y + y) + b;
    for (int x = 0; x < size.width; ++x) {
      const double rx = row_start.x() + a(0, 0) * x, ry = row_start.y() + a(1, 0) * x;
      double v = 0.0;
      const bool known = Sample<std::uint8_t>(region.image, region.mask, region.all_mapped, rx, ry, &v);
      o[x] = known ? static_cast<std::uint8_t>(v + 0.5) : mosaic::kUnmapped;  // v in [0, 255]
      if (m != nullptr) m[x] = known ? 255 : 0;
    }
  }
  return out;
}

RefinedMatch RefineTemplate(const cv::Mat& frame, const cv::Rect& rect, const ReferenceRaster& reference,
                            const Affine& frame_to_raster, const RefineOptions& options) {
  if (options.method == RefineMethod::kDirect) return RefineDirect(frame, rect, reference, frame_to_raster, options);
  return RefineVisp(frame, rect, reference, frame_to_raster, options);
}

}  // namespace mosaicloc::tracking
