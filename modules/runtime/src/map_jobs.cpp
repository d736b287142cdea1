#include "mosaicloc/runtime/map_jobs.hpp"
#include "mosaicloc/runtime/map_quality.hpp"
#include "mosaicloc/runtime/settings.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <optional>
#include <numbers>
#include <numeric>
#include <limits>
#include <sstream>
#include <unordered_map>

#include <opencv2/imgcodecs.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/dataset/camera_truth.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/mosaic/build_checkpoint.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/runtime/drive.hpp"
#include "mosaicloc/tracking/place_index.hpp"
#include "mosaicloc/tracking/reference.hpp"
#include "mosaicloc/tracking/relocalize.hpp"
#include "mosaicloc/tracking/render_window.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::runtime {
namespace {

namespace fs = std::filesystem;

// CRC32 of a file's bytes, in hex: part of a build's identity, so a checkpoint is never
// resumed against changed inputs.
std::string FileCrc(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) core::ThrowInvalidInput(file.string() + ": cannot be read");
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  char text[16];
  std::snprintf(text, sizeof(text), "%08x", mosaic::TileStore::Crc32(bytes));
  return text;
}

}  // namespace

// Paints every frame at its pose into a new map, written under a temporary name and renamed
// into place at the end: an interrupted build leaves no map (or the previous one). Progress
// is saved in MAP.checkpoint as it goes; --resume continues from there, and since the saved
// accumulators are exact, the map equals that of an uninterrupted build.
MapBuildSummary BuildMap(const MapBuildOptions& args, const std::function<void(double)>& progress) {
  std::vector<fs::path> datasets = {args.dataset};
  datasets.insert(datasets.end(), args.joined.begin(), args.joined.end());
  std::vector<std::unique_ptr<dataset::DatasetReader>> readers;
  for (const fs::path& d : datasets) readers.push_back(std::make_unique<dataset::DatasetReader>(d));
  const dataset::DatasetInfo& info = readers.front()->info();
  std::error_code ec;
  if (fs::exists(args.out, ec) && !args.overwrite) {
    core::ThrowInvalidInput(args.out.string() + ": already exists (add --overwrite to replace it)");
  }
  if (!(args.checkpoint_s >= 0.0)) core::ThrowInvalidInput("--checkpoint-s must be >= 0");
  const bool estimate = args.poses == "estimate";
  const bool groundtruth = args.poses == "groundtruth";
  if (!estimate && !args.report.empty()) {
    core::ThrowInvalidInput("--report: the consistency report is the estimated poses' (--poses estimate, the "
                            "default); with --poses " + args.poses + " there is none to write");
  }
  if (!estimate && !groundtruth && datasets.size() > 1) {
    core::ThrowInvalidInput("--poses " + args.poses + ": a TUM file holds one drive's poses; joined drives are "
                            "painted at estimated poses or at their ground truth");
  }
  for (std::size_t d = 1; d < readers.size(); ++d) {
    if (readers[d]->info().camera.mm_per_px != info.camera.mm_per_px) {
      core::ThrowInvalidInput(datasets[d].string() + ": its camera's mm_per_px is not " + datasets[0].string() +
                              "'s: drives painted into one map must share it");
    }
  }
  const fs::path checkpoint_file = args.out.string() + ".checkpoint";
  const fs::path estimated_file = args.out.string() + ".poses.tum";
  const fs::path estimated_views_file = args.out.string() + ".views.csv";
  std::optional<MapPosesSummary> mapping;
  // Estimated poses are kept beside the checkpoint: a resumed build paints with the same ones.
  bool estimated_before = estimate && args.resume && fs::exists(checkpoint_file, ec);
  for (std::size_t d = 0; d < datasets.size(); ++d) {
    estimated_before = estimated_before && fs::exists(DrivePath(estimated_file, static_cast<int>(d) + 1), ec);
  }
  if (estimate && !estimated_before) {
    MapPosesOptions pose_options;
    pose_options.dataset = args.dataset;
    pose_options.joined = args.joined;
    pose_options.join_start_sigma_mm = args.join_start_sigma_mm;
    pose_options.mapper.view_geometry = !args.flat_floor;
    pose_options.out = estimated_file;
    pose_options.views_out = estimated_views_file;
    pose_options.report = args.report;
    std::vector<const dataset::DatasetReader*> open;
    for (const auto& reader : readers) open.push_back(reader.get());
    mapping = EstimateMapPoses(pose_options, open, [&](double fraction) {
      if (progress) progress(0.5 * fraction);
    });
  }
  const double painting_from = estimate ? 0.5 : 0.0;
  std::vector<fs::path> poses_files;
  std::vector<dataset::Trajectory> poses;
  // Each frame is painted as its camera saw the floor where that is known: a tilted camera
  // looks at a slant (and beside its mounting point), a camera higher than calibrated shows
  // more floor per pixel. At the ground truth, where the simulator recorded it; at estimated
  // poses, where the mapper measured it (the view geometry applied, section 7a).
  std::vector<std::unordered_map<std::int64_t, FrameView>> views(datasets.size());
  std::vector<fs::path> views_files(datasets.size());
  std::vector<double> focal_px(datasets.size(), 0.0);
  for (std::size_t d = 0; d < datasets.size(); ++d) {
    poses_files.push_back(groundtruth ? datasets[d] / "groundtruth" / "data.tum"
                          : estimate  ? DrivePath(estimated_file, static_cast<int>(d) + 1)
                                      : fs::path(args.poses));
    if (groundtruth) {
      ViewTruth truth = ViewTruthOf(datasets[d], *readers[d]);
      poses.push_back(std::move(truth.world_from_vehicle));
      views[d] = std::move(truth.views);
      focal_px[d] = truth.focal_px;
      if (!views[d].empty()) views_files[d] = datasets[d] / dataset::kCameraTruthFile;
    } else {
      poses.push_back(dataset::ReadTum(poses_files.back()));
      const fs::path estimated_views = DrivePath(estimated_views_file, static_cast<int>(d) + 1);
      if (estimate && fs::exists(estimated_views, ec)) {
        const double height_mm = DefaultMapperOptions().tracker.solver.camera_height_mm;
        views[d] = FrameViews(dataset::ReadCameraTruth(estimated_views), height_mm);
        focal_px[d] = height_mm / readers[d]->info().camera.mm_per_px;
        views_files[d] = estimated_views;
      }
    }
  }
  mosaic::MapGrid grid;
  grid.mm_per_px = info.camera.mm_per_px;
  grid.tile_size_px = args.tile_size_px;
  grid.levels = args.levels;
  mosaic::MapBuilder builder(grid, mosaic::ParseBlend(args.blend));

  std::int64_t total = 0;
  std::map<std::string, std::string> identity = {
      {"poses", groundtruth || estimate ? args.poses : fs::absolute(args.poses).lexically_normal().string()},
      {"flat_floor", args.flat_floor ? "1" : "0"},
      {"blend", args.blend},
      {"tile_size_px", std::to_string(args.tile_size_px)},
      {"levels", std::to_string(args.levels)}};
  for (std::size_t d = 0; d < datasets.size(); ++d) {
    std::int64_t frames = 0;
    for (auto count = readers[d]->Frames(); count.Next(false);) ++frames;
    total += frames;
    const std::string suffix = d == 0 ? "" : "." + std::to_string(d + 1);
    identity["dataset" + suffix] = fs::absolute(datasets[d]).lexically_normal().string();
    identity["frames" + suffix] = std::to_string(frames);
    identity["frame_list_crc32" + suffix] = FileCrc(datasets[d] / "cam0" / "data.csv");
    identity["dataset_yaml_crc32" + suffix] = FileCrc(datasets[d] / "dataset.yaml");
    identity["poses_crc32" + suffix] = FileCrc(poses_files[d]);
    if (!views_files[d].empty()) identity["views_crc32" + suffix] = FileCrc(views_files[d]);
  }
  std::unique_ptr<mosaic::BuildCheckpoint> checkpoint;
  std::int64_t painted = 0;
  std::int64_t skipped = 0;
  std::int64_t resumed_after = 0;
  if (args.resume && fs::exists(checkpoint_file, ec)) {
    checkpoint = mosaic::BuildCheckpoint::Open(checkpoint_file, identity);
    checkpoint->Restore(builder);
    resumed_after = checkpoint->frames_done();
    painted = checkpoint->counter("painted");
    skipped = checkpoint->counter("skipped");
  } else {
    checkpoint = mosaic::BuildCheckpoint::Create(checkpoint_file, identity);
  }
  // A save writes every tile painted since the last (8 bytes a pixel: 2 GB for an 85 m lap's
  // 3,900 tiles), so saves are paced to cost at most a tenth of the painting: due when the
  // painting since the last took ten times what this one would, at the rate the last one
  // wrote (250 MB/s before the first).
  double save_bytes_per_s = 250e6;
  const auto save = [&](std::int64_t frames_done) {
    const auto started = std::chrono::steady_clock::now();
    const double bytes = static_cast<double>(builder.unsaved_bytes());
    checkpoint->Save(builder, frames_done, {{"painted", painted}, {"skipped", skipped}});
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    if (bytes > 64e6 && seconds > 0.0) save_bytes_per_s = bytes / seconds;
  };
  // The drives one after another; `done` counts frames over all of them.
  std::int64_t done = 0;
  auto last_save = std::chrono::steady_clock::now();
  for (std::size_t d = 0; d < datasets.size(); ++d) {
    const dataset::CameraInfo& camera = readers[d]->info().camera;
    auto frames = readers[d]->Frames();
    while (done < resumed_after) {
      if (!frames.Next(false)) break;
      ++done;
    }
    if (done < resumed_after) continue;  // this drive was painted before the interruption
    while (const auto frame = frames.Next()) {
      const auto pose = dataset::PoseAt(poses[d], frame->time, std::chrono::milliseconds(100));
      if (pose) {
        const auto found = views[d].find(frame->time.nanoseconds());
        const FrameView view = found == views[d].end() ? FrameView{} : found->second;
        builder.AddFrame(frame->image, *pose * camera.vehicle_from_camera, camera.mm_per_px * view.scale,
                         focal_px[d], view.tilt_x_rad, view.tilt_y_rad);
        ++painted;
      } else {
        ++skipped;
      }
      ++done;
      const double since_save = std::chrono::duration<double>(std::chrono::steady_clock::now() - last_save).count();
      if (args.checkpoint_s == 0.0 ||
          (since_save >= args.checkpoint_s &&
           since_save >= 10.0 * static_cast<double>(builder.unsaved_bytes()) / save_bytes_per_s)) {
        save(done);
        last_save = std::chrono::steady_clock::now();
      }
      if (progress) {
        progress(painting_from + (0.8 - painting_from) * static_cast<double>(done) /
                                     static_cast<double>(std::max<std::int64_t>(total, 1)));
      }
    }
  }
  if (painted == 0) core::ThrowInvalidInput(args.dataset.string() + ": no frame has a pose in " + args.poses);
  // No save here: writing the map takes less than the checkpoint would, so a build killed
  // while writing resumes from the last save and paints the rest again.

  const fs::path partial = args.out.string() + ".partial";
  std::int64_t place_features = 0;
  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(partial.string() + suffix, ec);
  {
    auto store = mosaic::TileStore::Create(partial, grid);
    builder.Write(*store, [&](double fraction) {
      if (progress) progress(0.8 + 0.15 * fraction);
    });
    place_features = IndexStore(*store, [&](double fraction) {
                       if (progress) progress(0.95 + 0.03 * fraction);
                     }).features;
    AssessStore(*store, [&](double fraction) {
      if (progress) progress(0.98 + 0.02 * fraction);
    });
    // The renamed file must hold the whole map: its log stays behind under the old name.
    store->Checkpoint();
  }
  for (const char* suffix : {"-wal", "-shm"}) fs::remove(partial.string() + suffix, ec);
  // A log the replaced map left beside it would be taken for the new map's.
  for (const char* suffix : {"-wal", "-shm"}) fs::remove(args.out.string() + suffix, ec);
  fs::rename(partial, args.out, ec);
  if (ec) core::ThrowRuntime(args.out.string() + ": cannot move the new map into place (" + ec.message() + ")");
  checkpoint.reset();
  mosaic::BuildCheckpoint::Remove(checkpoint_file);
  if (estimate) {
    for (std::size_t d = 0; d < datasets.size(); ++d) {
      fs::remove(DrivePath(estimated_file, static_cast<int>(d) + 1), ec);
      fs::remove(DrivePath(estimated_views_file, static_cast<int>(d) + 1), ec);
    }
  }
  const auto store = mosaic::TileStore::Open(args.out, false);
  return {total, painted, skipped, resumed_after, store->Count(), store->Count(0), place_features, std::move(mapping)};
}

