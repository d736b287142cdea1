// mosaicloc map: build, inspect, check and export mosaic maps (runtime/map_jobs.hpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "report.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/runtime/map_jobs.hpp"
#include "mosaicloc/runtime/map_poses.hpp"
#include "mosaicloc/runtime/map_quality.hpp"
#include "mosaicloc/tracking/place_index.hpp"
#include "progress.hpp"

namespace mosaicloc::app {
namespace {

namespace fs = std::filesystem;

struct MapArgs {
  runtime::MapBuildOptions build;
  runtime::MapPosesOptions poses;
  runtime::MapExportOptions export_;
  runtime::MapQualityJob quality;
  fs::path map;
  std::int64_t update_id = 0;  ///< map revert
};

// The estimated poses' figures, as the lines printed.
void PrintMapping(const runtime::MapPosesSummary& s) {
  const nlohmann::json j = s.ToJson();
  std::printf("poses from %lld frames and the encoders (%.1f m, %.1f s): %lld of %lld loop closures accepted, "
              "seams %.4f px RMS (max %.4f) after optimization\n",
              static_cast<long long>(s.mapping.frames), s.mapping.path_length_m, s.seconds,
              static_cast<long long>(s.mapping.loops_accepted), static_cast<long long>(s.mapping.loops_tried),
              j["seam_rms_px"].get<double>(), j["seam_max_px"].get<double>());
  if (s.flat_field.flat_frames > 0) {
    std::printf("  the camera's flat field, from %d frames along the drive: gain %.3f to %.3f, divided out before "
                "registering\n", s.flat_field.flat_frames, s.flat_field.min_gain, s.flat_field.max_gain);
  }
  if (s.error && s.chained_error) {
    std::printf("  against the ground truth (best rigid alignment): %.4f mm RMS, %.4f mm max "
                "(chained, before loop closure: %.3f mm RMS, %.3f mm max)\n",
                s.error->rms_mm, s.error->max_mm, s.chained_error->rms_mm, s.chained_error->max_mm);
  }
  for (const std::string& warning : s.mapping.warnings) std::printf("  warning: %s\n", warning.c_str());
}

void Poses(const runtime::MapPosesOptions& args, const GlobalOptions& global) {
  ProgressBar progress("map poses", global.quiet);
  const runtime::MapPosesSummary r = runtime::EstimateMapPoses(args, progress.Callback());
  progress.Finish();
  if (global.json) {
    PrintJson(r.ToJson());
    return;
  }
  PrintMapping(r);
  if (!args.out.empty()) {
    for (std::size_t d = 0; d < r.poses.size(); ++d) {
      std::printf("trajectory: %s\n", runtime::DrivePath(args.out, static_cast<int>(d) + 1).string().c_str());
    }
  }
  if (!args.report.empty()) std::printf("report: %s\n", (args.report / "consistency.json").string().c_str());
}

void Build(const runtime::MapBuildOptions& args, const GlobalOptions& global) {
  ProgressBar progress("map build", global.quiet,
                       "the work so far is kept in " + args.out.string() +
                           ".checkpoint, and the same command with --resume goes on from there; " +
                           args.out.string() + " is as it was");
  const runtime::MapBuildSummary r = runtime::BuildMap(args, progress.Callback());
  progress.Finish();
  if (global.json) {
    PrintJson(r.ToJson(args));
    return;
  }
  if (r.mapping && !global.quiet) PrintMapping(*r.mapping);
  std::printf("map %s: %lld frames painted (%lld without a pose), %lld tiles (%lld at level 0), a place index of "
              "%lld features",
              args.out.string().c_str(), static_cast<long long>(r.painted), static_cast<long long>(r.without_pose),
              static_cast<long long>(r.tiles), static_cast<long long>(r.level0_tiles),
              static_cast<long long>(r.place_features));
  if (r.resumed_after > 0) {
    std::printf("; resumed after %lld of %lld frames", static_cast<long long>(r.resumed_after),
                static_cast<long long>(r.frames));
  }
  std::printf("\n");
}

void Info(const MapArgs& args, const GlobalOptions& global) {
  const runtime::MapInfo info = runtime::InspectMap(args.map);
  const mosaic::MapGrid& grid = info.grid;
  if (global.json) {
    PrintJson(info.ToJson(args.map));
    return;
  }
  std::printf("map %s: format %d, %.4g mm/px, tiles of %d px, %d levels, %lld tiles, %.1f MiB on disk\n",
              args.map.string().c_str(), mosaic::kMapFormatVersion, grid.mm_per_px, grid.tile_size_px, grid.levels,
              static_cast<long long>(info.tiles), static_cast<double>(info.bytes_on_disk) / (1 << 20));
  if (const std::vector<double>& e = info.extent_mm; !e.empty()) {
    std::printf("  extent x %.1f .. %.1f mm, y %.1f .. %.1f mm (%.0f x %.0f px at level 0)\n", e[0], e[2], e[1], e[3],
                (e[2] - e[0]) / grid.mm_per_px, (e[3] - e[1]) / grid.mm_per_px);
  }
  for (int k = 0; k < grid.levels; ++k) {
    std::printf("  level %d: %.4g mm/px, %lld tiles\n", k, grid.LevelMmPerPx(k),
                static_cast<long long>(info.tiles_per_level[k]));
  }
  if (info.places) {
    std::printf("  place index: %lld features (%s, level %d) in %lld cells, %.1f MiB\n",
                static_cast<long long>(info.places->bytes / static_cast<std::int64_t>(tracking::kPlaceRecordBytes)),
                info.places->method.c_str(), info.places->level, static_cast<long long>(info.places->cells),
                static_cast<double>(info.places->bytes) / (1 << 20));
    if (const auto test = runtime::FloorRepeatTest::Of(*info.places)) std::printf("  floor: %s\n", test->Describe().c_str());
  } else {
    std::printf("  place index: none (global relocalization needs one: mosaicloc map index %s)\n",
                args.map.string().c_str());
  }
  if (info.updates > 0) {
    std::printf("  history: %lld recorded updates, %lld in force (mosaicloc map history %s)\n",
                static_cast<long long>(info.updates), static_cast<long long>(info.updates_in_force),
                args.map.string().c_str());
  }
  if (info.quality) {
    std::printf("  quality layer: %lld cells (tiles of level %d): mosaicloc map quality %s --out DIR\n",
                static_cast<long long>(info.quality->cells), info.quality->level, args.map.string().c_str());
  } else {
    std::printf("  quality layer: none (mosaicloc map quality %s --out DIR computes it)\n", args.map.string().c_str());
  }
}

void Index(const MapArgs& args, const GlobalOptions& global) {
  ProgressBar progress("map index", global.quiet, "the map and its place index are as they were");
  const runtime::MapIndexSummary r = runtime::IndexMap(args.map, progress.Callback());
  progress.Finish();
  if (global.json) {
    PrintJson(r.ToJson(args.map));
    return;
  }
  std::printf("%s: place index of %lld features in %lld cells, %.1f MiB, built in %.1f s\n", args.map.string().c_str(),
              static_cast<long long>(r.features), static_cast<long long>(r.cells),
              static_cast<double>(r.bytes) / (1 << 20), r.seconds);
  std::printf("  floor: %s; %.1f s\n", r.repeat_test.Describe().c_str(), r.repeat_test.seconds);
}

void Quality(const runtime::MapQualityJob& job, const GlobalOptions& global) {
  ProgressBar progress("map quality", global.quiet, "the map and its quality layer are as they were; nothing was written");
  const runtime::MapQualitySummary r = runtime::MapQuality(job, progress.Callback());
  progress.Finish();
  if (global.json) {
    PrintJson(r.json);
    return;
  }
  std::printf("%s: %lld cells of %.0f mm judged%s; %lld weak (%lld with little texture, %lld where the floor repeats) "
              "in %zu stretches; %lld at lanes' edges not judged in full\n",
              job.map.string().c_str(), static_cast<long long>(r.judged), r.cell_mm,
              r.computed ? fmt::format(" (computed in {:.1f} s and stored in the map)", r.seconds).c_str() : "",
              static_cast<long long>(r.weak_cells), static_cast<long long>(r.weak_texture),
              static_cast<long long>(r.repeating), r.stretches.size(), static_cast<long long>(r.unsearched));
  const std::size_t shown = std::min<std::size_t>(r.stretches.size(), 10);
  for (std::size_t i = 0; i < shown; ++i) {
    const runtime::WeakStretch& s = r.stretches[i];
    std::printf("  %2zu. %4lld cells around (%.0f, %.0f) mm, x %.0f..%.0f y %.0f..%.0f: %s\n", i + 1,
                static_cast<long long>(s.cells), s.centre_x_mm, s.centre_y_mm, s.x0_mm, s.x1_mm, s.y0_mm, s.y1_mm,
                s.reason.c_str());
  }
  if (r.stretches.size() > shown) std::printf("  ... %zu more in weak.csv\n", r.stretches.size() - shown);
  std::printf("written: %s (quality.png, weak.csv, quality.json)\n", job.out.string().c_str());
}

void Check(const MapArgs& args, const GlobalOptions& global) {
  ProgressBar progress("map check", global.quiet, "the tiles checked so far were intact");
  std::size_t tiles = 0;
  const std::vector<std::string> problems = runtime::CheckMap(args.map, &tiles, progress.Callback());
  progress.Finish();
  if (global.json) {
    const nlohmann::json result = {{"map", args.map.string()}, {"tiles", tiles}, {"damaged", problems}};
    PrintJson(result);
  }
  if (!problems.empty()) {
    std::string message = std::to_string(problems.size()) + " of " + std::to_string(tiles) + " tiles damaged:";
    for (const auto& problem : problems) message += "\n  " + problem;
    core::ThrowInvalidInput(message);
  }
  if (!global.json) std::printf("%s: all %zu tiles intact\n", args.map.string().c_str(), tiles);
}

void History(const MapArgs& args, const GlobalOptions& global) {
  const std::vector<mosaic::MapUpdate> history = runtime::MapHistory(args.map);
  if (global.json) {
    PrintJson(runtime::MapHistoryJson(args.map, history));
    return;
  }
  if (history.empty()) {
    std::printf("%s: no recorded updates (automatic mapping and map updates record theirs)\n", args.map.string().c_str());
    return;
  }
  std::printf("%s: %zu recorded updates\n", args.map.string().c_str(), history.size());
  for (const mosaic::MapUpdate& u : history) {
    std::printf("  %4lld  %s  %3lld tiles  %s%s\n", static_cast<long long>(u.id), u.time.c_str(),
                static_cast<long long>(u.tiles), u.reason.c_str(),
                u.reverted.empty() ? "" : fmt::format("  [reverted {}]", u.reverted).c_str());
  }
}

void Revert(const MapArgs& args, const GlobalOptions& global) {
  const runtime::MapRevertSummary r = runtime::RevertMapUpdate(args.map, args.update_id);
  if (global.json) {
    PrintJson(r.ToJson(args.map));
    return;
  }
  std::printf("%s: update %lld reverted (%s): %lld tiles restored, %lld removed%s\n", args.map.string().c_str(),
              static_cast<long long>(r.revert.id), r.revert.reason.c_str(), static_cast<long long>(r.revert.restored),
              static_cast<long long>(r.revert.removed),
              r.reindexed || r.reassessed ? "; place index and quality layer rebuilt" : "");
}

void Export(const runtime::MapExportOptions& args, const GlobalOptions& global) {
  const runtime::MapExportSummary r = runtime::ExportMap(args);
  if (!global.quiet) {
    std::printf("%s: level %d (%.4g mm/px), %lld x %lld px%s\n", args.out.string().c_str(), r.level, r.mm_per_px,
                static_cast<long long>(r.cols), static_cast<long long>(r.rows),
                r.damaged ? " (damaged tiles left black)" : "");
  }
}

}  // namespace

Action AddMapCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<MapArgs>();
  CLI::App* command = app.add_subcommand("map", "Build and inspect mosaic maps");
  command->require_subcommand(1);
  CLI::App* build = command->add_subcommand("build", "Paint a dataset's frames at their poses into a new map");
  build->add_option("--dataset", args->build.dataset, "Dataset directory")->required();
  build->add_option("--out", args->build.out, "Map file to write (*.mosaic)")->required();
  build->add_option("--poses", args->build.poses,
                    "'estimate' (default: from the frames and encoders alone, loops closed, a pose graph solved), "
                    "'groundtruth' or a TUM trajectory of world_from_vehicle");
  build->add_option("--report", args->build.report, "With --poses estimate (the default): write the consistency report here");
  build->add_option("--join", args->build.joined,
                    "A later drive over the same site to paint into the map too (repeatable): with --poses estimate "
                    "mapped with the first, starting where its dataset says, joined by loop closures")
      ->take_all();
  build->add_option("--join-sigma-mm", args->build.join_start_sigma_mm,
                    "How well a joined drive's start is known, mm (default 20): it sizes the search that joins it")
      ->check(CLI::PositiveNumber);
  build->add_flag("--flat-floor", args->build.flat_floor,
                  "With --poses estimate: take every frame to be at the calibrated height and straight down, without "
                  "estimating each frame's camera height and tilt from the registrations (on by default, and applied "
                  "only where the floor shows them)");
  build->add_option("--blend", args->build.blend, "feather (default) or best-view")
      ->check(CLI::IsMember({"feather", "best-view"}));
  build->add_option("--tile-size", args->build.tile_size_px, "Tile size in px, a power of two (default 256)")
      ->check(CLI::IsMember({32, 64, 128, 256, 512, 1024}));
  build->add_option("--levels", args->build.levels, "Pyramid levels (default 6)")->check(CLI::Range(1, 16));
  build->add_flag("--overwrite", args->build.overwrite, "Replace an existing map");
  build->add_flag("--resume", args->build.resume,
                  "Continue an interrupted build of the same arguments from its last checkpoint (MAP.checkpoint)");
  build->add_option("--checkpoint-s", args->build.checkpoint_s,
                    "Seconds between saves of the build's progress (default 10, and far enough apart that saving costs at most a tenth of the painting; 0: after every frame)");
  CLI::App* poses = command->add_subcommand(
      "poses", "Estimate a mapping drive's poses from its frames and encoders (no ground truth) and write them");
  poses->add_option("--dataset", args->poses.dataset, "Dataset directory")->required();
  poses->add_option("--out", args->poses.out, "TUM trajectory to write (world_from_vehicle at every frame)");
  poses->add_option("--report", args->poses.report, "Directory for the consistency report");
  poses->add_option("--join", args->poses.joined,
                    "A later drive over the same site, mapped with the first (repeatable); its trajectory goes to "
                    "OUT with .2, .3, ... before the extension")
      ->take_all();
  poses->add_option("--join-sigma-mm", args->poses.join_start_sigma_mm,
                    "How well a joined drive's start is known, mm (default 20): it sizes the search that joins it")
      ->check(CLI::PositiveNumber);
  poses->add_flag_callback("--flat-floor", [args] { args->poses.mapper.view_geometry = false; },
                  "Take every frame to be at the calibrated height and straight down, without estimating each "
                  "frame's camera height and tilt from the registrations (on by default, and applied only where the "
                  "floor shows them; view.csv in the report)");
  poses->add_option("--graph-out", args->poses.graph_out, "Write the pose graph in g2o's format (metres)");
  poses->add_option("--graph-in", args->poses.graph_in,
                    "Optimize this g2o pose graph of the drive's frames instead of registering them");
  CLI::App* info = command->add_subcommand("info", "Extent, resolution, levels, tiles and size of a map");
  info->add_option("MAP", args->map, "Map file")->required();
  CLI::App* check = command->add_subcommand(
      "check", "Verify every tile (CRC, PNG, size) and the place index's and quality layer's cells (CRC); exit 2 on damage");
  check->add_option("MAP", args->map, "Map file")->required();
  CLI::App* index = command->add_subcommand(
      "index", "Build (or rebuild) the map's place index, which global relocalization looks frames up in");
  index->add_option("MAP", args->map, "Map file")->required();
  CLI::App* quality = command->add_subcommand(
      "quality", "Where on the map fixes will be weak (little texture, floor that repeats), before a vehicle drives "
                 "there: quality.png, weak.csv, quality.json");
  quality->add_option("MAP", args->quality.map, "Map file")->required()->check(CLI::ExistingFile);
  quality->add_option("--out", args->quality.out, "Folder to write")->required();
  quality->add_flag("--rebuild", args->quality.rebuild, "Compute the map's quality layer again and store it");
  quality->add_option("--min-texture", args->quality.thresholds.min_texture,
                      "A cell with less texture than this is weak (default 4)")
      ->check(CLI::NonNegativeNumber);
  quality->add_option("--max-ambiguity", args->quality.thresholds.max_ambiguity,
                      "A cell whose floor matches this well elsewhere within 600 mm is weak (ZNCC, default 0.85)")
      ->check(CLI::Range(-1.0, 1.0));
  CLI::App* history = command->add_subcommand(
      "history", "The map's recorded updates (automatic mapping, map updates): when, why, how many tiles, reverted");
  history->add_option("MAP", args->map, "Map file")->required();
  CLI::App* revert = command->add_subcommand(
      "revert", "Undo a recorded update: its tiles as they were before it (a later update over them first)");
  revert->add_option("MAP", args->map, "Map file")->required();
  revert->add_option("ID", args->update_id, "The update's id (map history lists them)")->required()->check(CLI::PositiveNumber);
  CLI::App* export_command = command->add_subcommand("export", "Write a map level (or a region of it) as a PNG");
  export_command->add_option("MAP", args->export_.map, "Map file")->required();
  export_command->add_option("--out", args->export_.out, "PNG file to write")->required();
  export_command->add_option("--level", args->export_.level, "Pyramid level (default: the finest within 8192 px)")
      ->check(CLI::Range(0, 15));
  export_command->add_option("--region", args->export_.region, "x0,y0,x1,y1 in world mm");
  return [args, &global, build, poses, info, check, index, quality, history, revert, export_command] {
    if (index->parsed()) Index(*args, global);
    if (quality->parsed()) Quality(args->quality, global);
    if (build->parsed()) Build(args->build, global);
    if (poses->parsed()) Poses(args->poses, global);
    if (info->parsed()) Info(*args, global);
    if (check->parsed()) Check(*args, global);
    if (history->parsed()) History(*args, global);
    if (revert->parsed()) Revert(*args, global);
    if (export_command->parsed()) Export(args->export_, global);
  };
}

}  // namespace mosaicloc::app
