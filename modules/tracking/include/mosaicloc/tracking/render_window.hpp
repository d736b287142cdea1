#pragma once

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/tracking/reference.hpp"

namespace mosaicloc::tracking {

/// Renders the reference as the frame would see it: pixel (x, y) of the result shows raster
/// point frame_to_raster * (origin + (x, y)). Bilinear in double precision (no fixed-point
/// position rounding), rounded to 8 bits. `mask` (optional) is 255 where all four source
/// pixels are known.
cv::Mat RenderWindow(const ReferenceRaster& reference, const Eigen::Matrix<double, 2, 3>& frame_to_raster,
                     const cv::Point& origin, const cv::Size& size, cv::Mat* mask = nullptr);

/// RenderWindow of the whole view of `camera` at `world_from_camera`: the reference as the
/// camera would see it there (pixel (u, v) shows world point camera.PixelToWorld((u, v))).
cv::Mat RenderCameraView(const ReferenceRaster& reference, const camera::IdealCamera& camera,
                         const core::Pose2& world_from_camera, cv::Mat* mask = nullptr);

}  // namespace mosaicloc::tracking
