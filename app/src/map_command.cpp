#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "commands.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/mosaic/build_checkpoint.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "progress.hpp"

namespace mosaicloc::app {
namespace {

namespace fs = std::filesystem;

struct MapArgs {
  fs::path dataset;
  fs::path map;
  fs::path out;
  std::string poses = "groundtruth";
  std::string blend = "feather";
  int tile_size_px = 256;
  int levels = 6;
  int level = -1;
  std::string region;
  bool overwrite = false;
  bool resume = false;
  double checkpoint_s = 10.0;
};

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

// Paints every frame at its pose into a new map, written under a temporary name and renamed
// into place at the end: an interrupted build leaves no map (or the previous one). Progress
// is saved in MAP.checkpoint as it goes; --resume continues from there, and since the saved
// accumulators are exact, the map equals that of an uninterrupted build.
void Build(const MapArgs& args, const GlobalOptions& global) {
  const dataset::DatasetReader reader(args.dataset);
  const dataset::DatasetInfo& info = reader.info();
  const dataset::Trajectory poses =
      args.poses == "groundtruth" ? reader.GroundTruth() : dataset::ReadTum(args.poses);
  std::error_code ec;
  if (fs::exists(args.out, ec) && !args.overwrite) {
    core::ThrowInvalidInput(args.out.string() + ": already exists (add --overwrite to replace it)");
  }
  if (!(args.checkpoint_s >= 0.0)) core::ThrowInvalidInput("--checkpoint-s must be >= 0");
  mosaic::MapGrid grid;
  grid.mm_per_px = info.camera.mm_per_px;
  grid.tile_size_px = args.tile_size_px;
  grid.levels = args.levels;
  mosaic::MapBuilder builder(grid, mosaic::ParseBlend(args.blend));

  ProgressBar progress("map build", global.quiet);
  std::int64_t total = 0;
  for (auto count = reader.Frames(); count.Next(false);) ++total;
  const fs::path poses_file = args.poses == "groundtruth" ? args.dataset / "groundtruth" / "data.tum" : fs::path(args.poses);
  const std::map<std::string, std::string> identity = {
      {"dataset", fs::absolute(args.dataset).lexically_normal().string()},
      {"frames", std::to_string(total)},
      {"frame_list_crc32", FileCrc(args.dataset / "cam0" / "data.csv")},
      {"dataset_yaml_crc32", FileCrc(args.dataset / "dataset.yaml")},
      {"poses", args.poses == "groundtruth" ? "groundtruth" : fs::absolute(args.poses).lexically_normal().string()},
      {"poses_crc32", FileCrc(poses_file)},
      {"blend", args.blend},
      {"tile_size_px", std::to_string(args.tile_size_px)},
      {"levels", std::to_string(args.levels)}};
  const fs::path checkpoint_file = args.out.string() + ".checkpoint";
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
  const auto save = [&](std::int64_t frames_done) {
    checkpoint->Save(builder, frames_done, {{"painted", painted}, {"skipped", skipped}});
  };
  auto frames = reader.Frames();
  std::int64_t done = 0;
  for (; done < resumed_after && frames.Next(false); ++done) {
  }
  auto last_save = std::chrono::steady_clock::now();
  while (const auto frame = frames.Next()) {
    const auto pose = dataset::PoseAt(poses, frame->time, std::chrono::milliseconds(100));
    if (pose) {
      builder.AddFrame(frame->image, *pose * info.camera.vehicle_from_camera, info.camera.mm_per_px);
      ++painted;
    } else {
      ++skipped;
    }
    ++done;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - last_save).count() >= args.checkpoint_s) {
      save(done);
      last_save = std::chrono::steady_clock::now();
    }
    progress.Update(0.8 * static_cast<double>(done) / static_cast<double>(std::max<std::int64_t>(total, 1)));
  }
  if (painted == 0) core::ThrowInvalidInput(args.dataset.string() + ": no frame has a pose in " + args.poses);
  save(done);  // every frame painted: a build killed while writing resumes with the writing

