#include "mosaicloc/runtime/revisits.hpp"

#include <algorithm>
#include <numbers>
#include <unordered_map>
#include <vector>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/dataset/dataset.hpp"

namespace mosaicloc::runtime {

RevisitFigures MeasureRevisits(const std::filesystem::path& dataset_dir, const dataset::Trajectory& fixed,
                               const camera::IdealCamera& camera, const tracking::TrackerOptions& tracker_options,
                               const core::Pose2& vehicle_from_camera, const RevisitOptions& options) {
  RevisitFigures figures;
  tracking::TrackerOptions tiled = tracker_options;
  tiled.templates.mode = tracking::TemplateMode::kTiled;
  tiled.templates.tile_cols = options.tile_cols;
  tiled.templates.tile_rows = options.tile_rows;
  const tracking::Tracker tracker(camera, tiled);
  std::vector<Eigen::Vector2d> positions;
  positions.reserve(fixed.size());
  for (const dataset::StampedPose& pose : fixed) {
    positions.push_back((pose.world_from_vehicle * vehicle_from_camera).translation_mm());
  }
  std::vector<std::vector<std::size_t>> revisited;
  for (std::vector<std::size_t>& visits : dataset::RevisitedPlaces(positions, options.places)) {
    if (visits.size() >= 2) revisited.push_back(std::move(visits));
  }
  if (revisited.empty() || options.max_places <= 0) return figures;
  if (static_cast<std::int64_t>(revisited.size()) > options.max_places) {
    std::vector<std::vector<std::size_t>> kept;
    const double step = static_cast<double>(revisited.size()) / static_cast<double>(options.max_places);
    for (std::int64_t k = 0; k < options.max_places; ++k) {
      kept.push_back(std::move(revisited[static_cast<std::size_t>(static_cast<double>(k) * step)]));
    }
    revisited = std::move(kept);
  }

  // For every frame wanted: its place, and whether it is the place's first visit.
  struct Role {
    std::size_t place = 0;
    std::size_t sample = 0;
    bool first = false;
  };
  std::unordered_map<std::int64_t, std::vector<Role>> wanted;
  for (std::size_t place = 0; place < revisited.size(); ++place) {
    for (std::size_t k = 0; k < revisited[place].size(); ++k) {
      const std::size_t sample = revisited[place][k];
      wanted[fixed[sample].time.nanoseconds()].push_back({place, sample, k == 0});
    }
  }

  const double sigma_rad = options.prior_sigma_deg * std::numbers::pi / 180.0;
  const Eigen::Matrix3d prior_covariance =
      Eigen::Vector3d(options.prior_sigma_mm * options.prior_sigma_mm, options.prior_sigma_mm * options.prior_sigma_mm,
                      sigma_rad * sigma_rad)
          .asDiagonal();
  std::vector<cv::Mat> first_image(revisited.size());
  std::vector<std::vector<Eigen::Vector2d>> differences(revisited.size());
  const dataset::DatasetReader reader(dataset_dir);
  auto stream = reader.Frames();
  while (const auto frame = stream.Next([&](core::Timestamp time) { return wanted.count(time.nanoseconds()) > 0; })) {
    const auto roles = wanted.find(frame->time.nanoseconds());
    if (roles == wanted.end()) continue;
    for (const Role& role : roles->second) {
      if (role.first) {
        first_image[role.place] = frame->image;
        differences[role.place].push_back(Eigen::Vector2d::Zero());
        continue;
      }
      const cv::Mat& anchor = first_image[role.place];
      if (anchor.empty()) continue;  // the first visit is later in the file: not in time order
      const core::Pose2& first = fixed[revisited[role.place].front()].world_from_vehicle;
      const core::Pose2& later = fixed[role.sample].world_from_vehicle;
      const core::Pose2 implied = (first * vehicle_from_camera).Inverse() * (later * vehicle_from_camera);
      const tracking::TrackResult r = tracking::RegisterFrames(tracker, anchor, frame->image, implied, prior_covariance);
      if (!r.ok()) {
        ++figures.failures;
        core::Log().debug("revisit at {}: not registered to the first visit: {}", frame->time.nanoseconds(), r.reason);
        continue;
      }
      const core::Pose2 registered = first * vehicle_from_camera * r.world_from_camera;
      differences[role.place].push_back((later * vehicle_from_camera).translation_mm() - registered.translation_mm());
      core::Log().debug("revisit at {}: {:.5f}, {:.5f} mm from where the first visit (at {}) puts it",
                        frame->time.nanoseconds(), differences[role.place].back().x(),
                        differences[role.place].back().y(), fixed[revisited[role.place].front()].time.nanoseconds());
    }
    // A place whose visits are all in can let its first frame go.
    for (const Role& role : roles->second) {
      if (!role.first && role.sample == revisited[role.place].back()) first_image[role.place].release();
    }
  }
  if (const auto spread = dataset::SpreadAtPlaces(differences)) {
    figures.repeatability_mm = spread->rms_mm;
    figures.places = spread->places;
    figures.visits = spread->visits;
  }
  return figures;
}

}  // namespace mosaicloc::runtime
