#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "mosaicloc/runtime/localization_config.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/runtime/map_keeping.hpp"
#include "mosaicloc/runtime/replay.hpp"
#include "progress.hpp"
#include "report.hpp"

namespace mosaicloc::app {
namespace {

struct ReplayArgs {
  std::filesystem::path dataset;
  std::filesystem::path map;
  std::filesystem::path out;
  std::filesystem::path config;
  std::string mode;  // empty: mosaic with --map, else an error
  std::optional<double> required_overlap;
  std::vector<double> start_offset;  // dx_mm, dy_mm, dyaw_deg in the start's vehicle frame
  std::vector<double> truth_from_map;  // x_mm, y_mm, yaw_deg of a built map in the truth's frame
  bool prefetch = false;             // load tiles ahead on the prefetcher's threads, as `run` does
  bool relocalize = false;           // the start is not to be trusted: relocalize without it
  bool unknown_start = false;
  double kidnap_at_s = -1.0;
  double until_s = -1.0;
  std::vector<double> kidnap_offset;  // dx_mm, dy_mm, dyaw_deg in the vehicle's frame
  bool kidnap_told = false;
  std::int64_t revisit_places = 200;
  bool mapping = false;  // automatic mapping: extend (or create) the map with the floor off it
};

void Run(const ReplayArgs& args, const GlobalOptions& global) {
  const std::string mode = args.mode.empty() ? (args.map.empty() ? "" : "mosaic") : args.mode;
  if (mode.empty()) {
    core::ThrowInvalidInput("replay: give --map MAP to localize, or --mode dead-reckoning or visual-odometry");
  }
  if (mode == "mosaic" && args.map.empty()) core::ThrowInvalidInput("replay: --mode mosaic needs --map MAP");
  runtime::ReplayOptions options;
  options.dataset = args.dataset;
  options.map = args.map;
  options.out = args.out;
  options.mode = *runtime::ParseReplayMode(mode);  // CLI11 checked the name
  // Dead reckoning has nothing to configure but the overlap the speed limit is quoted for.
  if (!args.config.empty() && options.mode != runtime::ReplayMode::kDeadReckoning) {
    options.settings = runtime::LoadLocalizerConfig(args.config);
    options.config_file = args.config;
  }
  if (args.required_overlap) options.settings.required_overlap = *args.required_overlap;
  if (!args.start_offset.empty()) {
    options.start_offset =
        core::Pose2(args.start_offset[0], args.start_offset[1], args.start_offset[2] * std::numbers::pi / 180.0);
  }
  if (!args.truth_from_map.empty()) {
    options.truth_from_map = core::Pose2(args.truth_from_map[0], args.truth_from_map[1],
                                         args.truth_from_map[2] * std::numbers::pi / 180.0);
  }
  options.relocalize = args.relocalize;
  options.unknown_start = args.unknown_start;
  if (args.kidnap_at_s >= 0.0) {
    if (args.kidnap_offset.size() != 3) core::ThrowInvalidInput("--kidnap-at-s needs --kidnap-offset DX,DY,DYAW");
    options.kidnap_at_s = args.kidnap_at_s;
    options.kidnap_offset = core::Pose2(args.kidnap_offset[0], args.kidnap_offset[1],
                                        args.kidnap_offset[2] * std::numbers::pi / 180.0);
    options.kidnap_told = args.kidnap_told;
  }
  if (args.until_s >= 0.0) {
    if (mode != "mosaic") core::ThrowInvalidInput("replay: --until-s is for the mosaic mode");
    options.until_s = args.until_s;
  }
  options.prefetch = args.prefetch;
  options.revisit_places = args.revisit_places;
  options.mapping = args.mapping;
  if (args.mapping && mode != "mosaic") core::ThrowInvalidInput("replay: --mapping needs --map MAP (the mosaic mode)");

  ProgressBar progress("replay", global.quiet,
                       args.mapping ? "the map keeps the floor added so far (map history lists it); no report was written"
                                    : "no report was written");
  const runtime::ReplaySummary summary = runtime::Replay(options, progress.Callback());
  progress.Finish();
  PrintMetrics(summary.report, summary.metrics, global.json);
  runtime::ThrowIfMapKeepingStopped("replay --mapping", summary.map_keeping_failure);
}

}  // namespace

Action AddReplayCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<ReplayArgs>();
  std::vector<std::string> modes;
  for (const runtime::ReplayMode mode : runtime::kReplayModes) modes.emplace_back(runtime::ToString(mode));
  CLI::App* command = app.add_subcommand("replay", "Localize a recorded or simulated dataset and write a report");
  command->add_option("--dataset", args->dataset, "Dataset directory")->required();
  command->add_option("--map", args->map, "Mosaic map (*.mosaic) to localize against");
  command->add_flag("--mapping", args->mapping,
                    "Automatic mapping: add the floor driven over off the map to it (written as the drive goes); "
                    "creates the map when it does not exist");
  command->add_option("--out", args->out, "Report directory")->required();
  command->add_option("--config", args->config, "Localizer configuration (see config/default/localizer.yaml)")
      ->check(CLI::ExistingFile);
  command->add_option("--mode", args->mode,
                      "mosaic (default with --map): localize against the map; "
                      "dead-reckoning: wheel odometry only (the baseline); "
                      "visual-odometry: frame to frame, no map")
      ->check(CLI::IsMember(modes));
  command->add_option("--required-overlap", args->required_overlap,
                      "Fraction of image overlap the tracker needs (beta of the overlap speed limit)")
      ->check(CLI::Range(0.0, 0.95));
  command->add_option("--start-offset", args->start_offset,
                      "mosaic mode: start this far from the true start, dx_mm,dy_mm,dyaw_deg in the vehicle "
                      "frame (a kidnapped vehicle; relocalization must find it)")
      ->delimiter(',')
      ->expected(3);
  command->add_option("--truth-from-map", args->truth_from_map,
                      "x_mm,y_mm,yaw_deg: where a map built from a drive's own frames and encoders lies in the "
                      "ground truth's frame (its mapping report's truth_from_map): the truth is taken into the "
                      "map's frame before the start is taken from it and the fixes are checked against it")
      ->delimiter(',')
      ->expected(3);
  command->add_flag("--relocalize", args->relocalize,
                    "mosaic mode: the start pose is not to be trusted (the vehicle was moved while switched off, "
                    "or the start is a guess): search the map around it and take the one place found, whatever "
                    "the start's uncertainty says");
  command->add_flag("--unknown-start", args->unknown_start,
                    "mosaic mode: the start pose is not known at all: search the whole map through its place index "
                    "until a frame is found (global relocalization)");
  command->add_option("--kidnap-at-s", args->kidnap_at_s,
                      "mosaic mode: this many seconds into the drive the vehicle is carried away unseen: the "
                      "estimate is moved by --kidnap-offset and held there confidently")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--until-s", args->until_s,
                      "mosaic mode: localize only the frames up to this many seconds into the drive")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--kidnap-offset", args->kidnap_offset,
                      "dx_mm,dy_mm,dyaw_deg of the kidnap in the vehicle's frame")
      ->delimiter(',')
      ->expected(3);
  command->add_option("--revisit-places", args->revisit_places,
                      "mosaic mode: at most this many places the drive passes again are registered frame to frame "
                      "for the repeatability without ground truth (0: none)")
      ->check(CLI::NonNegativeNumber);
  command->add_flag("--kidnap-told", args->kidnap_told,
                    "with --kidnap-at-s: the localizer is told its pose is unknown, as the PLC's relocalize request "
                    "tells it");
  command->add_flag("--prefetch", args->prefetch,
                    "mosaic mode: load the map's tiles ahead on threads of their own, as `run` does "
                    "(map.prefetch_horizon_s of the configuration); the estimates do not change");
  return [args, &global] { Run(*args, global); };
}

}  // namespace mosaicloc::app
