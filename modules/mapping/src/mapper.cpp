#include "mosaicloc/mapping/mapper.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <list>
#include <numbers>
#include <unordered_map>

#include <Eigen/LU>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"

namespace mosaicloc::mapping {
namespace {

using Clock = std::chrono::steady_clock;

double Rad(double deg) { return deg * std::numbers::pi / 180.0; }
double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

Eigen::Matrix3d Diagonal(double sigma_mm, double sigma_rad) {
  return Eigen::Vector3d(sigma_mm * sigma_mm, sigma_mm * sigma_mm, sigma_rad * sigma_rad).asDiagonal();
}

// Decoded frames by index, the least recently used dropped first.
class FrameCache {
 public:
  FrameCache(const std::function<cv::Mat(std::size_t)>& load, std::size_t capacity)
      : load_(load), capacity_(std::max<std::size_t>(capacity, 2)) {}

  cv::Mat Get(int index) {
    const auto found = where_.find(index);
    if (found != where_.end()) {
      order_.splice(order_.begin(), order_, found->second);
      return found->second->second;
    }
    cv::Mat image = load_(static_cast<std::size_t>(index));
    order_.emplace_front(index, image);
    where_[index] = order_.begin();
    if (order_.size() > capacity_) {
      where_.erase(order_.back().first);
      order_.pop_back();
    }
    return image;
  }

 private:
  const std::function<cv::Mat(std::size_t)>& load_;
  std::size_t capacity_;
  std::list<std::pair<int, cv::Mat>> order_;
  std::unordered_map<int, std::list<std::pair<int, cv::Mat>>::iterator> where_;
};

// Frames by where their view centre lies, in square cells.
class SpatialIndex {
 public:
  explicit SpatialIndex(double cell_mm) : cell_mm_(cell_mm) {}
  void Add(int index, const Eigen::Vector2d& at) { cells_[Key(Cell(at.x()), Cell(at.y()))].push_back(index); }
  // Every frame within `radius_mm` (<= the cell) of `at`, checked against `positions`.
  std::vector<int> Near(const Eigen::Vector2d& at, double radius_mm, const std::vector<core::Pose2>& positions) const {
    std::vector<int> near;
    const std::int64_t cx = Cell(at.x()), cy = Cell(at.y());
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const auto cell = cells_.find(Key(cx + dx, cy + dy));
        if (cell == cells_.end()) continue;
        for (const int i : cell->second) {
          if ((positions[i].translation_mm() - at).norm() <= radius_mm) near.push_back(i);
        }
      }
    }
    std::sort(near.begin(), near.end());
    return near;
  }

 private:
  std::int64_t Cell(double v) const { return static_cast<std::int64_t>(std::floor(v / cell_mm_)); }
  static std::int64_t Key(std::int64_t cx, std::int64_t cy) { return cx * 0x100000001LL + cy; }
  double cell_mm_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

// RMS over the view's corners of how far `estimate` puts them from where `measured` does, px.
double SeamPx(const core::Pose2& measured, const core::Pose2& estimate, const camera::IdealCamera& camera) {
  const double half_w = 0.5 * camera.width_px() * camera.mm_per_px();
  const double half_h = 0.5 * camera.height_px() * camera.mm_per_px();
  double sum = 0.0;
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      const Eigen::Vector2d corner(sx * half_w, sy * half_h);
      sum += (measured * corner - estimate * corner).squaredNorm();
    }
  }
  return std::sqrt(sum / 4.0) / camera.mm_per_px();
}

// The difference of two relative poses as (dx, dy, dyaw) in the first's parent frame.
Eigen::Vector3d Difference(const core::Pose2& measured, const core::Pose2& predicted) {
  const Eigen::Vector2d d = measured.translation_mm() - predicted.translation_mm();
  return {d.x(), d.y(), core::WrapAngle(measured.yaw_rad() - predicted.yaw_rad())};
}

}  // namespace

