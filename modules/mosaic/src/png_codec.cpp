#include "png_codec.hpp"

#include <png.h>

#include <algorithm>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::mosaic::internal {
namespace {

// libpng reports errors by calling back and never returning: the callback keeps the
// message and jumps back to the setjmp of the function that drives libpng. Every C++
// object those functions use lives from before their setjmp, so the jump skips no
// destructor.
struct PngErrorState {
  char message[192] = "";
};

[[noreturn]] void OnPngError(png_structp png, png_const_charp message) {
  auto* state = static_cast<PngErrorState*>(png_get_error_ptr(png));
  std::snprintf(state->message, sizeof(state->message), "%s", message);
  png_longjmp(png, 1);
}

void OnPngWarning(png_structp, png_const_charp) {}

struct PngSource {
  const unsigned char* data;
  std::size_t bytes;
  std::size_t offset;
};

void ReadPngSource(png_structp png, png_bytep out, png_size_t length) {
  auto* source = static_cast<PngSource*>(png_get_io_ptr(png));
  if (length > source->bytes - source->offset) png_error(png, "the data ends early");
  std::memcpy(out, source->data + source->offset, length);
  source->offset += length;
}

void AppendPngBytes(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::vector<unsigned char>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + length);
}

void FlushNothing(png_structp) {}

// The bytes of a PNG's IDAT chunks, read in order as one zlib stream.
class IdatStream {
 public:
  void Add(const unsigned char* data, std::size_t bytes) {
    if (bytes > 0) segments_.push_back({data, bytes});
  }
  // Copies the next `bytes` bytes to `out`; false if the stream is shorter.
  bool Read(unsigned char* out, std::size_t bytes) {
    while (bytes > 0) {
      if (segment_ == segments_.size()) return false;
      const Segment& s = segments_[segment_];
      const std::size_t n = std::min(bytes, s.bytes - offset_);
      std::memcpy(out, s.data + offset_, n);
      out += n;
      bytes -= n;
      offset_ += n;
      if (offset_ == s.bytes) {
        ++segment_;
        offset_ = 0;
      }
    }
    return true;
  }
  // The next `bytes` bytes in place if they lie in one chunk (then skipped), else null.
  const unsigned char* Contiguous(std::size_t bytes) {
    if (segment_ == segments_.size() || segments_[segment_].bytes - offset_ < bytes) return nullptr;
    const unsigned char* p = segments_[segment_].data + offset_;
    offset_ += bytes;
    if (offset_ == segments_[segment_].bytes) {
      ++segment_;
      offset_ = 0;
    }
    return p;
  }

 private:
  struct Segment {
    const unsigned char* data;
    std::size_t bytes;
  };
  std::vector<Segment> segments_;
  std::size_t segment_ = 0, offset_ = 0;
};

std::uint32_t BigEndian32(const unsigned char* p) {
  return static_cast<std::uint32_t>(p[0]) << 24 | static_cast<std::uint32_t>(p[1]) << 16 |
         static_cast<std::uint32_t>(p[2]) << 8 | static_cast<std::uint32_t>(p[3]);
}

}  // namespace

bool DecodeStoredGreyPng(const unsigned char* data, std::size_t bytes, int size_px, cv::Mat& pixels) {
  if (size_px <= 0 || bytes < 8 + 25 || png_sig_cmp(data, 0, 8) != 0) return false;
  // IHDR first: size_px square, 8-bit grey, no interlace.
  const unsigned char* ihdr = data + 8;
  if (BigEndian32(ihdr) != 13 || std::memcmp(ihdr + 4, "IHDR", 4) != 0) return false;
  const unsigned char* h = ihdr + 8;
  const auto side = static_cast<std::uint32_t>(size_px);
  if (BigEndian32(h) != side || BigEndian32(h + 4) != side || h[8] != 8 || h[9] != 0 || h[10] != 0 || h[11] != 0 ||
      h[12] != 0) {
    return false;
  }
  // The chunks up to IEND: IDATs gathered, ancillary ones (lower-case first letter) skipped,
  // any other critical one left to libpng.
  IdatStream stream;
  bool ended = false;
  for (std::size_t at = 8 + 25; !ended;) {
    if (bytes - at < 12) return false;
    const std::uint32_t length = BigEndian32(data + at);
    const unsigned char* type = data + at + 4;
    if (length > bytes - at - 12) return false;
    if (std::memcmp(type, "IDAT", 4) == 0) {
      stream.Add(data + at + 8, length);
    } else if (std::memcmp(type, "IEND", 4) == 0) {
      ended = true;
    } else if ((type[0] & 0x20) == 0) {
      return false;
    }
    at += 12 + static_cast<std::size_t>(length);
  }
  // zlib header: deflate, no preset dictionary.
  unsigned char header[2];
  if (!stream.Read(header, 2) || (header[0] & 0x0F) != 8 || (header[0] * 256 + header[1]) % 31 != 0 ||
      (header[1] & 0x20) != 0) {
    return false;
  }
  // Stored blocks only; each row a 0 (no filter) byte and its pixels. The Adler-32 after the
  // last block is not checked: the caller has verified the whole PNG's CRC32.
  pixels.create(size_px, size_px, CV_8UC1);
  const std::size_t row_bytes = side + 1;
  const std::size_t total = row_bytes * side;
  std::size_t produced = 0;
  for (bool last = false; !last;) {
    unsigned char block[5];
    if (!stream.Read(block, 5) || (block[0] & 0x06) != 0) return false;
    last = (block[0] & 0x01) != 0;
    std::size_t length = block[1] | static_cast<std::size_t>(block[2]) << 8;
    const std::size_t complement = block[3] | static_cast<std::size_t>(block[4]) << 8;
    if ((length ^ complement) != 0xFFFF || length > total - produced) return false;
    while (length > 0) {
      const std::size_t column = produced % row_bytes;
      // A whole row in one chunk (nearly all): its filter byte and pixels in one step.
      if (column == 0 && length >= row_bytes) {
        if (const unsigned char* row = stream.Contiguous(row_bytes)) {
          if (row[0] != 0) return false;
          std::memcpy(pixels.ptr(static_cast<int>(produced / row_bytes)), row + 1, side);
          produced += row_bytes;
          length -= row_bytes;
          continue;
        }
      }
      if (column == 0) {
        unsigned char filter = 0;
        if (!stream.Read(&filter, 1) || filter != 0) return false;
        ++produced;
        --length;
        continue;
      }
      const std::size_t n = std::min(length, row_bytes - column);
      if (!stream.Read(pixels.ptr(static_cast<int>(produced / row_bytes)) + (column - 1), n)) return false;
      produced += n;
      length -= n;
    }
  }
  return produced == total;
}

