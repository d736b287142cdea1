#pragma once

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace mosaicloc::sim {

/// Exact-position resampling for synthetic registration pairs, where the truth must be known
/// far better than the 0.01 px the tracker is measured at. OpenCV's warpAffine and remap round
/// sample positions to 1/32 px, which alone is a 0.016 px error; this does not.
///
/// Output pixel (u, v) is the mean of `supersampling`^2 samples at
///   source_from_view * (u + (i + 0.5) / k - 0.5, v + (j + 0.5) / k - 0.5, 1),  i, j < k,
/// each interpolated bicubically (Keys, a = -0.5) in double precision from `source` (CV_8UC1,
/// border replicated). The result is CV_32FC1, unrounded.
cv::Mat ResampleExact(const cv::Mat& source, const Eigen::Matrix<double, 2, 3>& source_from_view, cv::Size size,
                      int supersampling);

}  // namespace mosaicloc::sim
