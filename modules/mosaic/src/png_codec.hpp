#pragma once
// The map tiles' PNG codec: 8-bit grey images to and from PNG bytes in memory, with libpng
// directly. OpenCV's imdecode spent about 300 us on a 64 KiB stored (zlib level 0) tile,
// most of it outside inflate, and linking OpenCV's image codecs maps a hundred shared
// libraries (GDAL among them) into every process that reads a map.

#include <cstddef>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace mosaicloc::mosaic::internal {

/// PNG bytes of an 8-bit grey image at zlib level 0-9. Level 0 writes unfiltered rows in
/// stored blocks, the fastest to decode; higher levels let libpng choose row filters.
/// Throws core::Error (runtime) when libpng fails.
std::vector<unsigned char> EncodeGreyPng(const cv::Mat& pixels, int zlib_level);

/// The fast path of DecodeGreyPng for the PNGs EncodeGreyPng writes at level 0: an 8-bit
/// grey `size_px` square whose rows are unfiltered in stored deflate blocks are copied out of
/// the IDAT chunks as they are. False, with `pixels` in no particular state, for any other
/// PNG (compressed, filtered, another size or format, or damaged): libpng decodes those and
/// says what is wrong. libpng spent about 1.8 instructions a pixel on a stored tile, a fifth of
/// a fast frame's work when the vehicle crosses 7 tiles a frame.
bool DecodeStoredGreyPng(const unsigned char* data, std::size_t bytes, int size_px, cv::Mat& pixels);

/// Decodes a PNG that must be 8-bit grey and `size_px` square into `pixels` (reusing its
/// memory when it is already CV_8UC1 of that size). The caller has verified the bytes'
/// CRC32, so libpng's own chunk and zlib checksums are not computed again. Returns an
/// empty string on success, else what is wrong ("not a decodable PNG: ...", or its size
/// and format).
std::string DecodeGreyPng(const unsigned char* data, std::size_t bytes, int size_px, cv::Mat& pixels);

}  // namespace mosaicloc::mosaic::internal
