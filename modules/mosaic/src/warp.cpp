#include "warp.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include <opencv2/core.hpp>

#if defined(__x86_64__)
#include <immintrin.h>
#define MOSAICLOC_WARP_AVX2 1
#endif

namespace mosaicloc::mosaic::internal {
namespace {

constexpr int kAbScale = 1024;   // positions are rounded to 1/1024 px first (OpenCV AB_BITS = 10)
constexpr int kRoundDelta = 16;  // then to 1/32 px (INTER_BITS = 5), to nearest
constexpr int kFractionBits = 5;

int Round(double value) { return static_cast<int>(std::lrint(value)); }  // as cvRound

struct Row {
  const PairRaster* source;
  const int* adelta;  // per output column: round(1024 m00 x)
  const int* bdelta;  // round(1024 m10 x)
  int x0, y0;         // per output row: round(1024 (m01 y + m02)) + 16, likewise for Y
};

// The raster pixel (sx, sy), inside the raster.
int Pixel(const PairRaster& source, int sx, int sy) {
  const int pair_row = sy < source.rows - 1 ? sy : sy - 1;
  return source.data[pair_row * source.stride + 2 * sx + (sy - pair_row)];
}

// One output pixel anywhere: neighbours of zero weight may lie outside, the others must be
// inside and mapped. Returns false (and writes 0) for an invalid pixel.
bool SamplePixel(const Row& row, int x, std::uint8_t* value) {
  const int X = (row.x0 + row.adelta[x]) >> kFractionBits;
  const int Y = (row.y0 + row.bdelta[x]) >> kFractionBits;
  const int ix = X >> kFractionBits, iy = Y >> kFractionBits;
  const int fx = X & 31, fy = Y & 31;
  const int weights[4] = {(32 - fx) * (32 - fy), fx * (32 - fy), (32 - fx) * fy, fx * fy};
  int sum = 0;
  for (int k = 0; k < 4; ++k) {
    if (weights[k] == 0) continue;
    const int sx = ix + (k & 1), sy = iy + (k >> 1);
    const int p = sx < 0 || sy < 0 || sx >= row.source->cols || sy >= row.source->rows ? 0 : Pixel(*row.source, sx, sy);
    if (p == 0) {
      *value = 0;
      return false;
    }
    sum += weights[k] * p;
  }
  *value = static_cast<std::uint8_t>((sum + 512) >> 10);
  return true;
}

// Columns [begin, end) of one output row whose four neighbours all lie in the source.
int RowInsideScalar(const Row& row, int begin, int end, std::uint8_t* out, std::uint8_t* mask, bool all_mapped) {
  int valid = 0;
  for (int x = begin; x < end; ++x) {
    const int X = (row.x0 + row.adelta[x]) >> kFractionBits;
    const int Y = (row.y0 + row.bdelta[x]) >> kFractionBits;
    const int fx = X & 31, fy = Y & 31;
    const std::uint8_t* p = row.source->data + (Y >> kFractionBits) * row.source->stride + 2 * (X >> kFractionBits);
    const int p00 = p[0], p10 = p[1], p01 = p[2], p11 = p[3];
    const int w00 = (32 - fx) * (32 - fy), w01 = fx * (32 - fy), w10 = (32 - fx) * fy, w11 = fx * fy;
    bool ok = true;
    if (!all_mapped) {
      ok = (p00 != 0 || w00 == 0) && (p01 != 0 || w01 == 0) && (p10 != 0 || w10 == 0) && (p11 != 0 || w11 == 0);
    }
    out[x] = ok ? static_cast<std::uint8_t>((w00 * p00 + w01 * p01 + w10 * p10 + w11 * p11 + 512) >> 10) : 0;
    if (mask) mask[x] = ok ? 255 : 0;
    valid += ok ? 1 : 0;
  }
  return valid;
}

#ifdef MOSAICLOC_WARP_AVX2
// The same arithmetic eight pixels at a time. One 32-bit load per pixel fetches
// (p00, p10, p01, p11); an unsigned-by-signed byte multiply-add with (32 - fy, fy) gives
// the two columns' vertical blends 32 p(c) in 16 bits, a 16-bit multiply-add with
// (32 - fx, fx) their sum, exactly sum w p.
#define MOSAICLOC_AVX2_INLINE __attribute__((target("avx2"), always_inline)) inline

// The four bytes at each of eight byte offsets. Eight loads beat one gather instruction on
// the processors measured (AMD Zen 3: 0.34 against 0.40 ms for a 640 x 480 view). The
// offsets are unsigned, so each indexes a load as extracted, without a sign extension.
MOSAICLOC_AVX2_INLINE __m256i LoadQuads(const std::uint8_t* data, __m256i offset) {
  alignas(32) std::uint32_t offsets[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(offsets), offset);
  int quads[8];
  for (int k = 0; k < 8; ++k) std::memcpy(&quads[k], data + offsets[k], 4);
  return _mm256_setr_epi32(quads[0], quads[1], quads[2], quads[3], quads[4], quads[5], quads[6], quads[7]);
}

// What the vector path needs of a row, in registers.
struct RowAvx2 {
  const std::uint8_t* data;
  const int* adelta;
  const int* bdelta;
  __m256i x0, y0;
  __m256i stride;  // 16-bit pairs (1, stride): madd with (2 ix, iy) gives the byte offset
};

MOSAICLOC_AVX2_INLINE __m256i EightAvx2(const RowAvx2& row, int at, bool all_mapped, __m256i* good) {
  const __m256i m31 = _mm256_set1_epi32(31);
  const __m256i m32 = _mm256_set1_epi32(32);
  const __m256i X = _mm256_srai_epi32(
      _mm256_add_epi32(row.x0, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(row.adelta + at))), kFractionBits);
  const __m256i Y = _mm256_srai_epi32(
      _mm256_add_epi32(row.y0, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(row.bdelta + at))), kFractionBits);
  // Byte offset iy stride + 2 ix, from 16-bit (2 ix, iy) pairs (both below 2^15).
  const __m256i index = _mm256_or_si256(_mm256_srai_epi32(X, kFractionBits - 1),
                                        _mm256_slli_epi32(_mm256_srai_epi32(Y, kFractionBits), 16));
  const __m256i offset = _mm256_madd_epi16(_mm256_and_si256(index, _mm256_set1_epi32(~1)), row.stride);
  const __m256i fx = _mm256_and_si256(X, m31);
  const __m256i fy = _mm256_and_si256(Y, m31);
  const __m256i wy = _mm256_or_si256(_mm256_sub_epi32(m32, fy), _mm256_slli_epi32(fy, 8));  // bytes (32 - fy, fy)
  const __m256i wy2 = _mm256_or_si256(wy, _mm256_slli_epi32(wy, 16));
  const __m256i wx = _mm256_or_si256(_mm256_sub_epi32(m32, fx), _mm256_slli_epi32(fx, 16));  // words (32 - fx, fx)
  const __m256i p = LoadQuads(row.data, offset);
  const __m256i sum = _mm256_madd_epi16(_mm256_maddubs_epi16(p, wy2), wx);
  __m256i value = _mm256_srai_epi32(_mm256_add_epi32(sum, _mm256_set1_epi32(512)), 10);
  if (!all_mapped) {
    // The mapped neighbours carry all the weight exactly when no neighbour of non-zero
    // weight is unmapped.
    const __m256i mapped = _mm256_madd_epi16(_mm256_maddubs_epi16(_mm256_min_epu8(p, _mm256_set1_epi8(1)), wy2), wx);
    *good = _mm256_cmpeq_epi32(mapped, _mm256_set1_epi32(1024));
    value = _mm256_and_si256(value, *good);
  }
  return value;
}