MapExtent LevelExtent(const mosaic::TileStore& store, int level) {
  MapExtent extent{std::numeric_limits<std::int64_t>::max(), std::numeric_limits<std::int64_t>::max(),
                std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::min()};
  const std::int64_t t = store.grid().tile_size_px;
  for (const auto& key : store.List(level)) {
    extent.col0 = std::min(extent.col0, key.col * t);
    extent.row0 = std::min(extent.row0, key.row * t);
    extent.col1 = std::max(extent.col1, (key.col + 1) * t - 1);
    extent.row1 = std::max(extent.row1, (key.row + 1) * t - 1);
  }
  return extent;
}

MapInfo InspectMap(const std::filesystem::path& map) {
  const auto store = mosaic::TileStore::Open(map, false);
  MapInfo info;
  info.grid = store->grid();
  for (int k = 0; k < info.grid.levels; ++k) info.tiles_per_level.push_back(store->Count(k));
  info.tiles = store->Count();
  for (const char* suffix : {"", "-wal"}) {
    std::error_code ec;
    const auto size = fs::file_size(map.string() + suffix, ec);
    if (!ec) info.bytes_on_disk += size;
  }
  const MapExtent e = LevelExtent(*store, 0);
  if (!e.empty()) {
    const auto at = [&](std::int64_t col, std::int64_t row, double outward) {
      return info.grid.RasterToWorld({static_cast<double>(col) + outward, static_cast<double>(row) - outward}, 0);
    };
    const Eigen::Vector2d low = at(e.col0, e.row1, -0.5), high = at(e.col1, e.row0, 0.5);
    info.extent_mm = {low.x(), low.y(), high.x(), high.y()};
  }
  info.places = store->Places();
  info.quality = store->Quality();
  for (const mosaic::MapUpdate& update : store->History()) {
    ++info.updates;
    if (update.reverted.empty()) ++info.updates_in_force;
  }
  return info;
}

