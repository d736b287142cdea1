#include "mosaicloc/tracking/templates.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::tracking {
namespace {

// Smallest eigenvalue of [[a, b], [b, c]].
double MinEigen(double a, double b, double c) {
  return 0.5 * (a + c) - std::sqrt(0.25 * (a - c) * (a - c) + b * b);
}

// Grid of cells for `count` templates over a w x h frame: cols x rows with cols * rows >= count,
// cells as square as the frame allows.
cv::Size CellGrid(int count, int width, int height) {
  int best_cols = 1;
  double best_score = 1e300;
  for (int cols = 1; cols <= count; ++cols) {
    const int rows = (count + cols - 1) / cols;
    const double aspect = (static_cast<double>(width) / cols) / (static_cast<double>(height) / rows);
    const double score = std::abs(std::log(aspect)) + 0.5 * (cols * rows - count);
    if (score < best_score) {
      best_score = score;
      best_cols = cols;
    }
  }
  return {best_cols, (count + best_cols - 1) / best_cols};
}

}  // namespace

bool TemplateOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (mode == TemplateMode::kSpread && (count < 1 || count > 64)) return fail("count must be in [1, 64]");
  if (mode == TemplateMode::kSpread && (size_px < 8 || size_px > 1024)) return fail("size_px must be in [8, 1024]");
  if (mode == TemplateMode::kTiled && (tile_cols < 1 || tile_rows < 1 || tile_cols * tile_rows > 256)) {
    return fail("tile_cols and tile_rows must be >= 1 and their product <= 256");
  }
  if (border_px < 1) return fail("border_px must be >= 1");
  if (!(min_texture >= 0.0)) return fail("min_texture must be >= 0");
  return true;
}

double TextureStrength(const cv::Mat& region) {
  cv::Mat gx, gy;
  cv::Sobel(region, gx, CV_32F, 1, 0, 3, 0.125);
  cv::Sobel(region, gy, CV_32F, 0, 1, 3, 0.125);
  const double n = static_cast<double>(region.total());
  return MinEigen(gx.dot(gx) / n, gx.dot(gy) / n, gy.dot(gy) / n);
}

std::vector<TemplateSpot> SelectTemplates(const cv::Mat& frame, const TemplateOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("template options: " + why);
  if (frame.empty() || frame.type() != CV_8UC1) core::ThrowInvalidInput("templates: expected an 8-bit grey frame");
  const int b = options.border_px;
  std::vector<TemplateSpot> spots;
  if (options.mode == TemplateMode::kTiled) {
    const int w = (frame.cols - 2 * b) / options.tile_cols;
    const int h = (frame.rows - 2 * b) / options.tile_rows;
    if (w < 8 || h < 8) core::ThrowInvalidInput("templates: the frame is too small for the tile grid");
    for (int r = 0; r < options.tile_rows; ++r) {
      for (int c = 0; c < options.tile_cols; ++c) {
        const cv::Rect rect(b + c * w, b + r * h, w, h);
        const double texture = TextureStrength(frame(rect));
        if (texture >= options.min_texture) spots.push_back({rect, texture});
      }
    }
    return spots;
  }

  const int s = options.size_px;
  if (s + 2 * b > frame.cols || s + 2 * b > frame.rows) {
    core::ThrowInvalidInput("templates: size_px " + std::to_string(s) + " does not fit in a " +
                            std::to_string(frame.cols) + "x" + std::to_string(frame.rows) + " frame");
  }
  // Box-filtered structure tensor at quarter resolution keeps the search cheap: the tensor
  // of a window is the mean of its cells.
  cv::Mat gx, gy;
  cv::Sobel(frame, gx, CV_32F, 1, 0, 3, 0.125);
  cv::Sobel(frame, gy, CV_32F, 0, 1, 3, 0.125);
  cv::Mat gxx = gx.mul(gx), gxy = gx.mul(gy), gyy = gy.mul(gy);
  constexpr int kStep = 4;
  cv::Mat sxx, sxy, syy;
  const cv::Size small(frame.cols / kStep, frame.rows / kStep);
  cv::resize(gxx, sxx, small, 0, 0, cv::INTER_AREA);
  cv::resize(gxy, sxy, small, 0, 0, cv::INTER_AREA);
  cv::resize(gyy, syy, small, 0, 0, cv::INTER_AREA);
  const int k = std::max(1, s / kStep);
  cv::Mat mxx, mxy, myy;
  cv::boxFilter(sxx, mxx, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
  cv::boxFilter(sxy, mxy, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
  cv::boxFilter(syy, myy, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);

  const cv::Size grid = CellGrid(options.count, frame.cols, frame.rows);
  const int max_x = frame.cols - b - s;
  const int max_y = frame.rows - b - s;
  for (int gr = 0; gr < grid.height; ++gr) {
    for (int gc = 0; gc < grid.width; ++gc) {
      if (static_cast<int>(spots.size()) + 0 >= options.count) break;
      // Template top-left corners whose centre lies in this cell.
      const int cx0 = gc * frame.cols / grid.width, cx1 = (gc + 1) * frame.cols / grid.width;
      const int cy0 = gr * frame.rows / grid.height, cy1 = (gr + 1) * frame.rows / grid.height;
      const int x_lo = std::clamp(cx0 - s / 2, b, max_x), x_hi = std::clamp(cx1 - s / 2, b, max_x);
      const int y_lo = std::clamp(cy0 - s / 2, b, max_y), y_hi = std::clamp(cy1 - s / 2, b, max_y);
      double best = -1.0;
      cv::Point best_at(x_lo, y_lo);
      for (int y = y_lo; y <= y_hi; y += kStep) {
        for (int x = x_lo; x <= x_hi; x += kStep) {
          const int sx = std::min(x / kStep, small.width - 1), sy = std::min(y / kStep, small.height - 1);
          const double e = MinEigen(mxx.at<float>(sy, sx), mxy.at<float>(sy, sx), myy.at<float>(sy, sx));
          if (e > best) {
            best = e;
            best_at = {x, y};
          }
        }
      }
      const cv::Rect rect(best_at.x, best_at.y, s, s);
      const double texture = TextureStrength(frame(rect));
      if (texture >= options.min_texture) spots.push_back({rect, texture});
    }
  }
  return spots;
}

}  // namespace mosaicloc::tracking