__attribute__((target("avx2"))) int RowInsideAvx2(const Row& scalar_row, int end, std::uint8_t* out,
                                                   std::uint8_t* mask, bool all_mapped, int* done) {
  // Copies in registers: the byte stores below could alias anything the compiler must
  // otherwise reload.
  const RowAvx2 row{scalar_row.source->data, scalar_row.adelta, scalar_row.bdelta, _mm256_set1_epi32(scalar_row.x0),
                    _mm256_set1_epi32(scalar_row.y0),
                    _mm256_set1_epi32(1 | static_cast<int>(scalar_row.source->stride << 16))};
  int valid = 0;
  int x = 0;
  for (; x + 16 <= end; x += 16) {
    __m256i good_a = _mm256_set1_epi32(-1), good_b = good_a;
    const __m256i a = EightAvx2(row, x, all_mapped, &good_a);
    const __m256i b = EightAvx2(row, x + 8, all_mapped, &good_b);
    // 2 x 8 int32 -> 16 uint8 in order.
    const __m256i words = _mm256_permute4x64_epi64(_mm256_packus_epi32(a, b), 0xD8);
    const __m128i bytes = _mm_packus_epi16(_mm256_castsi256_si128(words), _mm256_extracti128_si256(words, 1));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x), bytes);
    if (all_mapped && !mask) {
      valid += 16;
      continue;
    }
    const __m256i good_words = _mm256_permute4x64_epi64(_mm256_packs_epi32(good_a, good_b), 0xD8);
    const __m128i good_bytes = _mm_packs_epi16(_mm256_castsi256_si128(good_words), _mm256_extracti128_si256(good_words, 1));
    if (mask) _mm_storeu_si128(reinterpret_cast<__m128i*>(mask + x), good_bytes);
    valid += __builtin_popcount(static_cast<unsigned>(_mm_movemask_epi8(good_bytes)));
  }
  *done = x;
  return valid;
}

