#pragma once

#include <cstdint>

#include <opencv2/core/mat.hpp>

namespace mosaicloc::mosaic::internal {

/// An 8-bit raster of `rows` x `cols` pixels laid out for bilinear sampling: pair row r
/// (0 <= r < rows - 1) holds, for each column c, the two bytes p(r, c), p(r + 1, c), so the
/// four neighbours of a sample are four consecutive bytes. Twice the memory of the raster,
/// one load per sample instead of two.
struct PairRaster {
  const std::uint8_t* data = nullptr;  ///< pair row 0
  std::ptrdiff_t stride = 0;           ///< bytes from one pair row to the next (>= 2 cols)
  int cols = 0;
  int rows = 0;  ///< raster rows; there are rows - 1 pair rows
};

/// The pair layout of a whole CV_8UC1 image (rows >= 2) into `storage`.
PairRaster MakePairRaster(const cv::Mat& image, cv::Mat& storage);
/// Pair row r, columns [c0, c1), from the two raster rows `top` (r) and `bottom` (r + 1),
/// each pointing at column c0. Writes 2 (c1 - c0) bytes from pair column c0.
void InterleaveRows(const std::uint8_t* top, const std::uint8_t* bottom, int count, std::uint8_t* pairs);

/// Bilinear affine warp of an 8-bit raster in which 0 means "unmapped", giving the same
/// values as cv::warpAffine(source, out, map, size, INTER_LINEAR | WARP_INVERSE_MAP).
///
/// `map` (2 x 3, doubles, row-major) takes output pixel (x, y) to source position
/// (m00 x + m01 y + m02, m10 x + m11 y + m12). OpenCV samples that position in fixed point
/// (imgwarp.cpp, WarpAffineInvoker and remapBilinear), and so does this:
///   X = (round(1024 (m01 y + m02)) + round(1024 m00 x) + 16) >> 5   (Y likewise),
/// so X / 32 is the position to 1/32 px; with fx = X & 31, fy = Y & 31 the four
/// neighbours p00, p01, p10, p11 of pixel (X >> 5, Y >> 5) weigh
///   w00 = (32 - fx)(32 - fy), w01 = fx (32 - fy), w10 = (32 - fx) fy, w11 = fx fy,
/// which sum to 1024 exactly, and out = (sum w p + 512) >> 10. (OpenCV keeps the weights
/// scaled by 32, as 15-bit numbers, and rounds with >> 15: the same integer.) Roundings
/// are to nearest, ties to even, as cvRound.
///
/// An output pixel is valid when every neighbour of non-zero weight lies in the source and
/// is mapped (non-zero); invalid pixels are set to 0 and, when `mask` is given, marked 0 in
/// it (255 elsewhere). `source_all_mapped` says no source pixel is 0, which skips that test.
/// Only the pairs the samples fall on are read. Returns the number of valid pixels.
int WarpAffineBilinear(const PairRaster& source, const double map[6], cv::Mat& out, cv::Mat* mask,
                       bool source_all_mapped);

}  // namespace mosaicloc::mosaic::internal
