#include "mosaicloc/tracking/reference.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/LU>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"

namespace mosaicloc::tracking {

Eigen::Matrix<double, 2, 3> ComposeAffine(const Eigen::Matrix<double, 2, 3>& outer,
                                          const Eigen::Matrix<double, 2, 3>& inner) {
  Eigen::Matrix<double, 2, 3> result;
  result.leftCols<2>() = outer.leftCols<2>() * inner.leftCols<2>();
  result.col(2) = outer.leftCols<2>() * inner.col(2) + outer.col(2);
  return result;
}

double ReferenceRaster::mm_per_px() const {
  const Eigen::Matrix<double, 2, 3> a = RasterToWorld();
  return std::sqrt(std::abs(a.leftCols<2>().determinant()));
}

Eigen::Matrix<double, 2, 3> ReferenceRaster::WorldToRaster() const {
  const Eigen::Matrix<double, 2, 3> a = RasterToWorld();
  const Eigen::Matrix2d inverse = a.leftCols<2>().inverse();
  Eigen::Matrix<double, 2, 3> result;
  result.leftCols<2>() = inverse;
  result.col(2) = -inverse * a.col(2);
  return result;
}

CoarseReference Coarsen(const ReferenceRaster& reference, int levels) {
  CoarseReference coarse;
  coarse.raster = &reference;
  for (; coarse.halvings < levels; ++coarse.halvings) {
    std::unique_ptr<const ReferenceRaster> next = coarse.raster->Coarser();
    if (!next) break;
    coarse.owner = std::move(next);
    coarse.raster = coarse.owner.get();
  }
  return coarse;
}

Eigen::Matrix<double, 2, 3> MapReference::RasterToWorld() const {
  // design.md section 3: x = x0 + (col + 0.5) r, y = y0 - (row + 0.5) r.
  const mosaic::MapGrid& g = renderer_.grid();
  const double r = g.LevelMmPerPx(level_);
  Eigen::Matrix<double, 2, 3> a;
  a << r, 0.0, g.origin_x_mm + 0.5 * r, 0.0, -r, g.origin_y_mm - 0.5 * r;
  return a;
}

std::unique_ptr<const ReferenceRaster> MapReference::Coarser() const {
  if (level_ + 1 >= renderer_.grid().levels) return nullptr;
  return std::make_unique<MapReference>(renderer_, level_ + 1);
}

mosaic::RasterPatch ReferenceRaster::Region(std::int64_t col0, std::int64_t row0, int cols, int rows) const {
  mosaic::RasterPatch patch;
  cv::Mat store;  // the patch's own pixels
  Region(col0, row0, cols, rows, store, &patch);
  if (patch.all_mapped) patch.mask = cv::Mat(rows, cols, CV_8UC1, cv::Scalar(255));
  return patch;
}

void MapReference::Region(std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat& store,
                          mosaic::RasterPatch* patch) const {
  renderer_.Region(level_, col0, row0, cols, rows, store, patch);
}

ImageReference::ImageReference(cv::Mat image, const core::Pose2& world_from_camera, double mm_per_px)
    : image_(std::move(image)) {
  if (image_.empty() || image_.type() != CV_8UC1) {
    core::ThrowInvalidInput("reference image: expected a non-empty 8-bit grey image");
  }
  if (!(mm_per_px > 0.0)) core::ThrowInvalidInput("reference image: mm_per_px must be > 0");
  // world = R diag(s, -s) ((u, v) - c) + t  (the ideal camera of design.md section 3).
  const double cx = 0.5 * (image_.cols - 1);
  const double cy = 0.5 * (image_.rows - 1);
  Eigen::Matrix2d linear = world_from_camera.Rotation();
  linear.col(0) *= mm_per_px;
  linear.col(1) *= -mm_per_px;
  raster_to_world_.leftCols<2>() = linear;
  raster_to_world_.col(2) = world_from_camera.translation_mm() - linear * Eigen::Vector2d(cx, cy);
}

ImageReference::ImageReference(cv::Mat image, const core::Pose2& world_from_camera, double mm_per_px, cv::Mat half)
    : ImageReference(std::move(image), world_from_camera, mm_per_px) {
  if (half.empty()) return;  // made when asked for, as by the other constructor
  if (half.type() != CV_8UC1 || half.cols != image_.cols / 2 || half.rows != image_.rows / 2) {
    core::ThrowInvalidInput("reference image: the half image must be the image's 2x2 area average");
  }
  half_ = std::move(half);
}

ImageReference::ImageReference(cv::Mat image, const Eigen::Matrix<double, 2, 3>& raster_to_world)
    : image_(std::move(image)), raster_to_world_(raster_to_world) {}

Eigen::Matrix<double, 2, 3> ImageReference::RasterToWorld() const { return raster_to_world_; }

std::unique_ptr<const ReferenceRaster> ImageReference::Coarser() const {
  if (image_.cols < 4 || image_.rows < 4) return nullptr;
  cv::Mat half = half_;
  if (half.empty()) cv::resize(image_, half, cv::Size(image_.cols / 2, image_.rows / 2), 0, 0, cv::INTER_AREA);
  // Pixel i of the half image is centred on pixel 2i + 0.5 of this one.
  Eigen::Matrix<double, 2, 3> coarser;
  coarser.leftCols<2>() = 2.0 * raster_to_world_.leftCols<2>();
  coarser.col(2) = raster_to_world_.col(2) + raster_to_world_.leftCols<2>() * Eigen::Vector2d(0.5, 0.5);
  return std::unique_ptr<const ReferenceRaster>(new ImageReference(std::move(half), coarser));
}

void ImageReference::Region(std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat& store,
                            mosaic::RasterPatch* patch) const {
  if (store.type() != CV_8UC1 || store.cols < cols || store.rows < rows) {
    store.create(std::max(store.type() == CV_8UC1 ? store.rows : 0, rows),
                 std::max(store.type() == CV_8UC1 ? store.cols : 0, cols), CV_8UC1);
  }
  patch->image = store(cv::Rect(0, 0, cols, rows));
  patch->col0 = col0;
  patch->row0 = row0;
  patch->level = 0;
  patch->tiles_loaded = 0;
  patch->problems.clear();
  const std::int64_t x0 = std::max<std::int64_t>(col0, 0);
  const std::int64_t y0 = std::max<std::int64_t>(row0, 0);
  const std::int64_t x1 = std::min<std::int64_t>(col0 + cols, image_.cols);
  const std::int64_t y1 = std::min<std::int64_t>(row0 + rows, image_.rows);
  patch->all_mapped = x0 == col0 && y0 == row0 && x1 == col0 + cols && y1 == row0 + rows;
  if (!patch->all_mapped) {
    patch->image.setTo(cv::Scalar(mosaic::kUnmapped));
    patch->mask.create(rows, cols, CV_8UC1);
    patch->mask.setTo(cv::Scalar(0));
  } else {
    patch->mask.release();
  }
  if (x1 > x0 && y1 > y0) {
    const cv::Rect from(static_cast<int>(x0), static_cast<int>(y0), static_cast<int>(x1 - x0),
                        static_cast<int>(y1 - y0));
    const cv::Rect to(static_cast<int>(x0 - col0), static_cast<int>(y0 - row0), from.width, from.height);
    image_(from).copyTo(patch->image(to));
    if (!patch->all_mapped) patch->mask(to).setTo(cv::Scalar(255));
  }
}

}  // namespace mosaicloc::tracking
