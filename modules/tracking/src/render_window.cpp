#include "mosaicloc/tracking/render_window.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>

#include <opencv2/core.hpp>

#include "mosaicloc/mosaic/tile_store.hpp"
#include "render_window.hpp"
#include "simd.hpp"

#ifdef MOSAICLOC_TRACKING_AVX2
#include <immintrin.h>
#endif

namespace mosaicloc::tracking {
namespace {

using Affine = Eigen::Matrix<double, 2, 3>;

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

// Which samples of a block are known, for RenderRows: `known` has the block's stride, and its
// byte at a pixel is nonzero when that pixel and its right, lower and lower-right neighbours
// are all mapped (what Sample demands). Null when every pixel of the block is known.
struct KnownQuads {
  const std::uint8_t* known = nullptr;
  cv::Mat* mask = nullptr;  ///< RenderWindow's mask, written when not null
};

// Pixel x of a RenderRows row whose sample at block offset `at` is unknown: unmapped in the
// window and 0 in its mask.
MOSAICLOC_ALWAYS_INLINE bool Unknown(const KnownQuads& quads, std::size_t at) {
  return quads.known != nullptr && quads.known[at] == 0;
}

// Every sample's four pixels lie in the block; where `quads` says they are not all known the
// window is unmapped. Pixel (x, y) of `out` shows block point a (origin + (x, y)) + b, bilinear
// in double precision.
void RenderRows(const std::uint8_t* pixels, std::size_t stride, const Eigen::Matrix2d& a, const Eigen::Vector2d& b,
                const cv::Point& origin, const cv::Size& size, const KnownQuads& quads, cv::Mat* out) {
  for (int y = 0; y < size.height; ++y) {
    auto* o = out->ptr<std::uint8_t>(y);
    std::uint8_t* m = quads.mask != nullptr ? quads.mask->ptr<std::uint8_t>(y) : nullptr;
    const Eigen::Vector2d row_start = a * Eigen::Vector2d(origin.x, origin.y + y) + b;
    for (int x = 0; x < size.width; ++x) {
      const double rx = row_start.x() + a(0, 0) * x, ry = row_start.y() + a(1, 0) * x;
      const bool unknown = Unknown(quads, static_cast<std::size_t>(ry) * stride + static_cast<std::size_t>(rx));
      o[x] = unknown ? mosaic::kUnmapped : KnownSample(pixels, stride, a, row_start, x);
      if (m != nullptr) m[x] = unknown ? 0 : 255;
    }
  }
}

#ifdef MOSAICLOC_TRACKING_AVX2
// RenderRows four pixels at a time, the same operations on each.
MOSAICLOC_TARGET_AVX2 void RenderRowsAvx2(const std::uint8_t* pixels, std::size_t stride, const Eigen::Matrix2d& a,
                                          const Eigen::Vector2d& b, const cv::Point& origin, const cv::Size& size,
                                          const KnownQuads& quads, cv::Mat* out) {
  const __m256d ax = _mm256_set1_pd(a(0, 0)), ay = _mm256_set1_pd(a(1, 0));
  const __m256d one = _mm256_set1_pd(1.0), half = _mm256_set1_pd(0.5);
  const __m128i vstride = _mm_set1_epi32(static_cast<int>(stride));
  const __m128i low_byte = _mm_set1_epi32(0xFF);
  for (int y = 0; y < size.height; ++y) {
    auto* o = out->ptr<std::uint8_t>(y);
    std::uint8_t* m = quads.mask != nullptr ? quads.mask->ptr<std::uint8_t>(y) : nullptr;
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
      if (quads.known != nullptr) {
        for (int i = 0; i < 4; ++i) {
          const bool unknown = quads.known[at[i]] == 0;
          if (unknown) o[x + i] = mosaic::kUnmapped;
          if (m != nullptr) m[x + i] = unknown ? 0 : 255;
        }
      }
    }
    for (; x < size.width; ++x) {
      const double rx = row_start.x() + a(0, 0) * x, ry = row_start.y() + a(1, 0) * x;
      const bool unknown = Unknown(quads, static_cast<std::size_t>(ry) * stride + static_cast<std::size_t>(rx));
      o[x] = unknown ? mosaic::kUnmapped : KnownSample(pixels, stride, a, row_start, x);
      if (m != nullptr) m[x] = unknown ? 0 : 255;
    }
  }
}
#endif

}  // namespace

