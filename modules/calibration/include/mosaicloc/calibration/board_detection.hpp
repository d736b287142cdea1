#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/board.hpp"

namespace mosaicloc::calibration {

/// The board's features found in one grey image, pixels (x right, y down, pixel centres at
/// integers), in camera::BoardSpec::FeaturePoints order.
struct BoardDetection {
  std::vector<Eigen::Vector2d> points_px;
};

/// Finds the board with OpenCV (findChessboardCorners then cornerSubPix on the image low-passed
/// with a Gaussian of sigma 2 px, or
/// findCirclesGrid, whose blob centroids are already sub-pixel). Nothing when the whole
/// board is not found. `image` is CV_8UC1.
std::optional<BoardDetection> DetectBoard(const cv::Mat& image, const camera::BoardSpec& board);

}  // namespace mosaicloc::calibration
