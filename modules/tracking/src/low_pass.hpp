#pragma once

#include <opencv2/core/mat.hpp>

namespace mosaicloc::tracking::detail {

/// Radius of the Gaussian low-pass kernel used for `sigma_px`: ceil(3 sigma), 0 when sigma <= 0.
int LowPassRadius(double sigma_px);

/// Separable Gaussian low-pass of an 8-bit grey image with the kernel
/// cv::getGaussianKernel(2 LowPassRadius(sigma) + 1, sigma) in both directions and replicated
/// borders (cv::GaussianBlur with BORDER_REPLICATE), computed in float. `dst` gets the size of
/// `src` and is CV_8UC1 (rounded; within 1 grey level of OpenCV's fixed-point 8-bit blur) or
/// CV_32FC1 (as cv::GaussianBlur of the image converted to float, to float rounding), as
/// `depth` asks. Filtering one small window directly costs a fraction of cv::GaussianBlur's
/// per-call set-up, which dominates at the 50-130 px windows of the tracker. `dst` must not
/// share pixels with `src`. Throws core::Error (invalid input) on another type or depth.
void GaussianLowPass(const cv::Mat& src, cv::Mat& dst, double sigma_px, int depth);

/// The same filter of the whole of `src` (its edges replicated) evaluated on `rect` only:
/// `dst` (rect's size) holds the filtered pixels rect.x + x, rect.y + y, equal to the same
/// pixels of GaussianLowPass(src). Reads the pixels within the kernel radius of `rect`.
/// Throws core::Error (invalid input) as GaussianLowPass does, or when `rect` is empty or not
/// inside `src`.
void GaussianLowPassRect(const cv::Mat& src, const cv::Rect& rect, cv::Mat& dst, double sigma_px, int depth);

/// A `size` image of `type` carved from `store`, which grows (and only grows) to hold it: a
/// per-thread `store` gives a working image that is not allocated again frame after frame.
/// The pixels are uninitialised; the result is valid until `store` is next used.
cv::Mat ScratchImage(cv::Mat& store, cv::Size size, int type);

}  // namespace mosaicloc::tracking::detail
