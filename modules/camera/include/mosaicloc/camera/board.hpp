#pragma once

#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace mosaicloc::camera {

/// A planar calibration target.
///
/// Board frame B: on the board's surface, origin at the first feature (the first inner
/// corner of a chessboard, the first circle centre of a grid), x along a row of `cols`
/// features, y along a column of `rows` features, z out of the printed side. Feature
/// (i, j), i < cols, j < rows, is at
///   chessboard, symmetric circles: (i p, j p, 0)
///   asymmetric circles:            ((2 i + j mod 2) p, j p, 0)
/// with p = `pitch_mm`, listed row by row (the order OpenCV's detectors return).
struct BoardSpec {
  enum class Kind { kChessboard, kCircles, kAsymmetricCircles };
  Kind kind = Kind::kChessboard;
  int cols = 9;            ///< inner corners (chessboard) or circles along a row
  int rows = 6;            ///< inner corners or circles along a column
  double pitch_mm = 25.0;  ///< square side, or distance between neighbouring circle centres
  /// Circle diameter as a fraction of the pitch (circle boards; used to render and print).
  double circle_diameter_fraction = 0.5;

  bool Check(std::string* why) const;
  /// The spec in the form ParseBoardSpec reads, e.g. "chessboard:9x6:25mm".
  std::string ToString() const;
  int FeatureCount() const { return cols * rows; }
  /// Feature positions in the board frame B, mm, in detection order (z = 0).
  std::vector<Eigen::Vector3d> FeaturePoints() const;
};

/// Parses "chessboard:COLSxROWS:PITCHmm", "circles:COLSxROWS:PITCHmm" or
/// "acircles:COLSxROWS:PITCHmm" (a pitch without unit is mm). Throws core::Error (invalid
/// input) quoting the text and the accepted forms.
BoardSpec ParseBoardSpec(std::string_view text);

/// A printable image of the board: a white margin of one pitch around the pattern
/// (chessboard: (cols + 1) x (rows + 1) squares), `px_per_mm` pixels per millimetre, CV_8UC1.
cv::Mat DrawBoard(const BoardSpec& board, double px_per_mm);

/// The board's reflectance at a point of the board frame B (mm): 0 black, 1 white, with the
/// same layout as DrawBoard (white outside the pattern and its margin).
double BoardReflectance(const BoardSpec& board, double x_mm, double y_mm);

}  // namespace mosaicloc::camera
