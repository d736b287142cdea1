#include "mosaicloc/mapping/map_update.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_set>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/mosaic/builder.hpp"

namespace mosaicloc::mapping {
namespace {

// How a cell of the live view compares with the map's, and its sums (live l, map m) for the
// photometric fit of the live view to the map.
struct CellComparison {
  bool changed = false;
  double zncc = 1.0;  ///< where both are textured; else 1 (same) or -1 (changed)
  double n = 0.0, sum_l = 0.0, sum_m = 0.0, sum_ll = 0.0, sum_lm = 0.0;
};

// Compares two equally sized 8-bit blocks over the pixels `mask` marks (all when it is
// empty): the ZNCC where both are textured, the means where both are flat, and a flat block
// against a textured one is changed.
CellComparison CompareCell(const cv::Mat& live, const cv::Mat& map, const cv::Mat& mask, const MapUpdateOptions& options) {
  double sum_l = 0.0, sum_m = 0.0, sum_ll = 0.0, sum_mm = 0.0, sum_lm = 0.0, count = 0.0;
  for (int r = 0; r < live.rows; ++r) {
    const std::uint8_t* l = live.ptr<std::uint8_t>(r);
    const std::uint8_t* m = map.ptr<std::uint8_t>(r);
    const std::uint8_t* k = mask.empty() ? nullptr : mask.ptr<std::uint8_t>(r);
    for (int c = 0; c < live.cols; ++c) {
      if (k != nullptr && k[c] == 0) continue;
      count += 1.0;
      const double a = l[c], b = m[c];
      sum_l += a;
      sum_m += b;
      sum_ll += a * a;
      sum_mm += b * b;
      sum_lm += a * b;
    }
  }
  const double n = std::max(count, 1.0);
  const double mean_l = sum_l / n, mean_m = sum_m / n;
  const double var_l = std::max(0.0, sum_ll / n - mean_l * mean_l);
  const double var_m = std::max(0.0, sum_mm / n - mean_m * mean_m);
  const double flat = options.flat_dn * options.flat_dn;
  CellComparison result;
  result.n = n;
  result.sum_l = sum_l;
  result.sum_m = sum_m;
  result.sum_ll = sum_ll;
  result.sum_lm = sum_lm;
  if (var_l < flat && var_m < flat) {
    result.changed = std::abs(mean_l - mean_m) > options.max_flat_change_dn;
    result.zncc = result.changed ? -1.0 : 1.0;
  } else if (var_l < flat || var_m < flat) {
    result.changed = true;
    result.zncc = -1.0;
  } else {
    result.zncc = (sum_lm / n - mean_l * mean_m) / std::sqrt(var_l * var_m);
    result.changed = result.zncc < options.min_zncc;
  }
  return result;
}

}  // namespace

bool MapUpdateOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (passes < 2) return fail("passes must be at least 2 (one pass never writes)");
  if (!(pass_gap_s > 0.0)) return fail("pass_gap_s must be > 0");
  if (!(cell_mm > 0.0)) return fail("cell_mm must be > 0");
  if (!(min_zncc > -1.0 && min_zncc < 1.0)) return fail("min_zncc must be in (-1, 1)");
  if (!(border_zncc >= min_zncc && border_zncc <= 1.0)) return fail("border_zncc must be in [min_zncc, 1]");
  if (!(flat_dn >= 0.0) || !(max_flat_change_dn > 0.0)) return fail("flat_dn must be >= 0 and max_flat_change_dn > 0");
  if (!(max_changed_share > 0.0 && max_changed_share < 1.0)) return fail("max_changed_share must be in (0, 1)");
  if (min_cells < 1) return fail("min_cells must be at least 1");
  if (min_fixes_in_row < 1) return fail("min_fixes_in_row must be at least 1");
  if (!(max_nis > 0.0)) return fail("max_nis must be > 0");
  if (!(max_sigma_mm > 0.0)) return fail("max_sigma_mm must be > 0");
  if (!(max_ambiguity > -1.0)) return fail("max_ambiguity must be > -1");
  if (!(compare_every_fraction > 0.0)) return fail("compare_every_fraction must be > 0");
  if (!(margin_px >= 0.0)) return fail("margin_px must be >= 0");
  if (!(min_judged_share > 0.0 && min_judged_share <= 1.0)) return fail("min_judged_share must be in (0, 1]");
  return true;
}

