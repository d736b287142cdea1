#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"

namespace mosaicloc::localizer {

/// A downward camera on a vehicle, and what the tracker tolerates: the inputs of the speed
/// limit analysis (`mosaicloc limits`). Defaults are the simulator's camera and the
/// localizer's defaults.
struct SpeedLimitOptions {
  // The ideal (rectified) camera.
  int width_px = 640;
  int height_px = 480;
  double mm_per_px = 0.25;
  double frame_rate_hz = 30.0;      ///< one tracking cycle per frame: T_cyc = 1 / rate
  double exposure_us = 100.0;       ///< time the shutter (or strobe) is open, us
  double camera_height_mm = 200.0;  ///< optical centre above the floor the camera was calibrated on
  /// Direction of travel in the camera floor frame C, rad: 0 along image right, pi/2 along
  /// image up. For a vehicle driving forward it is -yaw of vehicle_from_camera.
  double travel_direction_rad = 0.0;
  /// Height over the floor of the axis the camera's body pitches and rolls about on its
  /// suspension, mm: a tilt a moves the image centre by this times a.
  double tilt_pivot_height_mm = 100.0;

  // The floor.
  /// Change of floor height (or of the camera's height through suspension pitch) per unit
  /// of travel, mm per mm: a slope of 1 mm per metre is 0.001.
  double depth_gradient = 0.002;
  /// The floor's relief: how deep its joints, grout or pits lie below the top surface the
  /// camera is calibrated to, mm (0: a flat floor).
  double relief_depth_mm = 0.0;
  /// How much the camera's height over the floor under it wanders along a mapping drive (an
  /// uneven floor felt through the wheels, a load), one standard deviation, mm.
  double height_variation_mm = 0.15;
  /// The path a mapping drive covers between loop closures (where it comes back over floor it
  /// mapped), m: nothing but the registrations holds the chain in between.
  double loop_spacing_m = 3.0;
  /// The ring light carried with the camera: its radius around the lens, mm (in the lens's
  /// plane).
  double light_ring_radius_mm = 50.0;

  // The tracker.
  double required_overlap = 0.5;         ///< beta: share of the footprint consecutive frames must share
  double distortion_tolerance_px = 0.5;  ///< misfit a rigid registration absorbs at the image corner, px
  double max_blur_px = 3.0;              ///< motion blur the tracker is known to work with, px
  double search_range_px = 96.0;         ///< the tracker's largest search half-range, px
  double odometry_error = 0.02;          ///< odometry error per distance travelled (2 %: 0.02)
  /// The largest error of the image scale the tracker is known to take at a first fix (it
  /// follows the scale after), relative: 0.15 is a camera 15 % higher than the map's.
  double max_scale_error = 0.15;
  /// The largest tilt the tracker is known to follow when it estimates the tilt, degrees.
  double max_tilt_deg = 1.5;

  /// Speed at which the per-cycle figures (step, instability ratio, blur) are given, m/s.
  double speed_mps = 7.2;

  bool Check(std::string* why) const;
};

/// The speed limits of a setup, in m/s, and the figures at the given speed.
///
/// Notation: V speed, T_cyc = 1 / frame rate, s mm per pixel, Lambda the footprint's length
/// along the direction of travel (how far the camera moves before an image no longer overlaps
/// the one before), S = V T_cyc the step from one image to the next.
struct SpeedLimits {
  double cycle_s = 0.0;                ///< T_cyc
  double footprint_along_mm = 0.0;     ///< Lambda
  double half_diagonal_px = 0.0;       ///< R, the image corner's distance from the centre

  /// Overlap speed limit V < (Lambda / T_cyc)(1 - beta): above it consecutive images share
  /// less than beta of their footprint, so frame-to-frame registration (visual odometry,
  /// and mapping by chaining frames) fails. The mosaic tracker registers against the map
  /// and is not bound by it.
  double overlap_limit_mps = 0.0;
  /// Distortion speed limit V < e h / (R g T_cyc): a floor whose height changes with
  /// gradient g moves by g S between frames, which scales one image against the other by
  /// g S / h; a rigid registration leaves R g S / h of misfit at the image corner, which
  /// must stay below the tolerance e. Binds frame-to-frame registration.
  double distortion_limit_mps = 0.0;
  /// The mosaic's counterpart of the distortion limit, independent of speed: for a rigid fit
  /// (solver.estimate_scale off) the floor's height may differ from the mapped one by at
  /// most e h / R, mm.
  double height_tolerance_mm = 0.0;
  /// With the image scale estimated: max_scale_error h, mm.
  double scaled_height_tolerance_mm = 0.0;
  /// The tilt a fit without it (solver.estimate_tilt off) absorbs: the keystone of a tilt a
  /// misplaces the image corner by a R^2 / f px (f = h / s, the focal length in pixels), which
  /// must stay below e: a < e h / (s R^2), degrees.
  double rigid_tilt_tolerance_deg = 0.0;
  /// With the tilt estimated: max_tilt_deg.
  double tilt_tolerance_deg = 0.0;
  /// How far a tilt moves the fix unless it is estimated and taken out: the pivot's height
  /// times the angle, mm per degree.
  double tilt_lever_mm_per_deg = 0.0;
  /// Motion blur limit V < b s / T_exp: the image smears by V T_exp / s pixels.
  double blur_limit_mps = 0.0;
  /// Prediction speed limit V < r s / (epsilon T_cyc): between two fixes the odometry
  /// prediction drifts by epsilon S, which must stay within the search half-range r. This is
  /// the mosaic tracker's own limit while it holds the lock.
  double prediction_limit_mps = 0.0;
  /// The fastest the mosaic tracker holds the lock: min(blur, prediction).
  double mosaic_limit_mps = 0.0;

