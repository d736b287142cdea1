#include "mosaicloc/mapping/map_extension.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include <Eigen/LU>
#include <fmt/format.h>
#include <opencv2/core.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"

namespace mosaicloc::mapping {
namespace {

double PositionSigmaMm(const Eigen::Matrix3d& covariance) {
  return std::sqrt(std::max(0.0, std::max(covariance(0, 0), covariance(1, 1))));
}

// The information of a registration's covariance, which must be positive definite.
Eigen::Matrix3d InformationOf(const Eigen::Matrix3d& covariance) {
  const Eigen::Matrix3d symmetric = 0.5 * (covariance + covariance.transpose());
  return symmetric.inverse();
}

}  // namespace

bool MapExtensionOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(max_segment_m > 0.0)) return fail("max_segment_m must be > 0");
  if (!(max_anchor_sigma_mm > 0.0)) return fail("max_anchor_sigma_mm must be > 0");
  if (!(return_prior_sigma_mm > 0.0) || !(return_prior_sigma_deg > 0.0)) {
    return fail("return_prior_sigma_mm and return_prior_sigma_deg must be > 0");
  }
  return true;
}

MapExtender::MapExtender(mosaic::TileStore& store, mosaic::TileCache& cache, const camera::IdealCamera& camera,
                         const tracking::TrackerOptions& tracker, const MapExtensionOptions& options)
    : store_(store), cache_(cache), camera_(camera), tracker_(camera, tracker), options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("map extension: " + why);
  if (std::abs(store_.grid().mm_per_px - camera_.mm_per_px()) > 1e-9) {
    core::ThrowInvalidInput(fmt::format("{}: map resolution {} mm/px differs from the camera's {} mm/px",
                                        store_.file().string(), store_.grid().mm_per_px, camera_.mm_per_px()));
  }
  map_empty_ = store_.Count(0) == 0;
}

MapExtender::Node MapExtender::NodeOf(const ExtensionFrame& frame) {
  return Node{frame.time, frame.image.clone(), frame.world_from_camera, frame.covariance};
}

void MapExtender::Append(Node node, const tracking::FrameLink& link) {
  const int n = static_cast<int>(segment_.size());
  edges_.push_back(PoseGraphEdge{n - 1, n, link.earlier_from_camera, InformationOf(link.covariance),
                                 EdgeKind::kSequential});
  segment_mm_ += core::Distance(segment_.back().world_from_camera, node.world_from_camera);
  segment_.push_back(std::move(node));
}

