#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/estimation/lock.hpp"
#include "mosaicloc/estimation/odometry.hpp"
#include "mosaicloc/estimation/pose_filter.hpp"
#include "mosaicloc/tracking/place_index.hpp"
#include "mosaicloc/tracking/relocalize.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::localizer {

/// What the localizer did with a frame (design.md section 7c; the PLC's mode register).
enum class Mode {
  kTrack = 1,           ///< registered against the map: a fix, or a miss where the map says one was due
  kVisualOdometry = 2,  ///< off the map: registered against the last keyframe and chained on from it
  kDeadReckoning = 3,   ///< off the map and not registered: the wheels alone
  kSearching = 4,       ///< the pose is unknown and the whole map is searched
};
/// "track", "visual-odometry", "dead-reckoning", "searching" (fixes.csv's mode column).
const char* ToString(Mode mode);

/// Visual odometry off the map (design.md section 7c): a frame off the map is registered
/// against the keyframe (the last frame with a fix or registered so, kept as the view moves on)
/// around the wheels' motion since it, and the estimate chained on from the keyframe's with the
/// registration's covariance added. Where the keyframe does not register (the view turned or
/// moved so that too few templates fall on it), the frame is registered against the frame
/// before it, which overlaps it far more, and becomes the keyframe; the wheels carry the
/// estimate only where that fails too.
struct VisualOdometryOptions {
  bool enabled = true;
  /// A registered frame becomes the keyframe once its view centre is this share of the view's
  /// shorter side away from the keyframe's (fewer links in the chain, less drift).
  double keyframe_fraction = 0.3;
  /// ... or once it has turned this far from the keyframe, degrees (in a tight turn the view
  /// turns away from the keyframe's faster than it moves).
  double keyframe_turn_deg = 3.0;
  /// A frame whose predicted view centre is farther than this share from the keyframe's is not
  /// registered against it (too little overlap); it becomes the keyframe, dead-reckoned.
  double max_fraction = 0.6;
  /// The wheels' motion since the keyframe as the registration's prior: uncertain by
  /// prior_sigma_mm + prior_sigma_fraction x its length, and prior_sigma_deg.
  double prior_sigma_mm = 2.0;
  double prior_sigma_fraction = 0.05;
  double prior_sigma_deg = 0.5;
  /// Floors on each link's standard deviation (the registration's covariance is scaled by
  /// LocalizerOptions::fix_covariance_scale first), mm and rad.
  double link_sigma_floor_mm = 0.005;
  double link_sigma_floor_rad = 3e-5;
  /// The body's roll per m/s² of lateral acceleration, leaning out of the turn (degrees; 0: a
  /// body that does not roll). A view tilted by phi about the camera's x axis that moves t
  /// forward sees the floor sheared, and the registration takes phi t / (2 h) of it for a
  /// turn: every link of a turn over-turns the same way, by k v² / (2 h) of the turn (1.2 % at
  /// 0.2°/(m/s²), 1.2 m/s and 200 mm). Each link's yaw is corrected by it, the roll taken from
  /// the filter's speed and yaw rate.
  double roll_deg_per_mps2 = 0.0;
  /// What is left of that, or all of it where the roll is not given: the chain's yaw is
  /// uncertain by this share of the turn it made since the last fix, all links alike (a bias,
  /// not noise that averages out). 0 for a body that does not roll: a wider covariance than
  /// the chain's error widens the search coming back onto the map, and on a floor that repeats
  /// a gate wider than the floor's period holds copies.
  double turn_sigma_fraction = 0.0;
  bool Check(std::string* why) const;
};

