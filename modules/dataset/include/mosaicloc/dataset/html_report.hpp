#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace mosaicloc::dataset {

/// What index.html says about where a report came from.
struct HtmlReportInputs {
  std::string title;
  /// Lines of "what: value" (the dataset, the map, the mode, the command), in order.
  std::vector<std::pair<std::string, std::string>> about;
  /// The configuration that produced the report (a YAML file's text); empty: the built-in
  /// defaults.
  std::string configuration;
};

/// Writes REPORT/index.html (atomic): one page to share, that needs nothing but the report
/// directory (no network, no script from elsewhere). The summary table of the main figures,
/// every figure of metrics.json, the plots present in the directory (shown from beside the
/// page), where the report came from and the configuration. Reads `directory`/metrics.json;
/// throws core::Error when it is missing or not JSON.
void WriteHtmlReport(const std::filesystem::path& directory, const HtmlReportInputs& inputs);

/// The plots a report directory may hold, in the order index.html shows them, with a caption.
const std::vector<std::pair<std::string, std::string>>& ReportPlots();

}  // namespace mosaicloc::dataset
