#include "mosaicloc/localizer/localizer.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include <fmt/format.h>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <opencv2/core.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/tracking/render_window.hpp"

namespace mosaicloc::localizer {
namespace {

// The yaw a registration of `link`'s frame against its keyframe takes in from a view tilted by
// `tilt` (rad, about the camera's x and y axes) while the camera moved link's translation: a
// floor point at p (camera mm, y up) is nearer by (tilt_y x - tilt_x y) of the height h, so it
// moves that much faster, and the least-squares rotation of the inlier templates' extra
// motion is sum(p' x t g(p)) / sum |p'|² (p' about their centroid).
double TiltYawBias(const tracking::TrackResult& link, const camera::IdealCamera& camera, const Eigen::Vector2d& tilt,
                   double height_mm) {
  std::vector<Eigen::Vector2d> points;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const tracking::TemplateReport& t : link.templates) {
    if (!t.inlier) continue;
    const cv::Rect& r = t.spot.rect;
    points.emplace_back((r.x + 0.5 * r.width - 0.5 - camera.cx()) * camera.mm_per_px(),
                        -(r.y + 0.5 * r.height - 0.5 - camera.cy()) * camera.mm_per_px());
    centroid += points.back();
  }
  if (points.size() < 2) return 0.0;
  centroid /= static_cast<double>(points.size());
  const Eigen::Vector2d t = link.world_from_camera.translation_mm();
  double moment = 0.0, spread = 0.0;
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2d q = p - centroid;
    const double g = (tilt.y() * p.x() - tilt.x() * p.y()) / height_mm;
    moment += (q.x() * t.y() - q.y() * t.x()) * g;
    spread += q.squaredNorm();
  }
  return spread > 0.0 ? moment / spread : 0.0;
}

// d(a * b)/d(a) for SE2 poses (x, y, yaw), b fixed: the lever arm of b's translation turns
// with a's yaw.
Eigen::Matrix3d ComposeJacobian(const core::Pose2& a, const core::Pose2& b) {
  const double c = std::cos(a.yaw_rad()), s = std::sin(a.yaw_rad());
  Eigen::Matrix3d j = Eigen::Matrix3d::Identity();
  j(0, 2) = -s * b.x_mm() - c * b.y_mm();
  j(1, 2) = c * b.x_mm() - s * b.y_mm();
  return j;
}

// The tracker for views partly off the map: edge_templates instead of the count.
tracking::TrackerOptions EdgeTrackerOptions(const LocalizerOptions& options) {
  tracking::TrackerOptions edge = options.tracker;
  if (options.edge_templates > 0) edge.templates.count = options.edge_templates;
  return edge;
}

// MapCoverage on a raster already at the level to sample.
double CoverageOn(const tracking::ReferenceRaster& raster, const camera::IdealCamera& camera,
                  const core::Pose2& world_from_camera, double margin_mm) {
  // A grid over the footprint in the frame's orientation, one sample per raster pixel.
  const double step_mm = raster.mm_per_px();
  const double half_w = 0.5 * camera.width_mm() + margin_mm;
  const double half_h = 0.5 * camera.height_mm() + margin_mm;
  const int cols = std::max(1, static_cast<int>(std::ceil(2.0 * half_w / step_mm)));
  const int rows = std::max(1, static_cast<int>(std::ceil(2.0 * half_h / step_mm)));
  // Grid pixel (i, j) -> camera floor point (-half_w + (i + 0.5) w / cols, half_h - ...).
  Eigen::Matrix<double, 2, 3> grid_to_camera;
  grid_to_camera << 2.0 * half_w / cols, 0.0, -half_w + half_w / cols, 0.0, -2.0 * half_h / rows,
      half_h - half_h / rows;
  const double c = std::cos(world_from_camera.yaw_rad()), s = std::sin(world_from_camera.yaw_rad());
  Eigen::Matrix<double, 2, 3> camera_to_world;
  camera_to_world << c, -s, world_from_camera.x_mm(), s, c, world_from_camera.y_mm();
  const Eigen::Matrix<double, 2, 3> grid_to_raster =
      tracking::ComposeAffine(raster.WorldToRaster(), tracking::ComposeAffine(camera_to_world, grid_to_camera));
  cv::Mat mask;
  tracking::RenderWindow(raster, grid_to_raster, cv::Point(0, 0), cv::Size(cols, rows), &mask);
  return static_cast<double>(cv::countNonZero(mask)) / static_cast<double>(mask.total());
}

// A template of the registration fell (partly) off the map.
bool PartlyOffTheMap(const tracking::TrackResult& track) {
  return std::any_of(track.templates.begin(), track.templates.end(),
                     [](const tracking::TemplateReport& t) { return t.off_map; });
}

// The share of the view's shorter side between two camera poses' view centres.
double ViewShift(const camera::IdealCamera& camera, const core::Pose2& a, const core::Pose2& b) {
  return (a.translation_mm() - b.translation_mm()).norm() / std::min(camera.width_mm(), camera.height_mm());
}

// The variance of the camera's tilt about either axis with nothing measured
// (LocalizerOptions::tilt_sigma_deg), rad².
double TiltPriorVariance(const LocalizerOptions& options) {
  const double sigma_rad = options.tilt_sigma_deg * std::numbers::pi / 180.0;
  return sigma_rad * sigma_rad;
}

// A Kalman update of `value` (a number, or a vector whose components share one variance and
// are measured with one variance) by a measurement of it.
template <typename Value>
void UpdateEstimate(const Value& measured, double measured_variance, Value& value, double& variance) {
  const double gain = variance / (variance + measured_variance);
  value += gain * (measured - value);
  variance *= 1.0 - gain;
}

}  // namespace

const char* ToString(Mode mode) {
  switch (mode) {
    case Mode::kTrack: return "track";
    case Mode::kVisualOdometry: return "visual-odometry";
    case Mode::kDeadReckoning: return "dead-reckoning";
    case Mode::kSearching: return "searching";
  }
  return "unknown";
}