// The same arithmetic sixteen pixels at a time, positions in 16 bits. With x0 = 32 q + r and
// adelta = 32 qa + ra (0 <= r, ra < 32), X = (x0 + adelta) >> 5 = q + qa + ((r + ra) >> 5):
// exact in wrapping 16-bit arithmetic when X < 2^16, which holds for rasters of at most
// 2048 columns. Words (2 ix, iy) interleaved by unpacklo / unpackhi give pixels 0-3, 8-11
// and 4-7, 12-15, which packing puts back in order.
struct Row16Avx2 {
  const std::uint8_t* data;
  const std::int16_t* qa;  // per column: adelta >> 5, wrapped to 16 bits
  const std::int16_t* ra;  // adelta & 31
  const std::int16_t* qb;  // bdelta likewise
  const std::int16_t* rb;
  __m256i qx, rx, qy, ry;  // the row's x0 and y0 split likewise, broadcast
  __m256i stride;          // 16-bit pairs (1, stride)
};

MOSAICLOC_AVX2_INLINE __m256i Load16(const std::int16_t* words) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(words));
}

MOSAICLOC_AVX2_INLINE __m256i Broadcast16(int value) { return _mm256_set1_epi16(static_cast<std::int16_t>(value)); }

// 8 x int32 (lanes of pixels 0-3, 8-11) and (4-7, 12-15) -> 16 bytes of pixels 0-15.
MOSAICLOC_AVX2_INLINE __m128i PackSixteen(__m256i low, __m256i high, bool saturate_signed) {
  const __m256i words = saturate_signed ? _mm256_packs_epi32(low, high) : _mm256_packus_epi32(low, high);
  const __m256i bytes = saturate_signed ? _mm256_packs_epi16(words, words) : _mm256_packus_epi16(words, words);
  return _mm256_castsi256_si128(_mm256_permute4x64_epi64(bytes, 0x08));
}

