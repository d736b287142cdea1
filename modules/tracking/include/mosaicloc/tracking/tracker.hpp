#pragma once

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/tracking/pose_solver.hpp"
#include "mosaicloc/tracking/reference.hpp"
#include "mosaicloc/tracking/refine.hpp"
#include "mosaicloc/tracking/templates.hpp"
#include "mosaicloc/tracking/zncc_search.hpp"

namespace mosaicloc::tracking {

struct TrackerOptions {
  TemplateOptions templates;
  SearchOptions search;
  RefineOptions refine;
  PoseSolverOptions solver;
  /// Search half-range = search_sigmas x the prior's standard deviation at the template
  /// (position and yaw), clamped to [min_search_px, max_search_px].
  double search_sigmas = 3.0;
  /// kSpread: extra templates searched, most textured first, when some of the first `count`
  /// are rejected by the coarse search (chosen only then).
  int spare_templates = 4;
  int min_search_px = 3;
  int max_search_px = 96;
  double min_peak = 0.3;       ///< coarse ZNCC below this: no match
  double max_ambiguity = 0.9;  ///< second peak / peak above this: ambiguous, not used
  double min_zncc = 0.7;       ///< refined ZNCC below this: not used
  /// Most rounds of refinement; each re-linearises around the latest pose. A round whose yaw
  /// change turns a template by less than repeat_below_px at its corners ends them.
  int refine_passes = 2;
  double repeat_below_px = 0.05;
  /// Share of a template's search window that must be mapped, or the template is off the map.
  double min_window_mapped = 0.5;
  bool Check(std::string* why) const;
};

/// Why a frame got no fix. Every failure is a normal outcome of the frame loop.
enum class TrackFailure {
  kNone,
  kNoTexture,      ///< no template of the frame has enough texture
  kOffMap,         ///< the predicted view is (mostly) not in the map
  kAmbiguous,      ///< every candidate match has an equally good second place (repetitive floor)
  kNoMatch,        ///< the templates were not found in their search windows
  kTooFewInliers,  ///< the matches disagree about the pose
  kNotConverged,   ///< the pose solver did not converge
};
const char* ToString(TrackFailure failure);

/// What happened to one template, for diagnostics and the benchmark.
struct TemplateReport {
  TemplateSpot spot;
  int search_range_px = 0;
  SearchPeak coarse;
  RefinedMatch refined;
  bool inlier = false;
  bool off_map = false;  ///< rejected because its place on the map is (partly) unmapped
  std::string rejected;  ///< empty when used
};

struct TrackResult {
  TrackFailure failure = TrackFailure::kNone;
  bool ok() const { return failure == TrackFailure::kNone; }
  std::string reason;  ///< one line, empty when ok
  core::Pose2 world_from_camera;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  ///< (x_mm, y_mm, yaw_rad)
  int inliers = 0;
  double rms_residual_mm = 0.0;
  double mean_zncc = 0.0;
  /// The image scale the frame was registered at: the camera's height over the floor under
  /// it relative to the calibrated one (1.004: 0.4 % higher). Estimated where
  /// solver.estimate_scale asks for it and the inliers determine it; else the prior's.
  double scale = 1.0;
  double scale_sigma = std::numeric_limits<double>::infinity();
  bool scale_estimated = false;
  /// The camera's tilt against the floor (PoseSolution::tilt_x_rad, ...), where
  /// solver.estimate_tilt asks for it and the refined templates determine it; else the tilt
  /// held (Track's TiltPrediction; 0 without one).
  double tilt_x_rad = 0.0;
  double tilt_y_rad = 0.0;
  double tilt_sigma_rad = std::numeric_limits<double>::infinity();
  bool tilt_estimated = false;
  std::vector<TemplateReport> templates;
};

/// A frame made ready to be registered more than once (against its predecessor, its keyframe)
/// and to be the reference of later frames: its 2x2 average and its templates, made once
/// (Tracker::Prepare).
struct PreparedFrame {
  cv::Mat image;
  cv::Mat half;
  std::vector<TemplateSpot> spots;
};

/// A prediction of the camera's tilt against the floor (rad, as TrackResult's) and its
/// standard deviation, held where a frame's templates are too few to estimate the tilt
/// (PoseSolverOptions::held_tilt_*).
struct TiltPrediction {
  double x_rad = 0.0;
  double y_rad = 0.0;
  double sigma_rad = 0.0;
};

/// Registers a live ideal frame against a reference raster (the map, or a previous frame):
/// templates where the frame is textured, a ZNCC search for each around its predicted place,
/// sub-pixel refinement, and a robust planar pose solve. Const: one Tracker may serve several
/// threads (ViSP trackers are created per call).
class Tracker {
 public:
  /// Throws core::Error (invalid input) when options fail Check().
  Tracker(const camera::IdealCamera& camera, const TrackerOptions& options);

  /// `prior` is the predicted world_from_camera and `prior_covariance` its covariance
  /// (x_mm, y_mm, yaw_rad), which sizes the search; `prior_scale` the predicted image scale
  /// (TrackResult::scale), `prior_tilt` the predicted tilt. Never throws for a frame that
  /// cannot be registered: the result says why.
  TrackResult Track(const cv::Mat& frame, const core::Pose2& prior, const Eigen::Matrix3d& prior_covariance,
                    const ReferenceRaster& reference, double prior_scale = 1.0,
                    const TiltPrediction& prior_tilt = {}) const;
  /// The same for a frame this tracker prepared (or one with the same template options).
  TrackResult Track(const PreparedFrame& frame, const core::Pose2& prior, const Eigen::Matrix3d& prior_covariance,
                    const ReferenceRaster& reference, double prior_scale = 1.0,
                    const TiltPrediction& prior_tilt = {}) const;
  /// The frame's half image and templates, as Track makes them; none for a frame Track would
  /// refuse (empty, or not this camera's 8-bit size), which Track then refuses as before.
  PreparedFrame Prepare(const cv::Mat& frame) const;

  const camera::IdealCamera& camera() const { return camera_; }
  const TrackerOptions& options() const { return options_; }

 private:
  camera::IdealCamera camera_;
  TrackerOptions options_;
};

/// A frame registered against an earlier one (visual odometry): when the earlier frame was
/// taken, and the camera's pose in the earlier camera's axes with its covariance (x mm, y mm,
/// yaw rad, in those axes).
struct FrameLink {
  core::Timestamp earlier_time;
  core::Pose2 earlier_from_camera;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
};

/// Frame-to-frame visual odometry with the same matcher: the previous frame is the reference.
/// Returns previous_from_current as the result's world_from_camera.
TrackResult RegisterFrames(const Tracker& tracker, const cv::Mat& previous, const cv::Mat& current,
                           const core::Pose2& prior_previous_from_current, const Eigen::Matrix3d& prior_covariance);
/// The same for frames the tracker prepared: the same result, without making either frame's
/// half image or the current frame's templates again.
TrackResult RegisterFrames(const Tracker& tracker, const PreparedFrame& previous, const PreparedFrame& current,
                           const core::Pose2& prior_previous_from_current, const Eigen::Matrix3d& prior_covariance);

}  // namespace mosaicloc::tracking