nlohmann::json MapInfo::ToJson(const std::filesystem::path& map) const {
  nlohmann::json levels = nlohmann::json::array();
  for (int k = 0; k < grid.levels; ++k) {
    levels.push_back({{"level", k}, {"mm_per_px", grid.LevelMmPerPx(k)}, {"tiles", tiles_per_level[k]}});
  }
  nlohmann::json result = {{"map", map.string()}, {"format_version", mosaic::kMapFormatVersion},
                           {"mm_per_px", grid.mm_per_px}, {"origin_x_mm", grid.origin_x_mm},
                           {"origin_y_mm", grid.origin_y_mm}, {"tile_size_px", grid.tile_size_px},
                           {"levels", levels}, {"tiles", tiles}, {"bytes_on_disk", bytes_on_disk}};
  if (!extent_mm.empty()) result["extent_mm"] = extent_mm;
  result["place_index"] = nullptr;
  if (places) {
    result["place_index"] = {{"format_version", places->format_version}, {"method", places->method},
                             {"level", places->level}, {"cells", places->cells},
                             {"features", places->bytes / static_cast<std::int64_t>(tracking::kPlaceRecordBytes)},
                             {"bytes", places->bytes},
                             {"repeat_test", nullptr}};
    if (const auto test = FloorRepeatTest::Of(*places)) result["place_index"]["repeat_test"] = test->ToJson();
  }
  result["quality"] = quality ? nlohmann::json{{"level", quality->level}, {"cells", quality->cells}}
                              : nlohmann::json(nullptr);
  result["updates"] = updates;
  result["updates_in_force"] = updates_in_force;
  return result;
}

