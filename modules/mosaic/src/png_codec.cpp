#include "png_codec.hpp"

#include <png.h>

#include <csetjmp>
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
