#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>

namespace mosaicloc::camera {

/// A real downward camera: pinhole intrinsics, radial distortion, mounted at a height above
/// the floor with a small tilt. The simulator renders raw images through it so calibration
/// has something real to recover; everything after calibration sees only ideal images.
///
/// Geometry. The level frame L sits at the optical centre with x, y parallel to the camera
/// floor frame C of design.md section 3 and z up. The optical frame O has x along image
/// right, y along image down and z along the optical axis. Without tilt the camera looks
/// straight down: a floor point p_C = (X, Y) is at P_O = (X, -Y, h). Tilt rotates the camera:
///   P_O = Rx(tilt_x) Ry(tilt_y) (X, -Y, h).
/// Projection with radial distortion in normalized coordinates (the model ViSP's
/// vpCameraParameters uses with k2 = 0, and OpenCV's with k1, k2 and no tangential terms):
///   x = P_O.x / P_O.z,  y = P_O.y / P_O.z,  d = 1 + k1 r^2 + k2 r^4,  r^2 = x^2 + y^2,
///   u = cx + fx x d,  v = cy + fy y d.
struct RealCameraOptions {
  int width_px = 640;
  int height_px = 480;
  double fx_px = 800.0;
  double fy_px = 800.0;
  double cx_px = 319.5;
  double cy_px = 239.5;
  double k1 = 0.0;  ///< radial distortion, r^2 term (normalized coordinates)
  double k2 = 0.0;  ///< radial distortion, r^4 term
  double height_mm = 200.0;  ///< optical centre above the floor
  double tilt_x_rad = 0.0;   ///< rotation about the image x axis
  double tilt_y_rad = 0.0;   ///< rotation about the image y axis
  bool Check(std::string* why) const;
};

class RealCamera {
 public:
  /// Throws core::Error (invalid input) when the options fail Check().
  explicit RealCamera(const RealCameraOptions& options);
  const RealCameraOptions& options() const { return options_; }

  /// Floor point in C (mm) to raw pixel; nothing if the point is behind the camera.
  std::optional<Eigen::Vector2d> FloorToPixel(const Eigen::Vector2d& point_camera_mm) const;
  /// Raw pixel to floor point in C (mm); nothing if the ray misses the floor or the
  /// distortion cannot be inverted there.
  std::optional<Eigen::Vector2d> PixelToFloor(const Eigen::Vector2d& pixel) const;

  /// Normalized (undistorted) coordinates to distorted pixel, and back (iterative).
  Eigen::Vector2d Distort(const Eigen::Vector2d& normalized) const;
  std::optional<Eigen::Vector2d> Undistort(const Eigen::Vector2d& pixel) const;

  /// Floor size of one pixel at the nadir, mm: height / focal length.
  double NadirMmPerPx() const;

 private:
  RealCameraOptions options_;
  Eigen::Matrix3d optical_from_level_;
};

}  // namespace mosaicloc::camera
