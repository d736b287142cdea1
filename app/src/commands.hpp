#pragma once

#include <functional>

#include <CLI/CLI.hpp>

namespace mosaicloc::app {

/// Options every subcommand understands.
struct GlobalOptions {
  bool quiet = false;
  bool json = false;
  std::string log_level = "info";
};

/// Each Add*Command registers a subcommand and returns the action to run when it is chosen.
/// Actions print results to stdout (JSON with --json) and throw core::Error on failure.
using Action = std::function<void()>;
Action AddSimulateCommand(CLI::App& app, const GlobalOptions& global);
Action AddDatasetCommand(CLI::App& app, const GlobalOptions& global);
Action AddEvaluateCommand(CLI::App& app, const GlobalOptions& global);
Action AddReplayCommand(CLI::App& app, const GlobalOptions& global);
Action AddMapCommand(CLI::App& app, const GlobalOptions& global);
Action AddBenchCommand(CLI::App& app, const GlobalOptions& global);
Action AddRunCommand(CLI::App& app, const GlobalOptions& global);
Action AddPlcSimCommand(CLI::App& app, const GlobalOptions& global);
Action AddLimitsCommand(CLI::App& app, const GlobalOptions& global);
Action AddCalibrateCommand(CLI::App& app, const GlobalOptions& global);
Action AddLocateCommand(CLI::App& app, const GlobalOptions& global);
Action AddReportCommand(CLI::App& app, const GlobalOptions& global);
Action AddServeCommand(CLI::App& app, const GlobalOptions& global);

}  // namespace mosaicloc::app
