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
  cv::Mat half;
  if (!frame.empty()) cv::resize(frame, half, cv::Size(frame.cols / 2, frame.rows / 2), 0, 0, cv::INTER_AREA);
  return SelectTemplates(frame, half, options);
}

std::vector<TemplateSpot> SelectTemplates(const cv::Mat& frame, const cv::Mat& half, const TemplateOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("template options: " + why);
  if (frame.empty() || frame.type() != CV_8UC1) core::ThrowInvalidInput("templates: expected an 8-bit grey frame");
  if (half.type() != CV_8UC1 || half.cols != frame.cols / 2 || half.rows != frame.rows / 2) {
    core::ThrowInvalidInput("templates: the half-resolution frame does not match the frame");
  }
  // Rectangles start on even pixels and have even sizes, so they map exactly onto the
  // half-resolution frame the coarse search uses.
  const int b = (options.border_px + 1) & ~1;
  const auto texture_of = [&half](const cv::Rect& rect) {
    return TextureStrength(half(cv::Rect(rect.x / 2, rect.y / 2, rect.width / 2, rect.height / 2)));
  };
  std::vector<TemplateSpot> spots;
  if (options.mode == TemplateMode::kTiled) {
    const int w = ((frame.cols - 2 * b) / options.tile_cols) & ~1;
    const int h = ((frame.rows - 2 * b) / options.tile_rows) & ~1;
    if (w < 16 || h < 16) core::ThrowInvalidInput("templates: the frame is too small for the tile grid");
    for (int r = 0; r < options.tile_rows; ++r) {
      for (int c = 0; c < options.tile_cols; ++c) {
        const cv::Rect rect(b + c * w, b + r * h, w, h);
        const double texture = texture_of(rect);
        if (texture >= options.min_texture) spots.push_back({rect, texture});
      }
    }
    return spots;
  }

  const int s = options.size_px & ~1;
  if (s + 2 * b > frame.cols || s + 2 * b > frame.rows) {
    core::ThrowInvalidInput("templates: size_px " + std::to_string(s) + " does not fit in a " +
                            std::to_string(frame.cols) + "x" + std::to_string(frame.rows) + " frame");
  }
  // Structure tensor of the frame at quarter resolution (enough to rank windows; the
  // threshold below is checked at half resolution), box-averaged over template-size windows
  // at an eighth of the frame's resolution: the tensor of a window is the mean of its cells.
  // Per-thread buffers: this runs every frame, and fresh allocations would cost more in page
  // faults than the arithmetic.
  struct Workspace {
    cv::Mat quarter, gx, gy, product;
  };
  thread_local Workspace w;
  cv::resize(half, w.quarter, cv::Size(half.cols / 2, half.rows / 2), 0, 0, cv::INTER_AREA);
  cv::Sobel(w.quarter, w.gx, CV_32F, 1, 0, 3, 0.125);
  cv::Sobel(w.quarter, w.gy, CV_32F, 0, 1, 3, 0.125);
  constexpr int kCell = 2;  // quarter-resolution pixels per cell = 8 frame pixels
  const cv::Size cells(w.quarter.cols / kCell, w.quarter.rows / kCell);
  cv::Mat sxx, sxy, syy;
  cv::multiply(w.gx, w.gx, w.product);
  cv::resize(w.product, sxx, cells, 0, 0, cv::INTER_AREA);
  cv::multiply(w.gx, w.gy, w.product);
  cv::resize(w.product, sxy, cells, 0, 0, cv::INTER_AREA);
  cv::multiply(w.gy, w.gy, w.product);
  cv::resize(w.product, syy, cells, 0, 0, cv::INTER_AREA);
  const int k = std::max(1, s / (4 * kCell));
  cv::Mat mxx, mxy, myy;
  cv::boxFilter(sxx, mxx, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
  cv::boxFilter(sxy, mxy, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);
  cv::boxFilter(syy, myy, -1, cv::Size(k, k), cv::Point(0, 0), true, cv::BORDER_REPLICATE);

  constexpr int kStep = 4 * kCell;  // frame pixels between candidate corners
  const cv::Size grid = CellGrid(options.count, frame.cols, frame.rows);
  const int max_x = (frame.cols - b - s) & ~1;
  const int max_y = (frame.rows - b - s) & ~1;
  for (int gr = 0; gr < grid.height; ++gr) {
    for (int gc = 0; gc < grid.width; ++gc) {
      if (gr * grid.width + gc >= options.count) break;
      // Template corners whose centre lies in this cell.
      const int cx0 = gc * frame.cols / grid.width, cx1 = (gc + 1) * frame.cols / grid.width;
      const int cy0 = gr * frame.rows / grid.height, cy1 = (gr + 1) * frame.rows / grid.height;
      const int x_lo = std::clamp(cx0 - s / 2, b, max_x), x_hi = std::clamp(cx1 - s / 2, b, max_x);
      const int y_lo = std::clamp(cy0 - s / 2, b, max_y), y_hi = std::clamp(cy1 - s / 2, b, max_y);
      double best = -1.0;
      cv::Point best_at(x_lo & ~1, y_lo & ~1);
      for (int y = y_lo; y <= y_hi; y += kStep) {
        for (int x = x_lo; x <= x_hi; x += kStep) {
          const int sx = std::min(x / kStep, cells.width - 1), sy = std::min(y / kStep, cells.height - 1);
          const double e = MinEigen(mxx.at<float>(sy, sx), mxy.at<float>(sy, sx), myy.at<float>(sy, sx));
          if (e > best) {
            best = e;
            best_at = {x & ~1, y & ~1};
          }
        }
      }
      const cv::Rect rect(best_at.x, best_at.y, s, s);
      const double texture = texture_of(rect);
      if (texture >= options.min_texture) spots.push_back({rect, texture});
    }
  }
  return spots;
}

}  // namespace mosaicloc::tracking
