#include "mosaicloc/camera/board.hpp"

#include <string>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::camera {
namespace {

TEST(BoardSpec, ParsesTheDocumentedForms) {
  const BoardSpec chess = ParseBoardSpec("chessboard:9x6:25mm");
  EXPECT_EQ(chess.kind, BoardSpec::Kind::kChessboard);
  EXPECT_EQ(chess.cols, 9);
  EXPECT_EQ(chess.rows, 6);
  EXPECT_DOUBLE_EQ(chess.pitch_mm, 25.0);
  EXPECT_EQ(chess.ToString(), "chessboard:9x6:25mm");
  const BoardSpec circles = ParseBoardSpec("circles:6x6:3.4cm");
  EXPECT_EQ(circles.kind, BoardSpec::Kind::kCircles);
  EXPECT_DOUBLE_EQ(circles.pitch_mm, 34.0);
  EXPECT_EQ(ParseBoardSpec("acircles:4x11:20").kind, BoardSpec::Kind::kAsymmetricCircles);
  EXPECT_EQ(ParseBoardSpec("acircles:4x11:20").FeaturePoints()[5].x(), 3 * 20.0);  // (2*1 + 1) p
}

TEST(BoardSpec, RejectsBadSpecsNamingThem) {
  for (const char* bad : {"chessboard", "chessboard:9x6", "chess:9x6:25mm", "chessboard:9by6:25mm",
                          "chessboard:9x6:-3mm", "chessboard:7x7:25mm", "chessboard:2x6:25mm", "circles:6x6:25in"}) {
    try {
      ParseBoardSpec(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const core::Error& e) {
      EXPECT_EQ(e.kind(), core::ErrorKind::kInvalidInput);
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

TEST(BoardSpec, ReflectanceIsWhiteOutsideThePatternAndAlternatesInside) {
  const BoardSpec board = ParseBoardSpec("chessboard:9x6:10mm");
  // The first inner corner is at the origin: the squares around it alternate.
  EXPECT_EQ(BoardReflectance(board, -5.0, -5.0), BoardReflectance(board, 5.0, 5.0));
  EXPECT_NE(BoardReflectance(board, -5.0, -5.0), BoardReflectance(board, 5.0, -5.0));
  // Beyond the pattern and its margin the board is white paper.
  EXPECT_EQ(BoardReflectance(board, -1000.0, 0.0), 1.0);
  EXPECT_EQ(BoardReflectance(board, 0.0, 1000.0), 1.0);
}

}  // namespace
}  // namespace mosaicloc::camera
