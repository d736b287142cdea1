// mosaicloc bench registration: our registration against its peers on the same pairs, in one
// run, on one core. mosaicloc bench soak: a long simulated drive localized in one process.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "report.hpp"
#include "mosaicloc/runtime/registration_bench.hpp"
#include "mosaicloc/runtime/soak.hpp"
#include "progress.hpp"

namespace mosaicloc::app {

Action AddBenchCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<runtime::RegistrationBenchOptions>();
  CLI::App* bench = app.add_subcommand("bench", "Benchmarks that print figures (never pass/fail)");
  bench->require_subcommand(1);
  CLI::App* registration = bench->add_subcommand(
      "registration", "Register 640x480 pairs cut from real textures with mosaicloc and its peers; print the table");
  registration->add_option("--texture", args->textures, "Texture image(s), e.g. ../shared/data/textures/*")
      ->required()
      ->check(CLI::ExistingFile);
  registration->add_option("--pairs", args->pairs, "Pairs per texture")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  registration->add_option("--seed", args->seed, "Random seed")->capture_default_str();
  registration->add_option("--max-shift-px", args->max_shift_px, "Largest offset along each axis, px")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 32.0));
  registration->add_option("--max-rotation-deg", args->max_rotation_deg, "Largest rotation, degrees")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  registration->add_option("--max-scale", args->max_scale_change,
                           "Largest change of the camera's height, relative (0.03: 3 %); with --max-tilt-deg the live "
                           "view is a pinhole's")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.2));
  registration->add_option("--max-tilt-deg", args->max_tilt_deg, "Largest tilt of the live camera about each axis, degrees")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  registration->add_option("--noise", args->noise_dn, "Sensor noise standard deviation, DN")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 50.0));
  registration->add_option("--methods", args->methods,
                           "Only these: ours, ours-9x128, ours-tiled, ours-visp, ours-tilt, ours-observer, ecc, ecc-homography, phase, "
                           "visp (default all)")
      ->delimiter(',')
      ->check(CLI::IsMember(runtime::RegistrationBenchMethods()));
  registration->add_option("--failure-px", args->failure_px, "An error above this (px at the centre) is a failure")
      ->capture_default_str();
  registration->add_option("--failure-deg", args->failure_deg, "A rotation error above this is a failure")
      ->capture_default_str();

  auto soak_args = std::make_shared<runtime::SoakRequest>();
  CLI::App* soak = bench->add_subcommand(
      "soak", "A long simulated drive localized in one process (frames rendered as they are needed, none stored): "
              "lock losses, wrong fixes, latency, and memory, file descriptors and threads over time");
  soak->add_option("--frames", soak_args->frames, "Frames to localize")->capture_default_str()->check(CLI::PositiveNumber);
  soak->add_option("--floor", soak_args->floor, "'procedural' or a texture image")->capture_default_str();
  soak->add_option("--route", soak_args->route, "straight, loop, network or serpentine")
      ->capture_default_str()
      ->check(CLI::IsMember({"straight", "loop", "network", "serpentine"}));
  soak->add_option("--speed-mps", soak_args->speed_mps, "Cruise speed, m/s")->capture_default_str();
  soak->add_option("--seed", soak_args->seed, "Seed of the drive")->capture_default_str();
  soak->add_option("--config", soak_args->simulator_config, "Simulator configuration (simulator.yaml) of the drive: its conditions")
      ->check(CLI::ExistingFile);
  soak->add_option("--localizer", soak_args->localizer_config, "Localizer configuration")->check(CLI::ExistingFile);
  soak->add_option("--work", soak_args->work, "Where the mapping lap and the map are made (default: a new temporary folder)");
  soak->add_option("--map-laps", soak_args->map_laps,
                   "Laps of the route mapped (the network's second lap takes other lanes: with 1 the drive leaves "
                   "the map every other lap)")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  soak->add_option("--threads", soak_args->threads, "Rendering threads")->capture_default_str()->check(CLI::Range(1, 64));

  return [args, soak_args, soak, &global] {
    if (soak->parsed()) {
      const runtime::SoakOptions options = runtime::SoakOptionsFor(*soak_args);
      ProgressBar progress("soak", global.quiet || global.json);
      // A stop signal ends the drive with the figures of the frames localized so far.
      const runtime::SoakSummary r = runtime::RunSoak(options, progress.DrawCallback(), &core::StopSignals::Reason);
      progress.Finish();
      if (global.json) {
        PrintJson(runtime::SoakJson(r, options.work));
      } else {
        std::fputs(runtime::SoakText(r, options.work).c_str(), stdout);
      }
      if (!r.stopped.empty()) {
        throw core::Stopped(core::StopSignals::Signal(), "soak: " + r.stopped + " after " + std::to_string(r.frames) +
                                                             " frames: their figures are printed");
      }
      return;
    }
    ProgressBar progress("registering pairs", global.quiet || global.json);
    const std::vector<runtime::RegistrationBenchRow> rows =
        runtime::RunRegistrationBench(*args, progress.Callback());
    progress.Finish();
    if (global.json) {
      nlohmann::json out = nlohmann::json::array();
      const auto number = [](double value) { return std::isnan(value) ? nlohmann::json() : nlohmann::json(value); };
      for (const runtime::RegistrationBenchRow& r : rows) {
        out.push_back({{"method", r.method}, {"pairs", r.pairs}, {"failure_rate", number(r.failure_rate)},
                       {"rms_px", number(r.rms_px)}, {"max_px", number(r.max_px)}, {"rms_deg", number(r.rms_deg)},
                       {"max_deg", number(r.max_deg)}, {"mean_ms", number(r.mean_ms)}, {"p50_ms", number(r.p50_ms)},
                       {"time_vs_ecc", number(r.time_vs_ecc)}});
      }
      PrintJson(out);
      return;
    }
    std::printf("%zu texture(s) x %d pairs, 640x480, offsets up to +-%.1f px and +-%.1f deg, height +-%.1f %%, "
                "tilt +-%.2f deg, noise %.1f DN, gain +-%.0f %%, offset +-%.0f DN; failure = error > %.2f px or %.2f "
                "deg; one core\n\n",
                args->textures.size(), args->pairs, args->max_shift_px, args->max_rotation_deg,
                100.0 * args->max_scale_change, args->max_tilt_deg, args->noise_dn, 100.0 * args->max_gain_change,
                args->max_offset_dn, args->failure_px, args->failure_deg);
    std::printf("%-48s %8s %9s %9s %9s %9s %9s %9s %9s\n", "method", "failures", "rms px", "max px", "rms deg",
                "max deg", "mean ms", "p50 ms", "vs ECC");
    for (const runtime::RegistrationBenchRow& r : rows) {
      std::printf("%-48s %7.1f%% %9.4f %9.4f %9.4f %9.4f %9.2f %9.2f %8.2f%%\n", r.method.c_str(),
                  100.0 * r.failure_rate, r.rms_px, r.max_px, r.rms_deg, r.max_deg, r.mean_ms, r.p50_ms,
                  100.0 * r.time_vs_ecc);
    }
  };
}

}  // namespace mosaicloc::app
