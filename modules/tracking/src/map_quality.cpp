#include "mosaicloc/tracking/map_quality.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/tracking/templates.hpp"

namespace mosaicloc::tracking {

bool MapQualityOptions::Check(std::string* why) const {
  const auto fail = [&](const char* text) {
    *why = text;
    return false;
  };
  if (level < 0 || level > 8) return fail("level must be in [0, 8]");
  if (template_px < 16 || template_px > 512) return fail("template_px must be in [16, 512]");
  if (search_level < 0 || search_level > 8) return fail("search_level must be in [0, 8]");
  if (!(search_radius_mm > 0.0 && search_radius_mm <= 10000.0)) return fail("search_radius_mm must be in (0, 10000]");
  if (!(exclusion_mm > 0.0 && exclusion_mm < search_radius_mm)) return fail("exclusion_mm must be in (0, search_radius_mm)");
  if (!(min_mapped > 0.0 && min_mapped <= 1.0)) return fail("min_mapped must be in (0, 1]");
  if (!(template_mm > 0.0 && template_mm <= 1000.0)) return fail("template_mm must be in (0, 1000]");
  return true;
}

namespace {

// The median texture of the template-sized windows of a cell's level-0 floor that are all
// mapped; -1 without one.
float CellTexture(const mosaic::RasterPatch& floor, int template_px) {
  std::vector<double> strengths;
  const int step = template_px;
  for (int y = 0; y + template_px <= floor.image.rows; y += step) {
    for (int x = 0; x + template_px <= floor.image.cols; x += step) {
      const cv::Rect window(x, y, template_px, template_px);
      if (!floor.all_mapped && cv::countNonZero(floor.mask(window)) < window.area()) continue;
      cv::Mat half;
      cv::resize(floor.image(window), half, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
      strengths.push_back(TextureStrength(half));
    }
  }
  if (strengths.empty()) return -1.0f;  // no window all on the floor: not judged
  std::nth_element(strengths.begin(), strengths.begin() + static_cast<std::ptrdiff_t>(strengths.size() / 2),
                   strengths.end());
  return static_cast<float>(strengths[strengths.size() / 2]);
}

// The best ZNCC of `floor`'s window `own` elsewhere in `floor` (farther than exclusion_px
// from its place, at places whose window is all mapped): coarse to fine, since the search
// covers a wide area. The whole area is correlated at half resolution; the best few places
// found there are correlated again at full resolution around themselves.
// x^2 + y^2: distances are compared squared (std::hypot, exact and slow, took an eighth of
// the assessment's time).
double Squared(double x, double y) { return x * x + y * y; }

// Whether the w x h window at (x, y) holds no unmapped pixel, from the integral image of the
// mapped pixels (1 each).
bool AllMapped(const cv::Mat& integral, int x, int y, int w, int h) {
  return integral.at<int>(y + h, x + w) - integral.at<int>(y, x + w) - integral.at<int>(y + h, x) +
             integral.at<int>(y, x) ==
         w * h;
}

// The working images of one cell, kept per thread: allocating them for every cell cost more
// in page faults than the correlation itself.
struct Scratch {
  cv::Mat region, mapped, integral, coarse, score, fine;
};

float BestElsewhere(const mosaic::RasterPatch& floor, const cv::Mat& fine_integral, const cv::Rect& own,
                    double exclusion_px, Scratch& scratch) {
  const auto all_mapped = AllMapped;
  constexpr int kCoarse = 4;  // the wide search's reduction
  cv::Mat& coarse = scratch.coarse;
  cv::resize(floor.image, coarse, cv::Size(), 1.0 / kCoarse, 1.0 / kCoarse, cv::INTER_AREA);
  const cv::Rect own_coarse(own.x / kCoarse, own.y / kCoarse, own.width / kCoarse, own.height / kCoarse);
  cv::Mat& score = scratch.score;
  cv::matchTemplate(coarse, coarse(own_coarse).clone(), score, cv::TM_CCOEFF_NORMED);
  // The best few coarse places, each at least half a template from the others.
  constexpr int kCandidates = 3;
  std::vector<cv::Point> places;
  const double coarse_exclusion = exclusion_px / kCoarse;
  const double half_width = own_coarse.width / 2.0;
  for (int k = 0; k < kCandidates; ++k) {
    float best = -2.0f;
    cv::Point at(-1, -1);
    for (int y = 0; y < score.rows; ++y) {
      const float* row = score.ptr<float>(y);
      for (int x = 0; x < score.cols; ++x) {
        if (!(row[x] > best) || !std::isfinite(row[x])) continue;
        if (Squared(x - own_coarse.x, y - own_coarse.y) <= coarse_exclusion * coarse_exclusion) continue;
        bool near = false;
        for (const cv::Point& p : places) near = near || Squared(x - p.x, y - p.y) < half_width * half_width;
        if (near || !all_mapped(fine_integral, kCoarse * x, kCoarse * y, own.width, own.height)) continue;
        best = row[x];
        at = {x, y};
      }
    }
    if (at.x < 0) break;
    places.push_back(at);
  }
  // Each again at full resolution, within a few pixels of where the coarse search put it.
  constexpr int kReach = kCoarse + 1;
  const cv::Mat templ = floor.image(own);
  float best = -1.0f;
  for (const cv::Point& p : places) {
    const cv::Rect window = cv::Rect(kCoarse * p.x - kReach, kCoarse * p.y - kReach, own.width + 2 * kReach, own.height + 2 * kReach) &
                            cv::Rect(0, 0, floor.image.cols, floor.image.rows);
    if (window.width < own.width || window.height < own.height) continue;
    cv::Mat& fine = scratch.fine;
    cv::matchTemplate(floor.image(window), templ, fine, cv::TM_CCOEFF_NORMED);
    for (int y = 0; y < fine.rows; ++y) {
      for (int x = 0; x < fine.cols; ++x) {
        const int fx = window.x + x, fy = window.y + y;
        const float value = fine.at<float>(y, x);
        if (!(value > best) || !std::isfinite(value)) continue;
        if (Squared(fx - own.x, fy - own.y) <= exclusion_px * exclusion_px) continue;
        if (!all_mapped(fine_integral, fx, fy, own.width, own.height)) continue;
        best = value;
      }
    }
  }
  return best;
}

}  // namespace

std::vector<mosaic::QualityCell> AssessMapQuality(const mosaic::TileStore& store, const MapQualityOptions& options,
                                                  const std::function<void(double)>& progress) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("map quality options: " + why);
  const mosaic::MapGrid& grid = store.grid();
  if (options.level >= grid.levels || options.search_level >= grid.levels) {
    core::ThrowInvalidInput(store.file().string() + ": the quality layer's levels (" + std::to_string(options.level) +
                            ", " + std::to_string(options.search_level) + ") are not below the map's " +
                            std::to_string(grid.levels) + " levels");
  }
  mosaic::TileCache cache(store, std::size_t{96} << 20);
  const mosaic::MapRenderer renderer(cache);
  const std::vector<mosaic::TileKey> keys = store.List(options.level);
  const int t = grid.tile_size_px;
  // A cell's extent on level 0 and on the search level (in pixels of that level).
  const std::int64_t scale0 = std::int64_t{1} << options.level;
  const double search_scale = std::ldexp(1.0, options.level - options.search_level);
  const int cell_search_px = std::max(8, static_cast<int>(std::lround(t * search_scale)));
  const int radius_px = static_cast<int>(std::ceil(options.search_radius_mm / grid.LevelMmPerPx(options.search_level)));
  const double exclusion_px = options.exclusion_mm / grid.LevelMmPerPx(options.search_level);
  const int template_search_px =
      std::min(cell_search_px, std::max(8, static_cast<int>(std::lround(options.template_mm / grid.LevelMmPerPx(options.search_level)))));
  // One cell; a problem (a damaged tile) is kept, not thrown, off the calling thread.
  const auto judge = [&](std::size_t n, mosaic::QualityCell& cell) -> std::string {
    const mosaic::TileKey& key = keys[n];
    cell.col = key.col;
    cell.row = key.row;
    const int size0 = static_cast<int>(t * scale0);
    const mosaic::RasterPatch floor = renderer.Region(0, key.col * t * scale0, key.row * t * scale0, size0, size0);
    if (!floor.problems.empty()) return floor.problems.front();
    cell.mapped = static_cast<float>(floor.all_mapped ? 1.0
                                                      : static_cast<double>(cv::countNonZero(floor.mask)) /
                                                            static_cast<double>(floor.mask.total()));
    if (cell.mapped <= 0.0f) return {};
    cell.texture = CellTexture(floor, options.template_px);
    cell.ambiguity = -1.0f;
    if (cell.mapped < options.min_mapped) return {};
    const std::int64_t col0 = static_cast<std::int64_t>(std::floor(static_cast<double>(key.col * t) * search_scale));
    const std::int64_t row0 = static_cast<std::int64_t>(std::floor(static_cast<double>(key.row * t) * search_scale));
    thread_local Scratch scratch;
    mosaic::RasterPatch around;
    renderer.Region(options.search_level, col0 - radius_px, row0 - radius_px, cell_search_px + 2 * radius_px,
                    cell_search_px + 2 * radius_px, scratch.region, &around);
    if (!around.problems.empty()) return around.problems.front();
    if (around.mask.empty()) around.mask = cv::Mat(around.image.size(), CV_8UC1, cv::Scalar(255));
    cv::min(around.mask, 1, scratch.mapped);  // the mask is 255 where mapped
    cv::integral(scratch.mapped, scratch.integral, CV_32S);
    // The template: a square of template_mm all on the floor, centred as near the cell's
    // centre as the floor allows (lanes are often narrower than a cell), if one fits.
    std::optional<cv::Point> corner;
    double nearest = 0.0;
    const int half = template_search_px / 2;
    for (int y = 0; y < cell_search_px; ++y) {
      for (int x = 0; x < cell_search_px; ++x) {
        const double off = Squared(x - 0.5 * cell_search_px, y - 0.5 * cell_search_px);
        if (corner && off >= nearest) continue;
        const cv::Point at(radius_px + x - half, radius_px + y - half);
        if (!AllMapped(scratch.integral, at.x, at.y, template_search_px, template_search_px)) continue;
        corner = at;
        nearest = off;
      }
    }
    if (corner) {
      const cv::Rect own(corner->x, corner->y, template_search_px, template_search_px);
      cell.ambiguity = BestElsewhere(around, scratch.integral, own, exclusion_px, scratch);
    }
    return {};
  };
  // The cells are independent: judged on every core (the tile cache is shared and
  // thread-safe), a batch at a time so that progress is told from this thread.
  std::vector<mosaic::QualityCell> judged(keys.size());
  std::vector<std::string> problems(keys.size());
  constexpr std::size_t kBatch = 64;
  for (std::size_t first = 0; first < keys.size(); first += kBatch) {
    const std::size_t last = std::min(keys.size(), first + kBatch);
    cv::parallel_for_(cv::Range(static_cast<int>(first), static_cast<int>(last)), [&](const cv::Range& range) {
      for (int n = range.start; n < range.end; ++n) {
        const auto i = static_cast<std::size_t>(n);
        try {
          problems[i] = judge(i, judged[i]);
        } catch (const std::exception& error) {
          problems[i] = error.what();
        }
      }
    });
    if (progress) progress(static_cast<double>(last) / static_cast<double>(keys.size()));
  }
  for (const std::string& problem : problems) {
    if (!problem.empty()) core::ThrowInvalidInput(problem);
  }
  std::vector<mosaic::QualityCell> cells;
  for (const mosaic::QualityCell& cell : judged) {
    if (cell.mapped > 0.0f) cells.push_back(cell);
  }
  if (progress) progress(1.0);
  return cells;
}

}  // namespace mosaicloc::tracking