struct LocalizerOptions {
  tracking::TrackerOptions tracker;
  estimation::PoseFilterOptions filter;
  estimation::LockOptions lock;
  estimation::OdometryOptions odometry;
  core::Pose2 vehicle_from_camera;
  /// Floor on a fix's standard deviation (model errors the tracker's covariance does not
  /// see: map painting, rectification), mm and rad.
  double fix_sigma_floor_mm = 0.003;
  double fix_sigma_floor_rad = 2e-5;
  /// Fix covariance inflation: the tracker's covariance counts every pixel as independent.
  double fix_covariance_scale = 4.0;
  /// A fix that would leave the estimate's position less certain than this (its largest
  /// standard deviation after the fix, mm) is not taken: an uncertain prediction (after visual
  /// odometry, say) takes on an uncertain fix's error (the lever of a tilt its templates were
  /// too few to measure), and the frame would be reported as fixed. A confident prediction
  /// keeps its certainty whatever the fix. The next frame usually does better.
  double max_fixed_sigma_mm = 0.25;
  /// Uncertainty of the encoder samples' time stamps, ms: 0 in replay (exact clocks); on a
  /// vehicle the PLC's update period and the polling make them late or early by a few ms,
  /// which puts the odometry v * dt behind or ahead along the heading and its heading
  /// omega * dt off while the vehicle turns. The prediction is widened by that much, for the
  /// search and for the gate.
  double odometry_timing_sigma_ms = 0.0;
  /// A map is not rigid: one built from a mapping drive is off the true geometry by a few mm
  /// over tens of metres where its loops could not all be closed, so two of its places d
  /// apart may be up to a few thousandths of d off each other. Odometry and visual odometry
  /// measure the true motion; a prediction carried off the map meets it again where the map's
  /// own error is not the one it had where the vehicle left it. The prediction is widened in
  /// position by this times the path driven off the map (visual odometry or dead reckoning)
  /// since the last fix, one standard deviation, mm per m: for the search and for the gate.
  double map_distortion_mm_per_m = 1.0;
  /// Relocalization, when the prediction is too uncertain for the tracker's search range or
  /// a kidnap is known (below): the frame is searched for on the coarse map around the
  /// prediction (tracking::Relocalizer). Without a known kidnap the search covers the
  /// prediction's gate (filter.gate_chi2) and a place outside it is never taken; with one,
  /// relocalize_radius_mm is searched whatever the prior says. On a floor that repeats,
  /// relocalize_radius_mm should exceed the period, or a kidnapped vehicle may take the one
  /// copy it sees.
  tracking::RelocalizeOptions relocalize;
  double relocalize_radius_mm = 600.0;
  /// A frame without a fix whose predicted view the map covers less than this share of is
  /// off the map (state and reason "off-map"): a miss is expected there, the filter
  /// dead-reckons, and the lock is not lost. At or above it a fix is expected (the tracker
  /// fixes views half on the map); keep it at least relocalize.min_coverage, so that a place a
  /// kidnap search may have to find is one the search can take.
  double on_map_coverage = 0.75;
  /// Evidence of a kidnap from the view itself: after this many frames in a row without a
  /// fix (other than for want of texture) where the view would be on the map (on_map_coverage)
  /// wherever the prediction's 3-sigma region puts it, the prior is wrong (a vehicle pushed
  /// aside while switched off, a confidently wrong start), and relocalize_radius_mm is searched
  /// without it. Misses at the map's edge or off it are no such evidence. 0: only on request.
  int relocalize_after_misses = 5;
  /// While the lock is lost and the searches around the prediction find nothing, every this
  /// many frames the whole map is searched through its place index (when the map has one), and
  /// a place taken if it is the only one the frame matches (design.md section 7b). 0: never.
  int lost_global_every = 5;
  /// Off the map, every this many frames the whole map is searched too, but only on a map whose
  /// floor is known not to repeat (tracking::PlaceIndex::floor_repeats false, the self-test
  /// `map build` and `map index` record): there no copy of the floor can be taken for the
  /// place, and a vehicle carried unseen to where its estimate is off the map finds itself
  /// again. On a floor that repeats, or one not tested, never (design.md section 7b). 0: never.
  int off_map_global_every = 10;
  /// A view partly off the map (a template's place was unmapped: at a lane's edge, coming back
  /// onto the map) is registered from templates that all lie on one side of it, where the yaw,
  /// and with it the vehicle's origin a lever arm away, is less well held; the first fix back
  /// on the map, with an uncertain prediction, stands on it alone. The place such a frame's
  /// registration found is registered again around it, in small search windows, with
  /// edge_templates templates (spread mode) instead of tracker.templates.count. 0: never.
  int edge_templates = 16;
  /// A filter that is confidently wrong (its odometry dated a few ms off while braking, say)
  /// rejects every fix at its gate, however well they agree. After this many consecutive
  /// rejected fixes that are off the prediction by the same amount (within their
  /// uncertainty), the filter restarts from the newest. 0: never.
  int reanchor_after_rejections = 3;
  /// The image scale (the camera's height over the floor against the calibrated one), where
  /// tracker.solver.estimate_scale measures it: a scalar Kalman filter of the fixes' scales
  /// whose value seeds each frame's registration. It starts at 1 with scale_sigma, and wanders
  /// by scale_drift_per_sqrt_s (load, tyre wear, an uneven floor) between fixes.
  double scale_sigma = 0.02;
  double scale_drift_per_sqrt_s = 0.002;
  /// Where tracker.solver.estimate_tilt measures the camera's tilt: the height over the floor
  /// of the axis the vehicle's body pitches and rolls about on its suspension, mm. A body
  /// tilted by an angle a moves the image centre on the floor by this times a against the
  /// camera's mounting point; the fix takes that out (0: the body tilts about the floor).
  double tilt_pivot_height_mm = 0.0;
  /// The body's tilt between the frames that measure it (tracker.solver.estimate_tilt with a
  /// tilt_pivot_height_mm): about each camera axis a first-order Gauss-Markov process of
  /// standard deviation tilt_sigma_deg that forgets itself over tilt_correlation_s, brought up
  /// to date by every fix that measures the tilt. A fix whose templates are too few to measure
  /// it takes the lever out at the tilt this predicts, and carries the prediction's uncertainty
  /// times the pivot's height in its covariance: a body that leans into a turn while the view
  /// comes back onto the edge of the map is not taken for a vehicle a millimetre aside.
  double tilt_sigma_deg = 0.5;
  double tilt_correlation_s = 2.0;
  VisualOdometryOptions visual_odometry;
  bool Check(std::string* why) const;
};