  const fs::path partial = args.out.string() + ".partial";
  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(partial.string() + suffix, ec);
  {
    auto store = mosaic::TileStore::Create(partial, grid);
    builder.Write(*store, [&](double fraction) { progress.Update(0.8 + 0.2 * fraction); });
    // The renamed file must hold the whole map: its log stays behind under the old name.
    store->Checkpoint();
  }
  for (const char* suffix : {"-wal", "-shm"}) fs::remove(partial.string() + suffix, ec);
  fs::rename(partial, args.out, ec);
  if (ec) core::ThrowRuntime(args.out.string() + ": cannot move the new map into place (" + ec.message() + ")");
  checkpoint.reset();
  mosaic::BuildCheckpoint::Remove(checkpoint_file);
  progress.Finish();
  const auto store = mosaic::TileStore::Open(args.out, false);
  if (global.json) {
    const nlohmann::json result = {{"map", fs::absolute(args.out).string()}, {"frames_painted", painted},
                                   {"frames_without_pose", skipped}, {"tiles", store->Count()},
                                   {"level0_tiles", store->Count(0)}, {"resumed_after_frames", resumed_after}};
    std::printf("%s\n", result.dump(2).c_str());
  } else {
    std::printf("map %s: %lld frames painted (%lld without a pose), %lld tiles (%lld at level 0)",
                args.out.string().c_str(), static_cast<long long>(painted), static_cast<long long>(skipped),
                static_cast<long long>(store->Count()), static_cast<long long>(store->Count(0)));
    if (resumed_after > 0) std::printf("; resumed after %lld of %lld frames", static_cast<long long>(resumed_after),
                                       static_cast<long long>(total));
    std::printf("\n");
  }
}

struct Extent {
  std::int64_t col0 = 0, row0 = 0, col1 = -1, row1 = -1;  // level pixels, inclusive
  bool empty() const { return col1 < col0; }
};

Extent LevelExtent(const mosaic::TileStore& store, int level) {
  Extent extent{std::numeric_limits<std::int64_t>::max(), std::numeric_limits<std::int64_t>::max(),
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

void Info(const MapArgs& args, const GlobalOptions& global) {
  const auto store = mosaic::TileStore::Open(args.map, false);
  const mosaic::MapGrid& grid = store->grid();
  const Extent extent = LevelExtent(*store, 0);
  std::uintmax_t bytes = 0;
  std::error_code ec;
  for (const char* suffix : {"", "-wal"}) {
    const auto size = fs::file_size(args.map.string() + suffix, ec);
    if (!ec) bytes += size;
  }
  nlohmann::json levels = nlohmann::json::array();
  for (int k = 0; k < grid.levels; ++k) {
    levels.push_back({{"level", k}, {"mm_per_px", grid.LevelMmPerPx(k)}, {"tiles", store->Count(k)}});
  }
  const Eigen::Vector2d low = grid.RasterToWorld({static_cast<double>(extent.col0) - 0.5, static_cast<double>(extent.row1) + 0.5}, 0);
  const Eigen::Vector2d high = grid.RasterToWorld({static_cast<double>(extent.col1) + 0.5, static_cast<double>(extent.row0) - 0.5}, 0);
  if (global.json) {
    nlohmann::json result = {{"map", args.map.string()}, {"format_version", mosaic::kMapFormatVersion},
                             {"mm_per_px", grid.mm_per_px}, {"origin_x_mm", grid.origin_x_mm},
                             {"origin_y_mm", grid.origin_y_mm}, {"tile_size_px", grid.tile_size_px},
                             {"levels", levels}, {"tiles", store->Count()}, {"bytes_on_disk", bytes}};
    if (!extent.empty()) result["extent_mm"] = {low.x(), low.y(), high.x(), high.y()};
    std::printf("%s\n", result.dump(2).c_str());
    return;
  }
  std::printf("map %s: format %d, %.4g mm/px, tiles of %d px, %d levels, %lld tiles, %.1f MiB on disk\n",
              args.map.string().c_str(), mosaic::kMapFormatVersion, grid.mm_per_px, grid.tile_size_px, grid.levels,
              static_cast<long long>(store->Count()), static_cast<double>(bytes) / (1 << 20));
  if (!extent.empty()) {
    std::printf("  extent x %.1f .. %.1f mm, y %.1f .. %.1f mm (%lld x %lld px at level 0)\n", low.x(), high.x(),
                low.y(), high.y(), static_cast<long long>(extent.col1 - extent.col0 + 1),
                static_cast<long long>(extent.row1 - extent.row0 + 1));
  }
  for (const auto& level : levels) {
    std::printf("  level %d: %.4g mm/px, %lld tiles\n", level["level"].get<int>(), level["mm_per_px"].get<double>(),
                static_cast<long long>(level["tiles"].get<std::int64_t>()));
  }
}

void Check(const MapArgs& args, const GlobalOptions& global) {
  const auto store = mosaic::TileStore::Open(args.map, false);
  const auto keys = store->List();
  std::vector<std::string> problems;
  ProgressBar progress("map check", global.quiet);
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const mosaic::TileRead read = store->Read(keys[i]);
    if (read.status == mosaic::TileStatus::kCorrupt) problems.push_back(read.problem);
    progress.Update(static_cast<double>(i + 1) / static_cast<double>(keys.size()));
  }
  progress.Finish();
  if (global.json) {
    const nlohmann::json result = {{"map", args.map.string()}, {"tiles", keys.size()}, {"damaged", problems}};
    std::printf("%s\n", result.dump(2).c_str());
  }
  if (!problems.empty()) {
    std::string message = std::to_string(problems.size()) + " of " + std::to_string(keys.size()) + " tiles damaged:";
    for (const auto& problem : problems) message += "\n  " + problem;
    core::ThrowInvalidInput(message);
  }
  if (!global.json) std::printf("%s: all %zu tiles intact\n", args.map.string().c_str(), keys.size());
}

void Export(const MapArgs& args, const GlobalOptions& global) {
  const auto store = mosaic::TileStore::Open(args.map, false);
  const mosaic::MapGrid& grid = store->grid();
  Extent extent;
  int level = args.level;
  if (!args.region.empty()) {
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    char c1 = 0, c2 = 0, c3 = 0;
    std::istringstream in(args.region);
    if (!(in >> x0 >> c1 >> y0 >> c2 >> x1 >> c3 >> y1) || c1 != ',' || c2 != ',' || c3 != ',' || x1 <= x0 || y1 <= y0) {
      core::ThrowInvalidInput("--region must be x0,y0,x1,y1 in mm with x0 < x1 and y0 < y1, got '" + args.region + "'");
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
        const Extent e = LevelExtent(*store, k);
        if (!e.empty() && e.col1 - e.col0 < 8192 && e.row1 - e.row0 < 8192) {
          level = k;
          break;
        }
      }
    }
    extent = LevelExtent(*store, level);
    if (extent.empty()) core::ThrowInvalidInput(args.map.string() + ": level " + std::to_string(level) + " has no tiles");
  }
  if (level >= grid.levels) core::ThrowInvalidInput("--level must be below " + std::to_string(grid.levels));
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
  if (!global.quiet) {
    std::printf("%s: level %d (%.4g mm/px), %lld x %lld px%s\n", args.out.string().c_str(), level,
                grid.LevelMmPerPx(level), static_cast<long long>(cols), static_cast<long long>(rows),
                patch.problems.empty() ? "" : " (damaged tiles left black)");
  }
}

}  // namespace

