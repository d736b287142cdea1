#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/mapping/pose_graph.hpp"
#include "mosaicloc/mapping/view_geometry.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::mapping {

struct MapperOptions {
  /// The matcher that registers frames with one another (frame to frame and loops).
  tracking::TrackerOptions tracker;
  /// Besides its predecessor, each frame is registered against its keyframe: the oldest recent
  /// frame whose view centre is within this share of the view's shorter side. The long edges
  /// make the chain's random walk take fewer steps.
  double keyframe_fraction = 0.7;
  /// A frame is tried for a loop closure when its camera has moved this far since the last frame
  /// tried.
  double loop_spacing_mm = 30.0;
  /// Earlier frames whose chained view centre is within this share of the view's shorter side
  /// are loop candidates,
  double loop_radius_fraction = 0.5;
  /// ... when at least this much path lies between them (nearer ones are the chain itself).
  double loop_min_separation_mm = 500.0;
  /// The loop's search half-range, px (the tracker's max_search_px for loops): a loop whose
  /// prediction's 3-sigma region it cannot cover is not tried, so that a copy of a repeating
  /// floor outside the search can never be taken for the place.
  int loop_max_search_px = 320;
  /// At most this many candidates per frame tried, each from a different pass over the place.
  int loop_candidates = 2;
  /// How far the chain may have drifted between two frames, one standard deviation: the
  /// prediction of a loop is uncertain by drift_sigma_mm + drift_mm_per_m x the path between the
  /// two frames (and likewise in yaw). It sizes the loop's search and gates what it finds.
  double drift_sigma_mm = 1.0;
  double drift_mm_per_m = 0.3;
  double drift_sigma_deg = 0.05;
  double drift_deg_per_m = 0.02;
  /// A registered pair's relative pose off its prediction by more than this (squared Mahalanobis
  /// distance, 3 degrees of freedom) is a wrong loop: on a repeating floor the chain cannot
  /// have drifted a whole pattern period.
  double loop_gate_chi2 = 16.27;
  /// The registration's own covariance is floored by these (one standard deviation): the
  /// tracker's estimate ignores biases that do not average out. Low enough that the links'
  /// own covariances, not the floor, tell a precise link from a loose one (design.md
  /// section 8: the keyframe links' yaw is four times looser than the consecutive ones').
  /// The yaw's floor is divided by the fraction of the view the two frames share (at least
  /// 0.1): a link's yaw error grows as its overlap shrinks, which the tracker's covariance,
  /// mostly under the floor, does not tell.
  double edge_min_sigma_mm = 0.002;
  double edge_min_sigma_deg = 0.0005;
  /// The wheels' motion between two frames, where their images do not register: uncertain by
  /// wheel_sigma_mm + wheel_sigma_fraction x its length and wheel_sigma_deg.
  double wheel_sigma_mm = 2.0;
  double wheel_sigma_fraction = 0.05;
  double wheel_sigma_deg = 0.5;
  /// The keyframe link is searched for within keyframe_sigma_mm and keyframe_sigma_deg (one
  /// sigma) of where the chain of links since the keyframe puts it, widened by the chain's
  /// drift (drift_mm_per_m, drift_deg_per_m, and the wheels' uncertainty where frames did not
  /// register): the chain predicts it to micrometres, and a window a quarter the size of the
  /// wheels' makes the keyframe link a third as costly; a copy of a repeating floor has less
  /// room too.
  double keyframe_sigma_mm = 0.25;
  double keyframe_sigma_deg = 0.05;
  /// Each frame's camera height and tilt over the floor under it estimated from the
  /// registrations themselves, and every registration corrected for its earlier frame's before
  /// the graph is solved: the step scaled by the height, the yaw rid of the tilt's bias
  /// (design.md section 7a). Over an uneven floor, or under a body that pitches and rolls,
  /// these are most of a self-built map's error. Each is applied only where the floor shows
  /// it (ViewGeometry's agreements): a flat floor's registrations are left as they are.
  bool view_geometry = true;
  ViewGeometryOptions geometry;
  OptimizeOptions optimize;
  /// Rounds of (optimize, drop the loops whose residual fails loop_gate_chi2).
  int outlier_rounds = 3;
  /// Decoded frames kept for loop closures (a small cache; frames are read again when needed).
  int frame_cache = 48;
  bool Check(std::string* why) const;
};

