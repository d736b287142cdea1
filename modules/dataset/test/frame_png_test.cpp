#include "mosaicloc/dataset/frame_png.hpp"

#include <malloc.h>
#include <png.h>
#include <zlib.h>

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::dataset {
namespace {

namespace fs = std::filesystem;

// A grey image with texture, of an odd size: every filter has work at every column.
cv::Mat Texture(int rows, int cols, int seed) {
  cv::Mat image(rows, cols, CV_8UC1);
  cv::RNG rng(static_cast<std::uint64_t>(seed));
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols / 3; ++x) image.at<unsigned char>(y, x) = static_cast<unsigned char>(4 * x + y);
  }
  return image;
}

void AppendBytes(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::vector<unsigned char>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + length);
}

// An 8-bit grey PNG written by libpng with only the given row filter(s), in IDAT chunks of
// `chunk_bytes`, interlaced or not.
std::vector<unsigned char> Encode(const cv::Mat& image, int filters, std::size_t chunk_bytes, bool interlace = false) {
  std::vector<unsigned char> out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    ADD_FAILURE() << "libpng could not encode the test image";
    return {};
  }
  png_set_write_fn(png, &out, AppendBytes, nullptr);
  png_set_compression_buffer_size(png, chunk_bytes);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.cols), static_cast<png_uint_32>(image.rows), 8,
               PNG_COLOR_TYPE_GRAY, interlace ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, filters);
  const png_text text{PNG_TEXT_COMPRESSION_NONE, const_cast<char*>("Comment"), const_cast<char*>("an ancillary chunk"),
                      18, 0, nullptr, nullptr};
  png_set_text(png, info, &text, 1);
  png_write_info(png, info);
  std::vector<png_bytep> rows;
  for (int r = 0; r < image.rows; ++r) rows.push_back(const_cast<png_bytep>(image.ptr(r)));
  png_write_image(png, rows.data());
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return out;
}

// `png` with a chunk of `type` and `data` (its CRC right) inserted at byte `at`, a chunk boundary.
std::vector<unsigned char> WithChunk(const std::vector<unsigned char>& png, std::size_t at, const std::string& type,
                                     const std::string& data) {
  std::string chunk;
  const auto put32 = [&chunk](std::uint32_t v) {
    for (int shift = 24; shift >= 0; shift -= 8) chunk += static_cast<char>(v >> shift);
  };
  put32(static_cast<std::uint32_t>(data.size()));
  chunk += type + data;
  put32(static_cast<std::uint32_t>(
      crc32(0, reinterpret_cast<const Bytef*>(chunk.data()) + 4, static_cast<uInt>(chunk.size() - 4))));
  std::string out(png.begin(), png.end());
  out.insert(at, chunk);
  return std::vector<unsigned char>(out.begin(), out.end());
}

// The byte offsets of the chunks of `type`.
std::vector<std::size_t> ChunksOf(const std::vector<unsigned char>& png, const std::string& type) {
  std::vector<std::size_t> found;
  for (std::size_t at = 8; at + 12 <= png.size();) {
    const std::size_t length = std::size_t{png[at]} << 24 | std::size_t{png[at + 1]} << 16 |
                               std::size_t{png[at + 2]} << 8 | png[at + 3];
    if (std::equal(type.begin(), type.end(), png.begin() + static_cast<std::ptrdiff_t>(at + 4))) found.push_back(at);
    at += 12 + length;
  }
  return found;
}

bool Same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

void WriteBytes(const fs::path& file, const std::vector<unsigned char>& bytes) {
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                              static_cast<std::streamsize>(bytes.size()));
}

TEST(FramePng, EveryRowFilterDecodesToTheImage) {
  const cv::Mat image = Texture(37, 61, 1);
  for (const int filter : {PNG_FILTER_NONE, PNG_FILTER_SUB, PNG_FILTER_UP, PNG_FILTER_AVG, PNG_FILTER_PAETH,
                           PNG_ALL_FILTERS}) {
    const std::vector<unsigned char> png = Encode(image, filter, 8192);
    cv::Mat decoded;
    ASSERT_TRUE(DecodeGreyPng(png.data(), png.size(), decoded)) << "filter mask " << filter;
    EXPECT_TRUE(Same(decoded, image)) << "filter mask " << filter;
  }
}

TEST(FramePng, ManyIdatChunksAndTheRecordersOwnPngs) {
  // A frame as big as a camera's, its compressed rows split over 100-byte IDAT chunks.
  const cv::Mat image = Texture(480, 640, 2);
  const std::vector<unsigned char> png = Encode(image, PNG_ALL_FILTERS, 100);
  cv::Mat decoded;
  ASSERT_TRUE(DecodeGreyPng(png.data(), png.size(), decoded));
  EXPECT_TRUE(Same(decoded, image));
  // OpenCV's encoder, as the dataset writer uses it, at its default and highest levels.
  for (const std::vector<int>& params : {std::vector<int>{}, std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, 9}}) {
    std::vector<unsigned char> encoded;
    ASSERT_TRUE(cv::imencode(".png", image, encoded, params));
    ASSERT_TRUE(DecodeGreyPng(encoded.data(), encoded.size(), decoded));
    EXPECT_TRUE(Same(decoded, image));
  }
}