/// What happened to one frame.
struct FrameOutcome {
  /// Why there is no fix, in one word (fixes.csv): "off-map", "rejected" (at the filter's
  /// gate, or too uncertain to take: LocalizerOptions::max_fixed_sigma_mm), or the tracker's failure ("no-texture", "no-match", "ambiguous",
  /// "too-few-inliers", "not-converged"); empty with a fix.
  std::string ReasonWord() const;

  bool fixed = false;                ///< a visual fix was accepted by the filter
  bool relocalized = false;          ///< the filter restarted from this fix (a relocalization or a re-anchoring)
  std::string reason;                ///< why not, when not
  core::Pose2 fix_world_from_vehicle;  ///< the tracker's fix (valid when the tracker succeeded)
  double fix_quality = 0.0;          ///< 0..1: mean refined ZNCC of the inliers
  core::Pose2 world_from_vehicle;    ///< the filter's estimate at the frame's time, after the fix
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  estimation::LockState lock = estimation::LockState::kTracking;
  Mode mode = Mode::kTrack;
  /// Visual odometry: the frame's registration against the keyframe (kVisualOdometry only).
  std::optional<tracking::FrameLink> link;
  /// The localizer keeps this frame as its keyframe from now on (a fix, a registered frame far
  /// enough from the last keyframe, or a frame off the map that starts a new chain).
  bool keyframe = false;
  /// The frame changed the mode: why (empty otherwise).
  std::string mode_switch;
  /// The image scale estimate after the frame, and its standard deviation (LocalizerOptions::
  /// scale_sigma): 1.004 is a camera 0.4 % higher over the floor than calibrated.
  double scale = 1.0;
  double scale_sigma = 0.0;
  /// Where the filter judged a fix (accepted, or rejected at its gate): the normalized
  /// innovation squared, the fix's squared Mahalanobis distance to the prediction (chi-square
  /// with 3 degrees of freedom when the filter's covariances are true), and each component of
  /// the innovation over its predicted standard deviation (x, y, yaw). Empty otherwise (no
  /// fix, or a fix that restarted the filter).
  std::optional<double> nis;
  Eigen::Vector3d normalized_innovation = Eigen::Vector3d::Zero();
  tracking::TrackResult track;       ///< the tracker's full diagnostics
};

