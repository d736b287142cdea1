#pragma once
// A test helper of the mapping tests: the ideal frame a camera takes of a floor picture.

#include <opencv2/core/mat.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"

namespace mosaicloc::mapping::test_views {

/// The frame `camera` takes at `world_from_camera` of a floor whose texel (c, r) lies at world
/// (c, r) x mm_per_texel (bicubic).
inline cv::Mat FloorView(const cv::Mat& floor, double mm_per_texel, const camera::IdealCamera& camera,
                         const core::Pose2& world_from_camera) {
  const Eigen::Matrix<double, 2, 3> world = camera.PixelToWorldAffine(world_from_camera);
  cv::Mat texel_from_pixel(2, 3, CV_64F);
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) texel_from_pixel.at<double>(r, c) = world(r, c) / mm_per_texel;
  }
  cv::Mat frame;
  cv::warpAffine(floor, frame, texel_from_pixel, cv::Size(camera.width_px(), camera.height_px()),
                 cv::INTER_CUBIC | cv::WARP_INVERSE_MAP);
  return frame;
}

}  // namespace mosaicloc::mapping::test_views
