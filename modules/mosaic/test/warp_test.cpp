// The bilinear warp kernel against the fixed-point arithmetic it documents, written out per
// pixel: exact equality of values, mask and count, at many affine maps, for rasters that take
// each vector path (16-bit positions up to 2048 columns, 32-bit beyond) and rows that leave
// the raster (the per-pixel path) or end in a partial vector.
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "warp.hpp"

namespace mosaicloc::mosaic::internal {
namespace {

struct Expected {
  cv::Mat image, mask;
  int valid = 0;
};

// warp.hpp's formula, one pixel at a time, reading the plain image.
Expected Reference(const cv::Mat& source, const double map[6], cv::Size size) {
  Expected e;
  e.image.create(size, CV_8UC1);
  e.mask.create(size, CV_8UC1);
  for (int y = 0; y < size.height; ++y) {
    const int x0 = cvRound((map[1] * y + map[2]) * 1024.0);
    const int y0 = cvRound((map[4] * y + map[5]) * 1024.0);
    for (int x = 0; x < size.width; ++x) {
      const int X = (x0 + cvRound(map[0] * x * 1024.0) + 16) >> 5;
      const int Y = (y0 + cvRound(map[3] * x * 1024.0) + 16) >> 5;
      const int ix = X >> 5, iy = Y >> 5, fx = X & 31, fy = Y & 31;
      const int w[4] = {(32 - fx) * (32 - fy), fx * (32 - fy), (32 - fx) * fy, fx * fy};
      int sum = 0;
      bool ok = true;
      for (int k = 0; k < 4; ++k) {
        if (w[k] == 0) continue;
        const int sx = ix + (k & 1), sy = iy + (k >> 1);
        const int p = sx < 0 || sy < 0 || sx >= source.cols || sy >= source.rows ? 0 : source.at<std::uint8_t>(sy, sx);
        ok = ok && p != 0;
        sum += w[k] * p;
      }
      e.image.at<std::uint8_t>(y, x) = ok ? static_cast<std::uint8_t>((sum + 512) >> 10) : 0;
      e.mask.at<std::uint8_t>(y, x) = ok ? 255 : 0;
      e.valid += ok ? 1 : 0;
    }
  }
  return e;
}

// A noisy raster with unmapped specks and an unmapped block, or none when `holes` is false.
cv::Mat Raster(int cols, int rows, bool holes, std::uint64_t seed) {
  cv::Mat raster(rows, cols, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(raster, cv::RNG::UNIFORM, 1, 256);
  if (holes) {
    for (int i = 0; i < rows * cols / 200; ++i) {
      raster.at<std::uint8_t>(static_cast<int>(rng.uniform(0, rows)), static_cast<int>(rng.uniform(0, cols))) = 0;
    }
    raster(cv::Rect(cols / 3, rows / 3, cols / 5, rows / 7)).setTo(cv::Scalar(0));
  }
  return raster;
}

// Random maps: any rotation, scale 0.6-1.6, centred near the raster's middle so that some
// views lie wholly inside and others cross its edges.
void CheckMaps(const cv::Mat& source, cv::Size size, bool holes, int trials, std::uint64_t seed) {
  cv::Mat storage;
  const PairRaster pairs = MakePairRaster(source, storage);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> angle(-3.2, 3.2), scale(0.6, 1.6), jitter(-0.3, 0.3);
  for (int trial = 0; trial < trials; ++trial) {
    const double a = angle(rng), k = scale(rng);
    const double c = std::cos(a) * k, s = std::sin(a) * k;
    const double centre_x = source.cols * (0.5 + jitter(rng)), centre_y = source.rows * (0.5 + jitter(rng));
    const double cx = 0.5 * (size.width - 1), cy = 0.5 * (size.height - 1);
    const double map[6] = {c, -s, centre_x - c * cx + s * cy, s, c, centre_y - s * cx - c * cy};
    const Expected expected = Reference(source, map, size);
    cv::Mat image(size, CV_8UC1), mask;
    const int valid = WarpAffineBilinear(pairs, map, image, &mask, !holes);
    ASSERT_EQ(valid, expected.valid) << "trial " << trial;
    ASSERT_EQ(cv::norm(image, expected.image, cv::NORM_INF), 0.0) << "trial " << trial;
    ASSERT_EQ(cv::norm(mask, expected.mask, cv::NORM_INF), 0.0) << "trial " << trial;
    // Without a mask, the same values and count.
    cv::Mat bare(size, CV_8UC1);
    EXPECT_EQ(WarpAffineBilinear(pairs, map, bare, nullptr, !holes), expected.valid) << "trial " << trial;
    EXPECT_EQ(cv::norm(bare, expected.image, cv::NORM_INF), 0.0) << "trial " << trial;
  }
}

TEST(WarpAffineBilinear, EqualsItsFormulaOnRastersOfSixteenBitPositions) {
  CheckMaps(Raster(700, 650, false, 1), cv::Size(333, 250), false, 40, 11);
  CheckMaps(Raster(700, 650, true, 2), cv::Size(333, 250), true, 40, 12);
  // The largest raster the sixteen-pixel path takes, with views reaching its far corner.
  CheckMaps(Raster(2048, 300, true, 3), cv::Size(640, 120), true, 10, 13);
}

TEST(WarpAffineBilinear, EqualsItsFormulaOnWiderRasters) {
  CheckMaps(Raster(2300, 200, false, 4), cv::Size(720, 96), false, 10, 14);
  CheckMaps(Raster(2300, 200, true, 5), cv::Size(720, 96), true, 10, 15);
}

TEST(InterleaveRows, PairsEveryColumnAndWritesNothingBeyond) {
  std::mt19937 rng(7);
  for (int count = 0; count <= 100; ++count) {
    std::vector<std::uint8_t> top(static_cast<std::size_t>(count)), bottom(top.size());
    for (std::size_t c = 0; c < top.size(); ++c) {
      top[c] = static_cast<std::uint8_t>(rng());
      bottom[c] = static_cast<std::uint8_t>(rng());
    }
    std::vector<std::uint8_t> pairs(2 * top.size() + 64, 0xA5);
    InterleaveRows(top.data(), bottom.data(), count, pairs.data());
    for (std::size_t c = 0; c < top.size(); ++c) {
      ASSERT_EQ(pairs[2 * c], top[c]) << "count " << count << " column " << c;
      ASSERT_EQ(pairs[2 * c + 1], bottom[c]) << "count " << count << " column " << c;
    }
    for (std::size_t i = 2 * top.size(); i < pairs.size(); ++i) ASSERT_EQ(pairs[i], 0xA5) << "count " << count;
  }
}

TEST(WarpAffineBilinear, EqualsOpenCvOnAnAxisAlignedShift) {
  // A shift by a multiple of 1/32 px leaves no rounding to argue about.
  const cv::Mat source = Raster(300, 200, false, 6);
  cv::Mat storage;
  const PairRaster pairs = MakePairRaster(source, storage);
  const double map[6] = {1.0, 0.0, 10.25, 0.0, 1.0, 20.75};
  cv::Mat image(cv::Size(256, 160), CV_8UC1);
  EXPECT_EQ(WarpAffineBilinear(pairs, map, image, nullptr, true), 256 * 160);
  cv::Mat direct;
  cv::warpAffine(source, direct, cv::Mat(2, 3, CV_64F, const_cast<double*>(map)), image.size(),
                 cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
  EXPECT_EQ(cv::norm(image, direct, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace mosaicloc::mosaic::internal