template <bool kAllMapped, bool kMask>
MOSAICLOC_AVX2_INLINE int SixteenAvx2(const Row16Avx2& row, int at, std::uint8_t* out, std::uint8_t* mask) {
  const __m256i m31 = _mm256_set1_epi16(31);
  const __m256i X = _mm256_add_epi16(_mm256_add_epi16(row.qx, Load16(row.qa + at)),
                                     _mm256_srli_epi16(_mm256_add_epi16(row.rx, Load16(row.ra + at)), kFractionBits));
  const __m256i Y = _mm256_add_epi16(_mm256_add_epi16(row.qy, Load16(row.qb + at)),
                                     _mm256_srli_epi16(_mm256_add_epi16(row.ry, Load16(row.rb + at)), kFractionBits));
  const __m256i two_ix = _mm256_and_si256(_mm256_srli_epi16(X, kFractionBits - 1), _mm256_set1_epi16(~1));
  const __m256i iy = _mm256_srli_epi16(Y, kFractionBits);
  const __m256i offset_low = _mm256_madd_epi16(_mm256_unpacklo_epi16(two_ix, iy), row.stride);
  const __m256i offset_high = _mm256_madd_epi16(_mm256_unpackhi_epi16(two_ix, iy), row.stride);
  const __m256i fx = _mm256_and_si256(X, m31);
  const __m256i fy = _mm256_and_si256(Y, m31);
  // Bytes (32 - fy, fy) are the word 32 + 255 fy; words (32 - fx, fx) pair up by unpacking.
  const __m256i wy = _mm256_add_epi16(_mm256_mullo_epi16(fy, _mm256_set1_epi16(255)), _mm256_set1_epi16(32));
  const __m256i wy_low = _mm256_unpacklo_epi16(wy, wy), wy_high = _mm256_unpackhi_epi16(wy, wy);
  const __m256i fx_complement = _mm256_sub_epi16(_mm256_set1_epi16(32), fx);
  const __m256i wx_low = _mm256_unpacklo_epi16(fx_complement, fx), wx_high = _mm256_unpackhi_epi16(fx_complement, fx);
  const __m256i p_low = LoadQuads(row.data, offset_low);
  const __m256i p_high = LoadQuads(row.data, offset_high);
  const __m256i half = _mm256_set1_epi32(512);
  __m256i value_low =
      _mm256_srai_epi32(_mm256_add_epi32(_mm256_madd_epi16(_mm256_maddubs_epi16(p_low, wy_low), wx_low), half), 10);
  __m256i value_high =
      _mm256_srai_epi32(_mm256_add_epi32(_mm256_madd_epi16(_mm256_maddubs_epi16(p_high, wy_high), wx_high), half), 10);
  if constexpr (kAllMapped) {
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + at), PackSixteen(value_low, value_high, false));
    if constexpr (kMask) _mm_storeu_si128(reinterpret_cast<__m128i*>(mask + at), _mm_set1_epi8(-1));
    return 16;
  }
  // The mapped neighbours carry all the weight exactly when no neighbour of non-zero weight
  // is unmapped.
  const __m256i one = _mm256_set1_epi8(1), full = _mm256_set1_epi32(1024);
  const __m256i good_low = _mm256_cmpeq_epi32(
      _mm256_madd_epi16(_mm256_maddubs_epi16(_mm256_min_epu8(p_low, one), wy_low), wx_low), full);
  const __m256i good_high = _mm256_cmpeq_epi32(
      _mm256_madd_epi16(_mm256_maddubs_epi16(_mm256_min_epu8(p_high, one), wy_high), wx_high), full);
  value_low = _mm256_and_si256(value_low, good_low);
  value_high = _mm256_and_si256(value_high, good_high);
  _mm_storeu_si128(reinterpret_cast<__m128i*>(out + at), PackSixteen(value_low, value_high, false));
  const __m128i good = PackSixteen(good_low, good_high, true);
  if constexpr (kMask) _mm_storeu_si128(reinterpret_cast<__m128i*>(mask + at), good);
  return __builtin_popcount(static_cast<unsigned>(_mm_movemask_epi8(good)));
}

// One loop per case, so that none tests the case per pixel.
template <bool kAllMapped, bool kMask>
__attribute__((target("avx2"))) int Sixteens(const Row16Avx2& row, int width, std::uint8_t* out, std::uint8_t* mask,
                                             int* done) {
  int valid = 0;
  int x = 0;
  for (; x + 16 <= width; x += 16) valid += SixteenAvx2<kAllMapped, kMask>(row, x, out, mask);
  *done = x;
  return valid;
}

