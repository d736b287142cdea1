#include "commands.hpp"
#include "mosaicloc/runtime/report.hpp"
#include "report.hpp"

namespace mosaicloc::app {

Action AddEvaluateCommand(CLI::App& app, const GlobalOptions& global) {
  struct Args {
    std::filesystem::path estimate;
    std::filesystem::path groundtruth;
    std::filesystem::path out;
  };
  auto args = std::make_shared<Args>();
  CLI::App* command = app.add_subcommand("evaluate", "Compare an estimated trajectory with ground truth (TUM files)");
  command->add_option("--estimate", args->estimate, "Estimated trajectory, TUM")->required();
  command->add_option("--groundtruth", args->groundtruth, "Reference trajectory, TUM")->required();
  command->add_option("--out", args->out, "Report directory: metrics.json and plots")->required();
  return [args, &global] {
    PrintMetrics(args->out, runtime::EvaluateTrajectoryFiles(args->estimate, args->groundtruth, args->out),
                 global.json);
  };
}

}  // namespace mosaicloc::app
