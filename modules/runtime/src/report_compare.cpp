#include "mosaicloc/runtime/report_compare.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <unordered_map>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::runtime {
namespace {

nlohmann::ordered_json ReadMetrics(const std::filesystem::path& directory) {
  const std::filesystem::path file = directory / "metrics.json";
  std::ifstream in(file);
  if (!in) core::ThrowInvalidInput(file.string() + ": cannot open (not a replay report?)");
  try {
    nlohmann::ordered_json json = nlohmann::ordered_json::parse(in);
    if (!json.is_object()) core::ThrowInvalidInput(file.string() + ": not a JSON object");
    return json;
  } catch (const nlohmann::json::exception& error) {
    core::ThrowInvalidInput(file.string() + ": not JSON (" + error.what() + ")");
  }
}

}  // namespace

ReportComparison CompareReports(const std::filesystem::path& a, const std::filesystem::path& b, int top) {
  const nlohmann::ordered_json ma = ReadMetrics(a), mb = ReadMetrics(b);
  ReportComparison comparison;
  const auto add = [&](const std::string& key) {
    FigureComparison figure;
    figure.key = key;
    figure.a = ma.contains(key) ? nlohmann::json(ma[key]) : nlohmann::json();
    figure.b = mb.contains(key) ? nlohmann::json(mb[key]) : nlohmann::json();
    if (figure.a.is_number() && figure.b.is_number()) figure.difference = figure.b.get<double>() - figure.a.get<double>();
    comparison.figures.push_back(std::move(figure));
  };
  for (const auto& [key, value] : ma.items()) add(key);
  for (const auto& [key, value] : mb.items()) {
    if (!ma.contains(key)) add(key);
  }

  const std::vector<dataset::FrameReport> ra = dataset::ReadFixesCsv(a / "fixes.csv");
  const std::vector<dataset::FrameReport> rb = dataset::ReadFixesCsv(b / "fixes.csv");
  std::unordered_map<std::int64_t, std::size_t> in_b;
  for (std::size_t i = 0; i < rb.size(); ++i) in_b[rb[i].time.nanoseconds()] = i;
  std::vector<FrameDifference> differences;
  double sum_sq = 0.0;
  for (const dataset::FrameReport& frame : ra) {
    const auto found = in_b.find(frame.time.nanoseconds());
    if (found == in_b.end()) {
      ++comparison.only_a;
      continue;
    }
    const dataset::FrameReport& other = rb[found->second];
    ++comparison.common_frames;
    if (frame.fixed && !other.fixed) ++comparison.fixed_only_a;
    if (!frame.fixed && other.fixed) ++comparison.fixed_only_b;
    const double distance = core::Distance(frame.world_from_vehicle, other.world_from_vehicle);
    sum_sq += distance * distance;
    differences.push_back({frame, other, distance});
  }
  comparison.only_b = static_cast<std::int64_t>(rb.size()) - comparison.common_frames;
  if (comparison.common_frames > 0) {
    comparison.position_difference_rms_mm = std::sqrt(sum_sq / static_cast<double>(comparison.common_frames));
  }
  const auto larger = [](const FrameDifference& x, const FrameDifference& y) { return x.distance_mm > y.distance_mm; };
  const std::size_t keep = std::min(differences.size(), static_cast<std::size_t>(std::max(top, 0)));
  std::partial_sort(differences.begin(), differences.begin() + static_cast<std::ptrdiff_t>(keep), differences.end(),
                    larger);
  differences.resize(keep);
  std::erase_if(differences, [](const FrameDifference& d) { return d.distance_mm == 0.0; });
  comparison.largest = std::move(differences);
  return comparison;
}

}  // namespace mosaicloc::runtime