/// The per-frame pipeline of the founding paper's Figure 3: odometry drives the filter; for
/// each frame the system model predicts the camera pose at the frame's time, the tracker
/// registers the frame against the map around it, and the filter takes the fix. One thread;
/// deterministic given the same inputs.
class Localizer {
 public:
  /// `reference` (the map, level 0) and `places` (its place index, for global relocalization;
  /// null: none) must outlive the localizer. Throws core::Error (invalid input) on bad options.
  Localizer(const camera::IdealCamera& camera, const LocalizerOptions& options,
            const tracking::ReferenceRaster& reference, const tracking::PlaceIndex* places = nullptr);

  /// Starts (or restarts) at a known pose.
  void Initialize(core::Timestamp time, const core::Pose2& world_from_vehicle, const Eigen::Matrix3d& covariance);
  /// Moves the estimate to a pose given from outside at `time` (an operator's or the PLC's),
  /// keeping what the filter has learnt of the wheels; requires initialized().
  void SetPose(core::Timestamp time, const core::Pose2& world_from_vehicle, const Eigen::Matrix3d& covariance);
  /// Starts without a known pose (design.md section 7b): every frame is looked for on the whole
  /// map through its place index until one is found (lock state "searching"). Without a usable
  /// index the frames get no fix, and the reason says how to build one.
  void InitializeUnknown(core::Timestamp time);
  bool initialized() const { return filter_.has_value(); }
  /// The pose is unknown and the whole map is searched (InitializeUnknown,
  /// RequestGlobalRelocalization), until a fix.
  bool pose_unknown() const { return pose_unknown_; }

  /// One encoder sample (raw PLC counters, the vehicle kind's two). Returns false when the
  /// sample was rejected; last_encoder_failure() says why.
  bool AddEncoders(core::Timestamp time, const core::EncoderCounts& counts);
  std::optional<estimation::OdometryFailure> last_encoder_failure() const { return encoder_failure_; }
  /// Odometry is unavailable (the PLC link is down or its heartbeat stale): the next sample
  /// only re-seeds the counters, so wheel turns unseen or counters reset by a PLC restart
  /// are not taken for motion. Meanwhile frames coast the filter on the system model.
  void SuspendOdometry() { odometry_.ForgetCounters(); }
  /// One ideal frame. The odometry should already reach past `time` (the fix is applied at
  /// the frame's own time inside the filter's history); a frame newer than the odometry
  /// coasts the filter to its time first.
  FrameOutcome ProcessFrame(core::Timestamp time, const cv::Mat& frame);

  /// The estimate at any time (system model).
  core::Pose2 PoseAt(core::Timestamp time) const;
  Eigen::Matrix3d CovarianceAt(core::Timestamp time) const;
  /// The latest state and velocities (for answering from another thread); requires
  /// initialized().
  estimation::MotionState Latest() const;
  /// What the filter has learnt of each wheel's scale error (left, right: 0.02 when the
  /// wheel travels 2 % farther than its calibrated radius says; a tricycle's drive wheel's, and
  /// its steering offset's error in radians), and the standard deviations.
  /// One that persists over long drives is a radius to recalibrate; over a short drive the
  /// estimate also absorbs encoder time-stamp errors. Requires initialized().
  Eigen::Vector2d wheel_scale_error() const;
  Eigen::Vector2d wheel_scale_sigma() const;
  const estimation::LockMonitor& lock() const { return lock_; }
  /// Restarts of the filter from a fix: relocalizations (a place found by a search and
  /// verified), and re-anchorings on fixes the gate kept rejecting, all off the prediction by
  /// the same amount (the odometry, not the fixes, was off).
  std::int64_t relocalizations() const { return relocalizations_; }
  std::int64_t reanchorings() const { return reanchorings_; }
  /// The vehicle's pose is not known (it was moved while switched off, or the start pose is a
  /// guess): from the next frame on, relocalize_radius_mm around the prediction is searched
  /// and the one place found taken, whatever the prior's covariance says, until a fix.
  void RequestRelocalization() { kidnapped_ = true; }
  /// The vehicle may be anywhere on the map (moved while switched off, the PLC's relocalize
  /// request): from the next frame on, the whole map is searched through its place index and
  /// a place taken only if it is the only one the frame matches; the estimate is meaningless
  /// until then. Without a usable index this is RequestRelocalization().
  void RequestGlobalRelocalization();
  /// A kidnap is known (requested, or seen by the view) and not yet resolved by a fix.
  bool kidnapped() const { return kidnapped_; }
  /// The mode of the latest frame, and how often it has changed since the start.
  Mode mode() const { return mode_; }
  std::int64_t mode_switches() const { return mode_switches_; }

