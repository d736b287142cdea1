#pragma once

#include <string>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"

namespace mosaicloc::camera {

/// The ideal (rectified) ground camera of design.md section 3: an orthographic view of the
/// floor with square pixels of `mm_per_px` and the principal point at the image centre.
/// Pixel centres are at integer (u, v), so the centre of a 640x480 image is (319.5, 239.5).
/// Camera floor frame C: origin at the image centre on the floor, x along image right,
/// y along image up (v grows downwards), so the view is not mirrored:
///   p_C = ((u - cx) s, -(v - cy) s).
struct IdealCameraOptions {
  int width_px = 640;
  int height_px = 480;
  double mm_per_px = 0.25;
  bool Check(std::string* why) const;
};

class IdealCamera {
 public:
  /// Throws core::Error (invalid input) when the options fail Check().
  explicit IdealCamera(const IdealCameraOptions& options);

  int width_px() const { return options_.width_px; }
  int height_px() const { return options_.height_px; }
  double mm_per_px() const { return options_.mm_per_px; }
  double cx() const { return 0.5 * (options_.width_px - 1); }
  double cy() const { return 0.5 * (options_.height_px - 1); }
  /// The same camera seeing `scale` times as much floor per pixel: the floor `scale` times
  /// as far below it as calibrated (a pinhole looking straight down).
  IdealCamera Scaled(double scale) const;
  /// Footprint on the floor, mm.
  double width_mm() const { return options_.width_px * options_.mm_per_px; }
  double height_mm() const { return options_.height_px * options_.mm_per_px; }

  /// Pixel (u, v) to the camera floor frame C, mm.
  Eigen::Vector2d PixelToCamera(const Eigen::Vector2d& pixel) const;
  /// Camera floor frame C (mm) to pixel.
  Eigen::Vector2d CameraToPixel(const Eigen::Vector2d& point_camera_mm) const;
  /// Pixel to world through world_from_camera.
  Eigen::Vector2d PixelToWorld(const Eigen::Vector2d& pixel, const core::Pose2& world_from_camera) const;
  /// World point (mm) to pixel; the result may lie outside the image.
  Eigen::Vector2d WorldToPixel(const Eigen::Vector2d& point_world_mm, const core::Pose2& world_from_camera) const;
  /// The 2x3 affine map pixel -> world (mm) for world_from_camera: [A | b] with world = A uv + b.
  Eigen::Matrix<double, 2, 3> PixelToWorldAffine(const core::Pose2& world_from_camera) const;
  bool Contains(const Eigen::Vector2d& pixel) const;
  /// How far the footprint can move along a direction (angle in frame C, rad) before the
  /// new image no longer overlaps the old one, mm: min(w / |cos a|, h / |sin a|).
  double FootprintLengthAlong(double direction_rad) const;

 private:
  IdealCameraOptions options_;
};

}  // namespace mosaicloc::camera
