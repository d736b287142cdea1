#include "mosaicloc/dataset/html_report.hpp"

#include <fstream>
#include <sstream>
#include <system_error>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"

namespace mosaicloc::dataset {
namespace {

std::string Escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

// A figure as the table shows it: numbers to four significant digits, counts per name inline.
std::string Shown(const nlohmann::json& value) {
  if (value.is_null()) return "n/a";
  if (value.is_number_float()) return fmt::format("{:.4g}", value.get<double>());
  if (value.is_object()) {
    std::string text;
    for (const auto& [name, count] : value.items()) text += (text.empty() ? "" : ", ") + name + " " + Shown(count);
    return text;
  }
  if (value.is_array()) {
    std::string text;
    for (const auto& element : value) text += (text.empty() ? "" : ", ") + Shown(element);
    return text;
  }
  return value.dump();
}

// The figures an integrator reads first, with what they mean.
const std::vector<std::pair<std::string, std::string>>& SummaryKeys() {
  static const std::vector<std::pair<std::string, std::string>> keys = {
      {"frames", "frames processed"},
      {"fix_rate", "share of frames with a visual fix"},
      {"wrong_fixes", "fixes more than 1 mm from the truth (n/a without one)"},
      {"lock_losses", "times the lock was lost"},
      {"frames_by_state", "frames per lock state"},
      {"fixes_by_state", "fixes per lock state"},
      {"frames_by_mode", "frames per mode"},
      {"fixes_by_mode", "fixes per mode"},
      {"no_fix_reasons", "frames without a fix, by reason"},
      {"revisit_repeatability_mm", "repeatability of the camera from revisits, without truth [mm]"},
      {"revisit_places", "revisited places it rests on"},
      {"repeatability_camera_mm", "the same against the truth [mm]"},
      {"repeatability_mm", "repeatability of the vehicle's origin against the truth [mm]"},
      {"position_rms_mm", "position error RMS against the truth [mm]"},
      {"nis_inside_95_share", "fixes inside the filter's 95 % bound (0.95 when consistent)"},
      {"nis_mean", "mean NIS (3 when the covariances are true)"},
      {"estimate_path_length_m", "path length [m]"},
      {"estimate_speed_mean_mps", "mean speed [m/s]"},
      {"estimate_speed_p99_mps", "speed, 99th percentile [m/s]"},
      {"overlap_speed_limit_mps", "overlap speed limit [m/s]"},
      {"processing_fps", "processing speed [frames/s]"},
      {"latency_p99_ms", "latency, 99th percentile [ms]"},
  };
  return keys;
}

}  // namespace

const std::vector<std::pair<std::string, std::string>>& ReportPlots() {
  static const std::vector<std::pair<std::string, std::string>> plots = {
      {"map_state.png", "The drive over the map, by lock state; frames without a fix crossed by reason."},
      {"map_quality.png", "The fixes over the map, by quality."},
      {"map_mode.png", "Every frame over the map, by what the localizer did: tracked the map, visual odometry off it, dead reckoning, searching."},
      {"timelines.png", "Fix quality, uncertainty, NIS against its bound, speed, latency, wheel scales."},
      {"trajectory.png", "Against the ground truth: the estimate coloured by its error."},
      {"position_error.png", "Position error against the ground truth."},
      {"heading_error.png", "Heading error against the ground truth."},
      {"height.png", "The camera's height held, against the truth."},
      {"map.png", "The map."},
  };
  return plots;
}

void WriteHtmlReport(const std::filesystem::path& directory, const HtmlReportInputs& inputs) {
  const std::filesystem::path metrics_file = directory / "metrics.json";
  std::ifstream in(metrics_file);
  if (!in) core::ThrowInvalidInput(metrics_file.string() + ": cannot open");
  nlohmann::json metrics;
  try {
    in >> metrics;
  } catch (const nlohmann::json::exception& error) {
    core::ThrowInvalidInput(metrics_file.string() + ": not JSON (" + error.what() + ")");
  }
  if (!metrics.is_object()) core::ThrowInvalidInput(metrics_file.string() + ": not a JSON object");

  std::ostringstream html;
  html << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" << Escape(inputs.title)
       << "</title>\n<style>\n"
       << "body{font-family:sans-serif;margin:2em;max-width:1100px;color:#222}"
       << "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}"
       << "th{background:#eee}td.v{font-family:monospace}img{max-width:100%;border:1px solid #ccc}"
       << "pre{background:#f6f6f6;padding:1em;overflow:auto}figure{margin:1.5em 0}.bad{color:#b00;font-weight:bold}\n"
       << "</style>\n</head>\n<body>\n<h1>" << Escape(inputs.title) << "</h1>\n";
  html << "<table id=\"about\">\n";
  for (const auto& [what, value] : inputs.about) {
    html << "<tr><th>" << Escape(what) << "</th><td>" << Escape(value) << "</td></tr>\n";
  }
  html << "</table>\n<h2>Summary</h2>\n<table id=\"summary\">\n<tr><th>figure</th><th>value</th><th>key</th></tr>\n";
  for (const auto& [key, meaning] : SummaryKeys()) {
    if (!metrics.contains(key)) continue;
    const nlohmann::json& value = metrics[key];
    if (key == "no_fix_reasons" && value.is_null()) {
      html << "<tr><td>" << Escape(meaning) << "</td><td class=\"v\">none</td><td>" << Escape(key) << "</td></tr>\n";
      continue;
    }
    const bool bad = key == "wrong_fixes" && value.is_number() && value.get<double>() > 0.0;
    html << "<tr><td>" << Escape(meaning) << "</td><td class=\"v" << (bad ? " bad" : "") << "\">"
         << Escape(Shown(value)) << "</td><td>" << Escape(key) << "</td></tr>\n";
  }
  // The filter's consistency in words: a covariance that understates the errors rejects good
  // fixes; one that overstates them is safe but gates loosely.
  if (metrics.contains("nis_inside_95_share") && metrics["nis_inside_95_share"].is_number()) {
    const double inside = metrics["nis_inside_95_share"].get<double>();
    const double mean = metrics.value("nis_mean", nlohmann::json(3.0)).is_number() ? metrics["nis_mean"].get<double>() : 3.0;
    const char* verdict = inside < 0.9    ? "understates the errors: good fixes will be rejected"
                          : mean < 1.0    ? "pessimistic: safe, but the gate admits more than it needs to"
                                          : "consistent with the innovations";
    html << "<tr><td>the filter's covariance</td><td class=\"v" << (inside < 0.9 ? " bad" : "") << "\">" << verdict
         << "</td><td>nis_*</td></tr>\n";
  }
  html << "</table>\n<h2>Plots</h2>\n";
  std::error_code ec;
  for (const auto& [file, caption] : ReportPlots()) {
    if (!std::filesystem::is_regular_file(directory / file, ec)) continue;
    html << "<figure><img src=\"" << Escape(file) << "\" alt=\"" << Escape(file) << "\"><figcaption>"
         << Escape(caption) << " (" << Escape(file) << ")</figcaption></figure>\n";
  }
  html << "<h2>Every figure (metrics.json)</h2>\n<table id=\"metrics\">\n";
  for (const auto& [key, value] : metrics.items()) {
    html << "<tr><td>" << Escape(key) << "</td><td class=\"v\">" << Escape(Shown(value)) << "</td></tr>\n";
  }
  html << "</table>\n<h2>Configuration</h2>\n<pre id=\"configuration\">"
       << Escape(inputs.configuration.empty() ? "(the built-in defaults)" : inputs.configuration) << "</pre>\n";
  // Marks on the page how many of its images loaded, for whoever checks it in a browser.
  html << "<script>\nwindow.addEventListener('load', function () {\n"
       << "  var images = document.images, loaded = 0;\n"
       << "  for (var i = 0; i < images.length; ++i) if (images[i].complete && images[i].naturalWidth > 0) ++loaded;\n"
       << "  document.body.setAttribute('data-images', String(images.length));\n"
       << "  document.body.setAttribute('data-images-loaded', String(loaded));\n"
       << "});\n</script>\n</body>\n</html>\n";
  core::WriteFileAtomically(directory / "index.html", html.str());
}

}  // namespace mosaicloc::dataset
