#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/camera_truth.hpp"

namespace mosaicloc::sim {

/// A smooth uneven floor: its height over the datum z = 0, mm, as a sum of plane waves in
/// random directions with wavelengths between one and two times `wavelength_m`. Heights have
/// the standard deviation `rms_mm` over the site; `seed` makes the same floor for a mapping
/// drive and a later one.
class FloorShape {
 public:
  FloorShape(double rms_mm, double wavelength_m, std::uint64_t seed);
  bool flat() const { return waves_.empty(); }
  double HeightMm(const Eigen::Vector2d& xy_mm) const;
  /// d height / d (x, y), mm per mm.
  Eigen::Vector2d Gradient(const Eigen::Vector2d& xy_mm) const;
  /// Both at once (one angle per wave): the height, and the gradient in `gradient`.
  double HeightAndGradient(const Eigen::Vector2d& xy_mm, Eigen::Vector2d* gradient) const;
  /// Where the ray from `origin` along `direction` (world, z up, direction pointing down)
  /// meets the floor, (x, y) mm.
  Eigen::Vector2d Intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const;

 private:
  struct Wave {
    Eigen::Vector2d wavevector;  ///< rad per mm
    double amplitude_mm;
    double phase;
  };
  std::vector<Wave> waves_;
};

/// How the vehicle's body moves on its wheels: a stiff suspension that pitches with the
/// longitudinal acceleration and rolls with the lateral one, about an axis `pivot_height_mm`
/// over the floor, and the third contact point (a caster) that, with the two drive wheels,
/// sets the body on an uneven floor. All zero: a rigid vehicle.
struct SuspensionOptions {
  /// Pitch per longitudinal acceleration, degrees per m/s^2 (nose up when accelerating).
  double pitch_deg_per_mps2 = 0.0;
  /// Roll per lateral acceleration, degrees per m/s^2 (the body leans out of a turn).
  double roll_deg_per_mps2 = 0.0;
  /// Height of the axis the body pitches and rolls about, over the floor, mm.
  double pivot_height_mm = 100.0;
  /// The caster's distance ahead of the drive axle, mm (negative: behind).
  double caster_x_mm = 400.0;
  bool Check(std::string* why) const;
};

/// Where the real camera is and where it looks. Camera axes: x and y those of the camera
/// floor frame C (image right and image up), z along the optical axis backwards (up when
/// the camera looks straight down).
struct CameraView {
  Eigen::Vector3d lens_mm = Eigen::Vector3d::Zero();          ///< world, z up, floor datum z = 0
  Eigen::Matrix3d world_from_camera = Eigen::Matrix3d::Identity();
};

/// The camera of a vehicle on a floor: calibrated height and mounting, a static height
/// offset and a slow drift (load, tyre wear), the floor's shape felt through the wheels and
/// the caster, the suspension's pitch and roll. A real pinhole: pixel (u, v) looks along
/// ((u - cx) s / h, -(v - cy) s / h, -1) in camera axes, s the calibrated mm per pixel at the
/// calibrated height h, after an optional residual radial distortion k1 (of the normalized
/// radius).
struct CameraPlacementOptions {
  double calibrated_height_mm = 200.0;
  double height_offset_mm = 0.0;
  double height_drift_mm_per_min = 0.0;
  double residual_k1 = 0.0;
  core::Pose2 vehicle_from_camera;
  double track_width_mm = 500.0;  ///< between the drive wheels' contact points
  SuspensionOptions suspension;
  double unevenness_mm = 0.0;
  double unevenness_wavelength_m = 2.0;
  std::uint64_t floor_seed = 1;
};

class CameraPlacement {
 public:
  /// Pixel geometry of the ideal camera images are rendered for.
  CameraPlacement(const CameraPlacementOptions& options, double mm_per_px, double cx, double cy);
  /// True when the camera looks straight down from a constant height over a flat floor and
  /// has no distortion: frames are then a scaled ideal view.
  bool straight_down() const;
  /// `acceleration_mps2`: the vehicle's (longitudinal, lateral) acceleration.
  CameraView At(const core::Pose2& world_from_vehicle, const Eigen::Vector2d& acceleration_mps2, double time_s) const;
  /// The floor point (x, y) mm that pixel (u, v) of `view` shows.
  Eigen::Vector2d PixelToWorld(const CameraView& view, const Eigen::Vector2d& pixel) const;
  /// What a tracker could recover of the view (dataset::CameraTruth).
  dataset::CameraTruth Truth(const CameraView& view, const core::Pose2& world_from_vehicle) const;
  const FloorShape& floor() const { return floor_; }

 private:
  CameraPlacementOptions options_;
  double mm_per_px_;
  double cx_;
  double cy_;
  FloorShape floor_;
};

}  // namespace mosaicloc::sim