bool VisualOdometryOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(keyframe_fraction > 0.0 && keyframe_fraction <= max_fraction)) {
    return fail("visual_odometry.keyframe_fraction must be in (0, max_fraction]");
  }
  if (!(max_fraction > 0.0 && max_fraction < 1.0)) return fail("visual_odometry.max_fraction must be in (0, 1)");
  if (!(keyframe_turn_deg > 0.0 && keyframe_turn_deg <= 45.0)) {
    return fail("visual_odometry.keyframe_turn_deg must be in (0, 45]");
  }
  if (!(prior_sigma_mm > 0.0) || !(prior_sigma_fraction >= 0.0) || !(prior_sigma_deg > 0.0)) {
    return fail("visual_odometry prior sigmas must be > 0 (the fraction >= 0)");
  }
  if (!(link_sigma_floor_mm >= 0.0) || !(link_sigma_floor_rad >= 0.0)) {
    return fail("visual_odometry link sigma floors must be >= 0");
  }
  if (!(std::abs(roll_deg_per_mps2) <= 5.0)) return fail("visual_odometry.roll_deg_per_mps2 must be in [-5, 5]");
  if (!(turn_sigma_fraction >= 0.0 && turn_sigma_fraction <= 0.5)) {
    return fail("visual_odometry.turn_sigma_fraction must be in [0, 0.5]");
  }
  return true;
}

bool LocalizerOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(fix_sigma_floor_mm >= 0.0) || !(fix_sigma_floor_rad >= 0.0)) return fail("fix sigma floors must be >= 0");
  if (!(fix_covariance_scale >= 1.0)) return fail("fix_covariance_scale must be >= 1");
  if (!(max_fixed_sigma_mm > 0.0)) return fail("max_fixed_sigma_mm must be > 0");
  if (!(relocalize_radius_mm > 0.0)) return fail("relocalize_radius_mm must be > 0");
  if (reanchor_after_rejections < 0 || reanchor_after_rejections == 1) {
    return fail("reanchor_after_rejections must be 0 (never) or >= 2");
  }
  if (relocalize_after_misses < 0) return fail("relocalize_after_misses must be >= 0");
  if (lost_global_every < 0) return fail("lost_global_every must be >= 0");
  if (off_map_global_every < 0) return fail("off_map_global_every must be >= 0");
  if (edge_templates < 0 || edge_templates > 64) return fail("edge_templates must be in [0, 64]");
  if (!(on_map_coverage > 0.0 && on_map_coverage <= 1.0)) return fail("on_map_coverage must be in (0, 1]");
  if (on_map_coverage < relocalize.min_coverage) {
    return fail("on_map_coverage must be at least relocalize.min_coverage: a kidnap search must be able to take "
                "the place the view is expected on");
  }
  if (!(odometry_timing_sigma_ms >= 0.0) || odometry_timing_sigma_ms > 1000.0) {
    return fail("odometry_timing_sigma_ms must be in [0, 1000]");
  }
  if (!(map_distortion_mm_per_m >= 0.0 && map_distortion_mm_per_m <= 100.0)) {
    return fail("map_distortion_mm_per_m must be in [0, 100]");
  }
  if (!(scale_sigma > 0.0 && scale_sigma <= 0.2)) return fail("scale_sigma must be in (0, 0.2]");
  if (!(scale_drift_per_sqrt_s >= 0.0 && scale_drift_per_sqrt_s <= 0.1)) {
    return fail("scale_drift_per_sqrt_s must be in [0, 0.1]");
  }
  if (!(tilt_pivot_height_mm >= -1000.0 && tilt_pivot_height_mm <= 2000.0)) {
    return fail("tilt_pivot_height_mm must be in [-1000, 2000]");
  }
  if (!(tilt_sigma_deg > 0.0 && tilt_sigma_deg <= 10.0)) return fail("tilt_sigma_deg must be in (0, 10]");
  if (!(tilt_correlation_s > 0.0 && tilt_correlation_s <= 3600.0)) {
    return fail("tilt_correlation_s must be in (0, 3600]");
  }
  if (!visual_odometry.Check(why)) return false;
  // The parts last, so that a complaint about a field of this struct is not hidden by one of theirs.
  return tracker.Check(why) && relocalize.Check(why) && filter.Check(why) && lock.Check(why) && odometry.Check(why);
}

Eigen::Matrix3d CameraCovariance(const core::Pose2& world_from_vehicle, const core::Pose2& vehicle_from_camera,
                                 const Eigen::Matrix3d& vehicle_covariance) {
  const Eigen::Matrix3d j = ComposeJacobian(world_from_vehicle, vehicle_from_camera);
  return j * vehicle_covariance * j.transpose();
}

Eigen::Matrix3d VehicleCovariance(const core::Pose2& world_from_camera, const core::Pose2& vehicle_from_camera,
                                  const Eigen::Matrix3d& camera_covariance) {
  const Eigen::Matrix3d j = ComposeJacobian(world_from_camera, vehicle_from_camera.Inverse());
  return j * camera_covariance * j.transpose();
}

std::string FrameOutcome::ReasonWord() const {
  if (fixed) return {};
  if (lock == estimation::LockState::kOffMap) return "off-map";
  if (track.ok()) return "rejected";
  std::string word = tracking::ToString(track.failure);
  std::replace(word.begin(), word.end(), ' ', '-');
  return word;
}

Localizer::Localizer(const camera::IdealCamera& camera, const LocalizerOptions& options,
                     const tracking::ReferenceRaster& reference, const tracking::PlaceIndex* places)
    : camera_(camera),
      options_(options),
      reference_(reference),
      places_(places),
      tracker_(camera, options.tracker),
      edge_tracker_(camera, EdgeTrackerOptions(options)),
      relocalizer_(tracker_, reference, options.relocalize),
      odometry_(options.odometry),
      lock_(options.lock),
      tick_quantization_(estimation::TickQuantizationCovariance(options.odometry.wheels)),
      scale_variance_(options.scale_sigma * options.scale_sigma),
      tilt_variance_(TiltPriorVariance(options)) {
  // The filter's calibration states are those of the vehicle's kinematics.
  options_.filter.kind = options_.odometry.wheels.kind;
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("localizer options: " + why);
  const tracking::TrackerOptions& t = options_.tracker;
  if (t.solver.estimate_tilt && options_.tilt_pivot_height_mm != 0.0 &&
      (!t.solver.estimate_scale || t.templates.count < t.solver.min_tilt_points)) {
    core::Log().warn(
        "localizer: solver.estimate_tilt with a tilt_pivot_height_mm, but the tilt is measured only with "
        "solver.estimate_scale and at least solver.min_tilt_points ({}) templates (templates.count: {}): every fix "
        "carries the lever of a tilt not measured, and after visual odometry is refused as too uncertain",
        t.solver.min_tilt_points, t.templates.count);
  }
}

