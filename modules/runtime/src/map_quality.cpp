#include "mosaicloc/runtime/map_quality.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/mosaic/quality.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/runtime/map_jobs.hpp"

namespace mosaicloc::runtime {
namespace fs = std::filesystem;

std::vector<mosaic::QualityCell> AssessStore(mosaic::TileStore& store, const std::function<void(double)>& progress) {
  const tracking::MapQualityOptions options;
  std::vector<mosaic::QualityCell> cells = tracking::AssessMapQuality(store, options, progress);
  store.WriteQuality(options.level, cells);
  return cells;
}

namespace {

const cv::Scalar kGood(80, 170, 40), kLittleTexture(0, 160, 240), kRepeats(40, 40, 215), kUnsearched(200, 120, 40);  // BGR

// The map at the finest level that fits in `largest_px`, in colour, and where its pixel (0, 0)
// lies: the level, and its first column and row.
struct Picture {
  cv::Mat image;
  cv::Mat mapped;  ///< 255 where the map has floor
  int level = 0;
  std::int64_t col0 = 0, row0 = 0;
};

Picture MapPicture(const mosaic::TileStore& store, int largest_px) {
  Picture picture;
  const mosaic::MapGrid& grid = store.grid();
  MapExtent extent;
  for (picture.level = 0; picture.level < grid.levels; ++picture.level) {
    extent = LevelExtent(store, picture.level);
    if (extent.empty()) break;
    if (extent.col1 - extent.col0 < largest_px && extent.row1 - extent.row0 < largest_px) break;
  }
  picture.level = std::min(picture.level, grid.levels - 1);
  extent = LevelExtent(store, picture.level);
  if (extent.empty()) return picture;
  mosaic::TileCache cache(store, std::size_t{64} << 20);
  const mosaic::MapRenderer renderer(cache);
  const mosaic::RasterPatch patch =
      renderer.Region(picture.level, extent.col0, extent.row0, static_cast<int>(extent.col1 - extent.col0 + 1),
                      static_cast<int>(extent.row1 - extent.row0 + 1));
  cv::Mat grey = patch.image.clone();
  if (!patch.all_mapped) grey.setTo(255, patch.mask == 0);
  cv::cvtColor(grey, picture.image, cv::COLOR_GRAY2BGR);
  picture.mapped = patch.all_mapped ? cv::Mat(grey.size(), CV_8UC1, cv::Scalar(255)) : patch.mask.clone();
  picture.col0 = extent.col0;
  picture.row0 = extent.row0;
  return picture;
}

nlohmann::json SummaryJson(const MapQualityJob& job, const MapQualitySummary& summary) {
  nlohmann::json stretches = nlohmann::json::array();
  for (const WeakStretch& s : summary.stretches) {
    stretches.push_back({{"cells", s.cells}, {"bounds_mm", {s.x0_mm, s.y0_mm, s.x1_mm, s.y1_mm}},
                         {"centre_mm", {s.centre_x_mm, s.centre_y_mm}}, {"reason", s.reason},
                         {"min_texture", s.min_texture}, {"max_ambiguity", s.max_ambiguity}});
  }
  return {{"map", job.map.string()}, {"level", summary.level}, {"cell_mm", summary.cell_mm},
          {"cells", summary.cells}, {"judged", summary.judged}, {"weak_cells", summary.weak_cells},
          {"weak_texture", summary.weak_texture}, {"repeating", summary.repeating}, {"unsearched", summary.unsearched},
          {"thresholds", {{"min_texture", job.thresholds.min_texture},
                          {"max_ambiguity", job.thresholds.max_ambiguity},
                          {"min_mapped", job.thresholds.min_mapped}}},
          {"computed_s", summary.computed ? nlohmann::json(summary.seconds) : nlohmann::json()},
          {"stretches", stretches}};
}

}  // namespace

MapQualitySummary MapQuality(const MapQualityJob& job, const std::function<void(double)>& progress) {
  MapQualitySummary summary;
  std::vector<mosaic::QualityCell> cells;
  std::unique_ptr<mosaic::TileStore> store = mosaic::TileStore::Open(job.map, false);
  std::optional<mosaic::QualityInfo> info = store->Quality();
  if (!info || job.rebuild) {
    store.reset();
    store = mosaic::TileStore::Open(job.map, true);
    const auto start = std::chrono::steady_clock::now();
    cells = AssessStore(*store, progress);
    store->Checkpoint();
    summary.computed = true;
    summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    info = store->Quality();
  } else {
    cells = store->ReadQuality();
  }
  const mosaic::MapGrid& grid = store->grid();
  summary.level = info->level;
  summary.cell_mm = grid.LevelMmPerPx(info->level) * grid.tile_size_px;
  summary.cells = static_cast<std::int64_t>(cells.size());

  // Weak cells, and their 8-connected stretches.
  std::map<std::pair<std::int64_t, std::int64_t>, std::string> weak;
  for (const mosaic::QualityCell& c : cells) {
    if (c.mapped >= job.thresholds.min_mapped) ++summary.judged;
    if (mosaic::VerdictOf(c, job.thresholds) == mosaic::QualityVerdict::kPartlyJudged) ++summary.unsearched;
    const std::string why = mosaic::WeakBecause(c, job.thresholds);
    if (why.empty()) continue;
    weak[{c.col, c.row}] = why;
    ++summary.weak_cells;
    if (why.find("texture") != std::string::npos) ++summary.weak_texture;
    if (why.find("repeats") != std::string::npos) ++summary.repeating;
  }
  std::map<std::pair<std::int64_t, std::int64_t>, const mosaic::QualityCell*> by_key;
  for (const mosaic::QualityCell& c : cells) by_key[{c.col, c.row}] = &c;
  std::map<std::pair<std::int64_t, std::int64_t>, bool> seen;
  for (const auto& [key, why] : weak) {
    if (seen[key]) continue;
    WeakStretch stretch;
    std::map<std::string, int> reasons;
    std::vector<std::pair<std::int64_t, std::int64_t>> todo{key};
    seen[key] = true;
    double sx = 0.0, sy = 0.0;
    stretch.x0_mm = stretch.y0_mm = 1e300;
    stretch.x1_mm = stretch.y1_mm = -1e300;
    stretch.min_texture = 1e300;
    while (!todo.empty()) {
      const auto k = todo.back();
      todo.pop_back();
      const mosaic::QualityCell& c = *by_key[k];
      ++stretch.cells;
      ++reasons[weak[k]];
      const double x0 = grid.origin_x_mm + static_cast<double>(k.first) * summary.cell_mm;
      const double y1 = grid.origin_y_mm - static_cast<double>(k.second) * summary.cell_mm;
      stretch.x0_mm = std::min(stretch.x0_mm, x0);
      stretch.x1_mm = std::max(stretch.x1_mm, x0 + summary.cell_mm);
      stretch.y0_mm = std::min(stretch.y0_mm, y1 - summary.cell_mm);
      stretch.y1_mm = std::max(stretch.y1_mm, y1);
      sx += x0 + 0.5 * summary.cell_mm;
      sy += y1 - 0.5 * summary.cell_mm;
      stretch.min_texture = std::min(stretch.min_texture, static_cast<double>(c.texture));
      stretch.max_ambiguity = std::max(stretch.max_ambiguity, static_cast<double>(c.ambiguity));
      for (std::int64_t dr = -1; dr <= 1; ++dr) {
        for (std::int64_t dc = -1; dc <= 1; ++dc) {
          const std::pair<std::int64_t, std::int64_t> n{k.first + dc, k.second + dr};
          if (weak.count(n) != 0 && !seen[n]) {
            seen[n] = true;
            todo.push_back(n);
          }
        }
      }
    }
    stretch.centre_x_mm = sx / static_cast<double>(stretch.cells);
    stretch.centre_y_mm = sy / static_cast<double>(stretch.cells);
    stretch.reason = std::max_element(reasons.begin(), reasons.end(), [](const auto& a, const auto& b) {
                       return a.second < b.second;
                     })->first;
    summary.stretches.push_back(stretch);
  }
  std::stable_sort(summary.stretches.begin(), summary.stretches.end(),
                   [](const WeakStretch& a, const WeakStretch& b) { return a.cells > b.cells; });

  std::error_code ec;
  fs::create_directories(job.out, ec);
  if (ec) core::ThrowRuntime(job.out.string() + ": cannot be created (" + ec.message() + ")");
  std::ostringstream csv;
  csv << "#stretch,cells,x0_mm,y0_mm,x1_mm,y1_mm,centre_x_mm,centre_y_mm,reason,min_texture,max_ambiguity\n";
  for (std::size_t i = 0; i < summary.stretches.size(); ++i) {
    const WeakStretch& s = summary.stretches[i];
    csv << fmt::format("{},{},{:.1f},{:.1f},{:.1f},{:.1f},{:.1f},{:.1f},{},{:.3f},{:.3f}\n", i + 1, s.cells, s.x0_mm,
                       s.y0_mm, s.x1_mm, s.y1_mm, s.centre_x_mm, s.centre_y_mm, s.reason, s.min_texture,
                       s.max_ambiguity);
  }
  core::WriteFileAtomically(job.out / "weak.csv", csv.str());

  // The picture: the map, every judged cell tinted by its verdict.
  Picture picture = MapPicture(*store, 1600);
  if (!picture.image.empty()) {
    const double cell_px = std::ldexp(static_cast<double>(grid.tile_size_px), summary.level - picture.level);
    cv::Mat tint = picture.image.clone();
    for (const mosaic::QualityCell& c : cells) {
      const mosaic::QualityVerdict verdict = mosaic::VerdictOf(c, job.thresholds);
      if (verdict == mosaic::QualityVerdict::kNotJudged) continue;
      const cv::Scalar colour = verdict == mosaic::QualityVerdict::kRepeats        ? kRepeats
                                : verdict == mosaic::QualityVerdict::kLittleTexture ? kLittleTexture
                                : verdict == mosaic::QualityVerdict::kPartlyJudged  ? kUnsearched
                                                                                   : kGood;
      const cv::Point corner(static_cast<int>(std::lround(static_cast<double>(c.col) * cell_px - static_cast<double>(picture.col0))),
                             static_cast<int>(std::lround(static_cast<double>(c.row) * cell_px - static_cast<double>(picture.row0))));
      const int side = std::max(1, static_cast<int>(std::lround(cell_px)));
      cv::rectangle(tint, cv::Rect(corner.x, corner.y, side, side), colour, cv::FILLED);
    }
    // Only the mapped floor is tinted: a cell is square, a lane is not.
    cv::Mat blended;
    cv::addWeighted(picture.image, 0.4, tint, 0.6, 0.0, blended);
    blended.copyTo(picture.image, picture.mapped);
    // Legend and scale bar on a white strip below.
    const int strip = 60;
    cv::copyMakeBorder(picture.image, picture.image, 0, strip, 0, std::max(0, 700 - picture.image.cols),
                       cv::BORDER_CONSTANT, cv::Scalar(255, 255, 255));
    const int y = picture.image.rows - strip + 22;
    int x = 10;
    const auto key = [&](const cv::Scalar& colour, const std::string& text) {
      cv::rectangle(picture.image, cv::Rect(x, y - 12, 14, 14), colour, cv::FILLED);
      cv::putText(picture.image, text, cv::Point(x + 20, y), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1,
                  cv::LINE_AA);
      x += 30 + 8 * static_cast<int>(text.size());
    };
    key(kGood, fmt::format("good ({})", summary.judged - summary.weak_cells - summary.unsearched));
    key(kLittleTexture, fmt::format("little texture ({})", summary.weak_texture));
    key(kRepeats, fmt::format("repeats ({})", summary.repeating));
    key(kUnsearched, fmt::format("lane edge, not judged in full ({})", summary.unsearched));
    const double mm_per_px = grid.LevelMmPerPx(picture.level);
    double bar_mm = std::pow(10.0, std::floor(std::log10(150.0 * mm_per_px)));
    if (bar_mm * 5.0 / mm_per_px <= 150.0) bar_mm *= 5.0;
    else if (bar_mm * 2.0 / mm_per_px <= 150.0) bar_mm *= 2.0;
    const int bar_px = static_cast<int>(std::lround(bar_mm / mm_per_px));
    const int by = picture.image.rows - 14;
    cv::line(picture.image, cv::Point(10, by), cv::Point(10 + bar_px, by), cv::Scalar(0, 0, 0), 2);
    cv::putText(picture.image, bar_mm >= 1000.0 ? fmt::format("{:g} m", bar_mm / 1000.0) : fmt::format("{:g} mm", bar_mm),
                cv::Point(20 + bar_px, by + 5), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    std::vector<unsigned char> png;
    if (!cv::imencode(".png", picture.image, png)) core::ThrowRuntime("quality.png: cannot be encoded");
    core::WriteFileAtomically(job.out / "quality.png", std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  }
  summary.json = SummaryJson(job, summary);
  core::WriteFileAtomically(job.out / "quality.json", summary.json.dump(2) + "\n");
  return summary;
}

}  // namespace mosaicloc::runtime