MapUpdater::MapUpdater(mosaic::TileStore& store, mosaic::TileCache& cache, const camera::IdealCamera& camera,
                       const MapUpdateOptions& options)
    : store_(store), cache_(cache), renderer_(cache), camera_(camera), options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("map update: " + why);
  if (std::abs(store_.grid().mm_per_px - camera_.mm_per_px()) > 1e-9) {
    core::ThrowInvalidInput(fmt::format("{}: map resolution {} mm/px differs from the camera's {} mm/px",
                                        store_.file().string(), store_.grid().mm_per_px, camera_.mm_per_px()));
  }
  cell_px_ = std::max(8, static_cast<int>(std::lround(options_.cell_mm / store_.grid().mm_per_px)));
  if (const std::optional<mosaic::QualityInfo> quality = store_.Quality()) {
    quality_level_ = quality->level;
    try {
      for (const mosaic::QualityCell& cell : store_.ReadQuality()) {
        if (cell.ambiguity > options_.max_ambiguity) repeating_.insert({cell.col, cell.row});
      }
    } catch (const core::Error& e) {
      disabled_ = true;
      summary_.warnings.push_back(std::string("no map updates: the quality layer, which says where the floor "
                                              "repeats, is damaged: ") + e.what());
      core::Log().warn("map update: {}", summary_.warnings.back());
    }
  }
}

const UpdateSummary& MapUpdater::summary() const {
  summary_.cells_pending = 0;
  for (const auto& [cell, state] : cells_) {
    if (state.changed_passes > 0 || state.changed_votes > 0) ++summary_.cells_pending;
  }
  return summary_;
}

void MapUpdater::Frame(const UpdateFrame& frame) {
  if (disabled_) return;
  if (!frame.fixed || frame.restarted) {
    // A restart is a fix the filter did not check against a prediction: the count starts there.
    fixes_in_row_ = frame.fixed ? 1 : 0;
    return;
  }
  ++fixes_in_row_;
  if (!frame.tracking || fixes_in_row_ < options_.min_fixes_in_row) return;
  if (!frame.nis || *frame.nis > options_.max_nis) return;
  const double sigma_mm = std::sqrt(std::max(frame.covariance(0, 0), frame.covariance(1, 1)));
  if (!(sigma_mm <= options_.max_sigma_mm)) return;
  const double spacing_mm =
      options_.compare_every_fraction * std::min(camera_.width_mm(), camera_.height_mm());
  if (last_compared_ && core::Distance(*last_compared_, frame.world_from_camera) < spacing_mm &&
      core::ToSeconds(frame.time - last_compared_time_) < options_.pass_gap_s) {
    return;
  }
  if (!repeating_.empty()) {
    const Eigen::Vector2d at = store_.grid().WorldToRaster(frame.world_from_camera.translation_mm(), quality_level_);
    const std::int64_t t = store_.grid().tile_size_px;
    const CellIndex cell{mosaic::FloorDiv(static_cast<std::int64_t>(std::floor(at.x() + 0.5)), t),
                         mosaic::FloorDiv(static_cast<std::int64_t>(std::floor(at.y() + 0.5)), t)};
    if (repeating_.count(cell) > 0) {
      ++summary_.repeating;
      return;
    }
  }
  const auto started = std::chrono::steady_clock::now();
  last_compared_ = frame.world_from_camera;
  last_compared_time_ = frame.time;
  const std::vector<CellIndex> due = Compare(frame);
  if (!due.empty()) Update(frame, due);
  summary_.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
}