void Localizer::Initialize(core::Timestamp time, const core::Pose2& world_from_vehicle,
                           const Eigen::Matrix3d& covariance) {
  filter_.emplace(options_.filter, time, world_from_vehicle, covariance);
  keyframe_.reset();
  last_registered_.reset();
  off_map_path_mm_ = 0.0;
  last_predicted_.reset();
  rejected_run_ = 0;
  unmatched_run_ = 0;
  kidnapped_ = false;
  pose_unknown_ = false;
}

void Localizer::SetPose(core::Timestamp time, const core::Pose2& world_from_vehicle,
                        const Eigen::Matrix3d& covariance) {
  if (!filter_) core::ThrowRuntime("localizer: SetPose before Initialize");
  filter_->RestartAt(time, world_from_vehicle, covariance);
  keyframe_.reset();  // it was placed by the estimate given up
  last_registered_.reset();
  rejected_run_ = 0;
  unmatched_run_ = 0;
}

void Localizer::InitializeUnknown(core::Timestamp time) {
  // A prior that says nothing: anywhere within a kilometre, any heading.
  Initialize(time, core::Pose2::Identity(), Eigen::Vector3d(1e12, 1e12, 10.0).asDiagonal());
  kidnapped_ = true;
  // Searching even without a usable index: every frame then says why nothing is found.
  pose_unknown_ = places_ != nullptr;
}

void Localizer::RequestGlobalRelocalization() {
  kidnapped_ = true;
  pose_unknown_ = places_ != nullptr && places_->usable();
}

bool Localizer::AddEncoders(core::Timestamp time, const core::EncoderCounts& counts) {
  const auto increment = odometry_.Update(time, counts);
  if (!increment) {
    encoder_failure_ = increment.error();
    return false;
  }
  if (filter_ && increment.value().dt > core::Duration::zero()) filter_->Predict(time, increment.value());
  return true;
}

core::Pose2 Localizer::PoseAt(core::Timestamp time) const {
  return filter_ ? filter_->PoseAt(time) : core::Pose2::Identity();
}

Eigen::Matrix3d Localizer::CovarianceAt(core::Timestamp time) const {
  return filter_ ? filter_->CovarianceAt(time) : Eigen::Matrix3d::Identity() * 1e12;
}

estimation::MotionState Localizer::Latest() const {
  if (!filter_) core::ThrowRuntime("localizer: Latest before Initialize");
  return filter_->Latest();
}

Eigen::Vector2d Localizer::wheel_scale_error() const {
  if (!filter_) core::ThrowRuntime("localizer: wheel_scale_error before Initialize");
  return filter_->wheel_scale_error();
}

Eigen::Vector2d Localizer::wheel_scale_sigma() const {
  if (!filter_) core::ThrowRuntime("localizer: wheel_scale_sigma before Initialize");
  return filter_->wheel_scale_covariance().diagonal().cwiseMax(0.0).cwiseSqrt();
}