 private:
  // Relocalizes the frame around the prediction: the verified registration, or nothing.
  // `kidnapped`: the prediction is not to be trusted, so the whole relocalize_radius_mm is
  // searched and any place may be taken; else the prediction's gate, and only places in it.
  tracking::TrackResult Relocalize(const cv::Mat& frame, const core::Pose2& prior_camera,
                                   const Eigen::Matrix3d& prior_camera_covariance, bool kidnapped) const;
  // A place a relocalization found with a prior that cannot rule out copies of the floor,
  // checked against the whole map through the place index (when there is a usable one): the
  // place the index verifies, or kAmbiguous when the frame matches elsewhere too.
  tracking::TrackResult CheckedAgainstTheMap(const cv::Mat& frame, tracking::TrackResult found) const;
  // What a frame without a fix says: off the map (none expected), a miss inside the map
  // that is evidence against the prior, or a miss that is neither.
  estimation::FrameVerdict ClassifyMiss(const FrameOutcome& outcome, const core::Pose2& prior_camera,
                                        const Eigen::Matrix3d& prior_camera_covariance, std::string* reason);
  // The predicted view is less than on_map_coverage on `coarse` (the map at the coverage's
  // level): says so in front of `reason`.
  bool OffTheMap(const tracking::ReferenceRaster& coarse, const core::Pose2& prior_camera, std::string* reason) const;
  // Where the camera's mounting point is, from the image centre the tracker found and the
  // camera's tilt (LocalizerOptions::tilt_pivot_height_mm).
  core::Pose2 MountingPoint(const tracking::TrackResult& track, const Eigen::Vector2d& tilt_rad) const;
  // The tilt the fix of `track` is taken at, and its standard deviation (rad): the one the
  // tracker measured (its sigma inflated as the fix's covariance is), or else the one
  // predicted (LocalizerOptions::tilt_sigma_deg). Zero both where no lever is taken out.
  std::pair<Eigen::Vector2d, double> FixTilt(const tracking::TrackResult& track) const;
  // The tilt predicted, which the tracker holds where a frame's templates are too few to
  // measure it (none unless the tilt is estimated).
  tracking::TiltPrediction PredictedTilt() const;
  // A registration of a view partly off the map, registered again around itself with more
  // templates; the one with more inliers.
  tracking::TrackResult AtTheEdge(const cv::Mat& frame, tracking::TrackResult found) const;
  // Off the map: registers the frame against the keyframe (or the frame before) and chains the
  // estimate on from it (true), or makes it the keyframe where it cannot be registered (false,
  // and why).
  bool VisualOdometry(core::Timestamp time, const cv::Mat& frame, const core::Pose2& predicted,
                      FrameOutcome* outcome);
  // Keeps the frame as the keyframe, at the filter's estimate for its time.
  void KeepKeyframe(core::Timestamp time, const cv::Mat& frame, double chain_turn_rad);
  // Restarts the filter from a fix (a relocalization, or a re-anchoring) and says so.
  void Restart(core::Timestamp time, const core::Pose2& fix, const Eigen::Matrix3d& fix_covariance,
               bool reanchoring, FrameOutcome* outcome);
  // One more fix rejected at the gate, `offset` off the prediction: extends or starts the run
  // of rejections off by the same amount; true when it is long enough to re-anchor on.
  bool RejectedAgain(core::Timestamp time, const Eigen::Vector3d& offset, const Eigen::Matrix3d& offset_covariance);

