#include "mosaicloc/calibration/board_detection.hpp"

#include <cmath>

#include <gtest/gtest.h>

namespace mosaicloc::calibration {
namespace {

TEST(Board, PrintedBoardIsDetectedWhereItsCornersAre) {
  const camera::BoardSpec board = camera::ParseBoardSpec("chessboard:9x6:10mm");
  const double px_per_mm = 4.0;
  const cv::Mat print = camera::DrawBoard(board, px_per_mm);
  const auto detection = DetectBoard(print, board);
  ASSERT_TRUE(detection.has_value());
  // Inner corners are two pitches from the left and bottom edges and one pitch apart. OpenCV
  // may number them from any end of the board: every corner must be on the grid.
  const double step = board.pitch_mm * px_per_mm;
  const double x0 = 2.0 * step - 0.5, y_bottom = print.rows - 2.0 * step - 0.5;
  for (const Eigen::Vector2d& p : detection->points_px) {
    const double i = (p.x() - x0) / step, j = (y_bottom - p.y()) / step;
    EXPECT_NEAR(i, std::round(i), 0.01) << p.transpose();
    EXPECT_NEAR(j, std::round(j), 0.01) << p.transpose();
    EXPECT_GE(std::round(i), 0);
    EXPECT_LT(std::round(i), board.cols);
    EXPECT_GE(std::round(j), 0);
    EXPECT_LT(std::round(j), board.rows);
  }
  EXPECT_NEAR((detection->points_px[1] - detection->points_px[0]).norm(), step, 0.02);
  EXPECT_FALSE(DetectBoard(cv::Mat(480, 640, CV_8UC1, cv::Scalar(128)), board).has_value());
}

}  // namespace
}  // namespace mosaicloc::calibration