FrameOutcome Localizer::ProcessFrame(core::Timestamp time, const cv::Mat& frame) {
  FrameOutcome outcome;
  if (!filter_) core::ThrowRuntime("localizer: ProcessFrame before Initialize");
  filter_->Coast(time);
  const core::Pose2 predicted = filter_->PoseAt(time);
  // What the filter's covariance does not carry, added to the prediction's for the search and
  // the gate. Time-stamp uncertainty of the odometry: a time-stamp error dt puts the pose dt
  // times the motion off, v dt along the heading and omega dt in heading; the last fix anchored
  // the state with the motion then, so the prediction here carries both, independent.
  Eigen::Matrix3d unmodelled = Eigen::Matrix3d::Zero();
  if (options_.odometry_timing_sigma_ms > 0.0) {
    const double sigma_s = options_.odometry_timing_sigma_ms * 1e-3;
    const auto& latest = filter_->Latest();
    for (const Eigen::Vector3d& twist : {latest.Twist(), fix_twist_}) {
      Eigen::Vector3d motion = twist;
      motion.head<2>() = predicted.Rotation() * twist.head<2>();
      unmodelled += sigma_s * sigma_s * motion * motion.transpose();
    }
  }
  // Up to a tick of each wheel is not counted yet (estimation::TickQuantizationCovariance): a
  // bounded error, so it widens this prediction and is not carried on to the next. Without it a
  // creeping vehicle's fixes, which see the micrometres the counts do not, are refused.
  Eigen::Matrix3d heading = Eigen::Matrix3d::Identity();
  heading.topLeftCorner<2, 2>() = predicted.Rotation();
  unmodelled += heading * tick_quantization_ * heading.transpose();
  // The map's own distortion between where the vehicle left it and where it is now
  // (LocalizerOptions::map_distortion_mm_per_m): the path counts while the last frame was off
  // the map.
  if (mode_ == Mode::kVisualOdometry || mode_ == Mode::kDeadReckoning) {
    if (last_predicted_) off_map_path_mm_ += (predicted.translation_mm() - last_predicted_->translation_mm()).norm();
  }
  last_predicted_ = predicted;
  const double distortion_mm = options_.map_distortion_mm_per_m * off_map_path_mm_ * 1e-3;
  unmodelled(0, 0) += distortion_mm * distortion_mm;
  unmodelled(1, 1) += distortion_mm * distortion_mm;
  const Eigen::Matrix3d predicted_covariance = filter_->CovarianceAt(time) + unmodelled;
  if (!scale_time_ || time > *scale_time_) {
    const double drift = options_.scale_drift_per_sqrt_s;
    if (scale_time_) scale_variance_ += drift * drift * core::ToSeconds(time - *scale_time_);
    scale_time_ = time;
  }
  if (!tilt_time_ || time > *tilt_time_) {
    if (tilt_time_) {  // first-order Gauss-Markov: the tilt forgets itself towards none
      const double kept = std::exp(-core::ToSeconds(time - *tilt_time_) / options_.tilt_correlation_s);
      tilt_ *= kept;
      tilt_variance_ = kept * kept * tilt_variance_ + (1.0 - kept * kept) * TiltPriorVariance(options_);
    }
    tilt_time_ = time;
  }
  const core::Pose2 prior_camera = predicted * options_.vehicle_from_camera;
  const Eigen::Matrix3d prior_camera_covariance =
      CameraCovariance(predicted, options_.vehicle_from_camera, predicted_covariance);

  // A known kidnap (requested, or the view missing the map frame after frame where the
  // prediction and its uncertainty say it is on it), or a prediction too uncertain for the
  // tracker's search range: relocalize on the coarse map (design.md section 7).
  if (options_.relocalize_after_misses > 0 && unmatched_run_ >= options_.relocalize_after_misses) kidnapped_ = true;
  const double prior_sigma_px =
      std::sqrt(std::max(prior_camera_covariance(0, 0), prior_camera_covariance(1, 1))) / camera_.mm_per_px();
  bool relocalize =
      kidnapped_ || options_.tracker.search_sigmas * prior_sigma_px > options_.tracker.max_search_px;
  if (pose_unknown_) {
    outcome.track = relocalizer_.SearchEverywhere(frame, *places_, scale_);
  } else if (relocalize) {
    outcome.track = Relocalize(frame, prior_camera, prior_camera_covariance, kidnapped_);
    // A kidnap the radius around the prediction does not resolve: the vehicle may be farther.
    if (kidnapped_ && outcome.track.failure == tracking::TrackFailure::kNoMatch && places_ != nullptr &&
        places_->usable()) {
      tracking::TrackResult everywhere = relocalizer_.SearchEverywhere(frame, *places_, scale_);
      if (everywhere.ok() || everywhere.failure == tracking::TrackFailure::kAmbiguous) {
        outcome.track = std::move(everywhere);
      }
    }
  } else {
    outcome.track = tracker_.Track(frame, prior_camera, prior_camera_covariance, reference_, scale_, PredictedTilt());
  }
  // Lost, and the search around the prediction does not recover it: the vehicle may be
  // anywhere (moved unseen while the view kept matching a little where the estimate says, so
  // no kidnap was seen). Every lost_global_every-th frame, the whole map is searched.
  // (On a floor known to repeat the whole map never gives a place alone: not searched.)
  if (!outcome.track.ok() && !pose_unknown_ && lock_.state() == estimation::LockState::kLost &&
      options_.lost_global_every > 0 && places_ != nullptr && places_->floor_repeats() != true &&
      places_->usable() &&
      ++lost_frames_ % options_.lost_global_every == 0) {
    tracking::TrackResult everywhere = relocalizer_.SearchEverywhere(frame, *places_, scale_);
    if (everywhere.ok()) {
      outcome.track = std::move(everywhere);
      relocalize = true;
    }
  }
  // Off the map, on a floor known not to repeat: the vehicle may have been carried unseen to
  // mapped floor its estimate does not put it on; a copy cannot be taken for the place there.
  if (!outcome.track.ok() && !pose_unknown_ && lock_.state() == estimation::LockState::kOffMap &&
      options_.off_map_global_every > 0 && places_ != nullptr && places_->floor_repeats() == false &&
      places_->usable() && ++off_map_frames_ % options_.off_map_global_every == 0) {
    tracking::TrackResult everywhere = relocalizer_.SearchEverywhere(frame, *places_, scale_);
    if (everywhere.ok()) {
      outcome.track = std::move(everywhere);
      relocalize = true;
    }
  }
  if (outcome.track.ok() && options_.edge_templates > 0 && PartlyOffTheMap(outcome.track)) {
    outcome.track = AtTheEdge(frame, std::move(outcome.track));
  }
  if (outcome.track.ok()) {
    const auto [tilt, tilt_sigma_rad] = FixTilt(outcome.track);
    const core::Pose2 fix = MountingPoint(outcome.track, tilt) * options_.vehicle_from_camera.Inverse();
    // The floors are errors of the camera's pose (map and rectification errors move what the
    // camera sees), so they go in before the lever arm: a yaw error of the camera moves the
    // vehicle's origin sideways by the arm, and the fix's covariance says so.
    Eigen::Matrix3d camera_covariance = options_.fix_covariance_scale * outcome.track.covariance;
    camera_covariance(0, 0) += options_.fix_sigma_floor_mm * options_.fix_sigma_floor_mm;
    camera_covariance(1, 1) += options_.fix_sigma_floor_mm * options_.fix_sigma_floor_mm;
    camera_covariance(2, 2) += options_.fix_sigma_floor_rad * options_.fix_sigma_floor_rad;
    // The lever taken out of the fix is as uncertain as the tilt it was taken at.
    const double lever_sigma_mm = options_.tilt_pivot_height_mm * tilt_sigma_rad;
    camera_covariance(0, 0) += lever_sigma_mm * lever_sigma_mm;
    camera_covariance(1, 1) += lever_sigma_mm * lever_sigma_mm;
    const Eigen::Matrix3d fix_covariance =
        VehicleCovariance(outcome.track.world_from_camera, options_.vehicle_from_camera, camera_covariance);
    outcome.fix_world_from_vehicle = fix;
    outcome.fix_quality = std::clamp(outcome.track.mean_zncc, 0.0, 1.0);
    // How certain the estimate would be after the fix: a relocalization's (and a re-anchoring's)
    // is the fix's own, an update's the filter's corrected covariance. Not a number: not taken.
    const auto largest_sigma_mm = [](const Eigen::Matrix3d& covariance) {
      const Eigen::Matrix2d xy = 0.5 * (covariance.topLeftCorner<2, 2>() + covariance.topLeftCorner<2, 2>().transpose());
      return std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(xy, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff());
    };
    const double fix_sigma_mm = largest_sigma_mm(fix_covariance);
    const double fixed_sigma_mm =
        relocalize ? fix_sigma_mm : largest_sigma_mm(filter_->CorrectedCovariance(time, fix_covariance, unmodelled));
    if (!(fixed_sigma_mm <= options_.max_fixed_sigma_mm)) {
      outcome.reason = fmt::format(
          "fix rejected: too uncertain (the estimate would be good to {:.3f} mm, one standard deviation, above "
          "{:.3f}{})",
          fixed_sigma_mm, options_.max_fixed_sigma_mm,
          lever_sigma_mm != 0.0 && !outcome.track.tilt_estimated
              ? fmt::format("; {} templates too few to measure the tilt, whose lever is {:.3f} mm uncertain",
                            outcome.track.inliers, std::abs(lever_sigma_mm))
              : std::string());
    } else if (relocalize) {
      // A verified relocalization replaces the prediction it contradicts.
      Restart(time, fix, fix_covariance, false, &outcome);
    } else {
      const estimation::FixOutcome applied = filter_->Correct(time, fix, fix_covariance, unmodelled);
      outcome.fixed = applied.accepted;
      if (applied.innovation_covariance(0, 0) > 0.0) {
        outcome.nis = applied.mahalanobis2;
        outcome.normalized_innovation = applied.innovation.cwiseQuotient(
            applied.innovation_covariance.diagonal().cwiseSqrt());
      }
      if (applied.accepted) {
        fix_twist_ = filter_->Latest().Twist();
        rejected_run_ = 0;
      } else {
        outcome.reason = "fix rejected: " + applied.reason;
        const bool gated = applied.mahalanobis2 > options_.filter.gate_chi2;  // not too late or too early
        const Eigen::Vector3d offset(fix.x_mm() - predicted.x_mm(), fix.y_mm() - predicted.y_mm(),
                                     core::WrapAngle(fix.yaw_rad() - predicted.yaw_rad()));
        if (!gated) {
          rejected_run_ = 0;
        } else if (fix_sigma_mm <= options_.max_fixed_sigma_mm &&
                   RejectedAgain(time, offset, fix_covariance + unmodelled)) {
          // A restart takes the fix's own uncertainty: only from a fix certain enough.
          Restart(time, fix, fix_covariance, true, &outcome);
        }
      }
    }
  } else {
    outcome.reason = tracking::ToString(outcome.track.failure) + std::string(": ") + outcome.track.reason;
  }
  if (outcome.fixed && outcome.track.scale_estimated) {
    UpdateEstimate(outcome.track.scale,
                   options_.fix_covariance_scale * outcome.track.scale_sigma * outcome.track.scale_sigma, scale_,
                   scale_variance_);
  }
  outcome.scale = scale_;
  outcome.scale_sigma = std::sqrt(scale_variance_);
  if (outcome.fixed && outcome.track.tilt_estimated) {
    UpdateEstimate(Eigen::Vector2d(outcome.track.tilt_x_rad, outcome.track.tilt_y_rad),
                   options_.fix_covariance_scale * outcome.track.tilt_sigma_rad * outcome.track.tilt_sigma_rad, tilt_,
                   tilt_variance_);
  }
  estimation::FrameVerdict verdict = estimation::FrameVerdict::kFixed;
  if (outcome.fixed) {
    off_map_path_mm_ = 0.0;
    unmatched_run_ = 0;
    lost_frames_ = 0;
    off_map_frames_ = 0;
    kidnapped_ = false;
    pose_unknown_ = false;
  } else if (pose_unknown_) {
    verdict = estimation::FrameVerdict::kSearching;
  } else {
    verdict = ClassifyMiss(outcome, prior_camera, prior_camera_covariance, &outcome.reason);
  }
  Mode mode = Mode::kTrack;
  if (verdict == estimation::FrameVerdict::kSearching) {
    mode = Mode::kSearching;
  } else if (verdict == estimation::FrameVerdict::kOffMap) {
    mode = options_.visual_odometry.enabled && VisualOdometry(time, frame, predicted, &outcome) ? Mode::kVisualOdometry
                                                                                                : Mode::kDeadReckoning;
  }
  if (outcome.fixed) {
    KeepKeyframe(time, frame, 0.0);
    outcome.keyframe = options_.visual_odometry.enabled;
  }
  outcome.world_from_vehicle = filter_->PoseAt(time);
  outcome.covariance = filter_->CovarianceAt(time);
  const double sigma_mm = std::sqrt(std::max(outcome.covariance(0, 0), outcome.covariance(1, 1)));
  outcome.lock = lock_.Update(verdict, sigma_mm, outcome.reason);
  outcome.mode = mode;
  if (mode != mode_) {
    // Every change is said, with what made it: the frame's reason, or the fix that ended it.
    outcome.mode_switch = outcome.fixed ? std::string("a fix on the map") : outcome.reason;
    core::Log().info("localizer: mode {} -> {} at {:.3f} s: {}", ToString(mode_), ToString(mode),
                     core::ToSeconds(time - core::Timestamp()), outcome.mode_switch);
    mode_ = mode;
    ++mode_switches_;
  }
  return outcome;
}