nlohmann::json MapHistoryJson(const std::filesystem::path& map, const std::vector<mosaic::MapUpdate>& history) {
  nlohmann::json updates = nlohmann::json::array();
  for (const mosaic::MapUpdate& u : history) {
    updates.push_back({{"id", u.id}, {"time", u.time}, {"reason", u.reason}, {"tiles", u.tiles},
                       {"reverted", u.reverted.empty() ? nlohmann::json() : nlohmann::json(u.reverted)}});
  }
  return {{"map", map.string()}, {"updates", updates}};
}

nlohmann::json MapRevertSummary::ToJson(const std::filesystem::path& map) const {
  return {{"map", map.string()}, {"update", revert.id}, {"reason", revert.reason},
          {"tiles_restored", revert.restored}, {"tiles_removed", revert.removed},
          {"place_index_rebuilt", reindexed}, {"quality_layer_rebuilt", reassessed}};
}

nlohmann::json MapIndexSummary::ToJson(const std::filesystem::path& map) const {
  return {{"map", map.string()}, {"cells", cells},     {"features", features},
          {"bytes", bytes},      {"seconds", seconds}, {"repeat_test", repeat_test.ToJson()}};
}

nlohmann::json MapBuildSummary::ToJson(const MapBuildOptions& options) const {
  nlohmann::json result = {{"map", fs::absolute(options.out).string()}, {"frames_painted", painted},
                           {"frames_without_pose", without_pose}, {"tiles", tiles},
                           {"level0_tiles", level0_tiles}, {"resumed_after_frames", resumed_after},
                           {"place_features", place_features}, {"poses", options.poses}};
  if (mapping) result["mapping"] = mapping->ToJson();
  return result;
}

