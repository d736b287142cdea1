#include "reports.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/fixes.hpp"

namespace mosaicloc::console::internal {
namespace fs = std::filesystem;

namespace {

nlohmann::json ReadJsonObject(const fs::path& file) {
  std::ifstream in(file);
  if (!in) core::ThrowInvalidInput(file.string() + ": cannot be opened");
  try {
    nlohmann::json json = nlohmann::json::parse(in);
    if (!json.is_object()) core::ThrowInvalidInput(file.string() + ": not a JSON object");
    return json;
  } catch (const nlohmann::json::exception& error) {
    core::ThrowInvalidInput(file.string() + ": not JSON (" + error.what() + ")");
  }
}

// Indices of `n` items to keep so that at most about `max_points` remain: every k-th, the
// last, and every item where `changed(i)` says something worth seeing begins.
template <typename Changed>
std::vector<std::size_t> Thinned(std::size_t n, std::size_t max_points, Changed changed) {
  const std::size_t step = std::max<std::size_t>(1, (n + max_points - 1) / std::max<std::size_t>(1, max_points));
  std::vector<std::size_t> keep;
  for (std::size_t i = 0; i < n; ++i) {
    if (i % step == 0 || i + 1 == n || (i > 0 && changed(i))) keep.push_back(i);
  }
  return keep;
}

// The fields of a CSV line (no quoting: the project's files never quote).
std::vector<std::string_view> Fields(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    if (comma == std::string_view::npos) return fields;
    start = comma + 1;
  }
}

template <typename T>
T Number(std::string_view text, const fs::path& file, int line, const char* what) {
  T value{};
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size()) {
    core::ThrowInvalidInput(file.string() + ":" + std::to_string(line) + ": " + what + " '" + std::string(text) +
                            "' is not a number");
  }
  return value;
}

ReportLayer ReplayLayer(const fs::path& folder, std::size_t max_points) {
  ReportLayer report;
  report.kind = "replay";
  const std::vector<dataset::FrameReport> rows = dataset::ReadFixesCsv(folder / "fixes.csv");
  const std::vector<std::size_t> keep = Thinned(rows.size(), max_points, [&](std::size_t i) {
    return rows[i].status != rows[i - 1].status || rows[i].fixed != rows[i - 1].fixed || rows[i].mode != rows[i - 1].mode;
  });
  // Columns: x_mm, y_mm, status, fix (0/1), quality 0..1000, sigma_mm.
  nlohmann::json points = nlohmann::json::array();
  for (const std::size_t i : keep) {
    const dataset::FrameReport& r = rows[i];
    points.push_back({std::round(r.world_from_vehicle.x_mm() * 1000.0) / 1000.0,
                      std::round(r.world_from_vehicle.y_mm() * 1000.0) / 1000.0, r.status, r.fixed ? 1 : 0,
                      static_cast<int>(std::lround(r.quality * 1000.0)), r.sigma_mm});
  }
  // With ground truth, the replay wrote each row's position error: a seventh column.
  const fs::path errors_file = folder / "errors.csv";
  const bool with_errors = fs::exists(errors_file);
  if (with_errors) {
    std::ifstream in(errors_file);
    std::string text;
    int line_number = 0;
    std::size_t row = 0, kept = 0;
    while (std::getline(in, text)) {
      ++line_number;
      if (text.empty() || text[0] == '#') continue;
      const std::vector<std::string_view> f = Fields(text);
      if (f.size() != 2 || row >= rows.size() ||
          Number<std::int64_t>(f[0], errors_file, line_number, "timestamp_ns") != rows[row].time.nanoseconds()) {
        core::ThrowInvalidInput(errors_file.string() + ":" + std::to_string(line_number) +
                                ": does not match fixes.csv's row " + std::to_string(row + 1) +
                                " (timestamp_ns,error_mm, one row per frame)");
      }
      if (kept < keep.size() && keep[kept] == row) {
        points[kept].push_back(f[1].empty() ? nlohmann::json(nullptr)
                                            : nlohmann::json(Number<double>(f[1], errors_file, line_number, "error_mm")));
        ++kept;
      }
      ++row;
    }
    if (row != rows.size()) {
      core::ThrowInvalidInput(errors_file.string() + ": " + std::to_string(row) + " rows for fixes.csv's " +
                              std::to_string(rows.size()));
    }
  }
  // The localizer's mode (fixes.csv written with the column): the last column.
  const bool with_modes =
      std::any_of(rows.begin(), rows.end(), [](const dataset::FrameReport& r) { return !r.mode.empty(); });
  if (with_modes) {
    for (std::size_t k = 0; k < keep.size(); ++k) points[k].push_back(rows[keep[k]].mode);
  }
  std::int64_t fixes = 0;
  for (const dataset::FrameReport& r : rows) fixes += r.fixed ? 1 : 0;
  nlohmann::json columns = {"x_mm", "y_mm", "status", "fix", "quality", "sigma_mm"};
  if (with_errors) columns.push_back("error_mm");
  if (with_modes) columns.push_back("mode");
  report.layer = {{"frames", rows.size()},
                  {"fixes", fixes},
                  {"columns", columns},
                  {"points", std::move(points)}};
  if (fs::exists(folder / "metrics.json")) report.layer["metrics"] = ReadJsonObject(folder / "metrics.json");
  return report;
}