void Localizer::KeepKeyframe(core::Timestamp time, const cv::Mat& frame, double chain_turn_rad) {
  if (!options_.visual_odometry.enabled) return;
  if (!keyframe_) keyframe_ = Keyframe{};
  keyframe_->chain_turn_rad = chain_turn_rad;
  keyframe_->time = time;
  frame.copyTo(keyframe_->image);  // reuses the buffer: one copy per kept frame
  keyframe_->world_from_vehicle = filter_->PoseAt(time);
  keyframe_->covariance = filter_->CovarianceAt(time);
  last_vo_camera_ = keyframe_->world_from_vehicle * options_.vehicle_from_camera;
}

bool Localizer::VisualOdometry(core::Timestamp time, const cv::Mat& frame, const core::Pose2& predicted,
                               FrameOutcome* outcome) {
  const VisualOdometryOptions& vo = options_.visual_odometry;
  const core::Pose2& vehicle_from_camera = options_.vehicle_from_camera;
  const core::Pose2 predicted_camera = predicted * vehicle_from_camera;
  // The encoder samples' time-stamp error puts the wheels' pose at the keyframe and now each
  // v sigma_t off along the heading (LocalizerOptions::odometry_timing_sigma_ms): the predicted
  // shift may be that much more than the true one.
  const double timing_mm = std::sqrt(2.0) * filter_->Latest().speed_mm_per_s() *
                           options_.odometry_timing_sigma_ms * 1e-3;
  const double reach = vo.max_fraction + 3.0 * timing_mm / std::min(camera_.width_mm(), camera_.height_mm());
  const double shift =
      keyframe_ ? ViewShift(camera_, keyframe_->world_from_vehicle * vehicle_from_camera, predicted_camera) : 0.0;
  if (!keyframe_ || keyframe_->image.size() != frame.size() || time <= keyframe_->time || shift > reach) {
    // Nothing to register against (no frame kept yet, or too far to overlap): this frame
    // starts the chain where the wheels put it.
    outcome->reason += !keyframe_ || shift <= reach
                           ? std::string("; visual odometry: a new keyframe")
                           : fmt::format("; visual odometry: a new keyframe (the view moved {:.2f} of its size from "
                                         "the last, over {:.3f} s)",
                                         shift, core::ToSeconds(time - keyframe_->time));
    KeepKeyframe(time, frame, keyframe_ ? keyframe_->chain_turn_rad : 0.0);
    outcome->keyframe = true;
    return false;
  }
  // The wheels' motion since an earlier frame of the chain, as the camera saw it, with its
  // uncertainty, as the registration's prior.
  const auto register_against = [&](const Keyframe& earlier) {
    const core::Pose2 prior_motion = Between(earlier.world_from_vehicle * vehicle_from_camera, predicted_camera);
    const double base_mm = vo.prior_sigma_mm + vo.prior_sigma_fraction * prior_motion.translation_mm().norm();
    const double sigma_mm = std::sqrt(base_mm * base_mm + timing_mm * timing_mm);
    const double sigma_rad = vo.prior_sigma_deg * std::numbers::pi / 180.0;
    const Eigen::Matrix3d prior =
        Eigen::Vector3d(sigma_mm * sigma_mm, sigma_mm * sigma_mm, sigma_rad * sigma_rad).asDiagonal();
    return tracking::RegisterFrames(tracker_, earlier.image, frame, prior_motion, prior);
  };
  const auto failed = [](const tracking::TrackResult& r) {
    return std::string(tracking::ToString(r.failure)) + (r.reason.empty() ? std::string() : " (" + r.reason + ")");
  };
  const Keyframe* base = &*keyframe_;
  tracking::TrackResult link = register_against(*base);
  if (!link.ok()) {
    // The frame before overlaps this one far more than the keyframe does: in a turn, or where
    // the view has moved on, its templates still fall on it.
    if (last_registered_ && last_registered_->time > keyframe_->time && last_registered_->time < time &&
        last_registered_->image.size() == frame.size()) {
      tracking::TrackResult before = register_against(*last_registered_);
      if (before.ok()) {
        outcome->reason += "; visual odometry: registered to the frame before (the keyframe: " + failed(link) + ")";
        link = std::move(before);
        base = &*last_registered_;
      }
    }
    if (!link.ok()) {
      outcome->reason += "; visual odometry: " + failed(link);
      return false;
    }
  }
  const core::Pose2 base_camera = base->world_from_vehicle * vehicle_from_camera;
  // The body's roll in the turn (VisualOdometryOptions::roll_deg_per_mps2), about the vehicle's
  // forward axis (in the camera's axes as mounted), biases the link's yaw (TiltYawBias).
  const estimation::MotionState motion = filter_->Latest();
  const double lateral_mps2 = motion.forward_speed_mm_per_s * 1e-3 * motion.yaw_rate_rad_per_s;
  const double roll_rad = vo.roll_deg_per_mps2 * std::numbers::pi / 180.0 * lateral_mps2;
  const Eigen::Vector2d tilt_camera = roll_rad * Eigen::Vector2d(std::cos(vehicle_from_camera.yaw_rad()),
                                                                 -std::sin(vehicle_from_camera.yaw_rad()));
  const double yaw_bias = TiltYawBias(link, camera_, tilt_camera, options_.tracker.solver.camera_height_mm);
  link.world_from_camera =
      core::Pose2(link.world_from_camera.translation_mm(), link.world_from_camera.yaw_rad() - yaw_bias);
  const double chain_turn_rad = base->chain_turn_rad + std::abs(link.world_from_camera.yaw_rad());
  // world_from_camera = base_camera * motion: the covariance of the frame registered against
  // carried through the composition, plus the link's turned into the world.
  Eigen::Matrix3d link_covariance = options_.fix_covariance_scale * link.covariance;
  link_covariance(0, 0) += vo.link_sigma_floor_mm * vo.link_sigma_floor_mm;
  link_covariance(1, 1) += vo.link_sigma_floor_mm * vo.link_sigma_floor_mm;
  link_covariance(2, 2) += vo.link_sigma_floor_rad * vo.link_sigma_floor_rad;
  const core::Pose2 camera_pose = base_camera * link.world_from_camera;
  const double c = std::cos(base_camera.yaw_rad()), s = std::sin(base_camera.yaw_rad());
  Eigen::Matrix3d turn = Eigen::Matrix3d::Identity();
  turn.topLeftCorner<2, 2>() << c, -s, s, c;
  const Eigen::Matrix3d through = ComposeJacobian(base_camera, link.world_from_camera);
  Eigen::Matrix3d camera_covariance =
      through * CameraCovariance(base->world_from_vehicle, vehicle_from_camera, base->covariance) *
          through.transpose() +
      turn * link_covariance * turn.transpose();
  // The chain's yaw bias grows with its turn, the same sign link after link: its variance is
  // (fraction x turn)², of which the keyframe's covariance holds the part up to the keyframe.
  camera_covariance(2, 2) += vo.turn_sigma_fraction * vo.turn_sigma_fraction *
                             (chain_turn_rad * chain_turn_rad - base->chain_turn_rad * base->chain_turn_rad);
  const core::Pose2 pose = camera_pose * vehicle_from_camera.Inverse();
  const Eigen::Matrix3d covariance = VehicleCovariance(camera_pose, vehicle_from_camera, camera_covariance);
  filter_->RestartAt(time, pose, covariance);
  outcome->fix_world_from_vehicle = pose;
  outcome->fix_quality = std::clamp(link.mean_zncc, 0.0, 1.0);
  outcome->link = tracking::FrameLink{base->time, link.world_from_camera, link_covariance};
  // A keyframe once the view has moved or turned far enough from the last, or when the next
  // frame, at this frame's pace, would lie beyond what registers against the last (a frame
  // just short of keyframe_fraction must not leave the next one beyond max_fraction); and
  // always when registered to the frame before, since the keyframe no longer registers.
  const double moved = ViewShift(camera_, base_camera, camera_pose);
  const double step = last_vo_camera_ ? ViewShift(camera_, *last_vo_camera_, camera_pose) : 0.0;
  last_vo_camera_ = camera_pose;
  const bool replace = base != &*keyframe_ || moved >= vo.keyframe_fraction || moved + step > 0.9 * vo.max_fraction ||
                       std::abs(link.world_from_camera.yaw_rad()) >= vo.keyframe_turn_deg * std::numbers::pi / 180.0;
  if (!replace && !last_registered_) last_registered_ = Keyframe{};
  Keyframe& kept = replace ? *keyframe_ : *last_registered_;  // buffers reused: one copy per frame
  outcome->keyframe = replace;
  kept.time = time;
  frame.copyTo(kept.image);
  kept.world_from_vehicle = pose;
  kept.covariance = covariance;
  kept.chain_turn_rad = chain_turn_rad;
  return true;
}