std::vector<mosaic::MapUpdate> MapHistory(const std::filesystem::path& map) {
  return mosaic::TileStore::Open(map, false)->History();
}

MapRevertSummary RevertMapUpdate(const std::filesystem::path& map, std::int64_t id) {
  const auto store = mosaic::TileStore::Open(map, true);
  MapRevertSummary summary;
  summary.revert = mosaic::RevertUpdate(*store, id);
  if (store->Places()) {
    IndexStore(*store);
    summary.reindexed = true;
  }
  if (store->Quality()) {
    AssessStore(*store);
    summary.reassessed = true;
  }
  return summary;
}

std::string FloorRepeatTest::Verdict() const {
  if (elsewhere > 0) return "repeats";
  return own > 0 ? "does not repeat" : "unknown";
}

std::string FloorRepeatTest::Describe() const {
  return Verdict() + " (" + std::to_string(views) + " views searched for everywhere: " + std::to_string(own) +
         " found at their own place, " + std::to_string(elsewhere) + " elsewhere too)";
}

nlohmann::json FloorRepeatTest::ToJson() const {
  return {{"views", views}, {"own", own}, {"elsewhere", elsewhere}, {"verdict", Verdict()}, {"seconds", seconds}};
}

std::optional<FloorRepeatTest> FloorRepeatTest::Of(const mosaic::PlaceIndexInfo& places) {
  if (places.repeat_test_views < 0) return std::nullopt;
  FloorRepeatTest test;
  test.views = places.repeat_test_views;
  test.own = places.repeat_test_own;
  test.elsewhere = places.repeat_test_elsewhere;
  return test;
}