namespace {
}  // namespace

std::vector<unsigned char> EncodeGreyPng(const cv::Mat& pixels, int zlib_level) {
  if (pixels.type() != CV_8UC1 || pixels.empty()) core::ThrowInvalidInput("a PNG tile must be a non-empty 8-bit grey image");
  std::vector<unsigned char> out;
  // Level 0 stores the rows as they are: one filter byte per row and a few bytes per
  // stored block and chunk on top.
  out.reserve(pixels.total() + static_cast<std::size_t>(pixels.rows) + 4096);
  std::vector<png_bytep> rows(static_cast<std::size_t>(pixels.rows));
  for (int r = 0; r < pixels.rows; ++r) rows[static_cast<std::size_t>(r)] = const_cast<png_bytep>(pixels.ptr(r));
  PngErrorState error;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, OnPngError, OnPngWarning);
  if (png == nullptr) core::ThrowRuntime("libpng cannot start a PNG encoder");
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    core::ThrowRuntime("libpng cannot start a PNG encoder");
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    core::ThrowRuntime(std::string("cannot encode a map tile as PNG: ") + error.message);
  }
  png_set_write_fn(png, &out, AppendPngBytes, FlushNothing);
  png_set_IHDR(png, info, static_cast<png_uint_32>(pixels.cols), static_cast<png_uint_32>(pixels.rows), 8,
               PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, zlib_level);
  // Filters only help a compressor; without one they are work for the decoder.
  if (zlib_level == 0) png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_NONE);
  png_write_info(png, info);
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

std::string DecodeGreyPng(const unsigned char* data, std::size_t bytes, int size_px, cv::Mat& pixels) {
  if (DecodeStoredGreyPng(data, bytes, size_px, pixels)) return {};
  if (bytes < 8 || png_sig_cmp(data, 0, 8) != 0) return "not a decodable PNG: no PNG signature";
  pixels.create(size_px, size_px, CV_8UC1);
  std::vector<png_bytep> rows(static_cast<std::size_t>(size_px));
  for (int r = 0; r < size_px; ++r) rows[static_cast<std::size_t>(r)] = pixels.ptr(r);
  PngSource source{data, bytes, 0};
  PngErrorState error;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &error, OnPngError, OnPngWarning);
  if (png == nullptr) return "not a decodable PNG: libpng cannot start a decoder";
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    return "not a decodable PNG: libpng cannot start a decoder";
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return std::string("not a decodable PNG: ") + error.message;
  }
  png_set_read_fn(png, &source, ReadPngSource);
  png_set_crc_action(png, PNG_CRC_QUIET_USE, PNG_CRC_QUIET_USE);
#ifdef PNG_IGNORE_ADLER32
  png_set_option(png, PNG_IGNORE_ADLER32, PNG_OPTION_ON);
#endif
  png_read_info(png, info);
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, color_type = 0, interlace = 0;
  png_get_IHDR(png, info, &width, &height, &bit_depth, &color_type, &interlace, nullptr, nullptr);
  if (bit_depth != 8 || color_type != PNG_COLOR_TYPE_GRAY || width != static_cast<png_uint_32>(size_px) ||
      height != static_cast<png_uint_32>(size_px)) {
    png_destroy_read_struct(&png, &info, nullptr);
    return "is a " + std::to_string(width) + " x " + std::to_string(height) + " PNG of " + std::to_string(bit_depth) +
           "-bit samples, colour type " + std::to_string(color_type) + ", not an 8-bit grey " + std::to_string(size_px) +
           " px square";
  }
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  png_read_image(png, rows.data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return {};
}

}  // namespace mosaicloc::mosaic::internal
