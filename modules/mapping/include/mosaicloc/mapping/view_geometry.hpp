#pragma once
// Each frame's camera height and tilt over the floor under it, from the registrations the
// mapper makes anyway (design.md section 7a), and the registrations corrected by them.

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::mapping {

/// What one registration of a later frame against an earlier one says of the earlier frame's
/// view, in image axes (x right, y down, pixels). An affine A fitted to the refined template
/// centres (later frame, about its centre) against where they lie in the earlier frame, rotated
/// back by its own angle, is to first order
///     A = (k_later / k_earlier) ((1 - n.step / h) I - step n^T / h)
/// with k a frame's height over the calibrated one, n the earlier camera's tilt against the
/// floor (the floor's depth grows by n.u over an offset u), h the calibrated height in pixels.
struct ViewObservation {
  int earlier = 0;
  int later = 0;
  Eigen::Vector2d step_px = Eigen::Vector2d::Zero();  ///< the later view's centre in the earlier frame
  double log_scale = 0.0;                             ///< log of A's isotropic part
  Eigen::Vector2d anisotropy = Eigen::Vector2d::Zero();  ///< A's symmetric trace-free part (p, q)
  double sigma = 0.0;  ///< one sigma of log_scale, p and q alike
};

/// The observation of a registration; none when it has fewer than `min_templates` refined
/// inlier templates (an affine needs three; more to tell its noise).
std::optional<ViewObservation> ObserveView(const tracking::TrackResult& registration, const camera::IdealCamera& camera,
                                           int earlier, int later, int min_templates = 6);

struct ViewGeometryOptions {
  /// How much a frame's tilt and log-height may differ from the previous frame's, one sigma:
  /// both follow the floor and the body's pitch, smoothly.
  double tilt_step_sigma_rad = 5e-5;
  double height_step_sigma = 1e-4;
  /// Weak priors that hold the solution where nothing else does (a frame no registration
  /// reaches): tilt 0, height the calibrated one.
  double tilt_prior_sigma_rad = 0.02;
  double height_prior_sigma = 0.02;
  /// An observation's sigma (of its log-scale and trace-free part) is at least this: a few
  /// templates that happen to fit well do not make it surer than 0.002 px over the 800 px of
  /// the calibrated height.
  double min_observation_sigma = 2.5e-6;
  /// The heights (the tilt) are used only where the two independent solutions agree at least
  /// this well (ViewGeometry::height_agreement), and better than chance (the correlation's t
  /// statistic 3 or more); else the calibrated height (no tilt) is kept.
  double min_agreement = 0.5;
  bool Check(std::string* why) const;
};

/// Per frame: the camera's height over the floor under it relative to the calibrated one, and
/// its tilt (image axes, rad).
struct ViewGeometry {
  std::vector<double> scale;            ///< 1 everywhere unless height_applied
  std::vector<Eigen::Vector2d> tilt;    ///< 0 everywhere unless tilt_applied
  /// How well the heights (and each tilt axis) solved from the registrations to the previous
  /// frame alone agree with those from the longer ones alone: their correlation over the
  /// frames. A flat floor's are noise and do not agree; a floor that is not flat shows in both.
  double height_agreement = 0.0;
  Eigen::Vector2d tilt_agreement = Eigen::Vector2d::Zero();
  bool height_applied = false;
  bool tilt_applied = false;
};

/// Solves every frame's log-height and tilt from the observations (linear least squares: each
/// observation's scale and trace-free part, the frames' smoothness and the priors), and keeps
/// each only where it shows (ViewGeometry's agreements).
/// `camera_height_mm`: the calibrated height (the tracker's solver.camera_height_mm);
/// `drive_starts`: frames that begin a later drive, not tied to the frame before them.
ViewGeometry SolveViewGeometry(const std::vector<ViewObservation>& observations, int frames,
                               const camera::IdealCamera& camera, double camera_height_mm,
                               const ViewGeometryOptions& options, const std::vector<int>& drive_starts = {});

/// `earlier_T_later` (a registration, camera frames, mm) corrected for the earlier frame's
/// height and tilt: its step scaled by the height, its yaw rid of the tilt's bias
/// (step x n) / (2h). What is left: the tracker's similarity, fitted to templates on one side
/// of the later view's centre (the overlap), takes part of the two views' tilt against each
/// other for rotation and step; the second-order fit's own estimate of that was measured too
/// noisy to correct it with (design.md section 7a).
core::Pose2 CorrectRegistration(const core::Pose2& earlier_T_later, const ViewObservation& observation,
                                const ViewGeometry& geometry, const camera::IdealCamera& camera,
                                double camera_height_mm);

}  // namespace mosaicloc::mapping