ReportLayer MappingLayer(const fs::path& folder, std::size_t max_points) {
  ReportLayer report;
  report.kind = "mapping";
  const nlohmann::json consistency = ReadJsonObject(folder / "consistency.json");
  // path.csv: #frame,x_mm,y_mm,yaw_rad,worst_seam_px (frames with a pose).
  struct Row {
    int frame;
    double x, y, seam;
  };
  std::vector<Row> path;
  const fs::path path_file = folder / "path.csv";
  std::ifstream in(path_file);
  if (!in) {
    core::ThrowInvalidInput(path_file.string() +
                            ": cannot be opened (a mapping report from before it was written: build the map again)");
  }
  std::string text;
  int line_number = 0;
  while (std::getline(in, text)) {
    ++line_number;
    if (text.empty() || text[0] == '#') continue;
    const std::vector<std::string_view> f = Fields(text);
    if (f.size() != 5) {
      core::ThrowInvalidInput(path_file.string() + ":" + std::to_string(line_number) + ": expected 5 fields, found " +
                              std::to_string(f.size()));
    }
    path.push_back({Number<int>(f[0], path_file, line_number, "frame"),
                    Number<double>(f[1], path_file, line_number, "x_mm"),
                    Number<double>(f[2], path_file, line_number, "y_mm"),
                    Number<double>(f[4], path_file, line_number, "worst_seam_px")});
    if (path.size() > 1 && path.back().frame <= path[path.size() - 2].frame) {
      core::ThrowInvalidInput(path_file.string() + ":" + std::to_string(line_number) + ": frames must increase");
    }
  }
  const std::vector<std::size_t> keep = Thinned(path.size(), max_points, [](std::size_t) { return false; });
  nlohmann::json points = nlohmann::json::array();
  for (std::size_t k = 0; k < keep.size(); ++k) {
    // The worst seam over the stretch a kept point stands for.
    const std::size_t end = k + 1 < keep.size() ? keep[k + 1] : path.size();
    double seam = 0.0;
    for (std::size_t j = keep[k]; j < end; ++j) seam = std::max(seam, path[j].seam);
    const Row& row = path[keep[k]];
    points.push_back({std::round(row.x * 1000.0) / 1000.0, std::round(row.y * 1000.0) / 1000.0, seam});
  }
  // Loops: both ends' positions, accepted or not, from loops.csv and the path's frames.
  nlohmann::json loops = nlohmann::json::array();
  const fs::path loops_file = folder / "loops.csv";
  std::ifstream loops_in(loops_file);
  if (loops_in) {
    const auto at = [&](int frame) -> const Row* {
      const auto it = std::lower_bound(path.begin(), path.end(), frame, [](const Row& r, int f) { return r.frame < f; });
      return it != path.end() && it->frame == frame ? &*it : nullptr;
    };
    line_number = 0;
    while (std::getline(loops_in, text)) {
      ++line_number;
      if (text.empty() || text[0] == '#') continue;
      const std::vector<std::string_view> f = Fields(text);
      if (f.size() != 8) {
        core::ThrowInvalidInput(loops_file.string() + ":" + std::to_string(line_number) + ": expected 8 fields, found " +
                                std::to_string(f.size()));
      }
      const Row* a = at(Number<int>(f[0], loops_file, line_number, "earlier"));
      const Row* b = at(Number<int>(f[1], loops_file, line_number, "later"));
      if (a == nullptr || b == nullptr) continue;  // a frame without a pose
      loops.push_back({{"from", {a->x, a->y}},
                       {"to", {b->x, b->y}},
                       {"accepted", f[2] == "1"},
                       {"correction_mm", Number<double>(f[3], loops_file, line_number, "correction_mm")},
                       {"reason", std::string(f[7])}});
    }
  }
  report.layer = {{"frames", path.size()},
                  {"columns", {"x_mm", "y_mm", "worst_seam_px"}},
                  {"points", std::move(points)},
                  {"loops", std::move(loops)},
                  {"metrics", consistency}};
  return report;
}

}  // namespace

ReportLayer ReadReportLayer(const fs::path& folder, std::size_t max_points) {
  if (!fs::is_directory(folder)) core::ThrowInvalidInput(folder.string() + ": not a folder (a report was expected)");
  ReportLayer report;
  if (fs::exists(folder / "fixes.csv")) {
    report = ReplayLayer(folder, max_points);
  } else if (fs::exists(folder / "consistency.json")) {
    report = MappingLayer(folder, max_points);
  } else {
    core::ThrowInvalidInput(folder.string() +
                            ": not a report (neither a replay's fixes.csv nor a mapping report's consistency.json)");
  }
  fs::path name = folder;
  if (name.filename().empty()) name = name.parent_path();
  report.name = name.filename().string();
  return report;
}

}  // namespace mosaicloc::console::internal
