#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "mosaicloc/runtime/report_compare.hpp"
#include "report.hpp"

namespace mosaicloc::app {
namespace {

std::string Shown(const nlohmann::json& value) {
  if (value.is_null()) return "n/a";
  if (value.is_number_float()) return fmt::format("{:.6g}", value.get<double>());
  return value.dump();
}

nlohmann::json FrameJson(const dataset::FrameReport& r) {
  return {{"x_mm", r.world_from_vehicle.x_mm()}, {"y_mm", r.world_from_vehicle.y_mm()},
          {"yaw_rad", r.world_from_vehicle.yaw_rad()}, {"status", r.status}, {"fix", r.fixed}, {"reason", r.reason}};
}

void Print(const runtime::ReportComparison& c, bool json) {
  if (json) {
    nlohmann::json result;
    for (const runtime::FigureComparison& f : c.figures) {
      result["figures"][f.key] = {{"a", f.a}, {"b", f.b}, {"b_minus_a", f.difference ? nlohmann::json(*f.difference) : nlohmann::json()}};
    }
    result["frames"] = {{"common", c.common_frames}, {"only_a", c.only_a}, {"only_b", c.only_b},
                        {"fixed_only_a", c.fixed_only_a}, {"fixed_only_b", c.fixed_only_b},
                        {"position_difference_rms_mm", c.position_difference_rms_mm ? nlohmann::json(*c.position_difference_rms_mm) : nlohmann::json()}};
    result["largest_differences"] = nlohmann::json::array();
    for (const runtime::FrameDifference& d : c.largest) {
      result["largest_differences"].push_back(
          {{"timestamp_ns", d.a.time.nanoseconds()}, {"distance_mm", d.distance_mm}, {"a", FrameJson(d.a)}, {"b", FrameJson(d.b)}});
    }
    PrintJson(result);
    return;
  }
  std::printf("%-32s %16s %16s %14s\n", "figure", "A", "B", "B - A");
  for (const runtime::FigureComparison& f : c.figures) {
    if (f.a.is_object() || f.b.is_object() || f.a.is_array() || f.b.is_array()) {
      std::printf("%-32s A: %s\n%-32s B: %s\n", f.key.c_str(), Shown(f.a).c_str(), "", Shown(f.b).c_str());
      continue;
    }
    std::printf("%-32s %16s %16s %14s\n", f.key.c_str(), Shown(f.a).c_str(), Shown(f.b).c_str(),
                f.difference ? fmt::format("{:+.4g}", *f.difference).c_str() : "");
  }
  std::printf("\nframes: %lld in both, %lld only in A, %lld only in B; fixed in A only %lld, in B only %lld\n",
              static_cast<long long>(c.common_frames), static_cast<long long>(c.only_a),
              static_cast<long long>(c.only_b), static_cast<long long>(c.fixed_only_a),
              static_cast<long long>(c.fixed_only_b));
  if (c.position_difference_rms_mm) std::printf("position difference RMS: %.4f mm\n", *c.position_difference_rms_mm);
  if (c.largest.empty()) return;
  std::printf("\nframes that differ most:\n%20s %12s %24s %24s\n", "timestamp_ns", "apart mm", "A (x, y mm; why)",
              "B (x, y mm; why)");
  for (const runtime::FrameDifference& d : c.largest) {
    const auto side = [](const dataset::FrameReport& r) {
      return fmt::format("{:.3f},{:.3f} {}", r.world_from_vehicle.x_mm(), r.world_from_vehicle.y_mm(),
                         r.fixed ? "fix" : r.reason);
    };
    std::printf("%20lld %12.4f %24s %24s\n", static_cast<long long>(d.a.time.nanoseconds()), d.distance_mm,
                side(d.a).c_str(), side(d.b).c_str());
  }
}

}  // namespace

Action AddReportCommand(CLI::App& app, const GlobalOptions& global) {
  struct Args {
    std::filesystem::path a;
    std::filesystem::path b;
    int top = 10;
  };
  auto args = std::make_shared<Args>();
  CLI::App* command = app.add_subcommand("report", "Work with replay reports");
  command->require_subcommand(1);
  CLI::App* compare = command->add_subcommand(
      "compare", "Two replays of one recording side by side: every figure, and the frames where they differ most");
  compare->add_option("A", args->a, "Report directory (metrics.json, fixes.csv)")->required()->check(CLI::ExistingDirectory);
  compare->add_option("B", args->b, "Report directory to compare with A")->required()->check(CLI::ExistingDirectory);
  compare->add_option("--top", args->top, "How many of the most different frames to list")->check(CLI::NonNegativeNumber);
  return [args, &global] { Print(runtime::CompareReports(args->a, args->b, args->top), global.json); };
}

}  // namespace mosaicloc::app
