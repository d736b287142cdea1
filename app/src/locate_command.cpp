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
    nlohmann::json frames = nlohmann::json::array();
    for (const runtime::LocatedFrame& f : r.frames) {
      nlohmann::json j = {{"frame", f.frame}, {"outcome", f.outcome}, {"candidates", f.candidates},
                          {"milliseconds", f.milliseconds}};
      if (f.outcome == "found") {
        j["x_mm"] = f.world_from_camera.x_mm();
        j["y_mm"] = f.world_from_camera.y_mm();
        j["yaw_rad"] = f.world_from_camera.yaw_rad();
        j["sigma_mm"] = std::sqrt(std::max(f.covariance(0, 0), f.covariance(1, 1)));
        j["zncc"] = f.mean_zncc;
        j["templates"] = f.inliers;
      } else {
        j["reason"] = f.reason;
      }
      if (f.error_mm) j["error_mm"] = *f.error_mm;
      frames.push_back(std::move(j));
    }
    const double n = std::max<double>(1.0, static_cast<double>(r.frames.size()));
    if (global.json) {
      nlohmann::json result = {{"map", args->options.map.string()},
                               {"frames", r.frames.size()},
                               {"found", r.found},
                               {"ambiguous", r.ambiguous},
                               {"no_match", r.no_match},
                               {"ms_p50", r.ms_p50},
                               {"ms_p99", r.ms_p99},
                               {"ms_max", r.ms_max},
                               {"index_features", r.index_features},
                               {"index_memory_bytes", r.index_memory_bytes},
                               {"index_load_s", r.index_load_s},
                               {"located", frames}};
      if (r.checked > 0) {
        result["checked"] = r.checked;
        result["within_0_05_mm"] = r.within_0_05_mm;
        result["wrong"] = r.wrong;
      }
      PrintJson(result);
      return;
    }
    for (const auto& j : frames) {
      if (j["outcome"] == "found") {
        std::printf("%s: x %.3f mm, y %.3f mm, yaw %.4f deg (sigma %.4f mm, ZNCC %.3f)%s\n",
                    j["frame"].get<std::string>().c_str(), j["x_mm"].get<double>(), j["y_mm"].get<double>(),
                    j["yaw_rad"].get<double>() * 180.0 / std::numbers::pi, j["sigma_mm"].get<double>(),
                    j["zncc"].get<double>(),
                    j.contains("error_mm") ? (" error " + std::to_string(j["error_mm"].get<double>()) + " mm").c_str()
                                           : "");
      } else if (!global.quiet) {
        std::printf("%s: %s: %s\n", j["frame"].get<std::string>().c_str(), j["outcome"].get<std::string>().c_str(),
                    j["reason"].get<std::string>().c_str());
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
