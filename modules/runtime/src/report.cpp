#include "mosaicloc/runtime/report.hpp"

#include <algorithm>
#include <cmath>
#include <system_error>
#include <utility>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/plots.hpp"

namespace mosaicloc::runtime {

dataset::Metrics EvaluateTrajectoryFiles(const std::filesystem::path& estimate,
                                         const std::filesystem::path& groundtruth,
                                         const std::filesystem::path& directory) {
  return WriteReport(directory, dataset::ReadTum(estimate), dataset::ReadTum(groundtruth), dataset::Metrics{},
                     estimate.filename().string());
}

dataset::Metrics WriteReport(const std::filesystem::path& directory, const dataset::Trajectory& estimate,
                             const std::optional<dataset::Trajectory>& groundtruth, dataset::Metrics metrics,
                             const std::string& title) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec) core::ThrowRuntime(directory.string() + ": cannot create the report directory (" + ec.message() + ")");
  dataset::WriteTum(directory / "estimate.tum", estimate);
  // No estimate at all (a start without a pose on a floor that repeats: never found): the
  // caller's counts are the report.
  if (groundtruth && !estimate.empty()) {
    const dataset::Evaluation evaluation = dataset::Evaluate(estimate, *groundtruth, dataset::EvaluationOptions{});
    // Keep what the caller measured; take the accuracy figures from the evaluation.
    metrics = dataset::WithEvaluation(std::move(metrics), evaluation.metrics);
    dataset::WritePlots(directory, evaluation, title);
  }
  dataset::WriteMetricsJson(directory / "metrics.json", metrics);
  return metrics;
}

dataset::FloorPicture FloorPictureOf(const MapSession& map, const std::vector<dataset::FrameReport>& reports) {
  dataset::FloorPicture picture;
  if (reports.empty()) return picture;
  Eigen::Vector2d lo = reports.front().world_from_vehicle.translation_mm(), hi = lo;
  for (const dataset::FrameReport& r : reports) {
    lo = lo.cwiseMin(r.world_from_vehicle.translation_mm());
    hi = hi.cwiseMax(r.world_from_vehicle.translation_mm());
  }
  const double margin_mm = std::max(500.0, 0.25 * (hi - lo).maxCoeff());
  lo.array() -= margin_mm;
  hi.array() += margin_mm;
  constexpr double kLargestPx = 1600.0, kTooLargePx = 6000.0;
  const mosaic::MapGrid& grid = map.grid();
  int level = 0;
  while (level + 1 < grid.levels && (hi - lo).maxCoeff() / grid.LevelMmPerPx(level) > kLargestPx) ++level;
  const double mm_per_px = grid.LevelMmPerPx(level);
  if ((hi - lo).maxCoeff() / mm_per_px > kTooLargePx) return picture;
  const Eigen::Vector2d top_left = grid.WorldToRaster({lo.x(), hi.y()}, level);
  const auto col0 = static_cast<std::int64_t>(std::floor(top_left.x()));
  const auto row0 = static_cast<std::int64_t>(std::floor(top_left.y()));
  const int cols = static_cast<int>(std::ceil((hi.x() - lo.x()) / mm_per_px)) + 2;
  const int rows = static_cast<int>(std::ceil((hi.y() - lo.y()) / mm_per_px)) + 2;
  const mosaic::RasterPatch patch = map.renderer().Region(level, col0, row0, cols, rows);
  picture.image = patch.image.clone();
  if (!patch.all_mapped) picture.image.setTo(255, patch.mask == 0);
  // Pixel (col, row)'s centre is raster (col, row): its outer edges are half a pixel out.
  const Eigen::Vector2d corner = grid.RasterToWorld({static_cast<double>(col0) - 0.5, static_cast<double>(row0) - 0.5}, level);
  picture.x0_mm = corner.x();
  picture.x1_mm = corner.x() + cols * mm_per_px;
  picture.y1_mm = corner.y();
  picture.y0_mm = corner.y() - rows * mm_per_px;
  return picture;
}

dataset::FrameReport FrameReportOf(core::Timestamp time, const localizer::FrameOutcome& outcome) {
  dataset::FrameReport report;
  report.time = time;
  report.fixed = outcome.fixed;
  report.world_from_vehicle = outcome.fixed ? outcome.fix_world_from_vehicle : outcome.world_from_vehicle;
  report.status = static_cast<int>(outcome.lock);
  report.quality = outcome.fixed ? outcome.fix_quality : 0.0;
  report.sigma_mm = std::sqrt(std::max(outcome.covariance(0, 0), outcome.covariance(1, 1)));
  report.scale = outcome.scale;
  report.nis = outcome.nis;
  report.reason = outcome.ReasonWord();
  report.mode = localizer::ToString(outcome.mode);
  return report;
}

}  // namespace mosaicloc::runtime