void MapExtender::Frame(const ExtensionFrame& frame) {
  if (frame.link) {
    const tracking::FrameLink& link = *frame.link;
    if (segment_.empty()) {
      // A stretch starts at the keyframe the first frame off the map was registered against,
      // if that keyframe's pose is known well enough to build on.
      // On a map with no floor yet the first stretch defines the map's frame: its start is
      // where the map says it is, however uncertain the estimate was (a start before the
      // wheels' first counts, say).
      if (!keyframe_ || keyframe_->time != link.earlier_time ||
          (!map_empty_ && PositionSigmaMm(keyframe_->covariance) > options_.max_anchor_sigma_mm)) {
        ++summary_.unanchored;
        if (!unanchored_warned_) {
          unanchored_warned_ = true;
          summary_.warnings.push_back(fmt::format(
              "frames off the map at {:.3f} s and later were not mapped: the keyframe they were registered "
              "against is not known to {} mm (map extension's max_anchor_sigma_mm)",
              core::ToSeconds(frame.time - core::Timestamp()), options_.max_anchor_sigma_mm));
          core::Log().warn("map extension: {}", summary_.warnings.back());
        }
        if (frame.keyframe) keyframe_ = NodeOf(frame);
        return;
      }
      segment_ = {*keyframe_};
      edges_.clear();
      segment_mm_ = 0.0;
    }
    // The localizer registered this frame against the frame before where its keyframe did not
    // register: that frame, registered against the keyframe, joins the stretch first.
    if (between_.held && link.earlier_time == between_.node.time &&
        between_.link.earlier_time == segment_.back().time) {
      const Node& b = between_.node;
      Append(Node{b.time, b.image.clone(), b.world_from_camera, b.covariance}, between_.link);
    }
    between_.held = false;
    if (link.earlier_time != segment_.back().time) {
      // Registered against a keyframe the stretch does not end in: the chain is broken here.
      Commit(std::nullopt, std::nullopt);
      if (frame.keyframe) keyframe_ = NodeOf(frame);
      return;
    }
    if (!frame.keyframe) {
      // The keyframes cover the floor: the frames between add nothing, unless the next keyframe
      // is registered against one of them.
      if (frame.image.empty()) return;
      between_.node.time = frame.time;
      frame.image.copyTo(between_.node.image);  // reuses the buffer
      between_.node.world_from_camera = frame.world_from_camera;
      between_.node.covariance = frame.covariance;
      between_.link = link;
      between_.held = true;
      return;
    }
    Node node = NodeOf(frame);
    keyframe_ = node;  // shares the image with the stretch's node
    Append(std::move(node), link);
    if (segment_mm_ >= 1000.0 * options_.max_segment_m) Commit(std::nullopt, std::nullopt);
    return;
  }
  if (frame.fixed) {
    if (segment_.size() >= 2) {
      // Back on the map: the fix, registered against the stretch's last keyframe, closes the
      // loop, and the stretch is solved between the two places the map holds.
      tracking::TrackResult back;
      if (const std::optional<PoseGraphEdge> edge = RegisterToLast(frame, EdgeKind::kLoop, &back)) {
        Commit(NodeOf(frame), *edge);
      } else {
        summary_.warnings.push_back(fmt::format("the return onto the map at {:.3f} s did not register against the "
                                                "last keyframe ({}): its stretch is held at its start only",
                                                core::ToSeconds(frame.time - core::Timestamp()), back.reason));
        core::Log().warn("map extension: {}", summary_.warnings.back());
        Commit(std::nullopt, std::nullopt);
      }
    } else {
      segment_.clear();
    }
    if (frame.keyframe) keyframe_ = NodeOf(frame);
    return;
  }
  if (frame.keyframe) {
    // The localizer started a new chain where the wheels put it (its registrations failed for
    // a few frames): if this frame still registers against the stretch's last keyframe, around
    // the wheels' motion since and as widely as a return onto the map, it bridges the break,
    // and the stretch goes on without the wheels' drift in it.
    tracking::TrackResult bridge;
    if (segment_.size() >= 2) {
      if (const std::optional<PoseGraphEdge> edge = RegisterToLast(frame, EdgeKind::kSequential, &bridge)) {
        Node node = NodeOf(frame);
        segment_mm_ += core::Distance(segment_.back().world_from_camera, node.world_from_camera);
        edges_.push_back(*edge);
        keyframe_ = node;
        segment_.push_back(std::move(node));
        ++summary_.bridged;
        if (segment_mm_ >= 1000.0 * options_.max_segment_m) Commit(std::nullopt, std::nullopt);
        return;
      }
    }
    // Otherwise the stretch ends here.
    if (segment_.size() >= 2) {
      summary_.warnings.push_back(fmt::format(
          "frames off the map stopped registering at {:.3f} s (faster than the overlap speed limit, or a floor "
          "without texture; the frame there against the stretch's last keyframe: {}): the floor after it is "
          "mapped only from the next fix on",
          core::ToSeconds(frame.time - core::Timestamp()), bridge.reason));
      core::Log().warn("map extension: {}", summary_.warnings.back());
      Commit(std::nullopt, std::nullopt);
    }
    segment_.clear();
    keyframe_ = NodeOf(frame);
  }
}

std::optional<PoseGraphEdge> MapExtender::RegisterToLast(const ExtensionFrame& frame, EdgeKind kind,
                                                         tracking::TrackResult* result) const {
  const Node& last = segment_.back();
  const double sigma_rad = options_.return_prior_sigma_deg * std::numbers::pi / 180.0;
  const double s = options_.return_prior_sigma_mm;
  *result = tracking::RegisterFrames(tracker_, last.image, frame.image,
                                     Between(last.world_from_camera, frame.world_from_camera),
                                     Eigen::Vector3d(s * s, s * s, sigma_rad * sigma_rad).asDiagonal());
  if (!result->ok()) return std::nullopt;
  const int n = static_cast<int>(segment_.size());
  // The same inflation and floors as the localizer's links would have.
  Eigen::Matrix3d covariance = 4.0 * result->covariance;
  covariance.diagonal() += Eigen::Vector3d(2.5e-5, 2.5e-5, 1e-9);
  return PoseGraphEdge{n - 1, n, result->world_from_camera, InformationOf(covariance), kind};
}

void MapExtender::Finish() {
  if (segment_.size() >= 2) Commit(std::nullopt, std::nullopt);
  segment_.clear();
}