FloorRepeatTest TestFloorRepeats(mosaic::TileStore& store, int views) {
  constexpr double kMappedShare = 0.8;  // of a view that must be mapped floor to be searched for
  const auto start = std::chrono::steady_clock::now();
  FloorRepeatTest test;
  const mosaic::MapGrid& grid = store.grid();
  mosaic::TileCache cache(store, std::size_t{64} << 20);
  const mosaic::MapRenderer renderer(cache);
  const tracking::MapReference reference(renderer, 0);
  const tracking::PlaceIndex places(store);
  if (places.usable() && places.Load()) {
    // The default camera at the map's resolution, and the localizer's default tracker and
    // relocalization: what a vehicle's global search does.
    const camera::IdealCamera camera(camera::IdealCameraOptions{640, 480, grid.mm_per_px});
    const LocalizationSettings settings;
    const tracking::Tracker tracker(camera, settings.localizer.tracker);
    const tracking::Relocalizer relocalizer(tracker, reference, settings.localizer.relocalize);
    const std::vector<mosaic::TileKey> tiles = store.List(0);
    const double tile_mm = grid.mm_per_px * grid.tile_size_px;
    // Whether a view is mapped enough is judged on a coarse camera of the same footprint (1/64
    // of the pixels); only a view that is gets rendered whole.
    const camera::IdealCamera coarse(camera::IdealCameraOptions{80, 60, 8.0 * grid.mm_per_px});
    // The tiles in a spread order (a stride coprime to their count walks all of them, far apart
    // first), each tried with the view along x and along y (lanes run either way), at most
    // 20 tiles per view wanted: a map of lanes narrower than the view has few places to try.
    std::size_t stride = std::max<std::size_t>(1, tiles.size() / static_cast<std::size_t>(std::max(views, 1)));
    while (std::gcd(stride, tiles.size()) != 1) ++stride;
    const std::size_t tries = std::min(tiles.size(), static_cast<std::size_t>(20 * std::max(views, 1)));
    for (std::size_t k = 0; k < tries && test.views < views; ++k) {
      const mosaic::TileKey& tile = tiles[(stride / 2 + k * stride) % tiles.size()];
      const Eigen::Vector2d centre(grid.origin_x_mm + (static_cast<double>(tile.col) + 0.5) * tile_mm,
                                   grid.origin_y_mm - (static_cast<double>(tile.row) + 0.5) * tile_mm);
      // Near the tile's centre (a lane a view wide is seldom centred on a tile).
      std::optional<core::Pose2> place;
      for (int candidate = 0; candidate < 18 && !place; ++candidate) {
        const double yaw = candidate % 2 == 0 ? 0.0 : 0.5 * std::numbers::pi;
        const Eigen::Vector2d shift(32.0 * ((candidate / 2) % 3 - 1), 32.0 * ((candidate / 6) - 1));
        cv::Mat mask;
        tracking::RenderCameraView(reference, coarse, core::Pose2(centre + shift, yaw), &mask);
        if (mask.empty() || cv::countNonZero(mask) >= kMappedShare * static_cast<double>(mask.total())) {
          place = core::Pose2(centre + shift, yaw);
        }
      }
      if (!place) continue;
      const cv::Mat view = tracking::RenderCameraView(reference, camera, *place);
      ++test.views;
      const tracking::TrackResult found = relocalizer.SearchEverywhere(view, places);
      if (found.ok() && core::Distance(found.world_from_camera, *place) <= 2.0) {
        ++test.own;
      } else if (found.ok() || found.failure == tracking::TrackFailure::kAmbiguous) {
        ++test.elsewhere;
      }
    }
  }
  store.WritePlaceRepeatTest(test.views, test.own, test.elsewhere);
  test.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return test;
}