std::vector<MapUpdater::CellIndex> MapUpdater::Compare(const UpdateFrame& frame) {
  const mosaic::MapGrid& grid = store_.grid();
  const double w = camera_.width_px(), h = camera_.height_px();
  // The cells the view's footprint touches, on the level-0 raster.
  double u0 = std::numeric_limits<double>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
  for (const Eigen::Vector2d& corner : {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(w - 0.5, -0.5),
                                       Eigen::Vector2d(-0.5, h - 0.5), Eigen::Vector2d(w - 0.5, h - 0.5)}) {
    const Eigen::Vector2d raster = grid.WorldToRaster(camera_.PixelToWorld(corner, frame.world_from_camera), 0);
    u0 = std::min(u0, raster.x());
    v0 = std::min(v0, raster.y());
    u1 = std::max(u1, raster.x());
    v1 = std::max(v1, raster.y());
  }
  const std::int64_t c = cell_px_;
  const std::int64_t cx0 = mosaic::FloorDiv(static_cast<std::int64_t>(std::floor(u0 + 0.5)), c);
  const std::int64_t cy0 = mosaic::FloorDiv(static_cast<std::int64_t>(std::floor(v0 + 0.5)), c);
  const std::int64_t cx1 = mosaic::FloorDiv(static_cast<std::int64_t>(std::floor(u1 + 0.5)), c);
  const std::int64_t cy1 = mosaic::FloorDiv(static_cast<std::int64_t>(std::floor(v1 + 0.5)), c);
  const int cols = static_cast<int>((cx1 - cx0 + 1) * c), rows = static_cast<int>((cy1 - cy0 + 1) * c);
  mosaic::RasterPatch map;
  renderer_.Region(0, cx0 * c, cy0 * c, cols, rows, region_store_, &map);
  if (!map.problems.empty()) return {};  // a damaged tile: `map check` names it; nothing is judged there

  // The live frame on the same pixels: raster-local (i, j) -> image pixel, affine.
  const auto pixel_of = [&](double i, double j) {
    const Eigen::Vector2d world =
        grid.RasterToWorld(Eigen::Vector2d(static_cast<double>(cx0 * c) + i, static_cast<double>(cy0 * c) + j), 0);
    return camera_.WorldToPixel(world, frame.world_from_camera);
  };
  const Eigen::Vector2d o = pixel_of(0, 0), di = pixel_of(1, 0) - o, dj = pixel_of(0, 1) - o;
  const cv::Mat pixel_from_local = (cv::Mat_<double>(2, 3) << di.x(), dj.x(), o.x(), di.y(), dj.y(), o.y());
  cv::Mat live;
  cv::warpAffine(frame.image, live, pixel_from_local, cv::Size(cols, rows), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                 cv::BORDER_CONSTANT, cv::Scalar(0));

  const double m = options_.margin_px;
  const auto inside = [&](double i, double j) {
    const Eigen::Vector2d p = o + i * di + j * dj;
    return p.x() >= m && p.y() >= m && p.x() <= w - 1.0 - m && p.y() <= h - 1.0 - m;
  };
  struct Judged {
    CellIndex cell;
    bool changed;
    double zncc;
  };
  std::vector<Judged> judged;
  std::vector<CellComparison> sums;
  // Which of those pixels the live frame holds, and which it holds margin_px inside its edge:
  // a cell at a lane's edge lies partly outside the view as it lies partly outside the map.
  const auto frame_pixels = [&](int margin) {
    cv::Mat frame_mask = cv::Mat::zeros(frame.image.size(), CV_8U);
    if (frame_mask.cols > 2 * margin && frame_mask.rows > 2 * margin) {
      frame_mask(cv::Rect(margin, margin, frame_mask.cols - 2 * margin, frame_mask.rows - 2 * margin)).setTo(255);
    }
    cv::Mat local;
    cv::warpAffine(frame_mask, local, pixel_from_local, cv::Size(cols, rows), cv::INTER_NEAREST | cv::WARP_INVERSE_MAP,
                   cv::BORDER_CONSTANT, cv::Scalar(0));
    return local;
  };
  const cv::Mat in_frame = frame_pixels(0);
  const cv::Mat in_view = frame_pixels(static_cast<int>(std::ceil(m)));
  for (std::int64_t cy = cy0; cy <= cy1; ++cy) {
    for (std::int64_t cx = cx0; cx <= cx1; ++cx) {
      const double i0 = static_cast<double>((cx - cx0) * c), j0 = static_cast<double>((cy - cy0) * c);
      const double i1 = i0 + static_cast<double>(c) - 1.0, j1 = j0 + static_cast<double>(c) - 1.0;
      const cv::Rect rect(static_cast<int>(i0), static_cast<int>(j0), static_cast<int>(c), static_cast<int>(c));
      const bool whole_in_view = inside(i0, j0) && inside(i1, j0) && inside(i0, j1) && inside(i1, j1);
      const int mapped = map.all_mapped ? rect.area() : cv::countNonZero(map.mask(rect));
      cv::Mat judged_pixels;  // empty: all of the cell
      if (mapped == rect.area()) {
        // Mapped whole: judged (and rewritten) only from a view that holds it whole; other
        // views along the lane do.
        if (!whole_in_view) continue;
      } else {
        // At a lane's edge: judged from a frame that holds all of the cell's mapped part (to a
        // pixel row), so that a rewrite from it repaints that part, on the pixels both the map
        // and the view hold, when they are min_judged_share of the cell.
        const cv::Mat mapped_pixels = map.mask(rect);
        if (cv::countNonZero(mapped_pixels & ~in_frame(rect)) > static_cast<int>(c)) continue;
        judged_pixels = in_view(rect) & mapped_pixels;
        if (cv::countNonZero(judged_pixels) < options_.min_judged_share * static_cast<double>(rect.area())) continue;
      }
      const CellComparison comparison = CompareCell(live(rect), map.image(rect), judged_pixels, options_);
      judged.push_back({{cx, cy}, comparison.changed, comparison.zncc});
      sums.push_back(comparison);
    }
  }
  // A change's edge runs through cells: one that borders a changed cell and correlates less
  // than border_zncc is part of the change too (else a strip of the old floor stays around it).
  std::unordered_set<CellIndex, CellIndexHash> changed_cells;
  for (const Judged& j : judged) {
    if (j.changed) changed_cells.insert(j.cell);
  }
  for (Judged& j : judged) {
    if (j.changed || !(j.zncc < options_.border_zncc)) continue;
    for (int dy = -1; dy <= 1 && !j.changed; ++dy) {
      for (int dx = -1; dx <= 1 && !j.changed; ++dx) {
        j.changed = changed_cells.count({j.cell.first + dx, j.cell.second + dy}) > 0;
      }
    }
  }
  int changed = 0;
  CellComparison same;  // the sums over the cells that look as mapped
  for (std::size_t k = 0; k < judged.size(); ++k) {
    if (judged[k].changed) {
      ++changed;
      continue;
    }
    same.n += sums[k].n;
    same.sum_l += sums[k].sum_l;
    same.sum_m += sums[k].sum_m;
    same.sum_ll += sums[k].sum_ll;
    same.sum_lm += sums[k].sum_lm;
  }
  if (static_cast<int>(judged.size()) < options_.min_cells) return {};
  ++summary_.compared;
  if (changed > options_.max_changed_share * static_cast<double>(judged.size())) {
    ++summary_.mostly_changed;
    return {};
  }
  // The live view's grey levels as the map has them (the light, the exposure and the map's
  // blending differ): map = gain x live + offset, least squares over the unchanged cells.
  gain_ = 1.0;
  offset_ = 0.0;
  const double var_l = same.n > 0.0 ? same.sum_ll / same.n - (same.sum_l / same.n) * (same.sum_l / same.n) : 0.0;
  if (var_l > 1.0) {
    gain_ = (same.sum_lm / same.n - same.sum_l / same.n * same.sum_m / same.n) / var_l;
    offset_ = same.sum_m / same.n - gain_ * same.sum_l / same.n;
  }
  std::vector<CellIndex> due;
  for (const Judged& j : judged) {
    auto it = cells_.find(j.cell);
    if (it == cells_.end()) {
      if (!j.changed) continue;  // as mapped, and never seen otherwise
      it = cells_.emplace(j.cell, CellState{0, 0, 0, frame.time}).first;
    }
    CellState& state = it->second;
    if (state.changed_votes + state.same_votes > 0 &&
        core::ToSeconds(frame.time - state.last_seen) > options_.pass_gap_s) {
      // The previous pass is over: it counts as changed when most of its sightings were.
      state.changed_passes = state.changed_votes > state.same_votes ? state.changed_passes + 1 : 0;
      state.changed_votes = state.same_votes = 0;
    }
    (j.changed ? state.changed_votes : state.same_votes) += 1;
    state.last_seen = frame.time;
    if (state.changed_passes == 0 && state.changed_votes == 0) {
      cells_.erase(it);
      continue;
    }
    if (j.changed && state.changed_votes > state.same_votes && state.changed_passes + 1 >= options_.passes) {
      due.push_back(j.cell);
    }
  }
  return due;
}