bool Localizer::OffTheMap(const tracking::ReferenceRaster& coarse, const core::Pose2& prior_camera,
                          std::string* reason) const {
  const double seen = CoverageOn(coarse, camera_, prior_camera, 0.0);
  if (seen >= options_.on_map_coverage) return false;
  *reason = "off-map: " + std::to_string(static_cast<int>(std::floor(100.0 * seen))) +
            " % of the predicted view is mapped (" + *reason + ")";
  return true;
}

tracking::TiltPrediction Localizer::PredictedTilt() const {
  if (!options_.tracker.solver.estimate_tilt) return {};
  return {tilt_.x(), tilt_.y(), std::sqrt(tilt_variance_)};
}

std::pair<Eigen::Vector2d, double> Localizer::FixTilt(const tracking::TrackResult& track) const {
  if (!options_.tracker.solver.estimate_tilt || options_.tilt_pivot_height_mm == 0.0) return {Eigen::Vector2d::Zero(), 0.0};
  if (track.tilt_estimated) {
    return {Eigen::Vector2d(track.tilt_x_rad, track.tilt_y_rad),
            std::sqrt(options_.fix_covariance_scale) * track.tilt_sigma_rad};
  }
  return {tilt_, std::sqrt(tilt_variance_)};
}

core::Pose2 Localizer::MountingPoint(const tracking::TrackResult& track, const Eigen::Vector2d& tilt_rad) const {
  if (options_.tilt_pivot_height_mm == 0.0) return track.world_from_camera;
  // The floor's normal in camera axes is (-tan tilt_y, tan tilt_x, 1): a body turned about an
  // axis p over the floor puts the image centre p times the normal's horizontal part away
  // from the mounting point, in the camera's axes.
  const Eigen::Vector2d offset_camera =
      options_.tilt_pivot_height_mm * Eigen::Vector2d(-std::tan(tilt_rad.y()), std::tan(tilt_rad.x()));
  return core::Pose2(track.world_from_camera.translation_mm() - track.world_from_camera.Rotation() * offset_camera,
                     track.world_from_camera.yaw_rad());
}