bool MapperOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!tracker.Check(why)) return false;
  if (!(keyframe_fraction > 0.0 && keyframe_fraction < 1.0)) return fail("keyframe_fraction must be in (0, 1)");
  if (!(loop_spacing_mm > 0.0)) return fail("loop_spacing_mm must be positive");
  if (!(loop_radius_fraction > 0.0 && loop_radius_fraction <= 1.0)) return fail("loop_radius_fraction must be in (0, 1]");
  if (!(loop_min_separation_mm > 0.0)) return fail("loop_min_separation_mm must be positive");
  if (loop_candidates < 0) return fail("loop_candidates must be 0 or more");
  if (!(drift_sigma_mm > 0.0 && drift_mm_per_m >= 0.0 && drift_sigma_deg > 0.0 && drift_deg_per_m >= 0.0)) {
    return fail("the drift sigmas must be positive");
  }
  if (!(loop_gate_chi2 > 0.0)) return fail("loop_gate_chi2 must be positive");
  if (!(edge_min_sigma_mm > 0.0 && edge_min_sigma_deg > 0.0)) return fail("the edge sigma floors must be positive");
  if (!(wheel_sigma_mm > 0.0 && wheel_sigma_fraction >= 0.0 && wheel_sigma_deg > 0.0)) {
    return fail("the wheel sigmas must be positive");
  }
  if (!(keyframe_sigma_mm > 0.0 && keyframe_sigma_deg > 0.0)) return fail("the keyframe sigmas must be positive");
  if (loop_max_search_px < tracker.min_search_px) return fail("loop_max_search_px must be at least the tracker's min_search_px");
  if (!(optimize.loop_huber_sigmas > 0.0)) return fail("optimize.loop_huber_sigmas must be positive");
  if (optimize.max_iterations < 1 || optimize.threads < 1) return fail("optimize: iterations and threads must be 1 or more");
  if (outlier_rounds < 1) return fail("outlier_rounds must be 1 or more");
  if (frame_cache < 2) return fail("frame_cache must be 2 or more");
  return geometry.Check(why);
}

