#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/sim/floor.hpp"

namespace mosaicloc::sim {

/// The floor's fine relief: joints, grout and pits below the top surface (the bricks' or
/// tiles' tops, which the camera's height is calibrated to). Depth 0: a flat floor.
struct ReliefOptions {
  /// Deepest point below the top surface, mm, in [0, 20].
  double depth_mm = 0.0;
  /// Where the relief comes from: "albedo" (the floor's own picture: its darkest parts, joints
  /// and grout, lie low) or "image" (a height image, white = top, black = depth_mm down,
  /// tiled like the floor with the same texel size).
  std::string source = "albedo";
  std::filesystem::path height_image;
  /// albedo: the share of the floor that lies at the full depth, in [0.01, 0.9] ...
  double low_fraction = 0.1;
  /// ... and the share on the slopes between the tops and the bottom, in [0.01, 0.5].
  double slope_fraction = 0.1;
  /// albedo: the picture is smoothed by a Gaussian of this standard deviation before its
  /// darkness becomes depth (so grains do not become pits), mm, in [0, 5].
  double smoothing_mm = 0.75;
  bool any() const { return depth_mm > 0.0; }
  bool Check(std::string* why) const;
};

/// A ring of point lights carried with the camera (the shielded ring light of floor cameras)
/// and the light of the surroundings. Every source shines like a Lambertian LED along the
/// optical axis; the floor reflects like a Lambertian surface and shadows itself.
struct LightOptions {
  /// Point sources evenly around the lens; 0: no light model (every point lit alike).
  int sources = 0;
  double ring_radius_mm = 50.0;
  /// The ring's height over the lens, mm (negative: below it, nearer the floor).
  double height_over_lens_mm = 0.0;
  /// The surroundings' light as a share of all light at the image centre of a flat floor at
  /// the calibrated height, in [0, 1].
  double ambient = 0.1;
  /// The ring's brightness (1 as calibrated; 0.85 is 15 % less), in [0, 4].
  double ring_gain = 1.0;
  bool any() const { return sources > 0; }
  bool Check(std::string* why) const;
};

/// The relief as a raster on the floor's texel grid (Floor's convention): depth below the top
/// surface, mm. Deterministic: a texel has the same depth whatever window it is rendered in.
class Relief {
 public:
  /// `source`: the floor itself (source "albedo") or the height image's floor ("image"),
  /// on the same texel grid as the floor the camera sees. Throws core::Error for bad options.
  Relief(std::unique_ptr<Floor> source, const ReliefOptions& options);
  /// The same from a floor the caller keeps alive as long as the Relief (the floor the camera
  /// sees, for source "albedo", sharing its tiles).
  Relief(const Floor& source, const ReliefOptions& options);
  double depth_mm() const { return options_.depth_mm; }
  /// Depths of texels [col0, col0 + cols) x [row0, row0 + rows), CV_32F mm (rows x cols).
  cv::Mat Depth(std::int64_t col0, std::int64_t row0, int cols, int rows) const;

 private:
  /// The source's brightness over texels [col0, col0 + cols) x [row0, row0 + rows), CV_32F,
  /// smoothed by the Gaussian from a margin rendered around them (so any window agrees).
  cv::Mat Smoothed(std::int64_t col0, std::int64_t row0, int cols, int rows) const;

  std::unique_ptr<Floor> owned_;
  const Floor* source_ = nullptr;
  ReliefOptions options_;
  int margin_ = 0;      ///< texels rendered around a window for the smoothing
  double sigma_ = 0.0;  ///< smoothing, texels
  double dark_ = 0.0;   ///< albedo: smoothed brightness at and below which the depth is full
  double light_ = 1.0;  ///< albedo: smoothed brightness at and above which it is the top
};

/// Where the camera is when it forms one image of a floor with relief under its light.
struct SurfaceView {
  Eigen::Vector3d lens_mm = Eigen::Vector3d::Zero();  ///< world, z up, floor datum z = 0
  /// Camera axes: x, y image right and up; z backwards along the optical axis.
  Eigen::Matrix3d world_from_camera = Eigen::Matrix3d::Identity();
  /// The smooth floor's height (the top surface) at a world point, mm; empty: 0.
  std::function<double(const Eigen::Vector2d&)> floor_height_mm;
};

/// What the Imager needs to render relief and light: the relief (may be null: flat), the
/// light, and the height the light is calibrated at (a flat floor's image centre there is lit
/// with 1).
struct Surface {
  const Relief* relief = nullptr;
  LightOptions light;
  double calibrated_height_mm = 200.0;
  bool any() const { return (relief != nullptr && relief->depth_mm() > 0.0) || light.any(); }
};

}  // namespace mosaicloc::sim