__attribute__((target("avx2"))) int RowInside16Avx2(const Row& scalar_row, const std::int16_t* split, int width,
                                                     std::uint8_t* out, std::uint8_t* mask, bool all_mapped,
                                                     int* done) {
  const std::size_t n = static_cast<std::size_t>(width);
  const Row16Avx2 row{scalar_row.source->data,
                      split,
                      split + n,
                      split + 2 * n,
                      split + 3 * n,
                      Broadcast16(scalar_row.x0 >> kFractionBits),
                      Broadcast16(scalar_row.x0 & 31),
                      Broadcast16(scalar_row.y0 >> kFractionBits),
                      Broadcast16(scalar_row.y0 & 31),
                      _mm256_set1_epi32(1 | static_cast<int>(scalar_row.source->stride << 16))};
  if (all_mapped) {
    return mask ? Sixteens<true, true>(row, width, out, mask, done) : Sixteens<true, false>(row, width, out, mask, done);
  }
  return mask ? Sixteens<false, true>(row, width, out, mask, done) : Sixteens<false, false>(row, width, out, mask, done);
}

bool HaveAvx2() {
  static const bool have = __builtin_cpu_supports("avx2");
  return have;
}
#endif

}  // namespace

#ifdef MOSAICLOC_WARP_AVX2
namespace {

MOSAICLOC_AVX2_INLINE void Interleave32(const std::uint8_t* top, const std::uint8_t* bottom, std::uint8_t* pairs) {
  const __m256i a = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(top));
  const __m256i b = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(bottom));
  const __m256i low = _mm256_unpacklo_epi8(a, b), high = _mm256_unpackhi_epi8(a, b);  // in-lane
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(pairs), _mm256_permute2x128_si256(low, high, 0x20));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(pairs + 32), _mm256_permute2x128_si256(low, high, 0x31));
}

__attribute__((target("avx2"))) void InterleaveAvx2(const std::uint8_t* top, const std::uint8_t* bottom, int count,
                                                    std::uint8_t* pairs) {
  int c = 0;
  for (; c + 32 <= count; c += 32) Interleave32(top + c, bottom + c, pairs + 2 * c);
  // The rest as one more block ending at the last column, over pairs already written.
  if (c < count) Interleave32(top + count - 32, bottom + count - 32, pairs + 2 * (count - 32));
}

void Interleave16(const std::uint8_t* top, const std::uint8_t* bottom, std::uint8_t* pairs) {  // SSE2
  const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(top));
  const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(bottom));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(pairs), _mm_unpacklo_epi8(a, b));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(pairs + 16), _mm_unpackhi_epi8(a, b));
}

}  // namespace
#endif

void InterleaveRows(const std::uint8_t* top, const std::uint8_t* bottom, int count, std::uint8_t* pairs) {
#ifdef MOSAICLOC_WARP_AVX2
  // Whole vectors only, never past `count`: the rows end at tile and buffer edges.
  if (count >= 32 && HaveAvx2()) {
    InterleaveAvx2(top, bottom, count, pairs);
    return;
  }
  if (count >= 16) {
    int c = 0;
    for (; c + 16 <= count; c += 16) Interleave16(top + c, bottom + c, pairs + 2 * c);
    if (c < count) Interleave16(top + count - 16, bottom + count - 16, pairs + 2 * (count - 16));
    return;
  }
#endif
  for (int c = 0; c < count; ++c) {
    pairs[2 * c] = top[c];
    pairs[2 * c + 1] = bottom[c];
  }
}

