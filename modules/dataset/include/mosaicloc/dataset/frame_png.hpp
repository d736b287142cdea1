#pragma once
// A recorded frame's image: the PNG file a dataset holds per frame, decoded.
//
// 8-bit grey PNGs without interlacing (what every recording and the simulator write) are
// inflated whole with libdeflate and unfiltered here: 0.8 ms for a 640 x 480 frame where
// OpenCV's imread, through libpng and zlib, took 2.2. A mapping drive's frames are decoded
// twice (registered, then painted), so this was a quarter of `map build`'s time. Any other
// PNG, and any file this path does not accept, goes to OpenCV as before.

#include <cstddef>
#include <filesystem>

#include <opencv2/core/mat.hpp>

namespace mosaicloc::dataset {

/// The 8-bit grey, non-interlaced PNG in `bytes` decoded into `pixels` (its memory reused when
/// it is already CV_8UC1 of the size). Every chunk's CRC and the zlib stream's Adler-32 are
/// checked. False, with `pixels` in no particular state, for anything else: another format,
/// interlacing, a damaged or truncated file.
bool DecodeGreyPng(const unsigned char* bytes, std::size_t size, cv::Mat& pixels);

/// The image in `file` as cv::imread(file, cv::IMREAD_UNCHANGED) reads it (empty when the
/// file is missing or cannot be decoded), through DecodeGreyPng where it can.
cv::Mat ReadImageFile(const std::filesystem::path& file);

}  // namespace mosaicloc::dataset