Action AddMapCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<MapArgs>();
  CLI::App* command = app.add_subcommand("map", "Build and inspect mosaic maps");
  command->require_subcommand(1);
  CLI::App* build = command->add_subcommand("build", "Paint a dataset's frames at their poses into a new map");
  build->add_option("--dataset", args->dataset, "Dataset directory")->required();
  build->add_option("--out", args->out, "Map file to write (*.mosaic)")->required();
  build->add_option("--poses", args->poses, "'groundtruth' (default) or a TUM trajectory of world_from_vehicle");
  build->add_option("--blend", args->blend, "feather (default) or best-view")
      ->check(CLI::IsMember({"feather", "best-view"}));
  build->add_option("--tile-size", args->tile_size_px, "Tile size in px, a power of two (default 256)")
      ->check(CLI::IsMember({32, 64, 128, 256, 512, 1024}));
  build->add_option("--levels", args->levels, "Pyramid levels (default 6)")->check(CLI::Range(1, 16));
  build->add_flag("--overwrite", args->overwrite, "Replace an existing map");
  build->add_flag("--resume", args->resume,
                  "Continue an interrupted build of the same arguments from its last checkpoint (MAP.checkpoint)");
  build->add_option("--checkpoint-s", args->checkpoint_s,
                    "Seconds between saves of the build's progress (default 10; 0: after every frame)");
  CLI::App* info = command->add_subcommand("info", "Extent, resolution, levels, tiles and size of a map");
  info->add_option("MAP", args->map, "Map file")->required();
  CLI::App* check = command->add_subcommand("check", "Verify every tile (CRC, PNG, size); exit 2 on damage");
  check->add_option("MAP", args->map, "Map file")->required();
  CLI::App* export_command = command->add_subcommand("export", "Write a map level (or a region of it) as a PNG");
  export_command->add_option("MAP", args->map, "Map file")->required();
  export_command->add_option("--out", args->out, "PNG file to write")->required();
  export_command->add_option("--level", args->level, "Pyramid level (default: the finest within 8192 px)")
      ->check(CLI::Range(0, 15));
  export_command->add_option("--region", args->region, "x0,y0,x1,y1 in world mm");
  return [args, &global, build, info, check, export_command] {
    if (build->parsed()) Build(*args, global);
    if (info->parsed()) Info(*args, global);
    if (check->parsed()) Check(*args, global);
    if (export_command->parsed()) Export(*args, global);
  };
}

}  // namespace mosaicloc::app