MappingResult MapPoses(const MappingInput& input, const MapperOptions& options,
                       const std::function<void(double)>& progress) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("mapping options: " + why);
  const int n = static_cast<int>(input.frame_times.size());
  if (n == 0) core::ThrowInvalidInput("mapping: the drive has no frames");
  if (!input.load_frame) core::ThrowInvalidInput("mapping: no way to read the frames (load_frame is empty)");
  if (input.wheels.size() != input.frame_times.size()) {
    core::ThrowInvalidInput("mapping: the wheels' poses do not match the frames");
  }
  for (std::size_t d = 0; d < input.later_drives.size(); ++d) {
    const LaterDrive& later = input.later_drives[d];
    const int previous_first = d == 0 ? 0 : input.later_drives[d - 1].first;
    if (later.first <= previous_first || later.first >= n) {
      core::ThrowInvalidInput("mapping: drive " + std::to_string(d + 2) + " must start after the one before it and "
                              "before the last frame");
    }
    if (!(later.start_sigma_mm > 0.0 && later.start_sigma_deg > 0.0)) {
      core::ThrowInvalidInput("mapping: drive " + std::to_string(d + 2) + ": the start's sigmas must be positive");
    }
  }
  const camera::IdealCamera& camera = input.camera;
  const core::Pose2& vehicle_from_camera = input.vehicle_from_camera;
  const tracking::Tracker tracker(camera, options.tracker);
  tracking::TrackerOptions loop_options = options.tracker;
  loop_options.max_search_px = options.loop_max_search_px;
  const tracking::Tracker loop_tracker(camera, loop_options);
  const double view_short_mm = std::min(camera.width_px(), camera.height_px()) * camera.mm_per_px();
  const double keyframe_mm = options.keyframe_fraction * view_short_mm;
  const double loop_radius_mm = options.loop_radius_fraction * view_short_mm;
  // A template at the view's corner moves this far per radian of yaw.
  const double half_diagonal_px = 0.5 * std::hypot(camera.width_px(), camera.height_px());
  // The yaw's floor grows as the two views' overlap shrinks (MapperOptions::edge_min_sigma_deg):
  // the templates that match lie in the overlap, so their spread, the yaw's lever, shrinks with it.
  auto edge_information = [&](const Eigen::Matrix3d& covariance, const core::Pose2& from_T_to) {
    const Eigen::Vector2d t = from_T_to.translation_mm();
    const double overlap =
        std::max((1.0 - std::abs(t.x()) / camera.width_mm()) * (1.0 - std::abs(t.y()) / camera.height_mm()), 0.1);
    return Eigen::Matrix3d(
        (covariance + Diagonal(options.edge_min_sigma_mm, Rad(options.edge_min_sigma_deg) / overlap)).inverse());
  };

  MappingResult result;
  result.frames = n;
  result.has_pose.assign(static_cast<std::size_t>(n), 1);
  std::vector<core::Pose2> chain(static_cast<std::size_t>(n));  // world_from_camera
  // Camera path length, mm; a new drive starts loop_min_separation_mm further on, so that any of
  // its frames may close a loop with any frame of the drives before.
  std::vector<double> path(static_cast<std::size_t>(n), 0.0);
  double path_length_mm = 0.0;
  // How far the chain may have drifted since its drive's first frame, one sigma summed edge by
  // edge (linearly: drift is mostly systematic): drift_mm_per_m along registered frames, the
  // wheels' own uncertainty where they carried it.
  std::vector<double> drift_mm(static_cast<std::size_t>(n), 0.0), drift_rad(static_cast<std::size_t>(n), 0.0);
  std::vector<int> drive_of(static_cast<std::size_t>(n), 0);
  // Per drive, how well its start is known in the first drive's frame.
  std::vector<double> start_mm = {0.0}, start_rad = {0.0};
  for (const LaterDrive& later : input.later_drives) {
    start_mm.push_back(later.start_sigma_mm);
    start_rad.push_back(Rad(later.start_sigma_deg));
  }
  // The chain's uncertainty of frame i relative to frame j.
  auto drift_between = [&](int j, int i) -> std::pair<double, double> {
    if (drive_of[i] == drive_of[j]) return {std::abs(drift_mm[i] - drift_mm[j]), std::abs(drift_rad[i] - drift_rad[j])};
    return {drift_mm[i] + drift_mm[j] + start_mm[drive_of[i]] + start_mm[drive_of[j]],
            drift_rad[i] + drift_rad[j] + start_rad[drive_of[i]] + start_rad[drive_of[j]]};
  };
  std::size_t next_drive = 0;  // index into later_drives of the next drive to start
  PoseGraph& graph = result.graph;
  std::vector<int> loop_of_edge;         // per graph edge: index into result.loops, or -1
  std::vector<char> registered_edge;     // per graph edge: 1 for a registration, 0 for the wheels' motion
  auto add_edge = [&](int from, int to, const core::Pose2& from_T_to, const Eigen::Matrix3d& information,
                      EdgeKind kind, int loop, bool registered = true) {
    graph.edges.push_back({from, to, from_T_to, information, kind});
    loop_of_edge.push_back(loop);
    registered_edge.push_back(registered ? 1 : 0);
  };
  // What each registration in the graph says of its earlier frame's view: (edge, observation).
  std::vector<std::pair<std::size_t, ViewObservation>> views;
  auto observe = [&](const tracking::TrackResult& registration, int earlier, int later) {
    if (!options.view_geometry) return;
    if (auto o = ObserveView(registration, camera, earlier, later)) views.emplace_back(graph.edges.size() - 1, *o);
  };

  FrameCache frames(input.load_frame, static_cast<std::size_t>(options.frame_cache));
  SpatialIndex index(loop_radius_mm);
  // The predecessor and the keyframe, prepared once for the registrations they are in.
  tracking::PreparedFrame previous, key;
  int keyframe = -1;
  int unregistered_from = -1;  // first frame of a run that did not register, or -1
  double last_tried_path = -1e300;
  struct Anchor {
    int earlier = -1, later = -1;
    core::Pose2 earlier_from_later;
  } last_loop;
  for (int i = 0; i < n; ++i) {
    if (progress) progress(0.9 * i / n);
    const auto started = Clock::now();
    const cv::Mat image = frames.Get(i);
    if (image.empty()) result.has_pose[i] = 0;
    const tracking::PreparedFrame current = tracker.Prepare(image);
    const bool drive_starts =
        next_drive < input.later_drives.size() && input.later_drives[next_drive].first == i;
    if (i == 0) {
      chain[0] = input.start * vehicle_from_camera;
    } else if (drive_starts) {
      // A later drive: placed where it says it started; only loop closures join it to the rest.
      const LaterDrive& later = input.later_drives[next_drive++];
      drive_of[i] = static_cast<int>(next_drive);
      chain[i] = later.start * vehicle_from_camera;
      path[i] = path[i - 1] + options.loop_min_separation_mm;
      previous = {};
      key = {};
      keyframe = -1;
      if (unregistered_from >= 0) {
        result.gaps.push_back({unregistered_from - 1, i - 1, path[i - 1] - path[unregistered_from - 1]});
        unregistered_from = -1;
      }
    } else {
      drive_of[i] = drive_of[i - 1];
      const core::Pose2 wheel_motion = input.wheels[i - 1].Inverse() * input.wheels[i];
      const core::Pose2 camera_motion = vehicle_from_camera.Inverse() * wheel_motion * vehicle_from_camera;
      const double wheel_mm = options.wheel_sigma_mm + options.wheel_sigma_fraction * camera_motion.translation_mm().norm();
      const Eigen::Matrix3d wheel_covariance = Diagonal(wheel_mm, Rad(options.wheel_sigma_deg));
      tracking::TrackResult r;
      if (!image.empty() && !previous.image.empty()) {
        r = tracking::RegisterFrames(tracker, previous, current, camera_motion, wheel_covariance);
      } else {
        r.failure = tracking::TrackFailure::kNoTexture;
      }
      core::Pose2 motion = camera_motion;
      if (r.ok()) {
        motion = r.world_from_camera;
        ++result.registered;
        add_edge(i - 1, i, motion, edge_information(r.covariance, motion), EdgeKind::kSequential, -1);
        observe(r, i - 1, i);
      } else {
        add_edge(i - 1, i, motion, wheel_covariance.inverse(), EdgeKind::kSequential, -1, false);
      }
      chain[i] = chain[i - 1] * motion;
      const double step_mm = motion.translation_mm().norm();
      path[i] = path[i - 1] + step_mm;
      path_length_mm += step_mm;
      drift_mm[i] = drift_mm[i - 1] + (r.ok() ? options.drift_mm_per_m * 1e-3 * step_mm : wheel_mm);
      drift_rad[i] = drift_rad[i - 1] +
                     (r.ok() ? Rad(options.drift_deg_per_m) * 1e-3 * step_mm : Rad(options.wheel_sigma_deg));
      bool keyed = false;
      if (keyframe >= 0 && keyframe != i - 1 && !image.empty()) {
        // The chain predicts the keyframe's pose well; a match far off it (a copy of a
        // repeating floor) is refused as a loop closure would be.
        const core::Pose2 predicted = chain[keyframe].Inverse() * chain[i];
        const auto [drift_key_mm, drift_key_rad] = drift_between(keyframe, i);
        const Eigen::Matrix3d prior =
            Diagonal(options.keyframe_sigma_mm + drift_key_mm, Rad(options.keyframe_sigma_deg) + drift_key_rad);
        const tracking::TrackResult k = tracking::RegisterFrames(tracker, key, current, predicted, prior);
        const Eigen::Vector3d d = Difference(k.world_from_camera, predicted);
        if (k.ok() && d.dot((prior + k.covariance).inverse() * d) <= options.loop_gate_chi2) {
          ++result.keyframe_edges;
          keyed = true;
          add_edge(keyframe, i, k.world_from_camera, edge_information(k.covariance, k.world_from_camera),
                   EdgeKind::kSequential, -1);
          observe(k, keyframe, i);
        }
      }
      if (r.ok() || keyed) {
        // Registered to a keyframe from before the frames that did not register, the frame
        // joins the piece they left: the keyframe bridged them, not the wheels.
        const bool bridged = keyed && keyframe < unregistered_from;
        if (unregistered_from >= 0) {
          if (!bridged) {
            // Registered to its predecessor, the frame joins the piece the wheels' edge ended at.
            const int last = r.ok() ? std::max(unregistered_from, i - 1) : i;
            result.gaps.push_back({unregistered_from - 1, last, path[last] - path[unregistered_from - 1]});
          }
          unregistered_from = -1;
        }
      } else if (unregistered_from < 0) {
        unregistered_from = i;
      }
    }
    if (image.empty()) {
      previous = {};  // the next frame has no predecessor to register against
    } else {
      previous = current;
      if (keyframe < 0 || (chain[i].translation_mm() - chain[keyframe].translation_mm()).norm() > keyframe_mm) {
        keyframe = i;
        key = current;
      }
    }
    result.register_seconds += Seconds(started);

    // Loop closures: earlier frames whose chained view is near this one, far back along the path.
    const auto loops_started = Clock::now();
    if (!image.empty() && path[i] - last_tried_path >= options.loop_spacing_mm) {
      last_tried_path = path[i];
      const std::vector<int> near = index.Near(chain[i].translation_mm(), loop_radius_mm, chain);
      // One candidate per pass over the place: the nearest of each run of frames.
      std::vector<std::pair<double, int>> candidates;
      for (std::size_t a = 0; a < near.size();) {
        std::size_t b = a;
        int best = -1;
        double best_mm = 1e300;
        while (b < near.size() && (b == a || path[near[b]] - path[near[b - 1]] < 0.5 * options.loop_min_separation_mm)) {
          const int j = near[b++];
          if (path[i] - path[j] < options.loop_min_separation_mm) continue;
          const double mm = (chain[j].translation_mm() - chain[i].translation_mm()).norm();
          if (mm < best_mm) best_mm = mm, best = j;
        }
        if (best >= 0) candidates.emplace_back(best_mm, best);
        a = b;
      }
      std::sort(candidates.begin(), candidates.end());
      if (static_cast<int>(candidates.size()) > options.loop_candidates) candidates.resize(options.loop_candidates);
      for (const auto& [unused, j] : candidates) {
        // The prediction: along the chain, or through the last loop closed when that is surer.
        core::Pose2 predicted = chain[j].Inverse() * chain[i];
        auto [sigma_mm, sigma_rad] = drift_between(j, i);
        if (last_loop.later >= 0 && drive_of[last_loop.later] == drive_of[i] &&
            drive_of[last_loop.earlier] == drive_of[j]) {
          const auto [later_mm, later_rad] = drift_between(last_loop.later, i);
          const auto [earlier_mm, earlier_rad] = drift_between(last_loop.earlier, j);
          if (later_mm + earlier_mm < sigma_mm) {
            predicted = chain[j].Inverse() * chain[last_loop.earlier] * last_loop.earlier_from_later *
                        chain[last_loop.later].Inverse() * chain[i];
            sigma_mm = later_mm + earlier_mm;
            sigma_rad = later_rad + earlier_rad;
          }
        }
        sigma_mm += options.drift_sigma_mm;
        sigma_rad += Rad(options.drift_sigma_deg);
        const Eigen::Matrix3d drift = Diagonal(sigma_mm, sigma_rad);
        LoopClosure loop;
        loop.earlier = j;
        loop.later = i;
        // A search that cannot cover the prediction's 3-sigma region could take a copy of a
        // repeating floor for the place: such a loop is not tried.
        if (loop_options.search_sigmas * (sigma_mm / camera.mm_per_px() + sigma_rad * half_diagonal_px) >
            loop_options.max_search_px) {
          char text[160];
          std::snprintf(text, sizeof text,
                        "the chain is uncertain by %.1f mm here, more than the search covers: not verifiable", sigma_mm);
          loop.rejected = text;
          loop.rejected_by = "not verifiable";
          result.loops.push_back(loop);
          continue;
        }
        const cv::Mat earlier = frames.Get(j);
        if (earlier.empty()) continue;
        ++result.loops_tried;
        const tracking::TrackResult r = tracking::RegisterFrames(loop_tracker, earlier, image, predicted, drift);
        loop.mean_zncc = r.mean_zncc;
        loop.inliers = r.inliers;
        if (!r.ok()) {
          loop.rejected = r.reason.empty() ? tracking::ToString(r.failure) : r.reason;
          loop.rejected_by = tracking::ToString(r.failure);
          result.loops.push_back(loop);
          continue;
        }
        const Eigen::Vector3d d = Difference(r.world_from_camera, predicted);
        loop.correction_mm = d.head<2>().norm();
        loop.chi2 = d.dot((drift + r.covariance).inverse() * d);
        if (loop.chi2 > options.loop_gate_chi2) {
          char text[160];
          std::snprintf(text, sizeof text, "%.2f mm off the chain's prediction (chi2 %.1f > %.1f)", loop.correction_mm,
                        loop.chi2, options.loop_gate_chi2);
          loop.rejected = text;
          loop.rejected_by = "off the prediction";
          result.loops.push_back(loop);
          continue;
        }
        loop.accepted = true;
        result.loops.push_back(loop);
        add_edge(j, i, r.world_from_camera, edge_information(r.covariance, r.world_from_camera), EdgeKind::kLoop,
                 static_cast<int>(result.loops.size()) - 1);
        observe(r, j, i);
        last_loop = {j, i, r.world_from_camera};
      }
    }
    index.Add(i, chain[i].translation_mm());
    result.loop_seconds += Seconds(loops_started);
  }
  if (unregistered_from >= 0) result.gaps.push_back({unregistered_from - 1, n - 1, path[n - 1] - path[unregistered_from - 1]});
  result.path_length_m = 1e-3 * path_length_mm;

  // The pose graph: the chain as the start, the first frame held; loops that the rest of the
  // map contradicts are dropped and the graph solved again.
  const auto optimize_started = Clock::now();
  if (options.view_geometry) {
    std::vector<ViewObservation> observations;
    observations.reserve(views.size());
    for (const auto& [edge, o] : views) observations.push_back(o);
    const double height_mm = options.tracker.solver.camera_height_mm;
    std::vector<int> drive_starts;
    for (const LaterDrive& later : input.later_drives) drive_starts.push_back(later.first);
    result.view = SolveViewGeometry(observations, n, camera, height_mm, options.geometry, drive_starts);
    for (const auto& [edge, o] : views) {
      PoseGraphEdge& e = graph.edges[edge];
      e.from_T_to = CorrectRegistration(e.from_T_to, o, result.view, camera, height_mm);
    }
  }
  graph.nodes = chain;
  graph.fixed = {0};
  for (int round = 0; round < options.outlier_rounds; ++round) {
    result.optimize = Optimize(graph, options.optimize);
    bool dropped = false;
    for (std::size_t e = 0; e < graph.edges.size();) {
      const double chi2 = graph.edges[e].kind == EdgeKind::kLoop ? EdgeResidual(graph, graph.edges[e]).squaredNorm() : 0.0;
      if (chi2 > options.loop_gate_chi2) {
        LoopClosure& loop = result.loops[static_cast<std::size_t>(loop_of_edge[e])];
        char text[160];
        std::snprintf(text, sizeof text, "contradicted by the rest of the map (chi2 %.1f after optimization)", chi2);
        loop.accepted = false;
        loop.rejected = text;
        loop.rejected_by = "contradicted by the map";
        graph.edges.erase(graph.edges.begin() + static_cast<std::ptrdiff_t>(e));
        loop_of_edge.erase(loop_of_edge.begin() + static_cast<std::ptrdiff_t>(e));
        registered_edge.erase(registered_edge.begin() + static_cast<std::ptrdiff_t>(e));
        dropped = true;
      } else {
        ++e;
      }
    }
    if (!dropped) break;
    if (round + 1 == options.outlier_rounds) result.optimize = Optimize(graph, options.optimize);
  }
  if (!result.optimize.converged) {
    result.warnings.push_back("the pose graph's solution did not converge (" + result.optimize.message +
                              "): the poses may not be the best the registrations allow");
  }
  result.optimize_seconds = Seconds(optimize_started);
  for (const LoopClosure& loop : result.loops) result.loops_accepted += loop.accepted ? 1 : 0;

  for (std::size_t e = 0; e < graph.edges.size(); ++e) {
    const PoseGraphEdge& edge = graph.edges[e];
    if (!registered_edge[e]) continue;  // the wheels' motion, not a registration
    Seam seam;
    seam.from = edge.from;
    seam.to = edge.to;
    seam.kind = edge.kind;
    seam.before_px = SeamPx(edge.from_T_to, chain[edge.from].Inverse() * chain[edge.to], camera);
    seam.after_px = SeamPx(edge.from_T_to, graph.nodes[edge.from].Inverse() * graph.nodes[edge.to], camera);
    result.seams.push_back(seam);
  }
  // Pieces: frames joined by registrations, of the frames that were read.
  std::vector<int> parent(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) parent[i] = i;
  auto root = [&parent](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (std::size_t e = 0; e < graph.edges.size(); ++e) {
    if (registered_edge[e]) parent[root(graph.edges[e].from)] = root(graph.edges[e].to);
  }
  for (int i = 0; i < n; ++i) result.pieces += result.has_pose[i] && root(i) == i ? 1 : 0;

  result.world_from_vehicle.resize(static_cast<std::size_t>(n));
  result.chained_world_from_vehicle.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    result.world_from_vehicle[i] = graph.nodes[i] * vehicle_from_camera.Inverse();
    result.chained_world_from_vehicle[i] = chain[i] * vehicle_from_camera.Inverse();
  }
  if (result.loops_accepted == 0) {
    char text[200];
    std::snprintf(text, sizeof text,
                  "the drive never came back over floor it had mapped (no loop closed): nothing bounds the drift of "
                  "its %.1f m",
                  result.path_length_m);
    result.warnings.emplace_back(text);
  }
  for (const MappingGap& gap : result.gaps) {
    char text[200];
    std::snprintf(text, sizeof text, "frames %d to %d did not register with one another: %.0f mm bridged by the wheels",
                  gap.first, gap.last, gap.length_mm);
    result.warnings.emplace_back(text);
  }
  if (result.pieces > 1) {
    char text[200];
    std::snprintf(text, sizeof text,
                  "the map is %d pieces that no registration joins: only the wheels place them relative to one "
                  "another (drive over the gaps again to join them)",
                  result.pieces);
    result.warnings.emplace_back(text);
  }
  if (progress) progress(1.0);
  return result;
}

}  // namespace mosaicloc::mapping
