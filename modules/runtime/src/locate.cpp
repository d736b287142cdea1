#include "mosaicloc/runtime/locate.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <opencv2/imgcodecs.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/trajectory.hpp"
#include "mosaicloc/runtime/map_session.hpp"
#include "mosaicloc/tracking/relocalize.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::runtime {
namespace {

// One frame looked up and verified.
LocatedFrame LocateOne(const tracking::Relocalizer& relocalizer, const tracking::PlaceIndex& places,
                       const cv::Mat& image, double scale, const std::string& name) {
  LocatedFrame located;
  located.frame = name;
  const auto start = std::chrono::steady_clock::now();
  tracking::PlaceLookup lookup;
  const tracking::TrackResult r = relocalizer.SearchEverywhere(image, places, scale, &lookup);
  located.milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  located.candidates = static_cast<int>(lookup.candidates.size());
  if (r.ok()) {
    located.outcome = "found";
    located.world_from_camera = r.world_from_camera;
    located.covariance = r.covariance;
    located.mean_zncc = r.mean_zncc;
    located.inliers = r.inliers;
  } else {
    located.outcome = r.failure == tracking::TrackFailure::kAmbiguous ? "ambiguous" : "no-match";
    located.reason = r.reason;
  }
  return located;
}

// The counts and times over every frame located.
void Tally(double wrong_mm, LocateSummary* summary) {
  std::vector<double> times;
  for (const LocatedFrame& f : summary->frames) {
    times.push_back(f.milliseconds);
    summary->found += f.outcome == "found" ? 1 : 0;
    summary->ambiguous += f.outcome == "ambiguous" ? 1 : 0;
    summary->no_match += f.outcome == "no-match" ? 1 : 0;
    if (f.error_mm) {
      ++summary->checked;
      summary->within_0_05_mm += *f.error_mm <= 0.05 ? 1 : 0;
      summary->wrong += *f.error_mm > wrong_mm ? 1 : 0;
    }
  }
  if (times.empty()) return;
  std::sort(times.begin(), times.end());
  const auto at = [&times](double p) {
    return times[std::min(times.size() - 1, static_cast<std::size_t>(p * static_cast<double>(times.size())))];
  };
  summary->ms_p50 = at(0.5);
  summary->ms_p99 = at(0.99);
  summary->ms_max = times.back();
}

}  // namespace

