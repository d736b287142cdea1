#pragma once

#include <vector>

#include <opencv2/core/mat.hpp>

namespace mosaicloc::calibration {

/// The brightness pattern an image carries wherever the camera looks (the lens's vignetting,
/// uneven lighting fixed to the vehicle), estimated from the frames of a drive over a
/// textured floor: at each pixel the median over frames that each show a different patch of
/// floor, so the floor's own pattern averages away, fitted by a smooth polynomial.
///
/// Frame-to-frame registration needs it removed when it must be exact to a thousandth of a
/// pixel: the pattern stays on the pixels while the floor moves, so the two images of a
/// floor point differ by a brightness ramp, and a ramp across a template moves its best
/// match by a fixed fraction of the frame's motion.
class FlatFieldEstimator {
 public:
  /// `stride_px`: every stride-th pixel in both directions is sampled.
  explicit FlatFieldEstimator(int stride_px = 4) : stride_(stride_px) {}

  /// An 8-bit grey frame; all must have the size of the first.
  void Add(const cv::Mat& frame);
  int frames() const { return frames_; }

  /// Relative gain (CV_32F, the frames' size, mean 1): the pixel-wise median over the frames
  /// added, least-squares fitted by a polynomial of `degree` in the pixel coordinates.
  /// All ones when no frame was added.
  cv::Mat Gain(int degree = 4) const;

 private:
  int stride_;
  int frames_ = 0;
  cv::Size size_;
  std::vector<std::vector<unsigned char>> samples_;  ///< per sampled pixel, one value per frame
};

/// `frame` (8-bit grey) divided by `gain` (as FlatFieldEstimator::Gain), rounded to 8 bits.
cv::Mat DivideByGain(const cv::Mat& frame, const cv::Mat& gain);

}  // namespace mosaicloc::calibration