tracking::TrackResult Localizer::AtTheEdge(const cv::Mat& frame, tracking::TrackResult found) const {
  // Around the place found, to a pixel or two: the search windows stay small, so the extra
  // templates cost about as much as the refinement of the first ones.
  const double sigma_mm = 0.5 * camera_.mm_per_px();
  const Eigen::Matrix3d around = Eigen::Vector3d(sigma_mm * sigma_mm, sigma_mm * sigma_mm, 1e-6).asDiagonal();
  tracking::TrackResult precise =
      edge_tracker_.Track(frame, found.world_from_camera, around, reference_, found.scale, PredictedTilt());
  if (!precise.ok() || precise.inliers < found.inliers) return found;
  return precise;
}

estimation::FrameVerdict Localizer::ClassifyMiss(const FrameOutcome& outcome, const core::Pose2& prior_camera,
                                                 const Eigen::Matrix3d& prior_camera_covariance, std::string* reason) {
  if (outcome.track.failure == tracking::TrackFailure::kNoTexture) return estimation::FrameVerdict::kMissed;
  // The tracker found the floor where the prediction put it, or some of it (templates matched
  // but too few agreed, or the solve did not converge), and the filter's gate refused the fix
  // or there was none: no evidence against the prior. A map that no longer fits the floor
  // well (changed, or painted at another height) does that; a search without the prior would
  // then find a copy of a repeating floor a period away where the map fits better.
  // On a floor the map's self-test found free of copies, a partial match is no reason to keep
  // the prior: a search without it finds the place or nothing, never a copy (design.md 7b).
  const bool partial = outcome.track.failure == tracking::TrackFailure::kTooFewInliers ||
                       outcome.track.failure == tracking::TrackFailure::kNotConverged;
  const bool no_copies = places_ != nullptr && places_->floor_repeats() == false;
  const bool found_some = outcome.track.ok() || (partial && !no_copies);
  if (found_some && !kidnapped_) {
    unmatched_run_ = 0;
    if (!outcome.track.ok() && options_.visual_odometry.enabled) {
      // Some of the view matched, too little for a fix: where most of the predicted view is
      // unmapped (a lane's edge, floor just mapped behind the vehicle) that is off the map, and
      // visual odometry carries the estimate on.
      const tracking::CoarseReference coarse = tracking::Coarsen(reference_, std::min(2, options_.relocalize.level));
      if (OffTheMap(*coarse.raster, prior_camera, reason)) return estimation::FrameVerdict::kOffMap;
    }
    return estimation::FrameVerdict::kMissed;
  }
  // A known kidnap makes the prediction meaningless: where it lies says nothing.
  if (kidnapped_) {
    ++unmatched_run_;
    return estimation::FrameVerdict::kMissed;
  }
  const tracking::CoarseReference coarse = tracking::Coarsen(reference_, std::min(2, options_.relocalize.level));
  if (OffTheMap(*coarse.raster, prior_camera, reason)) {
    unmatched_run_ = 0;
    return estimation::FrameVerdict::kOffMap;
  }
  // Evidence against the prior only if, wherever its 3-sigma region puts the camera, the view
  // would have been as much on the map: the ends of the position ellipse's axes and the yaw
  // turned either way.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> position(prior_camera_covariance.topLeftCorner<2, 2>());
  bool inside = true;
  for (int k = 0; k < 6 && inside; ++k) {
    Eigen::Vector3d shift = Eigen::Vector3d::Zero();
    if (k < 4) {
      const int axis = k / 2;
      shift.head<2>() = (k % 2 == 0 ? 3.0 : -3.0) * std::sqrt(std::max(position.eigenvalues()(axis), 0.0)) *
                        position.eigenvectors().col(axis);
    } else {
      shift.z() = (k == 4 ? 3.0 : -3.0) * std::sqrt(std::max(prior_camera_covariance(2, 2), 0.0));
    }
    const core::Pose2 moved(prior_camera.x_mm() + shift.x(), prior_camera.y_mm() + shift.y(),
                            prior_camera.yaw_rad() + shift.z());
    inside = CoverageOn(*coarse.raster, camera_, moved, 0.0) >= options_.on_map_coverage;
  }
  unmatched_run_ = inside ? unmatched_run_ + 1 : 0;  // at the map's edge the view may be off it
  return estimation::FrameVerdict::kMissed;
}