/// A later drive over the same site, mapped together with the first: its frames follow the
/// first drive's (and any before it) in MappingInput, from index `first` on.
struct LaterDrive {
  int first = 0;
  /// Where the vehicle was at the drive's first frame (world_from_vehicle, the first drive's
  /// world), and how well that is known, one standard deviation: it sizes the search for the
  /// loop closures that join the drive to the others and gates them.
  core::Pose2 start;
  double start_sigma_mm = 20.0;
  double start_sigma_deg = 1.0;
};

/// A mapping drive (or several): the frames (ideal images), in time order, read on demand, and
/// the wheels' dead-reckoned pose (only its differences within a drive are used).
struct MappingInput {
  camera::IdealCamera camera{camera::IdealCameraOptions{}};
  core::Pose2 vehicle_from_camera;
  std::vector<core::Timestamp> frame_times;
  /// The frame's image by index; an empty Mat is a frame that cannot be read (skipped).
  std::function<cv::Mat(std::size_t)> load_frame;
  /// The wheels' world_from_vehicle at each frame's time (any origin).
  std::vector<core::Pose2> wheels;
  /// Where the vehicle was at the first frame: the map's frame.
  core::Pose2 start;
  /// Further drives, in order of their first frames: no wheel motion joins a drive to the one
  /// before; loop closures onto the floor the others mapped do.
  std::vector<LaterDrive> later_drives;
};

/// A loop closure tried between a frame and an earlier one that sees the same floor.
struct LoopClosure {
  int earlier = 0;
  int later = 0;
  bool accepted = false;
  std::string rejected;         ///< why not, when not
  /// The kind of reason, for counting: "not verifiable" (the search could not cover the
  /// chain's uncertainty), the tracker's failure ("ambiguous", "no-match", ...), "off the
  /// prediction" (the drift gate) or "contradicted by the map" (after optimization).
  std::string rejected_by;
  double correction_mm = 0.0;   ///< how far the chain's prediction was off
  double chi2 = 0.0;            ///< of the correction against the drift's covariance
  double mean_zncc = 0.0;
  int inliers = 0;
};

/// The registration residual of a pair of overlapping frames: how far, RMS over the view's
/// corners, the relative pose of the map puts one frame's view from where registration put it.
struct Seam {
  int from = 0;
  int to = 0;
  EdgeKind kind = EdgeKind::kSequential;
  double before_px = 0.0;  ///< at the chained poses
  double after_px = 0.0;   ///< at the optimized poses
};

/// A stretch of the drive whose frames did not register with one another: the wheels bridge it.
struct MappingGap {
  int first = 0;  ///< the frame before the gap
  int last = 0;   ///< the first frame after it, where registrations go on again
  double length_mm = 0.0;
};

struct MappingResult {
  /// Per frame: the vehicle's optimized pose (world_from_vehicle), and the chained one.
  std::vector<core::Pose2> world_from_vehicle;
  std::vector<core::Pose2> chained_world_from_vehicle;
  std::vector<char> has_pose;  ///< 0 for a frame that could not be read
  PoseGraph graph;             ///< nodes: world_from_camera, optimized
  std::vector<LoopClosure> loops;
  std::vector<Seam> seams;
  std::vector<MappingGap> gaps;
  /// The drive's pieces: frames joined by registrations (loop closures included). More than
  /// one: only the wheels place the pieces relative to one another (each gap that no loop
  /// bridges splits the map).
  int pieces = 0;
  OptimizeReport optimize;
  std::int64_t frames = 0;
  std::int64_t registered = 0;       ///< frames registered against their predecessor
  std::int64_t keyframe_edges = 0;   ///< registrations against a keyframe
  std::int64_t loops_tried = 0;
  std::int64_t loops_accepted = 0;
  double path_length_m = 0.0;
  double register_seconds = 0.0;
  double loop_seconds = 0.0;
  double optimize_seconds = 0.0;
  /// Per frame, where MapperOptions::view_geometry: the camera's height over the floor under it
  /// relative to the calibrated one, and its tilt against the floor (image axes, rad).
  ViewGeometry view;
  /// Said to the user: e.g. a drive that never revisited its floor, whose drift nothing bounds.
  std::vector<std::string> warnings;
};

/// Builds the drive's poses from its frames and wheels alone: frames registered to their
/// predecessor and keyframe (the wheels' motion as the prior; the wheels' motion itself where
/// they do not register), loop closures wherever the chain comes back over floor it saw
/// (verified by the tracker and gated by the chain's drift), and a pose graph of all of them
/// solved with Ceres, robust on the loops. `progress` gets 0..1. Throws core::Error (invalid
/// input) when options fail Check() or the input has no frames.
MappingResult MapPoses(const MappingInput& input, const MapperOptions& options,
                       const std::function<void(double)>& progress = {});

}  // namespace mosaicloc::mapping
