#include "mosaicloc/camera/ideal_camera.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::camera {

bool IdealCameraOptions::Check(std::string* why) const {
  if (width_px < 8 || height_px < 8 || width_px > 16384 || height_px > 16384) {
    *why = "width_px and height_px must be in [8, 16384], got " + std::to_string(width_px) + "x" +
           std::to_string(height_px);
    return false;
  }
  if (!(mm_per_px > 0.0 && mm_per_px < 100.0)) {
    *why = "mm_per_px must be in (0, 100), got " + std::to_string(mm_per_px);
    return false;
  }
  return true;
}

IdealCamera::IdealCamera(const IdealCameraOptions& options) : options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("ideal camera: " + why);
}

IdealCamera IdealCamera::Scaled(double scale) const {
  IdealCameraOptions options = options_;
  options.mm_per_px *= scale;
  return IdealCamera(options);
}

Eigen::Vector2d IdealCamera::PixelToCamera(const Eigen::Vector2d& pixel) const {
  return {(pixel.x() - cx()) * options_.mm_per_px, -(pixel.y() - cy()) * options_.mm_per_px};
}

Eigen::Vector2d IdealCamera::CameraToPixel(const Eigen::Vector2d& point_camera_mm) const {
  return {cx() + point_camera_mm.x() / options_.mm_per_px, cy() - point_camera_mm.y() / options_.mm_per_px};
}

Eigen::Vector2d IdealCamera::PixelToWorld(const Eigen::Vector2d& pixel, const core::Pose2& world_from_camera) const {
  return world_from_camera * PixelToCamera(pixel);
}

Eigen::Vector2d IdealCamera::WorldToPixel(const Eigen::Vector2d& point_world_mm,
                                          const core::Pose2& world_from_camera) const {
  return CameraToPixel(world_from_camera.Inverse() * point_world_mm);
}

Eigen::Matrix<double, 2, 3> IdealCamera::PixelToWorldAffine(const core::Pose2& world_from_camera) const {
  // world = R (S (uv - c)) + t with S = diag(s, -s).
  const double s = options_.mm_per_px;
  Eigen::Matrix2d scale;
  scale << s, 0.0, 0.0, -s;
  const Eigen::Matrix2d linear = world_from_camera.Rotation() * scale;
  Eigen::Matrix<double, 2, 3> affine;
  affine.leftCols<2>() = linear;
  affine.col(2) = world_from_camera.translation_mm() - linear * Eigen::Vector2d(cx(), cy());
  return affine;
}

bool IdealCamera::Contains(const Eigen::Vector2d& pixel) const {
  return pixel.x() >= -0.5 && pixel.y() >= -0.5 && pixel.x() < options_.width_px - 0.5 &&
         pixel.y() < options_.height_px - 0.5;
}

double IdealCamera::FootprintLengthAlong(double direction_rad) const {
  const double c = std::abs(std::cos(direction_rad));
  const double s = std::abs(std::sin(direction_rad));
  const double along_x = c > 1e-12 ? width_mm() / c : std::numeric_limits<double>::infinity();
  const double along_y = s > 1e-12 ? height_mm() / s : std::numeric_limits<double>::infinity();
  return std::min(along_x, along_y);
}

}  // namespace mosaicloc::camera