MapIndexSummary IndexStore(mosaic::TileStore& store, const std::function<void(double)>& progress) {
  const auto start = std::chrono::steady_clock::now();
  const tracking::PlaceIndexOptions options;
  const std::vector<mosaic::PlaceCell> cells = tracking::BuildPlaceCells(store, options, progress);
  store.WritePlaces(tracking::PlaceIndexInfoFor(options), cells);
  MapIndexSummary summary;
  summary.cells = static_cast<std::int64_t>(cells.size());
  for (const auto& cell : cells) {
    summary.bytes += static_cast<std::int64_t>(cell.data.size());
    summary.features += static_cast<std::int64_t>(cell.data.size() / tracking::kPlaceRecordBytes);
  }
  summary.repeat_test = TestFloorRepeats(store);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

MapIndexSummary IndexMap(const std::filesystem::path& map, const std::function<void(double)>& progress) {
  const auto store = mosaic::TileStore::Open(map, /*writable=*/true);
  MapIndexSummary summary = IndexStore(*store, progress);
  store->Checkpoint();
  return summary;
}

std::vector<std::string> CheckMap(const std::filesystem::path& map, std::size_t* tiles,
                                  const std::function<void(double)>& progress) {
  const auto store = mosaic::TileStore::Open(map, false);
  const auto keys = store->List();
  std::vector<std::string> problems;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const mosaic::TileRead read = store->Read(keys[i]);
    if (read.status == mosaic::TileStatus::kCorrupt) problems.push_back(read.problem);
    if (progress) progress(static_cast<double>(i + 1) / static_cast<double>(keys.size()));
  }
  *tiles = keys.size();
  try {
    if (store->Places()) store->ReadPlaces();
  } catch (const core::Error& e) {
    problems.push_back(e.what());
  }
  try {
    if (store->Quality()) store->ReadQuality();
  } catch (const core::Error& e) {
    problems.push_back(e.what());
  }
  for (const mosaic::MapUpdate& update : store->History()) {
    try {
      store->Replaced(update.id);
    } catch (const core::Error& e) {
      problems.push_back(e.what());
    }
  }
  return problems;
}

MapExportSummary ExportMap(const MapExportOptions& args) {
  const auto store = mosaic::TileStore::Open(args.map, false);
  const mosaic::MapGrid& grid = store->grid();
  MapExtent extent;
  int level = args.level;
  if (!args.region.empty()) {
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    char c1 = 0, c2 = 0, c3 = 0;
    std::istringstream in(args.region);
    if (!(in >> x0 >> c1 >> y0 >> c2 >> x1 >> c3 >> y1) || c1 != ',' || c2 != ',' || c3 != ',' || x1 <= x0 || y1 <= y0) {
      core::ThrowInvalidInput("region must be x0,y0,x1,y1 in mm with x0 < x1 and y0 < y1, got '" + args.region + "'");
    }
    if (level < 0) level = 0;
    const Eigen::Vector2d a = grid.WorldToRaster({x0, y1}, level);
    const Eigen::Vector2d b = grid.WorldToRaster({x1, y0}, level);
    extent = {static_cast<std::int64_t>(std::floor(a.x() + 0.5)), static_cast<std::int64_t>(std::floor(a.y() + 0.5)),
              static_cast<std::int64_t>(std::ceil(b.x() - 0.5)), static_cast<std::int64_t>(std::ceil(b.y() - 0.5))};
  } else {
    // Default: the finest level that fits in 8192 px.
    if (level < 0) {
      level = grid.levels - 1;
      for (int k = 0; k < grid.levels; ++k) {
        const MapExtent e = LevelExtent(*store, k);
        if (!e.empty() && e.col1 - e.col0 < 8192 && e.row1 - e.row0 < 8192) {
          level = k;
          break;
        }
      }
    }
    extent = LevelExtent(*store, level);
    if (extent.empty()) core::ThrowInvalidInput(args.map.string() + ": level " + std::to_string(level) + " has no tiles");
  }
  if (level >= grid.levels) core::ThrowInvalidInput("level must be below " + std::to_string(grid.levels));
  const std::int64_t cols = extent.col1 - extent.col0 + 1;
  const std::int64_t rows = extent.row1 - extent.row0 + 1;
  if (cols > 32768 || rows > 32768) {
    core::ThrowInvalidInput("the export would be " + std::to_string(cols) + " x " + std::to_string(rows) +
                            " px: choose a coarser --level or a smaller --region");
  }
  mosaic::TileCache cache(*store, std::size_t{64} << 20);
  const mosaic::MapRenderer renderer(cache);
  const mosaic::RasterPatch patch =
      renderer.Region(level, extent.col0, extent.row0, static_cast<int>(cols), static_cast<int>(rows));
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", patch.image, png)) core::ThrowRuntime("cannot encode the export");
  core::WriteFileAtomically(args.out, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  return {level, grid.LevelMmPerPx(level), cols, rows, !patch.problems.empty()};
}

}  // namespace mosaicloc::runtime
