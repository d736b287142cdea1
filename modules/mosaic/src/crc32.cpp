#include "crc32.hpp"

#include <zlib.h>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define MOSAICLOC_CRC32_FOLD 1
#endif

namespace mosaicloc::mosaic::internal {
namespace {

std::uint32_t ZlibCrc32(std::uint32_t crc, const unsigned char* data, std::size_t bytes) {
  return static_cast<std::uint32_t>(crc32_z(crc, data, bytes));
}

#ifdef MOSAICLOC_CRC32_FOLD

// CRC-32 (the reflected polynomial 0xEDB88320 of zlib and PNG) by carry-less multiplication,
// after Gopal et al., "Fast CRC Computation for Generic Polynomials Using PCLMULQDQ
// Instruction" (Intel, 2009). Four 128-bit lanes of the message are kept; each step
// multiplies a lane by x^(512+64) and x^512 mod P (the lane's two halves) and adds the next
// 64 bytes, which moves the lane 64 bytes further without changing its residue mod P. The
// lanes are then folded into one (x^(128+64), x^128 mod P), the remaining 16-byte blocks
// likewise, the 128 bits reduced to 64 and to the 32-bit remainder by Barrett reduction.
// The constants are those powers of x mod P, bit-reflected and shifted left by one (the
// product of two reflected 32..64-bit values is one bit short).
struct FoldConstants {
  std::uint64_t x544, x480;  // lanes 512 bits apart: x^(4*128+32) and x^(4*128-32) mod P
  std::uint64_t x160, x96;   // adjacent lanes: x^(128+32) and x^(128-32) mod P
  std::uint64_t x64;         // 128 -> 64 bits: x^64 mod P
  std::uint64_t p, mu;       // P itself (33 bits) and floor(x^64 / P), for Barrett
};
constexpr FoldConstants kFold{0x154442bd4ULL, 0x1c6e41596ULL, 0x1751997d0ULL, 0x0ccaa009eULL,
                              0x163cd6124ULL, 0x1db710641ULL, 0x1f7011641ULL};

// a * k_low(a's low half) + a * k_high(a's high half) + next: one lane moved on.
__attribute__((target("pclmul,sse4.1"))) inline __m128i FoldLane(__m128i lane, __m128i k, __m128i next) {
  const __m128i low = _mm_clmulepi64_si128(lane, k, 0x00);
  const __m128i high = _mm_clmulepi64_si128(lane, k, 0x11);
  return _mm_xor_si128(_mm_xor_si128(low, high), next);
}

// The CRC register (not inverted) after `bytes` (>= 64, a multiple of 16) more bytes.
__attribute__((target("pclmul,sse4.1"))) std::uint32_t Fold(std::uint32_t crc, const unsigned char* data,
                                                             std::size_t bytes) {
  const auto load = [](const unsigned char* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); };
  __m128i lane0 = _mm_xor_si128(load(data), _mm_cvtsi32_si128(static_cast<int>(crc)));
  __m128i lane1 = load(data + 16);
  __m128i lane2 = load(data + 32);
  __m128i lane3 = load(data + 48);
  data += 64;
  bytes -= 64;
  const __m128i far = _mm_set_epi64x(static_cast<long long>(kFold.x480), static_cast<long long>(kFold.x544));
  for (; bytes >= 64; bytes -= 64, data += 64) {
    lane0 = FoldLane(lane0, far, load(data));
    lane1 = FoldLane(lane1, far, load(data + 16));
    lane2 = FoldLane(lane2, far, load(data + 32));
    lane3 = FoldLane(lane3, far, load(data + 48));
  }
  const __m128i near = _mm_set_epi64x(static_cast<long long>(kFold.x96), static_cast<long long>(kFold.x160));
  __m128i acc = FoldLane(lane0, near, lane1);
  acc = FoldLane(acc, near, lane2);
  acc = FoldLane(acc, near, lane3);
  for (; bytes >= 16; bytes -= 16, data += 16) acc = FoldLane(acc, near, load(data));

  // 128 -> 96 bits: the low half times x^96 mod P onto the high half.
  const __m128i low32 = _mm_set_epi32(0, -1, 0, -1);
  __m128i t = _mm_clmulepi64_si128(acc, near, 0x10);
  acc = _mm_xor_si128(_mm_srli_si128(acc, 8), t);
  // 96 -> 64 bits: the low 32 times x^64 mod P onto the rest.
  t = _mm_srli_si128(acc, 4);
  acc = _mm_clmulepi64_si128(_mm_and_si128(acc, low32), _mm_set_epi64x(0, static_cast<long long>(kFold.x64)), 0x00);
  acc = _mm_xor_si128(acc, t);
  // Barrett: q = floor(R / P) from mu, R - q P is the remainder.
  const __m128i barrett = _mm_set_epi64x(static_cast<long long>(kFold.mu), static_cast<long long>(kFold.p));
  t = _mm_clmulepi64_si128(_mm_and_si128(acc, low32), barrett, 0x10);
  t = _mm_clmulepi64_si128(_mm_and_si128(t, low32), barrett, 0x00);
  acc = _mm_xor_si128(acc, t);
  return static_cast<std::uint32_t>(_mm_extract_epi32(acc, 1));
}

bool HasFold() {
  static const bool has = __builtin_cpu_supports("pclmul") && __builtin_cpu_supports("sse4.1");
  return has;
}

#endif

}  // namespace

std::uint32_t Crc32Update(std::uint32_t crc, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
#ifdef MOSAICLOC_CRC32_FOLD
  if (bytes >= 64 && HasFold()) {
    const std::size_t folded = bytes & ~static_cast<std::size_t>(15);
    // zlib's crc32 takes and returns the inverted register.
    const std::uint32_t reg = Fold(~crc, p, folded);
    return ZlibCrc32(~reg, p + folded, bytes - folded);
  }
#endif
  return ZlibCrc32(crc, p, bytes);
}

std::uint32_t Crc32ZlibOnly(std::uint32_t crc, const void* data, std::size_t bytes) {
  return ZlibCrc32(crc, static_cast<const unsigned char*>(data), bytes);
}

}  // namespace mosaicloc::mosaic::internal