void MapUpdater::Update(const UpdateFrame& frame, const std::vector<CellIndex>& cells) {
  const mosaic::MapGrid& grid = store_.grid();
  mosaic::MapBuilder builder(grid, mosaic::Blend::kBestView);
  // In the map's grey levels (Compare's fit), so that the new floor meets the old without a step.
  cv::Mat image;
  frame.image.convertTo(image, CV_8U, gain_, offset_);
  builder.AddFrame(image, frame.world_from_camera, grid.mm_per_px);
  // The cells' pixels, tile by tile.
  const std::int64_t c = cell_px_, t = grid.tile_size_px;
  std::map<std::pair<std::int64_t, std::int64_t>, std::vector<cv::Rect>> by_tile;
  for (const CellIndex& cell : cells) {
    const std::int64_t x0 = cell.first * c, y0 = cell.second * c;
    for (std::int64_t ty = mosaic::FloorDiv(y0, t); ty <= mosaic::FloorDiv(y0 + c - 1, t); ++ty) {
      for (std::int64_t tx = mosaic::FloorDiv(x0, t); tx <= mosaic::FloorDiv(x0 + c - 1, t); ++tx) {
        const std::int64_t a = std::max(x0, tx * t), b = std::max(y0, ty * t);
        const std::int64_t e = std::min(x0 + c, (tx + 1) * t), f = std::min(y0 + c, (ty + 1) * t);
        by_tile[{tx, ty}].push_back(
            cv::Rect(static_cast<int>(a - tx * t), static_cast<int>(b - ty * t), static_cast<int>(e - a), static_cast<int>(f - b)));
      }
    }
  }
  std::vector<mosaic::TileWrite> writes;
  for (const auto& [index, rects] : by_tile) {
    const mosaic::TileKey key{0, index.first, index.second};
    const mosaic::TileRead read = store_.Read(key);
    if (read.status != mosaic::TileStatus::kOk) {
      if (read.status == mosaic::TileStatus::kCorrupt) {
        summary_.warnings.push_back("not updated in a damaged tile: " + read.problem);
        core::Log().warn("map update: {}", summary_.warnings.back());
      }
      continue;
    }
    const cv::Mat painted = builder.FinishTile(key);
    cv::Mat out = read.pixels.clone();
    for (const cv::Rect& rect : rects) painted(rect).copyTo(out(rect), painted(rect) != mosaic::kUnmapped);
    if (cv::countNonZero(out != read.pixels) > 0) writes.push_back({key, out});
  }
  for (const CellIndex& cell : cells) cells_.erase(cell);
  if (writes.empty()) return;
  double x = 0.0, y = 0.0;
  for (const CellIndex& cell : cells) {
    const Eigen::Vector2d centre = grid.RasterToWorld(
        Eigen::Vector2d((static_cast<double>(cell.first) + 0.5) * static_cast<double>(c) - 0.5,
                        (static_cast<double>(cell.second) + 0.5) * static_cast<double>(c) - 0.5),
        0);
    x += centre.x() / static_cast<double>(cells.size());
    y += centre.y() / static_cast<double>(cells.size());
  }
  const std::string reason =
      fmt::format("map update: {} cells of {:g} mm around ({:.0f}, {:.0f}) mm seen changed on {} passes, painted "
                  "from the frame at {:.3f} s",
                  cells.size(), options_.cell_mm, x, y, options_.passes, core::ToSeconds(frame.time - core::Timestamp()));
  const std::optional<std::int64_t> id = mosaic::WriteWithPyramid(store_, writes, reason);
  for (const mosaic::TileWrite& write : writes) cache_.InvalidateWithPyramid(write.key);
  ++summary_.updates;
  summary_.cells_updated += static_cast<std::int64_t>(cells.size());
  summary_.tiles_written += static_cast<std::int64_t>(writes.size());
  summary_.painted.emplace_back(frame.time, frame.world_from_camera);
  core::Log().info("{} (update {})", reason, id.value_or(0));
}

}  // namespace mosaicloc::mapping
