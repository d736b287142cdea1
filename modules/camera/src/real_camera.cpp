#include "mosaicloc/camera/real_camera.hpp"

#include <cmath>

#include <Eigen/Geometry>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::camera {

bool RealCameraOptions::Check(std::string* why) const {
  if (width_px < 8 || height_px < 8) {
    *why = "real camera width_px and height_px must be >= 8";
    return false;
  }
  if (!(fx_px > 0.0) || !(fy_px > 0.0)) {
    *why = "real camera fx_px and fy_px must be > 0";
    return false;
  }
  if (!std::isfinite(cx_px) || !std::isfinite(cy_px) || !std::isfinite(k1) || !std::isfinite(k2)) {
    *why = "real camera cx_px, cy_px, k1, k2 must be finite";
    return false;
  }
  if (!(height_mm > 0.0)) {
    *why = "real camera height_mm must be > 0";
    return false;
  }
  if (!(std::abs(tilt_x_rad) < 0.5) || !(std::abs(tilt_y_rad) < 0.5)) {
    *why = "real camera tilt_x_rad and tilt_y_rad must be within +-0.5 rad (a downward camera)";
    return false;
  }
  return true;
}

RealCamera::RealCamera(const RealCameraOptions& options) : options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput(why);
  optical_from_level_ = (Eigen::AngleAxisd(options_.tilt_x_rad, Eigen::Vector3d::UnitX()) *
                         Eigen::AngleAxisd(options_.tilt_y_rad, Eigen::Vector3d::UnitY()))
                            .toRotationMatrix();
}

Eigen::Vector2d RealCamera::Distort(const Eigen::Vector2d& normalized) const {
  const double r2 = normalized.squaredNorm();
  const double d = 1.0 + options_.k1 * r2 + options_.k2 * r2 * r2;
  return {options_.cx_px + options_.fx_px * normalized.x() * d, options_.cy_px + options_.fy_px * normalized.y() * d};
}

std::optional<Eigen::Vector2d> RealCamera::Undistort(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d distorted((pixel.x() - options_.cx_px) / options_.fx_px,
                                  (pixel.y() - options_.cy_px) / options_.fy_px);
  // Newton on f(r) = r (1 + k1 r^2 + k2 r^4) - r_d along the (unchanged) radial direction.
  const double r_d = distorted.norm();
  if (r_d < 1e-15) return distorted;
  double r = r_d;
  for (int i = 0; i < 50; ++i) {
    const double r2 = r * r;
    const double f = r * (1.0 + options_.k1 * r2 + options_.k2 * r2 * r2) - r_d;
    const double df = 1.0 + 3.0 * options_.k1 * r2 + 5.0 * options_.k2 * r2 * r2;
    if (df <= 1e-6) return std::nullopt;  // beyond the monotonic part of the distortion curve
    const double step = f / df;
    r -= step;
    if (std::abs(step) < 1e-15) break;
  }
  if (!(r > 0.0) || !std::isfinite(r)) return std::nullopt;
  return distorted * (r / r_d);
}

std::optional<Eigen::Vector2d> RealCamera::FloorToPixel(const Eigen::Vector2d& point_camera_mm) const {
  const Eigen::Vector3d p_optical =
      optical_from_level_ * Eigen::Vector3d(point_camera_mm.x(), -point_camera_mm.y(), options_.height_mm);
  if (p_optical.z() <= 1e-9) return std::nullopt;
  return Distort(p_optical.head<2>() / p_optical.z());
}

std::optional<Eigen::Vector2d> RealCamera::PixelToFloor(const Eigen::Vector2d& pixel) const {
  const auto normalized = Undistort(pixel);
  if (!normalized) return std::nullopt;
  const Eigen::Vector3d ray_level = optical_from_level_.transpose() * normalized->homogeneous();
  if (ray_level.z() <= 1e-9) return std::nullopt;
  const Eigen::Vector3d p_level = ray_level * (options_.height_mm / ray_level.z());
  return Eigen::Vector2d(p_level.x(), -p_level.y());
}

double RealCamera::NadirMmPerPx() const { return options_.height_mm / options_.fx_px; }

}  // namespace mosaicloc::camera
