#pragma once

#include <cstdint>
#include <memory>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/mosaic/renderer.hpp"

namespace mosaicloc::tracking {

/// outer o inner for 2x3 affine maps [A | b]: x -> A_outer (A_inner x + b_inner) + b_outer.
Eigen::Matrix<double, 2, 3> ComposeAffine(const Eigen::Matrix<double, 2, 3>& outer,
                                          const Eigen::Matrix<double, 2, 3>& inner);

/// [A | b] applied to a point: A p + b.
inline Eigen::Vector2d ApplyAffine(const Eigen::Matrix<double, 2, 3>& affine, const Eigen::Vector2d& point) {
  return affine.leftCols<2>() * point + affine.col(2);
}

/// What a live frame is registered against: an 8-bit raster of the floor whose placement in
/// the world is known exactly. Raster pixel (col, row) has its centre at
///   world_mm = A (col, row)^T + b,   [A | b] = RasterToWorld().
/// Pixel value mosaic::kUnmapped (0) means "no data here". Implementations are const and
/// thread-safe.
class ReferenceRaster {
 public:
  virtual ~ReferenceRaster() = default;
  /// The 2x3 affine map raster (col, row) -> world mm.
  virtual Eigen::Matrix<double, 2, 3> RasterToWorld() const = 0;
  /// Pixels [col0, col0 + cols) x [row0, row0 + rows) with a mask of known pixels.
  mosaic::RasterPatch Region(std::int64_t col0, std::int64_t row0, int cols, int rows) const;
  /// The same into caller-owned pixels, for the tracker's blocks of every frame: the image a
  /// cols x rows view of `store` (grown as needed and overwritten by the next call with it),
  /// the mask left empty when every pixel is known (all_mapped), else 255 where known.
  virtual void Region(std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat& store,
                      mosaic::RasterPatch* patch) const = 0;
  /// The same floor at half the resolution (2x2 area averages: pixel i covers pixels 2i and
  /// 2i + 1 of this raster), or nullptr when there is none. The coarse search runs there.
  virtual std::unique_ptr<const ReferenceRaster> Coarser() const = 0;
  /// Size of a raster pixel on the floor, mm.
  double mm_per_px() const;
  /// world mm -> raster (col, row), the inverse of RasterToWorld().
  Eigen::Matrix<double, 2, 3> WorldToRaster() const;
};

/// A reference halved up to a number of times: `raster` is the coarsest reached (the
/// reference itself after no halving), `halvings` how many were made and `owner` holds the
/// coarser raster when there is one.
struct CoarseReference {
  std::unique_ptr<const ReferenceRaster> owner;
  const ReferenceRaster* raster = nullptr;
  int halvings = 0;
};
/// `reference` halved up to `levels` times (fewer where it has no coarser level).
CoarseReference Coarsen(const ReferenceRaster& reference, int levels);

/// One level of the mosaic map.
class MapReference final : public ReferenceRaster {
 public:
  MapReference(const mosaic::MapRenderer& renderer, int level) : renderer_(renderer), level_(level) {}
  Eigen::Matrix<double, 2, 3> RasterToWorld() const override;
  using ReferenceRaster::Region;
  void Region(std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat& store,
              mosaic::RasterPatch* patch) const override;
  std::unique_ptr<const ReferenceRaster> Coarser() const override;
  int level() const { return level_; }

 private:
  const mosaic::MapRenderer& renderer_;
  int level_;
};

/// A single ideal image placed in the world at world_from_camera (design.md section 3): the
/// previous frame for visual odometry, or a reference image in tests and benchmarks. Pixels
/// outside the image are unknown. The image is shared, not copied.
class ImageReference final : public ReferenceRaster {
 public:
  /// Throws core::Error (invalid input) unless `image` is a non-empty CV_8UC1 and mm_per_px > 0.
  ImageReference(cv::Mat image, const core::Pose2& world_from_camera, double mm_per_px);
  /// The same with the image's 2x2 area average already made (cv::resize with INTER_AREA to
  /// half the size, as detail::HalveImage makes it): Coarser() then takes it instead. An empty
  /// `half` is the other constructor; one of another size or type throws core::Error.
  ImageReference(cv::Mat image, const core::Pose2& world_from_camera, double mm_per_px, cv::Mat half);
  Eigen::Matrix<double, 2, 3> RasterToWorld() const override;
  using ReferenceRaster::Region;
  void Region(std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat& store,
              mosaic::RasterPatch* patch) const override;
  /// The half image given, or built on each call (a 2x2 area average of the image).
  std::unique_ptr<const ReferenceRaster> Coarser() const override;

 private:
  ImageReference(cv::Mat image, const Eigen::Matrix<double, 2, 3>& raster_to_world);
  cv::Mat image_;
  cv::Mat half_;  ///< empty unless given
  Eigen::Matrix<double, 2, 3> raster_to_world_;
};

}  // namespace mosaicloc::tracking