detail::RasterBounds detail::BoundsOf(const Affine& frame_to_raster, const cv::Rect& rect) {
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

void detail::FetchRegion(const ReferenceRaster& reference, const RasterBounds& bounds, int margin, cv::Mat& store,
                 mosaic::RasterPatch* patch) {
  reference.Region(bounds.col0 - margin, bounds.row0 - margin, static_cast<int>(bounds.col1 - bounds.col0 + 1 + 2 * margin),
                   static_cast<int>(bounds.row1 - bounds.row0 + 1 + 2 * margin), store, patch);
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

cv::Mat RenderCameraView(const ReferenceRaster& reference, const camera::IdealCamera& camera,
                         const core::Pose2& world_from_camera, cv::Mat* mask) {
  const Affine frame_to_raster = ComposeAffine(reference.WorldToRaster(), camera.PixelToWorldAffine(world_from_camera));
  return RenderWindow(reference, frame_to_raster, cv::Point(0, 0), cv::Size(camera.width_px(), camera.height_px()),
                      mask);
}

cv::Mat detail::RenderWindowKnown(const ReferenceRaster& reference, const Affine& frame_to_raster,
                                  const cv::Point& origin, const cv::Size& size, cv::Mat* mask, bool* all_known) {
  *all_known = false;
  const cv::Rect rect(origin, size);
  // Per-thread pixels: several windows are rendered every frame.
  thread_local cv::Mat region_store;
  thread_local mosaic::RasterPatch region;
  detail::FetchRegion(reference, detail::BoundsOf(frame_to_raster, rect), 2, region_store, &region);
  const Eigen::Matrix2d a = frame_to_raster.leftCols<2>();
  const Eigen::Vector2d b = frame_to_raster.col(2) - Eigen::Vector2d(static_cast<double>(region.col0),
                                                                      static_cast<double>(region.row0));
  cv::Mat out(size, CV_8UC1);
  // Every sample's four pixels inside the block (the usual case): the same arithmetic as Sample
  // without its per-pixel bounds checks. The sample positions are an affine image of the
  // window, so they lie within the hull of its corners.
  bool inside = true;
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
    KnownQuads quads;
    if (!region.all_mapped) {
      // Part of the block unmapped (a window across the map's or a frame's edge): which pixels
      // have all four of their bilinear sources, laid out with the block's stride.
      thread_local cv::Mat known;
      const int rows = region.image.rows, cols = region.image.cols;
      known.create(rows, static_cast<int>(stride), CV_8UC1);
      const cv::Mat& m = region.mask;
      cv::Mat quad = known(cv::Rect(0, 0, cols - 1, rows - 1));
      cv::bitwise_and(m(cv::Rect(0, 0, cols - 1, rows - 1)), m(cv::Rect(1, 0, cols - 1, rows - 1)), quad);
      cv::bitwise_and(quad, m(cv::Rect(0, 1, cols - 1, rows - 1)), quad);
      cv::bitwise_and(quad, m(cv::Rect(1, 1, cols - 1, rows - 1)), quad);
      quads.known = known.ptr<std::uint8_t>(0);
      if (mask != nullptr) mask->create(size, CV_8UC1);
      quads.mask = mask;
    }
    render_rows(pixels, stride, a, b, origin, size, quads, &out);
    *all_known = region.all_mapped;
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
      const bool known = detail::Sample<std::uint8_t>(region.image, region.mask, region.all_mapped, rx, ry, &v);
      o[x] = known ? static_cast<std::uint8_t>(v + 0.5) : mosaic::kUnmapped;  // v in [0, 255]
      if (m != nullptr) m[x] = known ? 255 : 0;
    }
  }
  return out;
}

}  // namespace mosaicloc::tracking
