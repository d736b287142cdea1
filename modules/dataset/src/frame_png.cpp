#include "mosaicloc/dataset/frame_png.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

#include <libdeflate.h>
#include <opencv2/imgcodecs.hpp>

namespace mosaicloc::dataset {
namespace {

constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
// Larger images are left to OpenCV and its own limits.
constexpr std::uint64_t kMaxRawBytes = std::uint64_t{1} << 30;

std::uint32_t BigEndian32(const unsigned char* p) {
  return static_cast<std::uint32_t>(p[0]) << 24 | static_cast<std::uint32_t>(p[1]) << 16 |
         static_cast<std::uint32_t>(p[2]) << 8 | static_cast<std::uint32_t>(p[3]);
}

struct FreeDecompressor {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

libdeflate_decompressor* Decompressor() {
  thread_local std::unique_ptr<libdeflate_decompressor, FreeDecompressor> decompressor(
      libdeflate_alloc_decompressor());
  return decompressor.get();
}

int Paeth(int a, int b, int c) {
  const int p = a + b - c;
  const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

// One row of one-byte pixels unfiltered into `out` (PNG's five filters); `up` is the row above,
// zeros for the first. False for an unknown filter type.
bool Unfilter(unsigned char filter, const unsigned char* in, const unsigned char* up, unsigned char* out,
              std::size_t width) {
  switch (filter) {
    case 0:
      std::memcpy(out, in, width);
      return true;
    case 1: {
      unsigned char left = 0;
      for (std::size_t x = 0; x < width; ++x) out[x] = left = static_cast<unsigned char>(in[x] + left);
      return true;
    }
    case 2:
      for (std::size_t x = 0; x < width; ++x) out[x] = static_cast<unsigned char>(in[x] + up[x]);
      return true;
    case 3: {
      int left = 0;
      for (std::size_t x = 0; x < width; ++x) {
        out[x] = static_cast<unsigned char>(in[x] + ((left + up[x]) >> 1));
        left = out[x];
      }
      return true;
    }
    case 4: {
      int left = 0, upper_left = 0;
      for (std::size_t x = 0; x < width; ++x) {
        out[x] = static_cast<unsigned char>(in[x] + Paeth(left, up[x], upper_left));
        left = out[x];
        upper_left = up[x];
      }
      return true;
    }
    default:
      return false;
  }
}

}  // namespace

bool DecodeGreyPng(const unsigned char* bytes, std::size_t size, cv::Mat& pixels) {
  // The signature and IHDR first: 8-bit grey, deflate, PNG's filters, no interlace.
  if (size < 8 + 25 || std::memcmp(bytes, kSignature, 8) != 0) return false;
  const unsigned char* ihdr = bytes + 8;
  if (BigEndian32(ihdr) != 13 || std::memcmp(ihdr + 4, "IHDR", 4) != 0) return false;
  if (libdeflate_crc32(0, ihdr + 4, 17) != BigEndian32(ihdr + 21)) return false;
  const unsigned char* h = ihdr + 8;
  const std::uint32_t width = BigEndian32(h), height = BigEndian32(h + 4);
  if (width == 0 || height == 0 || width > 0x7FFFFFFF || height > 0x7FFFFFFF || h[8] != 8 || h[9] != 0 || h[10] != 0 ||
      h[11] != 0 || h[12] != 0) {
    return false;
  }
  const std::uint64_t row_bytes = std::uint64_t{width} + 1;
  const std::uint64_t raw_bytes = row_bytes * height;
  if (raw_bytes > kMaxRawBytes) return false;
  // The chunks up to IEND, each checked against its CRC and its type made of letters: the
  // IDATs' data gathered (they must follow one another), ancillary chunks (a lower-case first
  // letter) passed over, any other critical one refused.
  thread_local std::vector<unsigned char> stream;
  stream.clear();
  enum { kBefore, kInside, kAfter } idat = kBefore;
  bool ended = false;
  for (std::size_t at = 8 + 25; !ended;) {
    if (size - at < 12) return false;
    const std::uint32_t length = BigEndian32(bytes + at);
    if (length > size - at - 12) return false;
    const unsigned char* type = bytes + at + 4;
    if (!std::all_of(type, type + 4, [](unsigned char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'); })) {
      return false;
    }
    if (libdeflate_crc32(0, type, 4 + std::size_t{length}) != BigEndian32(type + 4 + length)) return false;
    if (std::memcmp(type, "IDAT", 4) == 0) {
      if (idat == kAfter) return false;
      idat = kInside;
      stream.insert(stream.end(), type + 4, type + 4 + length);
    } else {
      if (idat == kInside) idat = kAfter;
      if (std::memcmp(type, "IEND", 4) == 0) {
        ended = true;
      } else if ((type[0] & 0x20) == 0) {
        return false;
      }
    }
    at += 12 + std::size_t{length};
  }
  // Deflate packs at most 1032 bytes into one, so a header that claims more image than its
  // data can hold is refused before anything that size is allocated.
  if (idat == kBefore || raw_bytes > 1032 * std::uint64_t{stream.size()} + 1024) return false;
  // The rows, each a filter byte and its pixels, inflated in one call (the Adler-32 checked).
  thread_local std::vector<unsigned char> raw;
  raw.resize(raw_bytes);
  if (libdeflate_zlib_decompress(Decompressor(), stream.data(), stream.size(), raw.data(), raw.size(), nullptr) !=
      LIBDEFLATE_SUCCESS) {
    return false;
  }
  pixels.create(static_cast<int>(height), static_cast<int>(width), CV_8UC1);
  thread_local std::vector<unsigned char> zeros;
  zeros.assign(width, 0);
  const unsigned char* up = zeros.data();
  for (std::uint32_t y = 0; y < height; ++y) {
    const unsigned char* row = raw.data() + row_bytes * y;
    unsigned char* out = pixels.ptr(static_cast<int>(y));
    if (!Unfilter(row[0], row + 1, up, out, width)) return false;
    up = out;
  }
  return true;
}

cv::Mat ReadImageFile(const std::filesystem::path& file) {
  thread_local std::vector<unsigned char> bytes;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> in(std::fopen(file.c_str(), "rb"), &std::fclose);
  if (!in) return cv::Mat();
  bytes.clear();
  unsigned char chunk[1 << 16];
  for (std::size_t n; (n = std::fread(chunk, 1, sizeof(chunk), in.get())) > 0;) {
    bytes.insert(bytes.end(), chunk, chunk + n);
  }
  if (std::ferror(in.get()) != 0 || bytes.empty()) return cv::Mat();
  cv::Mat pixels;
  if (DecodeGreyPng(bytes.data(), bytes.size(), pixels)) return pixels;
  try {
    return cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    return cv::Mat();  // as imread answers a file it cannot decode
  }
}

}  // namespace mosaicloc::dataset
