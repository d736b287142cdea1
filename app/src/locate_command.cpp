// mosaicloc locate: where on a map single frames were taken, without a prior (runtime/locate.hpp).
#include <algorithm>
#include <cstdio>
#include <memory>
#include <numbers>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "mosaicloc/runtime/localization_config.hpp"
#include "mosaicloc/runtime/locate.hpp"
#include "progress.hpp"
#include "report.hpp"

namespace mosaicloc::app {
Action AddLocateCommand(CLI::App& app, const GlobalOptions& global) {
  struct Args {
    runtime::LocateOptions options;
    std::filesystem::path config;
  };
  auto args = std::make_shared<Args>();
  CLI::App* command = app.add_subcommand(
      "locate", "Find where on a map frames were taken, from each frame alone (global relocalization)");
  command->add_option("--map", args->options.map, "Map file with a place index (mosaicloc map index)")->required();
  command->add_option("IMAGE", args->options.images, "Ideal frames (8-bit grey PNG at the map's resolution)");
  command->add_option("--dataset", args->options.dataset,
                      "Take the frames from a dataset instead; with its ground truth, each answer is checked");
  command->add_option("--every", args->options.every, "With --dataset: every k-th frame (default 1)")
      ->check(CLI::PositiveNumber);
  command->add_option("--max-frames", args->options.max_frames, "With --dataset: at most this many frames");
  command->add_option("--config", args->config, "Localizer configuration (tracker and relocalize.* keys)");
  command->add_option("--scale", args->options.scale,
                      "Image scale the frames were taken at (the camera's height over the calibrated one; default 1)");
  command->add_option("--wrong-mm", args->options.wrong_mm, "With ground truth: an answer this far off is wrong (default 1)");
  return [args, &global] {
    if (!args->config.empty()) args->options.settings = runtime::LoadLocalizerConfig(args->config);
    ProgressBar progress("locate", global.quiet || args->options.dataset.empty());
    const runtime::LocateSummary r = runtime::Locate(args->options, progress.Callback());
    progress.Finish();
    const double n = std::max<double>(1.0, static_cast<double>(r.frames.size()));
    if (global.json) {
      PrintJson(r.ToJson(args->options.map));
      return;
    }
    for (const runtime::LocatedFrame& f : r.frames) {
      if (f.outcome == "found") {
        std::printf("%s: x %.3f mm, y %.3f mm, yaw %.4f deg (sigma %.4f mm, ZNCC %.3f)%s\n", f.frame.c_str(),
                    f.world_from_camera.x_mm(), f.world_from_camera.y_mm(),
                    f.world_from_camera.yaw_rad() * 180.0 / std::numbers::pi, f.SigmaMm(), f.mean_zncc,
                    f.error_mm ? (" error " + std::to_string(*f.error_mm) + " mm").c_str() : "");
      } else if (!global.quiet) {
        std::printf("%s: %s: %s\n", f.frame.c_str(), f.outcome.c_str(), f.reason.c_str());
      }
    }
    std::printf("%zu frames: %d found (%.1f %%), %d ambiguous, %d without a place; %.1f ms p50, %.1f ms p99 per frame; "
                "index of %lld features, %.1f MiB in memory, loaded in %.2f s\n",
                r.frames.size(), r.found, 100.0 * r.found / n, r.ambiguous, r.no_match, r.ms_p50, r.ms_p99,
                static_cast<long long>(r.index_features),
                static_cast<double>(r.index_memory_bytes) / (1 << 20), r.index_load_s);
    if (r.checked > 0) {
      std::printf("against the ground truth: %d of %d within 0.05 mm, %d wrong (over %.3g mm)\n", r.within_0_05_mm,
                  r.checked, r.wrong, args->options.wrong_mm);
    }
  };
}

}  // namespace mosaicloc::app
