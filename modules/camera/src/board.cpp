#include "mosaicloc/camera/board.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::camera {
namespace {

constexpr std::string_view kBoardForms =
    "expected chessboard:COLSxROWS:PITCHmm (inner corners), circles:COLSxROWS:PITCHmm or "
    "acircles:COLSxROWS:PITCHmm, e.g. chessboard:9x6:25mm";

std::optional<int> ParseInt(std::string_view text) {
  int value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

std::optional<double> ParseDouble(std::string_view text) {
  if (text.empty()) return std::nullopt;
  double value = 0.0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

}  // namespace

bool BoardSpec::Check(std::string* why) const {
  if (cols < 3 || rows < 3 || cols > 100 || rows > 100) {
    *why = "board needs 3 to 100 features along each side, got " + std::to_string(cols) + "x" + std::to_string(rows);
    return false;
  }
  if (kind == Kind::kChessboard && cols == rows) {
    // A square chessboard's corner order is ambiguous by a quarter turn.
    *why = "a chessboard needs different corner counts along its sides (e.g. 9x6), got " + std::to_string(cols) +
           "x" + std::to_string(rows);
    return false;
  }
  if (!(pitch_mm > 0.1 && pitch_mm < 10000.0)) {
    *why = "board pitch must be in (0.1, 10000) mm, got " + std::to_string(pitch_mm);
    return false;
  }
  if (!(circle_diameter_fraction > 0.05 && circle_diameter_fraction < 0.9)) {
    *why = "board circle diameter must be 0.05 to 0.9 of the pitch";
    return false;
  }
  return true;
}

std::string BoardSpec::ToString() const {
  const char* kind_name = kind == Kind::kChessboard ? "chessboard" : kind == Kind::kCircles ? "circles" : "acircles";
  char pitch[32];
  std::snprintf(pitch, sizeof(pitch), "%g", pitch_mm);
  return std::string(kind_name) + ":" + std::to_string(cols) + "x" + std::to_string(rows) + ":" + pitch + "mm";
}

std::vector<Eigen::Vector3d> BoardSpec::FeaturePoints() const {
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<std::size_t>(FeatureCount()));
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < cols; ++i) {
      const double x = kind == Kind::kAsymmetricCircles ? (2 * i + j % 2) * pitch_mm : i * pitch_mm;
      points.emplace_back(x, j * pitch_mm, 0.0);
    }
  }
  return points;
}

BoardSpec ParseBoardSpec(std::string_view text) {
  const auto fail = [&](const std::string& reason) -> BoardSpec {
    core::ThrowInvalidInput("bad board '" + std::string(text) + "': " + reason + "; " + std::string(kBoardForms));
  };
  const std::size_t colon1 = text.find(':');
  const std::size_t colon2 = colon1 == std::string_view::npos ? colon1 : text.find(':', colon1 + 1);
  if (colon2 == std::string_view::npos) return fail("it has not three ':'-separated parts");
  const std::string_view kind = text.substr(0, colon1);
  const std::string_view size = text.substr(colon1 + 1, colon2 - colon1 - 1);
  std::string_view pitch = text.substr(colon2 + 1);
  BoardSpec spec;
  if (kind == "chessboard") {
    spec.kind = BoardSpec::Kind::kChessboard;
  } else if (kind == "circles") {
    spec.kind = BoardSpec::Kind::kCircles;
  } else if (kind == "acircles") {
    spec.kind = BoardSpec::Kind::kAsymmetricCircles;
  } else {
    return fail("unknown kind '" + std::string(kind) + "'");
  }
  const std::size_t x = size.find('x');
  const auto cols = x == std::string_view::npos ? std::nullopt : ParseInt(size.substr(0, x));
  const auto rows = x == std::string_view::npos ? std::nullopt : ParseInt(size.substr(x + 1));
  if (!cols || !rows) return fail("size '" + std::string(size) + "' is not COLSxROWS");
  spec.cols = *cols;
  spec.rows = *rows;
  double unit = 1.0;
  if (pitch.size() > 2 && pitch.substr(pitch.size() - 2) == "mm") {
    pitch.remove_suffix(2);
  } else if (pitch.size() > 2 && pitch.substr(pitch.size() - 2) == "cm") {
    pitch.remove_suffix(2);
    unit = 10.0;
  }
  const auto pitch_value = ParseDouble(pitch);
  if (!pitch_value) return fail("pitch '" + std::string(text.substr(colon2 + 1)) + "' is not a length like 25mm");
  spec.pitch_mm = *pitch_value * unit;
  std::string why;
  if (!spec.Check(&why)) return fail(why);
  return spec;
}