// What libpng refuses, this decoder refuses too: a chunk type that is not four letters (whose
// CRC may still hold: four 0xFF bytes have the CRC 0xFFFFFFFF), image data split by another
// chunk, a header that claims more image than its data can hold, and no image data at all.
TEST(FramePng, MalformedChunksAreRefused) {
  const cv::Mat image = Texture(40, 50, 4);
  const std::vector<unsigned char> good = Encode(image, PNG_ALL_FILTERS, 100);
  const std::vector<std::size_t> idats = ChunksOf(good, "IDAT");
  const std::vector<std::size_t> iend = ChunksOf(good, "IEND");
  ASSERT_GE(idats.size(), 2U);
  ASSERT_EQ(iend.size(), 1U);
  cv::Mat decoded;
  ASSERT_TRUE(DecodeGreyPng(good.data(), good.size(), decoded));
  const std::vector<unsigned char> ancillary = WithChunk(good, iend[0], "tEXt", std::string("Comment\0fine", 12));
  EXPECT_TRUE(DecodeGreyPng(ancillary.data(), ancillary.size(), decoded)) << "an ancillary chunk is passed over";
  const std::vector<unsigned char> not_letters = WithChunk(good, iend[0], "\xff\xff\xff\xff", "");
  EXPECT_FALSE(DecodeGreyPng(not_letters.data(), not_letters.size(), decoded));
  const std::vector<unsigned char> split = WithChunk(good, idats[1], "tEXt", std::string("Comment\0between", 15));
  EXPECT_FALSE(DecodeGreyPng(split.data(), split.size(), decoded));
  // A header that claims far more image (20000 x 20000) than its data could hold.
  std::string huge(good.begin(), good.end());
  huge.replace(16, 8, std::string("\x00\x00\x4e\x20\x00\x00\x4e\x20", 8));
  const uLong header_crc = crc32(0, reinterpret_cast<const Bytef*>(huge.data()) + 12, 17);
  for (int k = 0; k < 4; ++k) huge[29 + k] = static_cast<char>(header_crc >> (24 - 8 * k));
  const std::vector<unsigned char> claims_more(huge.begin(), huge.end());
  const std::size_t mapped_before = mallinfo2().hblkhd;
  EXPECT_FALSE(DecodeGreyPng(claims_more.data(), claims_more.size(), decoded));
  // Refused before its 400 MB were allocated (and kept for the next frame). The allocator's
  // figures are zero under AddressSanitizer, where this holds trivially.
  EXPECT_LT(mallinfo2().hblkhd, mapped_before + (std::size_t{64} << 20));
  std::string bytes(good.begin(), good.end());
  bytes.erase(idats[0], iend[0] - idats[0]);
  const std::vector<unsigned char> no_data(bytes.begin(), bytes.end());
  EXPECT_FALSE(DecodeGreyPng(no_data.data(), no_data.size(), decoded));
}

TEST(FramePng, DamagedOrOtherPngsAreRefusedAndReadAsOpenCvReadsThem) {
  test::ScratchDir scratch;
  const cv::Mat image = Texture(40, 50, 3);
  const std::vector<unsigned char> good = Encode(image, PNG_ALL_FILTERS, 8192);
  cv::Mat decoded;
  // Any byte after the signature changed: a chunk's CRC (or the IDAT's Adler-32) no longer
  // holds. Every prefix: a truncated file.
  for (std::size_t at = 8; at < good.size(); at += 7) {
    std::vector<unsigned char> damaged = good;
    damaged[at] ^= 0x10;
    EXPECT_FALSE(DecodeGreyPng(damaged.data(), damaged.size(), decoded)) << "byte " << at;
  }
  for (std::size_t size = 0; size < good.size(); size += 5) {
    EXPECT_FALSE(DecodeGreyPng(good.data(), size, decoded)) << size << " bytes";
  }
  // Other kinds of PNG are left to OpenCV, which reads them as before.
  const cv::Mat colour(20, 30, CV_8UC3, cv::Scalar(10, 20, 30));
  const cv::Mat deep(20, 30, CV_16UC1, cv::Scalar(1000));
  for (const cv::Mat& other : {colour, deep}) {
    std::vector<unsigned char> png;
    ASSERT_TRUE(cv::imencode(".png", other, png));
    EXPECT_FALSE(DecodeGreyPng(png.data(), png.size(), decoded));
    const fs::path file = scratch.path() / "other.png";
    WriteBytes(file, png);
    EXPECT_TRUE(Same(ReadImageFile(file), other));
  }
  const std::vector<unsigned char> interlaced = Encode(image, PNG_ALL_FILTERS, 8192, true);
  EXPECT_FALSE(DecodeGreyPng(interlaced.data(), interlaced.size(), decoded));
  WriteBytes(scratch.path() / "interlaced.png", interlaced);
  EXPECT_TRUE(Same(ReadImageFile(scratch.path() / "interlaced.png"), image));
  // What neither can read is an empty image, as imread gives.
  std::vector<unsigned char> broken = good;
  broken.resize(good.size() / 2);
  WriteBytes(scratch.path() / "broken.png", broken);
  EXPECT_TRUE(ReadImageFile(scratch.path() / "broken.png").empty());
  WriteBytes(scratch.path() / "empty.png", {});
  EXPECT_TRUE(ReadImageFile(scratch.path() / "empty.png").empty());
  EXPECT_TRUE(ReadImageFile(scratch.path() / "missing.png").empty());
  WriteBytes(scratch.path() / "good.png", good);
  EXPECT_TRUE(Same(ReadImageFile(scratch.path() / "good.png"), image));
}

}  // namespace
}  // namespace mosaicloc::dataset
