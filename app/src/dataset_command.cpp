#include <cstdio>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "report.hpp"
#include "mosaicloc/dataset/dataset.hpp"

namespace mosaicloc::app {

Action AddDatasetCommand(CLI::App& app, const GlobalOptions& global) {
  auto directory = std::make_shared<std::filesystem::path>();
  CLI::App* command = app.add_subcommand("dataset", "Inspect datasets");
  command->require_subcommand(1);
  CLI::App* check = command->add_subcommand("check", "Read every file and line of a dataset and report the first problem");
  check->add_option("DIR", *directory, "Dataset directory")->required();
  return [directory, &global] {
    const dataset::DatasetReader reader(*directory);
    const auto summary = reader.Validate();
    if (global.json) {
      const nlohmann::json result = {{"dataset", directory->string()},
                                     {"valid", true},
                                     {"frames", summary.frames},
                                     {"encoder_samples", summary.encoder_samples},
                                     {"groundtruth_poses", summary.groundtruth_poses},
                                     {"duration_s", summary.duration_s},
                                     {"skipped_frames", summary.skipped_frames},
                                     {"skipped_encoder_samples", summary.skipped_encoder_samples}};
      PrintJson(result);
    } else {
      std::printf("%s: %s\n", directory->string().c_str(), summary.Describe().c_str());
    }
  };
}

}  // namespace mosaicloc::app
