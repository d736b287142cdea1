#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "report.hpp"
#include "mosaicloc/sim/simulator.hpp"
#include "progress.hpp"
#include "mosaicloc/sim/config.hpp"

namespace mosaicloc::app {
namespace {

struct SimulateArgs {
  std::filesystem::path out;
  std::filesystem::path config;
  std::string floor;
  std::int64_t floor_seed = -1;
  double floor_mm_per_texel = 0.0;
  std::string route;
  std::int64_t frames = 0;
  int laps = 0;
  double speed_mps = 0.0;
  std::int64_t seed = -1;
  int threads = 0;
  bool overwrite = false;
};

void Run(const SimulateArgs& args, const GlobalOptions& global) {
  sim::SimulatorOptions options = args.config.empty() ? sim::SimulatorOptions{} : sim::LoadSimulatorConfig(args.config);
  if (!args.floor.empty()) options.floor = sim::FloorChoice::Named(args.floor, options.floor);
  if (args.floor_seed >= 0) options.floor.seed = static_cast<std::uint64_t>(args.floor_seed);
  if (args.floor_mm_per_texel > 0.0) options.floor.mm_per_texel = args.floor_mm_per_texel;
  if (!args.route.empty()) options.route.name = args.route;
  if (args.frames > 0) {
    options.frames = args.frames;
    options.laps = 0;
  }
  if (args.laps > 0) options.laps = args.laps;
  if (args.speed_mps > 0.0) options.route.speed_mps = args.speed_mps;
  if (args.seed >= 0) options.seed = static_cast<std::uint64_t>(args.seed);
  if (args.threads > 0) options.threads = args.threads;

  ProgressBar progress("simulate", global.quiet, "no dataset was written");
  const sim::SimulationSummary summary =
      sim::Simulate(options, args.out, args.overwrite, progress.Callback());
  progress.Finish();

  if (global.json) {
    const nlohmann::json result = {{"dataset", std::filesystem::absolute(args.out).string()},
                                   {"frames", summary.frames_written},
                                   {"frames_dropped", summary.frames_dropped},
                                   {"encoder_samples", summary.encoder_samples},
                                   {"duration_s", summary.duration_s},
                                   {"path_length_m", summary.path_length_m},
                                   {"lap_length_m", summary.lap_length_m},
                                   {"laps_driven", summary.laps_driven},
                                   {"max_speed_mps", summary.max_speed_mps}};
    PrintJson(result);
  } else {
    std::printf("dataset %s: %lld frames (%lld dropped), %lld encoder samples, %.1f s, %.2f m driven"
                " (%.2f laps of %.2f m), top speed %.2f m/s\n",
                args.out.string().c_str(), static_cast<long long>(summary.frames_written),
                static_cast<long long>(summary.frames_dropped), static_cast<long long>(summary.encoder_samples),
                summary.duration_s, summary.path_length_m, summary.laps_driven,
                summary.lap_length_m, summary.max_speed_mps);
  }
}

}  // namespace

Action AddSimulateCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* command = app.add_subcommand("simulate", "Simulate a vehicle driving over a floor and write a dataset");
  command->add_option("--out", args->out, "Dataset directory to write")->required();
  command->add_option("--config", args->config, "Simulator configuration (see config/default/simulator.yaml)")
      ->check(CLI::ExistingFile);
  command->add_option("--floor", args->floor, "'procedural' (default) or an image file tiled over the floor");
  command->add_option("--floor-seed", args->floor_seed, "Procedural floor seed (separate from --seed)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--floor-mm-per-texel", args->floor_mm_per_texel,
                      "Floor texel size in mm (default 0.125 procedural, 0.25 image)")
      ->check(CLI::PositiveNumber);
  command->add_option("--route", args->route, "straight, loop (default), network or serpentine")
      ->check(CLI::IsMember({"straight", "loop", "network", "serpentine"}));
  auto* frames = command->add_option("--frames", args->frames, "Frames to capture (default 900)")
                     ->check(CLI::PositiveNumber);
  command->add_option("--laps", args->laps, "Complete laps to drive, whatever the speed")
      ->check(CLI::PositiveNumber)
      ->excludes(frames);
  command->add_option("--speed-mps", args->speed_mps, "Cruise speed, m/s (default 1)")->check(CLI::Range(0.001, 30.0));
  command->add_option("--seed", args->seed, "Seed of noise, path deviation, jitter and drops")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--threads", args->threads, "Rendering threads (output does not depend on it)")
      ->check(CLI::Range(1, 64));
  command->add_flag("--overwrite", args->overwrite, "Replace an existing dataset directory");
  return [args, &global] { Run(*args, global); };
}

}  // namespace mosaicloc::app