void MapExtender::Commit(const std::optional<Node>& end, const std::optional<PoseGraphEdge>& end_edge) {
  if (segment_.size() < 2) {
    segment_.clear();
    return;
  }
  const auto started = std::chrono::steady_clock::now();
  PoseGraph graph;
  for (const Node& node : segment_) graph.nodes.push_back(node.world_from_camera);
  graph.edges = edges_;
  graph.fixed = {0};
  if (end && end_edge) {
    const core::Pose2 chained = segment_.back().world_from_camera * end_edge->from_T_to;
    const double correction_mm = core::Distance(chained, end->world_from_camera);
    summary_.closure_max_mm = std::max(summary_.closure_max_mm, correction_mm);
    graph.nodes.push_back(end->world_from_camera);
    graph.edges.push_back(*end_edge);
    graph.fixed.push_back(static_cast<int>(graph.nodes.size()) - 1);
    // The return is the stretch's one hold at its far end, verified by its registration: it
    // pulls with its full weight. Under a robust loss a closure of some millimetres (hundreds of
    // its sigmas) would pull with a bounded force, and the chain's drift would stay standing
    // as a seam where the stretch meets the map.
    OptimizeOptions solve;
    solve.loop_huber_sigmas = 0.0;
    const OptimizeReport report = Optimize(graph, solve);
    core::Log().info("map extension: a stretch of {} keyframes ({:.2f} m) closed onto the map, {:.3f} mm corrected "
                     "({} iterations)",
                     segment_.size() - 1, segment_mm_ / 1000.0, correction_mm, report.iterations);
    ++summary_.closed;
  }
  std::vector<Node> nodes(segment_.begin() + 1, segment_.end());
  for (std::size_t i = 0; i < nodes.size(); ++i) nodes[i].world_from_camera = graph.nodes[i + 1];
  Paint(nodes);
  ++summary_.segments;
  summary_.keyframes += static_cast<std::int64_t>(nodes.size());
  for (const Node& node : nodes) painted_.emplace_back(node.time, node.world_from_camera);
  // The localizer's keyframe, when it is the stretch's last node, now lies where it was painted.
  if (keyframe_ && keyframe_->time == nodes.back().time) keyframe_->world_from_camera = nodes.back().world_from_camera;
  segment_.clear();
  edges_.clear();
  segment_mm_ = 0.0;
  summary_.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
}

void MapExtender::Paint(const std::vector<Node>& nodes) {
  const mosaic::MapGrid& grid = store_.grid();
  mosaic::MapBuilder builder(grid, options_.blend);
  for (const Node& node : nodes) builder.AddFrame(node.image, node.world_from_camera, grid.mm_per_px);
  std::vector<mosaic::TileWrite> writes;
  for (const mosaic::TileKey& key : builder.TileKeys()) {
    const cv::Mat painted = builder.FinishTile(key);
    const mosaic::TileRead read = store_.Read(key);
    if (read.status == mosaic::TileStatus::kCorrupt) {
      // Never written over: `map check` names it, and the floor there stays unmapped.
      summary_.warnings.push_back("not extended into a damaged tile: " + read.problem);
      core::Log().warn("map extension: {}", summary_.warnings.back());
      continue;
    }
    if (read.status == mosaic::TileStatus::kAbsent) {
      if (cv::countNonZero(painted) > 0) writes.push_back({key, painted});
      continue;
    }
    // Only the pixels the map lacks: the mapped floor is never moved or overwritten.
    const cv::Mat unmapped = read.pixels == mosaic::kUnmapped;
    cv::Mat out = read.pixels.clone();
    painted.copyTo(out, unmapped);
    if (cv::countNonZero(out != read.pixels) > 0) writes.push_back({key, out});
  }
  if (writes.empty()) return;
  map_empty_ = false;
  // One transaction, recorded in the map's history (`map revert` undoes it): a crash leaves the
  // map before or after.
  mosaic::WriteWithPyramid(store_, writes,
                           fmt::format("automatic mapping: {} frames of the drive from {:.3f} s to {:.3f} s",
                                       nodes.size(), core::ToSeconds(nodes.front().time - core::Timestamp()),
                                       core::ToSeconds(nodes.back().time - core::Timestamp())));
  for (const mosaic::TileWrite& write : writes) cache_.InvalidateWithPyramid(write.key);
  summary_.tiles_written += static_cast<std::int64_t>(writes.size());
  core::Log().info("map extension: committed {} frames, {} tiles written; the map holds {} tiles at level 0",
                   nodes.size(), writes.size(), store_.Count(0));
}

}  // namespace mosaicloc::mapping
