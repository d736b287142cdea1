// mosaicloc limits: the speed limits of a camera setup (the founding paper's section 2.2
// analysis), so an integrator can choose frame rate, exposure and field of view for a speed.
#include <cstdio>
#include <optional>

#include "commands.hpp"
#include "mosaicloc/runtime/speed_limits_report.hpp"
#include "report.hpp"

namespace mosaicloc::app {

Action AddLimitsCommand(CLI::App& app, const GlobalOptions& global) {
  struct Args {
    std::filesystem::path config;
    std::optional<double> speed_mps;
  };
  auto args = std::make_shared<Args>();
  CLI::App* command = app.add_subcommand(
      "limits", "Speed limits of a camera setup: overlap, distortion, blur, prediction, and the instability ratio");
  command->add_option("--config", args->config, "Setup YAML (see config/default/limits.yaml); defaults without it")
      ->check(CLI::ExistingFile);
  command->add_option("--speed-mps", args->speed_mps, "Speed for the per-frame figures, m/s (overrides speed_mps)")
      ->check(CLI::Range(0.0, 1000.0));
  return [args, &global] {
    const runtime::SpeedLimitsReport report = runtime::AnalyseSpeedLimits(args->config, args->speed_mps);
    if (global.json) {
      PrintJson(report.ToJson());
    } else {
      std::fputs(report.Text().c_str(), stdout);
    }
  };
}

}  // namespace mosaicloc::app
