#include "commands.hpp"
#include "mosaicloc/dataset/trajectory.hpp"
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
    const dataset::Trajectory estimate = dataset::ReadTum(args->estimate);
    const dataset::Trajectory groundtruth = dataset::ReadTum(args->groundtruth);
    const dataset::Metrics metrics =
        runtime::WriteReport(args->out, estimate, groundtruth, dataset::Metrics{}, args->estimate.filename().string());
    PrintMetrics(args->out, metrics, global.json);
  };
}

}  // namespace mosaicloc::app
