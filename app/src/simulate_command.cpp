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
  sim::SimulatorOverrides overrides;
  bool overwrite = false;
};

void Run(const SimulateArgs& args, const GlobalOptions& global) {
  const sim::SimulatorOptions options = sim::SimulatorOptionsFor(args.config, args.overrides);

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
  command->add_option("--floor", args->overrides.floor, "'procedural' (default) or an image file tiled over the floor");
  command->add_option("--floor-seed", args->overrides.floor_seed, "Procedural floor seed (separate from --seed)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--floor-mm-per-texel", args->overrides.floor_mm_per_texel,
                      "Floor texel size in mm (default 0.125 procedural, 0.25 image)")
      ->check(CLI::PositiveNumber);
  command->add_option("--route", args->overrides.route, "straight, loop (default), network or serpentine")
      ->check(CLI::IsMember({"straight", "loop", "network", "serpentine"}));
  auto* frames = command->add_option("--frames", args->overrides.frames, "Frames to capture (default 900)")
                     ->check(CLI::PositiveNumber);
  command->add_option("--laps", args->overrides.laps, "Complete laps to drive, whatever the speed")
      ->check(CLI::PositiveNumber)
      ->excludes(frames);
  command->add_option("--speed-mps", args->overrides.speed_mps, "Cruise speed, m/s (default 1)")->check(CLI::Range(0.001, 30.0));
  command->add_option("--seed", args->overrides.seed, "Seed of noise, path deviation, jitter and drops")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--threads", args->overrides.threads, "Rendering threads (output does not depend on it)")
      ->check(CLI::Range(1, 64));
  command->add_flag("--overwrite", args->overwrite, "Replace an existing dataset directory");
  return [args, &global] { Run(*args, global); };
}

}  // namespace mosaicloc::app