PairRaster MakePairRaster(const cv::Mat& image, cv::Mat& storage) {
  CV_Assert(image.type() == CV_8UC1 && image.rows >= 2);
  storage.create(image.rows - 1, 2 * image.cols, CV_8UC1);
  for (int r = 0; r + 1 < image.rows; ++r) {
    InterleaveRows(image.ptr<std::uint8_t>(r), image.ptr<std::uint8_t>(r + 1), image.cols, storage.ptr<std::uint8_t>(r));
  }
  return PairRaster{storage.data, static_cast<std::ptrdiff_t>(storage.step[0]), image.cols, image.rows};
}

int WarpAffineBilinear(const PairRaster& source, const double map[6], cv::Mat& out, cv::Mat* mask,
                       bool source_all_mapped) {
  CV_Assert(!out.empty() && out.type() == CV_8UC1 && source.rows >= 2 && source.cols >= 1 &&
            static_cast<double>(source.stride) * source.rows < 2147483647.0);
  const int width = out.cols, height = out.rows;
  if (mask) mask->create(out.size(), CV_8UC1);
  thread_local std::vector<int> delta;
  delta.resize(2 * static_cast<std::size_t>(width) + 16);
  int* adelta = delta.data();
  int* bdelta = delta.data() + width + 8;
  for (int x = 0; x < width; ++x) {
    adelta[x] = Round(map[0] * x * kAbScale);
    bdelta[x] = Round(map[3] * x * kAbScale);
  }
  Row row{&source, adelta, bdelta, 0, 0};
  // The vector paths pack (2 ix, iy) and the stride into 16 bits; the sixteen-pixel one
  // also the positions X and Y, in 1/32 px.
  const bool vector = source.cols < (1 << 14) && source.rows < (1 << 15) && source.stride < (1 << 15);
  const bool vector16 = vector && source.cols <= 2048 && source.rows <= 2048;
  thread_local std::vector<std::int16_t> split;  // qa, ra, qb, rb of each column (see Row16Avx2)
  if (vector16) {
    split.resize(4 * static_cast<std::size_t>(width));
    for (int x = 0; x < width; ++x) {
      split[x] = static_cast<std::int16_t>(adelta[x] >> kFractionBits);
      split[width + x] = static_cast<std::int16_t>(adelta[x] & 31);
      split[2 * width + x] = static_cast<std::int16_t>(bdelta[x] >> kFractionBits);
      split[3 * width + x] = static_cast<std::int16_t>(bdelta[x] & 31);
    }
  }
  int valid = 0;
  for (int y = 0; y < height; ++y) {
    row.x0 = Round((map[1] * y + map[2]) * kAbScale) + kRoundDelta;
    row.y0 = Round((map[4] * y + map[5]) * kAbScale) + kRoundDelta;
    std::uint8_t* o = out.ptr<std::uint8_t>(y);
    std::uint8_t* m = mask ? mask->ptr<std::uint8_t>(y) : nullptr;
    // Positions are monotonic along a row, so all its samples have their four neighbours
    // in the source when its two ends do.
    const auto inside = [&](int x) {
      const int X = (row.x0 + adelta[x]) >> kFractionBits;
      const int Y = (row.y0 + bdelta[x]) >> kFractionBits;
      const int ix = X >> kFractionBits, iy = Y >> kFractionBits;
      return ix >= 0 && iy >= 0 && ix + 1 < source.cols && iy + 1 < source.rows;
    };
    if (width > 0 && inside(0) && inside(width - 1)) {
      int x = 0;
#ifdef MOSAICLOC_WARP_AVX2
      if (vector16 && HaveAvx2()) {
        valid += RowInside16Avx2(row, split.data(), width, o, m, source_all_mapped, &x);
      } else if (vector && HaveAvx2()) {
        valid += RowInsideAvx2(row, width, o, m, source_all_mapped, &x);
      }
#endif
      valid += RowInsideScalar(row, x, width, o, m, source_all_mapped);
      continue;
    }
    for (int x = 0; x < width; ++x) {
      const bool ok = SamplePixel(row, x, o + x);
      if (m) m[x] = ok ? 255 : 0;
      valid += ok ? 1 : 0;
    }
  }
  return valid;
}

}  // namespace mosaicloc::mosaic::internal