LocateSummary Locate(const LocateOptions& options, const std::function<void(double)>& progress) {
  if (options.images.empty() == options.dataset.empty()) {
    core::ThrowInvalidInput("locate: give either images or a dataset");
  }
  if (options.every < 1) core::ThrowInvalidInput("locate: --every must be at least 1");
  if (!(options.scale > 0.5 && options.scale < 2.0)) core::ThrowInvalidInput("locate: --scale must be in (0.5, 2)");
  std::optional<dataset::DatasetReader> reader;
  std::vector<cv::Mat> images;
  int width = 0, height = 0;
  double mm_per_px = 0.0;
  if (!options.dataset.empty()) {
    reader.emplace(options.dataset);
    width = reader->info().camera.width_px;
    height = reader->info().camera.height_px;
    mm_per_px = reader->info().camera.mm_per_px;
  } else {
    for (const auto& path : options.images) {
      cv::Mat image = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
      if (image.empty()) core::ThrowInvalidInput(path.string() + ": cannot read the image");
      if (image.type() != CV_8UC1) core::ThrowInvalidInput(path.string() + ": not an 8-bit grey image");
      if (!images.empty() && image.size() != images.front().size()) {
        core::ThrowInvalidInput(path.string() + ": its size differs from the first image's");
      }
      width = image.cols;
      height = image.rows;
      images.push_back(std::move(image));
    }
  }
  MapSessionOptions map_options;
  map_options.cache_budget_bytes = options.settings.cache_budget_mib << 20;
  {
    // The map's resolution is the camera's (design.md section 3): the images' is taken from it.
    const auto store = mosaic::TileStore::Open(options.map, false);
    if (mm_per_px == 0.0) mm_per_px = store->grid().mm_per_px;
  }
  map_options.camera_mm_per_px = mm_per_px;
  MapSession map(options.map, map_options);
  if (!map.places().usable()) core::ThrowInvalidInput("locate: " + map.places().problem());
  const camera::IdealCamera camera(camera::IdealCameraOptions{width, height, mm_per_px});
  const tracking::Tracker tracker(camera, options.settings.localizer.tracker);
  const tracking::Relocalizer relocalizer(tracker, map.reference(), options.settings.localizer.relocalize);
  if (!map.places().Load()) core::ThrowInvalidInput("locate: " + map.places().problem());

  LocateSummary summary;
  summary.index_features = map.places().features();
  summary.index_memory_bytes = map.places().memory_bytes();
  summary.index_load_s = map.places().load_seconds();
  if (!reader) {
    for (std::size_t i = 0; i < images.size(); ++i) {
      summary.frames.push_back(LocateOne(relocalizer, map.places(), images[i], options.scale, options.images[i].string()));
      if (progress) progress(static_cast<double>(i + 1) / static_cast<double>(images.size()));
    }
    Tally(options.wrong_mm, &summary);
    return summary;
  }
  std::optional<dataset::Trajectory> truth;
  if (reader->HasGroundTruth()) truth = reader->GroundTruth();
  const auto vehicle_truth = dataset::RecordedVehicleTruth(reader->info());
  const core::Pose2 vehicle_from_camera =
      vehicle_truth ? vehicle_truth->vehicle_from_camera : reader->info().camera.vehicle_from_camera;
  auto frames = reader->Frames();
  std::int64_t index = 0;
  std::int64_t done = 0;
  std::int64_t total = 0;
  {
    auto count = reader->Frames();
    while (count.Next(false)) ++total;
  }
  while (true) {
    const bool wanted = index % options.every == 0;
    const auto frame = frames.Next(wanted);
    if (!frame) break;
    ++index;
    if (!wanted) continue;
    LocatedFrame located = LocateOne(relocalizer, map.places(), frame->image, options.scale, frame->path.string());
    if (truth && located.outcome == "found") {
      const auto pose = dataset::PoseAt(*truth, frame->time, std::chrono::milliseconds(100));
      if (pose) located.error_mm = core::Distance(*pose * vehicle_from_camera, located.world_from_camera);
    }
    summary.frames.push_back(std::move(located));
    ++done;
    if (progress) progress(static_cast<double>(index) / static_cast<double>(std::max<std::int64_t>(total, 1)));
    if (options.max_frames > 0 && done >= options.max_frames) break;
  }
  Tally(options.wrong_mm, &summary);
  return summary;
}

double LocatedFrame::SigmaMm() const { return std::sqrt(std::max(covariance(0, 0), covariance(1, 1))); }

nlohmann::json LocatedFrame::ToJson() const {
  nlohmann::json j = {{"frame", frame}, {"outcome", outcome}, {"candidates", candidates}, {"milliseconds", milliseconds}};
  if (outcome == "found") {
    j["x_mm"] = world_from_camera.x_mm();
    j["y_mm"] = world_from_camera.y_mm();
    j["yaw_rad"] = world_from_camera.yaw_rad();
    j["sigma_mm"] = SigmaMm();
    j["zncc"] = mean_zncc;
    j["templates"] = inliers;
  } else {
    j["reason"] = reason;
  }
  if (error_mm) j["error_mm"] = *error_mm;
  return j;
}

nlohmann::json LocateSummary::ToJson(const std::filesystem::path& map) const {
  nlohmann::json located = nlohmann::json::array();
  for (const LocatedFrame& f : frames) located.push_back(f.ToJson());
  nlohmann::json result = {{"map", map.string()},
                           {"frames", frames.size()},
                           {"found", found},
                           {"ambiguous", ambiguous},
                           {"no_match", no_match},
                           {"ms_p50", ms_p50},
                           {"ms_p99", ms_p99},
                           {"ms_max", ms_max},
                           {"index_features", index_features},
                           {"index_memory_bytes", index_memory_bytes},
                           {"index_load_s", index_load_s},
                           {"located", located}};
  if (checked > 0) {
    result["checked"] = checked;
    result["within_0_05_mm"] = within_0_05_mm;
    result["wrong"] = wrong;
  }
  return result;
}

}  // namespace mosaicloc::runtime
