// mosaicloc: floor-texture localization for AGVs. One program, one subcommand per job.
#include <cstdio>
#include <exception>
#include <map>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/core/stop_signals.hpp"

namespace {

// Exit codes: 0 success, 2 bad usage or input, 1 runtime failure (design.md section 5).
constexpr int kExitRuntime = 1;
constexpr int kExitBadInput = 2;

}  // namespace

int main(int argc, char** argv) {
  using namespace mosaicloc;
  CLI::App app{"mosaicloc: localize a vehicle to a fraction of a millimetre over a mosaic of its floor"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "mosaicloc 0.1.0");
  app::GlobalOptions global;
  app.add_flag("-q,--quiet", global.quiet, "No progress bars or log messages below warnings")->configurable(false);
  app.add_flag("--json", global.json, "Print the result as JSON on standard output");
  app.add_option("--log-level", global.log_level, "debug, info, warning, error or off")
      ->check(CLI::IsMember({"debug", "info", "warning", "error", "off"}));

  std::map<CLI::App*, app::Action> actions;
  const auto add = [&](app::Action (*adder)(CLI::App&, const app::GlobalOptions&)) {
    app::Action action = adder(app, global);
    actions[app.get_subcommands({}).back()] = std::move(action);
  };
  add(app::AddSimulateCommand);
  add(app::AddDatasetCommand);
  add(app::AddEvaluateCommand);
  add(app::AddReplayCommand);
  add(app::AddMapCommand);
  add(app::AddLocateCommand);
  add(app::AddReportCommand);
  add(app::AddServeCommand);
  add(app::AddBenchCommand);
  add(app::AddRunCommand);
  add(app::AddPlcSimCommand);
  add(app::AddLimitsCommand);
  add(app::AddCalibrateCommand);

  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --help-all, --version
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "mosaicloc: %s\nRun with --help for usage.\n", e.what());
    return kExitBadInput;
  }

  try {
    core::SetLogLevel(global.quiet ? core::LogLevel::kWarning : core::ParseLogLevel(global.log_level));
    for (CLI::App* chosen : app.get_subcommands()) actions.at(chosen)();
  } catch (const core::Stopped& e) {
    std::fprintf(stderr, "mosaicloc: %s\n", e.what());
    return 128 + e.signal();
  } catch (const core::Error& e) {
    std::fprintf(stderr, "mosaicloc: %s\n", e.what());
    return e.kind() == core::ErrorKind::kInvalidInput ? kExitBadInput : kExitRuntime;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mosaicloc: unexpected failure: %s\n", e.what());
    return kExitRuntime;
  }
  return 0;
}