  camera::IdealCamera camera_;
  LocalizerOptions options_;
  const tracking::ReferenceRaster& reference_;
  const tracking::PlaceIndex* places_ = nullptr;
  tracking::Tracker tracker_;
  tracking::Tracker edge_tracker_;  ///< with edge_templates, for views partly off the map
  tracking::Relocalizer relocalizer_;
  estimation::WheelOdometry odometry_;
  std::optional<estimation::PoseFilter> filter_;
  estimation::LockMonitor lock_;
  Eigen::Matrix3d tick_quantization_;  ///< the counts' quantization, vehicle frame
  std::int64_t relocalizations_ = 0;
  std::int64_t reanchorings_ = 0;
  // The run of consecutive fixes the gate rejected: how many, the last one's offset from the
  // prediction (x, y, yaw) and that offset's covariance.
  int rejected_run_ = 0;
  Eigen::Vector3d rejected_offset_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rejected_covariance_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d rejected_prediction_covariance_ = Eigen::Matrix3d::Zero();  ///< the filter's, then
  /// The body twist per second (forward, lateral, yaw rate) when the last fix was accepted.
  Eigen::Vector3d fix_twist_ = Eigen::Vector3d::Zero();
  /// Consecutive frames without a fix whose prediction, with its uncertainty, lies on the map
  /// (frames without texture neither count nor break the run).
  int unmatched_run_ = 0;
  std::int64_t lost_frames_ = 0;  ///< frames without a fix while lost
  std::int64_t off_map_frames_ = 0;  ///< frames without a fix while off the map
  bool kidnapped_ = false;
  bool pose_unknown_ = false;
  // Visual odometry's keyframe: its time, image (owned: the caller's buffer may be reused),
  // and the estimate and covariance of world_from_vehicle at its time.
  struct Keyframe {
    core::Timestamp time;
    cv::Mat image;
    core::Pose2 world_from_vehicle;
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    double chain_turn_rad = 0.0;  ///< how far the chain of links had turned at it since the last fix
  };
  std::optional<Keyframe> keyframe_;
  /// The last frame visual odometry registered, kept the same way (no older than the keyframe
  /// when it counts): what a frame the keyframe does not register is registered against.
  std::optional<Keyframe> last_registered_;
  std::optional<core::Pose2> last_vo_camera_;  ///< the camera pose of the last frame visual odometry registered
  Mode mode_ = Mode::kTrack;
  std::int64_t mode_switches_ = 0;
  std::optional<estimation::OdometryFailure> encoder_failure_;  ///< of the last sample rejected
  /// The path driven since the last fix while off the map (map_distortion_mm_per_m), and the
  /// prediction it was measured along, at the last frame.
  double off_map_path_mm_ = 0.0;
  std::optional<core::Pose2> last_predicted_;
  // The image scale's estimate, its variance, and the time it was last brought to.
  double scale_ = 1.0;
  double scale_variance_ = 0.0;
  std::optional<core::Timestamp> scale_time_;
  // The camera's tilt (rad, about its x and y axes; LocalizerOptions::tilt_sigma_deg), the
  // variance of either (both axes are predicted and measured alike), and the time they were
  // last brought to.
  Eigen::Vector2d tilt_ = Eigen::Vector2d::Zero();
  double tilt_variance_ = 0.0;
  std::optional<core::Timestamp> tilt_time_;
};

/// Share (0..1) of the floor seen by a camera at `world_from_camera`, grown by `margin_mm`
/// on every side, that `reference` maps; sampled on its coarser level `level` (0: itself).
double MapCoverage(const tracking::ReferenceRaster& reference, const camera::IdealCamera& camera,
                   const core::Pose2& world_from_camera, double margin_mm, int level);

/// Covariance of world_from_camera = world_from_vehicle * vehicle_from_camera given the
/// covariance of world_from_vehicle (first order), and the inverse mapping.
Eigen::Matrix3d CameraCovariance(const core::Pose2& world_from_vehicle, const core::Pose2& vehicle_from_camera,
                                 const Eigen::Matrix3d& vehicle_covariance);
Eigen::Matrix3d VehicleCovariance(const core::Pose2& world_from_camera, const core::Pose2& vehicle_from_camera,
                                  const Eigen::Matrix3d& camera_covariance);

}  // namespace mosaicloc::localizer