void Localizer::Restart(core::Timestamp time, const core::Pose2& fix, const Eigen::Matrix3d& fix_covariance,
                        bool reanchoring, FrameOutcome* outcome) {
  filter_->RestartAt(time, fix, fix_covariance);
  outcome->fixed = true;
  outcome->relocalized = true;
  outcome->reason.clear();
  ++(reanchoring ? reanchorings_ : relocalizations_);
  rejected_run_ = 0;
}

bool Localizer::RejectedAgain(core::Timestamp time, const Eigen::Vector3d& offset,
                              const Eigen::Matrix3d& offset_covariance) {
  // Rejected fixes that all put the vehicle the same amount off the prediction say the
  // prediction is off, not they. Between two such fixes the offset changes by both fixes'
  // errors and by the odometry's error over the interval (the prediction's covariance grew
  // by it: no fix came in).
  const Eigen::Matrix3d prediction_covariance = filter_->CovarianceAt(time);
  Eigen::Matrix3d drift = prediction_covariance - rejected_prediction_covariance_;
  if ((drift.diagonal().array() < 0.0).any()) drift.setZero();
  const Eigen::Vector3d change = offset - rejected_offset_;
  const Eigen::Matrix3d both = offset_covariance + rejected_covariance_ + drift;
  const bool same = rejected_run_ > 0 && change.dot(both.inverse() * change) <= options_.filter.gate_chi2;
  rejected_run_ = same ? rejected_run_ + 1 : 1;
  rejected_offset_ = offset;
  rejected_covariance_ = offset_covariance;
  rejected_prediction_covariance_ = prediction_covariance;
  return options_.reanchor_after_rejections > 0 && rejected_run_ >= options_.reanchor_after_rejections;
}

tracking::TrackResult Localizer::Relocalize(const cv::Mat& frame, const core::Pose2& prior_camera,
                                           const Eigen::Matrix3d& prior_camera_covariance, bool kidnapped) const {
  if (kidnapped) {
    // The covariance no longer says where to look: the whole radius is searched, any place taken.
    tracking::TrackResult found = relocalizer_.Search(frame, prior_camera, prior_camera_covariance,
                                                      options_.relocalize_radius_mm, std::nullopt, scale_);
    // On a floor that repeats, the place nearest a prior that is not to be trusted may be a
    // copy. Where the map has a place index, it says whether the frame matches anywhere else:
    // if so, no place is taken.
    return found.ok() ? CheckedAgainstTheMap(frame, std::move(found)) : found;
  }
  // The prediction's gate, and a little more for the candidates' own uncertainty.
  const double sigma_mm = std::sqrt(std::max(prior_camera_covariance(0, 0), prior_camera_covariance(1, 1)));
  const double gate_mm = std::sqrt(options_.filter.gate_chi2) * sigma_mm + 20.0;
  const double radius_mm = std::min(options_.relocalize_radius_mm, gate_mm);
  tracking::TrackResult found =
      relocalizer_.Search(frame, prior_camera, prior_camera_covariance, radius_mm,
                          tracking::RelocalizeGate{options_.filter.gate_chi2, options_.fix_covariance_scale,
                                                   places_ != nullptr && places_->floor_repeats() == true},
                          scale_);
  // A gate wider than the search (a long dead reckoning) holds places the search did not see:
  // the nearest of those it saw may be a copy of the floor. Checked against the whole map, as
  // for a kidnap. So is a place found while the lock is lost on a floor not known to be free of
  // copies: the prediction has failed frame after frame, and a prediction wrong by more than
  // its covariance says (a vehicle moved unseen) puts a copy inside the gate as readily as the
  // true place.
  if (found.ok() && gate_mm > radius_mm) return CheckedAgainstTheMap(frame, std::move(found));
  if (found.ok() && lock_.state() == estimation::LockState::kLost && places_ != nullptr &&
      places_->floor_repeats() != false) {
    return CheckedAgainstTheMap(frame, std::move(found));
  }
  return found;
}

tracking::TrackResult Localizer::CheckedAgainstTheMap(const cv::Mat& frame, tracking::TrackResult found) const {
  if (places_ == nullptr || !places_->usable()) return found;
  if (places_->floor_repeats() == true) {
    // The whole map never confirms a place on such a floor (Relocalizer::SearchEverywhere).
    tracking::TrackResult refused;
    refused.failure = tracking::TrackFailure::kAmbiguous;
    refused.reason = "the floor repeats (the map's self-test): the place nearest an untrusted prior may be a copy, "
                     "and the whole map cannot tell them apart";
    return refused;
  }
  tracking::TrackResult everywhere = relocalizer_.SearchEverywhere(frame, *places_, scale_);
  if (everywhere.ok() || everywhere.failure == tracking::TrackFailure::kAmbiguous) return everywhere;
  if (places_->floor_repeats() == false) return found;  // the index did not see the frame: no copy to fear
  // On a floor never tested for copies (an index without the self-test's verdict, or none of
  // whose views could be placed), the place nearest a prior that is not to be trusted may be a
  // copy of the true place, and the whole map could not say which it is.
  tracking::TrackResult refused;
  refused.failure = tracking::TrackFailure::kAmbiguous;
  refused.reason = "the floor was never tested for copies (`mosaicloc map index` tests it) and the whole map could "
                   "not place the frame: the place nearest an untrusted prior may be a copy";
  return refused;
}

double MapCoverage(const tracking::ReferenceRaster& reference, const camera::IdealCamera& camera,
                   const core::Pose2& world_from_camera, double margin_mm, int level) {
  const tracking::CoarseReference coarse = tracking::Coarsen(reference, level);
  return CoverageOn(*coarse.raster, camera, world_from_camera, margin_mm);
}

}  // namespace mosaicloc::localizer
