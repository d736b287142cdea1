// mosaicloc run: loads the run configuration, opens the camera source, and runs
// runtime::LiveRun, printing its status lines and summary; SIGINT and SIGTERM stop it.

#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "mosaicloc/core/stop_signals.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/runtime/live_run.hpp"
#include "mosaicloc/runtime/map_keeping.hpp"
#include "mosaicloc/runtime/run_config.hpp"

namespace mosaicloc::app {
namespace {

// A status line of the live run, as JSON or as text.
void PrintStatus(const nlohmann::json& line, bool json) {
  if (json) {
    std::printf("%s\n", line.dump().c_str());
  } else {
    std::printf("%7.1f s  %-8s  fixes %3lld/%-3lld frames  latency %5.2f ms  PLC %-7s rtt %5.2f ms  errors %lld  "
                "requests %lld/%lld  x %.2f y %.2f mm  yaw %.3f deg  scale %.4f\n",
                line["t_s"].get<double>(), line["lock"].get<std::string>().c_str(),
                line["fixes_per_s"].get<long long>(), line["frames_per_s"].get<long long>(),
                line["latency_p50_ms"].get<double>(), line["plc"].get<std::string>().c_str(),
                line["plc_round_trip_ms"].get<double>(), line["plc_errors"].get<long long>(),
                line["answered"].get<long long>(), line["requests"].get<long long>(), line["x_mm"].get<double>(),
                line["y_mm"].get<double>(), line["yaw_deg"].get<double>(), line["scale"].get<double>());
  }
  std::fflush(stdout);
}

struct RunArgs {
  std::filesystem::path config;
  std::filesystem::path record;
  double duration_s = 0.0;
  std::optional<double> start_unix_s;
  bool mapping = false;
};

void Run(const RunArgs& args, const GlobalOptions& global) {
  runtime::RunConfig config = runtime::LoadRunConfig(args.config);
  if (args.start_unix_s) config.dataset_start_unix_s = *args.start_unix_s;
  if (args.mapping) config.mapping = true;
  if (!args.record.empty() && std::filesystem::exists(args.record)) {
    core::ThrowInvalidInput("run: --record " + args.record.string() + " exists; give a new directory");
  }
  runtime::LiveSource source = runtime::OpenLiveSource(config);
  runtime::LiveRun run(config, std::move(source.frames), source.camera, source.vehicle, args.record);
  runtime::LiveRun::StatusCallback status;
  if (!global.quiet) status = [&global](const nlohmann::json& line) { PrintStatus(line, global.json); };
  const core::StopSignals signals;
  const nlohmann::json summary = run.Run(args.duration_s, status, &core::StopSignals::Reason);
  if (global.json) {
    // One JSON object per line: the status lines, then this summary.
    std::printf("%s\n", nlohmann::json{{"summary", summary}}.dump().c_str());
  } else {
    std::printf("stopped: %s\n", summary["stopped"].get<std::string>().c_str());
    std::printf("frames %lld, fixes %lld (%.1f %%), dropped %lld, lock losses %lld, image scale %.4f\n",
                summary["frames"].get<long long>(), summary["fixes"].get<long long>(),
                100.0 * summary["fix_rate"].get<double>(), summary["frames_dropped"].get<long long>(),
                summary["lock_losses"].get<long long>(), summary["scale"].get<double>());
    if (!summary["processing_p50_ms"].is_null()) {
      std::printf("per frame: processing %.2f ms p50, %.2f ms p99; capture to fix %.2f ms p50, %.2f ms p99\n",
                  summary["processing_p50_ms"].get<double>(), summary["processing_p99_ms"].get<double>(),
                  summary["latency_p50_ms"].get<double>(), summary["latency_p99_ms"].get<double>());
    }
    if (summary.contains("map_extension_tiles")) {
      std::printf("map kept: %lld stretches added (%lld tiles), %lld updates (%lld cells); %lld frames not mapped\n",
                  summary["map_extension_segments"].get<long long>(), summary["map_extension_tiles"].get<long long>(),
                  summary["map_updates"].get<long long>(), summary["map_update_cells"].get<long long>(),
                  summary["map_keeping_dropped"].get<long long>());
      if (summary["map_extension_overspeed_frames"].get<long long>() > 0) {
        std::printf("map kept: %lld frames off the map faster than the overlap speed limit (up to %.2f m/s)\n",
                    summary["map_extension_overspeed_frames"].get<long long>(),
                    summary["map_extension_speed_max_mps"].get<double>());
      }
    }
    std::printf("PLC: %lld requests, %lld answered, %lld fix writes, %lld read errors, %lld timeouts, "
                "%lld odometry outages\n",
                summary["requests"].get<long long>(), summary["answered"].get<long long>(),
                summary["fix_writes"].get<long long>(), summary["plc_read_errors"].get<long long>(),
                summary["plc_timeouts"].get<long long>(), summary["odometry_outages"].get<long long>());
    if (!args.record.empty()) {
      std::printf("recorded %s: validate with mosaicloc replay --dataset %s --map %s --out REPORT\n",
                  args.record.string().c_str(), args.record.string().c_str(), config.map.string().c_str());
    }
  }
  runtime::ThrowIfMapKeepingStopped("run", summary.value("map_keeping_failure", std::string()));
}

}  // namespace

Action AddRunCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* command = app.add_subcommand("run", "Localize live: camera + PLC link + map (stop with Ctrl-C)");
  command->add_option("--config", args->config, "Run configuration (see config/default/run.yaml)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--record", args->record,
                      "Write what the run saw (frames, encoder ticks, fixes) as a dataset to this new directory");
  command->add_option("--duration", args->duration_s, "Stop after this many seconds (default: until stopped)")
      ->check(CLI::PositiveNumber);
  command->add_option("--start-unix", args->start_unix_s,
                      "camera source dataset: start playing at this wall-clock time (seconds since the Unix "
                      "epoch), in step with a plc-sim given the same time (overrides camera.dataset.start_unix_s)")
      ->check(CLI::NonNegativeNumber);
  command->add_flag("--mapping", args->mapping,
                   "Keep the map as the vehicle drives: floor off the map added, floor that changed rewritten "
                   "(the configuration's mapping: true); the map is created empty when it does not exist");
  return [args, &global] { Run(*args, global); };
}

}  // namespace mosaicloc::app
