// mosaicloc bench registration: our registration against its peers on the same pairs, in one
// run, on one core. mosaicloc bench soak: a long simulated drive localized in one process.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

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
      // A soak runs for hours: its progress goes to standard error even with --json (the
      // figures go to standard output), unless --quiet.
      ProgressBar progress("soak", global.quiet);
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
      PrintJson(runtime::RegistrationBenchJson(rows));
    } else {
      std::fputs(runtime::RegistrationBenchText(*args, rows).c_str(), stdout);
    }
  };
}

}  // namespace mosaicloc::app
