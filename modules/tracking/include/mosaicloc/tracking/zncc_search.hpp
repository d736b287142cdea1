#pragma once

#include <string>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace mosaicloc::tracking {

struct SearchOptions {
  /// Above this many pixels of search range on either side (at the level searched), the
  /// search starts at coarser levels (halving until the range fits) and refines downwards.
  int max_direct_range_px = 16;
  /// Local maxima closer than this to the best one (px, at the coarsest level) are the same peak.
  int exclusion_radius_px = 2;
  /// Gaussian low-pass (sigma, px) of template and window before correlating; 0 = off.
  double prefilter_sigma_px = 1.0;
  bool Check(std::string* why) const;
};

/// The ZNCC (OpenCV TM_CCOEFF_NORMED) peak of a template in a search window.
struct SearchPeak {
  bool found = false;
  /// Top-left of the template in window pixels at the peak, sub-pixel (parabola through the
  /// peak and its neighbours).
  Eigen::Vector2d offset_px = Eigen::Vector2d::Zero();
  double peak = 0.0;        ///< ZNCC at the best integer position, in [-1, 1]
  double second = -1.0;     ///< best other local maximum of ZNCC (-1 if none)
  /// second / peak (both at the level where the whole range was searched) for a positive
  /// peak: near 1 means two places match equally well.
  double ambiguity = 1.0;
  /// peak minus the mean ZNCC two pixels away in x and y: how well defined the peak is.
  double sharpness = 0.0;
  int coarsest_level = 0;   ///< pyramid level (0 = as given) where the whole range was searched
};

/// Finds where `templ` (CV_8UC1) best matches inside `window` (CV_8UC1, at least as large).
/// Pixels of the window outside `window_mask` (optional, 255 = valid) should be filled with
/// something neutral by the caller; the search does not weight them.
SearchPeak SearchZncc(const cv::Mat& templ, const cv::Mat& window, const SearchOptions& options);

}  // namespace mosaicloc::tracking