double BoardReflectance(const BoardSpec& board, double x_mm, double y_mm) {
  const double p = board.pitch_mm;
  if (board.kind == BoardSpec::Kind::kChessboard) {
    // Squares cover [-p, cols p] x [-p, rows p]; the square at the first corner's lower left is black.
    if (x_mm < -p || y_mm < -p || x_mm >= board.cols * p || y_mm >= board.rows * p) return 1.0;
    const auto a = static_cast<long>(std::floor(x_mm / p)) + 1;
    const auto b = static_cast<long>(std::floor(y_mm / p)) + 1;
    return (a + b) % 2 == 0 ? 0.0 : 1.0;
  }
  // Nearest circle centre: rows are p apart; asymmetric rows are offset by p and spaced 2p.
  const double radius = 0.5 * board.circle_diameter_fraction * p;
  const long j = std::lround(y_mm / p);
  if (j < 0 || j >= board.rows) return 1.0;
  long i = 0;
  double cx = 0.0;
  if (board.kind == BoardSpec::Kind::kCircles) {
    i = std::lround(x_mm / p);
    cx = i * p;
  } else {
    const double offset = (j % 2) * p;
    i = std::lround((x_mm - offset) / (2.0 * p));
    cx = (2 * i) * p + offset;
  }
  if (i < 0 || i >= board.cols) return 1.0;
  const double dx = x_mm - cx, dy = y_mm - j * p;
  return dx * dx + dy * dy <= radius * radius ? 0.0 : 1.0;
}

cv::Mat DrawBoard(const BoardSpec& board, double px_per_mm) {
  std::string why;
  if (!board.Check(&why)) core::ThrowInvalidInput(why);
  if (!(px_per_mm > 0.0 && px_per_mm < 100.0)) core::ThrowInvalidInput("board resolution must be in (0, 100) px/mm");
  const double p = board.pitch_mm;
  const double extent_x = board.kind == BoardSpec::Kind::kAsymmetricCircles ? (2 * board.cols - 1) * p
                                                                             : (board.cols - 1) * p;
  const double extent_y = (board.rows - 1) * p;
  const double x0 = -2.0 * p, y0 = -2.0 * p;  // pattern (one pitch beyond the features) plus a one-pitch margin
  const int width = static_cast<int>(std::ceil((extent_x + 4.0 * p) * px_per_mm));
  const int height = static_cast<int>(std::ceil((extent_y + 4.0 * p) * px_per_mm));
  if (static_cast<double>(width) * height > 4e8) core::ThrowInvalidInput("printable board image would be too large");
  cv::Mat image(height, width, CV_8UC1);
  constexpr int kSamples = 3;
  for (int row = 0; row < height; ++row) {
    auto* out = image.ptr<unsigned char>(row);
    for (int col = 0; col < width; ++col) {
      double sum = 0.0;
      for (int sy = 0; sy < kSamples; ++sy) {
        for (int sx = 0; sx < kSamples; ++sx) {
          const double x = x0 + (col + (sx + 0.5) / kSamples) / px_per_mm;
          // Image rows grow downwards; board y grows upwards on the print.
          const double y = y0 + extent_y + 4.0 * p - (row + (sy + 0.5) / kSamples) / px_per_mm;
          sum += BoardReflectance(board, x, y);
        }
      }
      out[col] = static_cast<unsigned char>(std::lround(255.0 * sum / (kSamples * kSamples)));
    }
  }
  return image;
}

}  // namespace mosaicloc::camera