  // Relief (the founding paper's distortion term from depth within the view), for a floor
  // whose low parts lie d below its tops; all 0 on a flat floor.
  /// The low parts move slower in the image than the tops by d / (h + d), relative: a fit
  /// of the scale follows the mean of what it matches.
  double relief_scale = 0.0;
  /// Parallax at the image corner, R d / (h + d) px (and mm on the floor): how far a low
  /// point seen there lies from where a view straight down puts it, against the tops. The
  /// mosaic averages the looks from all over the view; a template at the corner over relief
  /// can be biased by up to this.
  double relief_parallax_px = 0.0;
  double relief_parallax_mm = 0.0;
  /// The shadow a ring light of radius rho casts into a joint of depth d at the image centre,
  /// d rho / h, mm; it grows towards the corners by the parallax.
  double relief_shadow_mm = 0.0;
  /// Relief distortion speed limit V < e s (h + d) / (d T_cyc): above it the low parts and
  /// the tops drift more than e apart between consecutive frames. Binds frame-to-frame
  /// registration (visual odometry and the mapping chain).
  double relief_distortion_limit_mps = 0.0;

  // Mapping by chaining frames over a floor whose height under the camera wanders by dh.
  /// A registered step is measured at the calibrated scale: a camera dh higher makes it dh / h
  /// short, relative (the registrations' own relative scales cannot tell: section 7a).
  double mapping_scale_error = 0.0;
  /// How far the chain can be off between two loop closures L apart where the height stays
  /// dh off: L dh / h, mm.
  double mapping_drift_mm = 0.0;

  // At speed_mps.
  double step_mm = 0.0;            ///< S
  double instability_ratio = 0.0;  ///< S / Lambda: frame-to-frame registration needs < 1 - beta
  double blur_px = 0.0;            ///< V T_exp / s
  double prediction_error_mm = 0.0;  ///< epsilon S
  /// Whether speed_mps is within frame-to-frame registration's limits (instability ratio and
  /// distortion) and within the mosaic tracker's.
  bool frame_to_frame_holds = false;
  bool mosaic_holds = false;
};

/// Throws core::Error (invalid input) when the options fail Check().
SpeedLimits AnalyseSpeedLimits(const SpeedLimitOptions& options);

/// The overlap speed limit watched while the floor is mapped by chaining frames (automatic
/// mapping off the map, design.md section 7d): each step between consecutive frames is compared
/// with what the view allows along the step's own direction, Lambda (1 - beta), so the verdict
/// holds at the frame interval the camera actually delivers (dropped frames included).
class OverlapSpeedWatch {
 public:
  /// Throws core::Error (invalid input) when required_overlap is not in [0, 1).
  OverlapSpeedWatch(const camera::IdealCamera& camera, double required_overlap);

  /// A frame over the limit: the speed and the limit at this frame's interval, m/s.
  struct Excess {
    double speed_mps = 0.0;
    double limit_mps = 0.0;
    bool first = false;  ///< the first frame over the limit after at least `quiet_s` below it: say it
  };
  /// The camera's pose at a frame; `mapping` whether the frame is off the map (chained). Steps
  /// are measured between consecutive frames whatever their mode, judged only when mapping.
  std::optional<Excess> Frame(core::Timestamp time, const core::Pose2& world_from_camera, bool mapping);

  double required_overlap() const { return required_overlap_; }
  std::int64_t frames_over() const { return frames_over_; }
  /// The fastest step while mapping, m/s (0 before the second frame).
  double max_speed_mps() const { return max_speed_mps_; }
  /// How long the speed must stay under the limit before the next excess is said again, s.
  static constexpr double kQuietS = 2.0;

 private:
  camera::IdealCamera camera_;
  double required_overlap_ = 0.5;
  std::optional<core::Timestamp> last_time_;
  core::Pose2 last_pose_;
  std::optional<core::Timestamp> last_over_;
  std::int64_t frames_over_ = 0;
  double max_speed_mps_ = 0.0;
};

/// Reads a camera setup (`mosaicloc limits --config`, config/default/limits.yaml) over the
/// defaults; every problem is reported at once as core::Error naming file, line and key.
SpeedLimitOptions LoadSpeedLimitConfig(const std::filesystem::path& file);

}  // namespace mosaicloc::localizer
