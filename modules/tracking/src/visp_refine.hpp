#pragma once

// The interface to ViSP's template trackers. ViSP 3.5's headers do not compile as C++20
// (constructors declared with template-ids), so visp_refine.cpp is built as C++17 and this
// header uses nothing newer.

#include <string>

#include <opencv2/core/mat.hpp>

namespace mosaicloc::tracking::detail {

enum class VispWarp { kTranslation, kSrt, kHomography };

struct VispRequest {
  bool ssd = false;  ///< SSD inverse compositional, else ZNCC inverse compositional
  VispWarp warp = VispWarp::kTranslation;
  int sampling = 1;
  int max_iterations = 20;
  int pyramid_levels = 1;
  cv::Rect zone;        ///< the template inside the template image
  double start_u = 0.0;  ///< template image pixel (u, v) starts at window pixel (u + start_u, v + start_v)
  double start_v = 0.0;
};

struct VispAnswer {
  bool ok = false;
  bool diverged = false;
  std::string message;
  int iterations = 0;
  double centre_u = 0.0;  ///< where the zone's centre lies in the window, px
  double centre_v = 0.0;
  double rotation_rad = 0.0;  ///< of the zone's x axis through the warp
};

/// Tracks `zone` of `templ_image` into `window` (both CV_8UC1) with ViSP. Never throws.
VispAnswer TrackWithVisp(const cv::Mat& templ_image, const cv::Mat& window, const VispRequest& request);

}  // namespace mosaicloc::tracking::detail
