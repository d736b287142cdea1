#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/sim/relief.hpp"

namespace mosaicloc::sim {

/// How the simulated floor camera forms an image. Defaults: a strobed LED floor camera.
struct ImagingOptions {
  double exposure_us = 100.0;          ///< motion blur = speed x exposure
  double noise_std_dn = 2.0;           ///< additive Gaussian sensor noise, 8-bit digital numbers
  double vignetting = 0.15;            ///< relative brightness loss at the image corners
  double illumination_amplitude = 0.05;  ///< slow relative gain change over time
  double illumination_period_s = 30.0;
  /// Optional lens dust/grime: fraction of the image covered by dark semi-transparent
  /// blobs fixed in the image (0 disables).
  double dust_fraction = 0.0;
  bool Check(std::string* why) const;
};

/// Renders ideal images of a floor: each pixel is the area average of the floor over the
/// pixel's square footprint (supersampled), blurred along the motion during the exposure,
/// shaded by vignetting and illumination, with sensor noise. Thread-safe: Render() is const
/// and takes its randomness from the caller's per-frame seed.
class Imager {
 public:
  /// `surface`: the floor's relief and the camera's light, drawn by the ray renders that are
  /// given a SurfaceView; the relief outlives the Imager.
  Imager(const Floor& floor, const camera::IdealCamera& camera, const ImagingOptions& options, std::uint64_t seed,
         const Surface& surface = {});

  /// The image at world_from_camera; `camera_velocity_mm_per_s` is the camera's velocity in
  /// its own floor frame C (for motion blur); `time_s` drives the illumination change.
  cv::Mat Render(const core::Pose2& world_from_camera, const Eigen::Vector2d& camera_velocity_mm_per_s,
                 double time_s, std::uint64_t frame_seed) const;
  /// The noise-free, blur-free, evenly lit image (the "true" view), for tests.
  cv::Mat RenderClean(const core::Pose2& world_from_camera) const;

  /// Where on the floor (world mm) a pixel (u, v) of the camera looks: any smooth map, e.g.
  /// a tilted pinhole over an uneven floor (CameraPlacement::PixelToWorld).
  using PixelToWorld = std::function<Eigen::Vector2d(const Eigen::Vector2d& pixel)>;
  /// The same image formed through `pixel_to_world` instead of the ideal camera at a pose;
  /// it is evaluated exactly every few pixels and interpolated between.
  cv::Mat Render(const PixelToWorld& pixel_to_world, const Eigen::Vector2d& camera_velocity_mm_per_s, double time_s,
                 std::uint64_t frame_seed) const;
  cv::Mat RenderClean(const PixelToWorld& pixel_to_world) const;
  /// The same through rays that meet a floor with relief, lit by the camera's ring light
  /// (the Surface given at construction): every supersample's ray is followed down into the
  /// relief to the first surface it meets, which is shaded by the light it sees (Lambertian,
  /// with shadows) and the ambient light. `pixel_to_world` gives where a ray meets the top
  /// surface.
  cv::Mat Render(const PixelToWorld& pixel_to_world, const SurfaceView& view,
                 const Eigen::Vector2d& camera_velocity_mm_per_s, double time_s, std::uint64_t frame_seed) const;
  cv::Mat RenderClean(const PixelToWorld& pixel_to_world, const SurfaceView& view) const;

  int supersampling() const { return supersampling_; }

 private:
  cv::Mat RenderSupersampled(const core::Pose2& world_from_camera, double blur_margin_px) const;
  cv::Mat RenderSupersampled(const PixelToWorld& pixel_to_world) const;
  /// A supersampled CV_32F view of the surface (relief and light).
  cv::Mat RenderSurface(const PixelToWorld& pixel_to_world, const SurfaceView& view) const;
  /// Motion blur, area average to pixels, shading and noise of a supersampled view.
  cv::Mat Develop(cv::Mat super, const Eigen::Vector2d& camera_velocity_mm_per_s, double time_s,
                  std::uint64_t frame_seed) const;
  double BlurSupersamples(const Eigen::Vector2d& camera_velocity_mm_per_s) const;

  const Floor& floor_;
  camera::IdealCamera camera_;
  ImagingOptions options_;
  int supersampling_ = 2;
  cv::Mat static_gain_;  ///< vignetting x dust, CV_32F
  Surface surface_;
  std::vector<Eigen::Vector3d> light_in_camera_;  ///< the ring's sources, camera axes, from the lens
  double light_e0_ = 1.0;                         ///< irradiance of the calibrated image centre
  double illumination_phase_ = 0.0;
};

}  // namespace mosaicloc::sim
