// The procedural floor. A tile of 256 x 256 texels is built from world-anchored layers:
//
//   grain   value noise on lattices of 1, 2, 4, 8 texels (0.125-1 mm), summed through a
//           cubic x2 upsampling pyramid, then shaped by Sand() into separate bright grains
//           and dark pits on a weaker background texture;
//   smooth  the same pyramid on 2 mm - 512 mm lattices (mottling) plus stains evaluated on
//           the 2 mm grid, bilinearly upsampled to texels;
//   stones  irregular polygons with a shadow rim and a lit facet, and pores, drawn
//           anti-aliased into a premultiplied grey + opacity canvas;
//   cracks  meandering walks with branches, drawn into a coverage canvas.
// A texel is stones over (matrix + grain), plus smooth, then darkened by crack coverage.
//
// Every lattice value and every feature comes from a hash of (seed, layer, level or world
// cell), and every tile is computed from global coordinates only, so tiles join without
// seams and a texel does not depend on which tile or window it is rendered in.
// Lattice sample (i, j) of level k sits at texel position ((i + 0.5) 2^k, (j + 0.5) 2^k),
// which is exactly where cv::resize by 2 puts the source samples; with enough margin,
// resizing a patch reproduces the global upsampled field.
//
// Stones, stains and cracks live in "texel-axis millimetres": u = col position * mm_per_texel
// (along world +x), v = row position * mm_per_texel (along world -y).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "floor_internal.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/sim/floor.hpp"

namespace mosaicloc::sim {
namespace {

using internal::CellKey;
using internal::CellRandom;
using internal::FloorDiv;
using internal::LayerKey;
using internal::Mix32;

constexpr int kTileTexels = 256;
constexpr int kDrawShift = 4;  // fixed-point bits of drawing coordinates
constexpr double kDrawScale = 1 << kDrawShift;
constexpr int kFringeTexels = 2;  // reach of anti-aliasing beyond a shape's outline

// Hash layers.
constexpr std::uint64_t kLayerGrain = 0x100;
constexpr std::uint64_t kLayerMottle = 0x200;
constexpr std::uint64_t kLayerStainShape = 0x300;
constexpr std::uint64_t kLayerStones = 0x400;
constexpr std::uint64_t kLayerPores = 0x500;
constexpr std::uint64_t kLayerStains = 0x600;
constexpr std::uint64_t kLayerCracks = 0x700;
constexpr std::uint64_t kLayerCrackBranches = 0x800;

// Physical scales, mm.
constexpr double kSmoothFinestMm = 2.0;    // finest lattice of the smooth field
constexpr double kMottleCoarsestMm = 600;  // no mottling lattice coarser than this
constexpr double kStainMinRadiusMm = 25.0;
constexpr double kStainMaxRadiusMm = 250.0;
constexpr double kStainReach = 1.8;  // stain influence radius / nominal radius
constexpr double kStainCellMm = 2.0 * kStainMaxRadiusMm;
constexpr double kCrackStepMm = 1.0;
constexpr double kCrackMaxWidthMm = 1.6;
constexpr double kCrackHaloScale = 2.5;  // width of the darkened zone along a crack / its width
constexpr double kCrackHaloOpacity = 0.3;
constexpr double kCrackBranchReach = 1.35;  // crack extent from its start / its length
constexpr double kPoreMinDiameterMm = 0.3;
constexpr double kPoreMaxDiameterMm = 2.0;
constexpr double kPoreCellMm = 4.0;
constexpr double kStoneReach = 1.3;        // polygon vertex radius / nominal radius, at most
constexpr double kStoneMeanAspect = 0.75;  // mean minor/major axis ratio
constexpr double kRimMinMm = 0.1;          // dark rim around a stone: width =
constexpr double kRimMaxMm = 0.25;         //   uniform(min, max) + per_radius * radius
constexpr double kRimPerRadius = 0.06;

// Grey values, DN.
constexpr double kCrackDn = 22.0;
constexpr double kPoreDn = 38.0;
constexpr double kRimDarkeningDn = 55.0;
constexpr float kStoneTextureGain = 0.4F;  // grain strength inside stones, relative
constexpr double kGrainGain = 0.9;         // 1 / std of Sand(g) for g ~ N(0, 1)

// Variance of unit white noise after d cubic x2 upsamplings (d = 0, 1, 2, 3+), measured
// over 2e7 samples.
constexpr std::array<double, 4> kCubicChainVariance = {1.0, 0.73, 0.75, 0.76};

struct IndexRange {
  std::int64_t lo = 0;  // inclusive
  std::int64_t hi = 0;  // inclusive
  int size() const { return static_cast<int>(hi - lo + 1); }
};

/// A field sampled on the level-k lattice: values(r, c) is sample (i0 + c, j0 + r).
struct Grid {
  int level = 0;
  std::int64_t i0 = 0;
  std::int64_t j0 = 0;
  cv::Mat values;  // CV_32F
};

/// Source samples needed to produce dst samples [dst.lo, dst.hi] when upsampling by
/// `factor` with cv::resize: dst X reads src around S = (X + 0.5) / factor - 0.5.
IndexRange SourceRange(IndexRange dst, int factor, int interpolation) {
  const int before = interpolation == cv::INTER_CUBIC ? 1 : 0;
  const int after = interpolation == cv::INTER_CUBIC ? 2 : 1;
  return {FloorDiv(2 * dst.lo + 1 - factor, 2 * factor) - before,
          FloorDiv(2 * dst.hi + 1 - factor, 2 * factor) + after};
}

Grid Upsample(const Grid& src, int log2_factor, int interpolation, IndexRange cols,
              IndexRange rows) {
  const int factor = 1 << log2_factor;
  cv::Mat big;
  cv::resize(src.values, big, cv::Size(src.values.cols * factor, src.values.rows * factor), 0, 0,
             interpolation);
  const cv::Rect crop(static_cast<int>(cols.lo - factor * src.i0),
                      static_cast<int>(rows.lo - factor * src.j0), cols.size(), rows.size());
  Grid dst;
  dst.level = src.level - log2_factor;
  dst.i0 = cols.lo;
  dst.j0 = rows.lo;
  dst.values = big(crop);
  return dst;
}

/// Adds amplitude * (unit-variance uniform noise) hashed from (key, i, j) to every sample.
void AddLattice(Grid& grid, std::uint32_t key, float amplitude) {
  constexpr int kChunk = 16;  // fixed-length inner loop, so that -O2 vectorises it
  constexpr float kUnit = 3.4641016F / 16777216.0F;  // sqrt(12) / 2^24
  const float scale = amplitude * kUnit;
  const float offset = amplitude * 3.4641016F * 0.5F;
  const int cols = grid.values.cols;
  std::vector<float> noise(static_cast<std::size_t>((cols + kChunk - 1) / kChunk * kChunk));
  const auto i0 = static_cast<std::uint32_t>(grid.i0);
  for (int r = 0; r < grid.values.rows; ++r) {
    const auto j = static_cast<std::uint32_t>(grid.j0 + r);
    const std::uint32_t row_add = Mix32(j ^ key) + i0;
    const std::uint32_t row_xor = Mix32(j + key);
    for (std::size_t c0 = 0; c0 < noise.size(); c0 += kChunk) {
      float* chunk = noise.data() + c0;
      const std::uint32_t first = row_add + static_cast<std::uint32_t>(c0);
      for (std::uint32_t c = 0; c < kChunk; ++c) {
        const std::uint32_t h = Mix32(Mix32(first + c) ^ row_xor);
        chunk[c] = static_cast<float>(static_cast<std::int32_t>(h >> 8)) * scale - offset;
      }
    }
    float* out = grid.values.ptr<float>(r);
    const float* add = noise.data();
    MOSAICLOC_IVDEP
    for (int c = 0; c < cols; ++c) out[c] += add[c];
  }
}

/// Sum over levels of amplitude(level) * noise(level), each upsampled by cubic x2 steps
/// down to `bottom`, evaluated on [cols] x [rows] of the bottom level.
Grid NoisePyramid(std::uint64_t layer_key, int bottom, const std::vector<float>& amplitudes,
                  IndexRange cols, IndexRange rows) {
  const int top = bottom + static_cast<int>(amplitudes.size()) - 1;
  std::vector<std::pair<IndexRange, IndexRange>> ranges(amplitudes.size());
  ranges[0] = {cols, rows};
  for (std::size_t n = 1; n < ranges.size(); ++n) {
    ranges[n] = {SourceRange(ranges[n - 1].first, 2, cv::INTER_CUBIC),
                 SourceRange(ranges[n - 1].second, 2, cv::INTER_CUBIC)};
  }
  Grid grid;
  for (int level = top; level >= bottom; --level) {
    const auto n = static_cast<std::size_t>(level - bottom);
    if (level == top) {
      grid.level = level;
      grid.i0 = ranges[n].first.lo;
      grid.j0 = ranges[n].second.lo;
      grid.values = cv::Mat::zeros(ranges[n].second.size(), ranges[n].first.size(), CV_32F);
    } else {
      grid = Upsample(grid, 1, cv::INTER_CUBIC, ranges[n].first, ranges[n].second);
    }
    if (amplitudes[n] != 0.0F) {
      AddLattice(grid,
                 static_cast<std::uint32_t>(LayerKey(layer_key, static_cast<std::uint64_t>(level))),
                 amplitudes[n]);
    }
  }
  return grid;
}

/// Clamps x to [0, 1] without branches, so that -O2 vectorises the loops using it.
inline float Saturate(float x) { return 0.5F * (std::fabs(x) - std::fabs(x - 1.0F) + 1.0F); }

inline float SmoothStepF(float edge0, float inverse_width, float x) {
  const float t = Saturate((x - edge0) * inverse_width);
  return t * t * (3.0F - 2.0F * t);
}

/// Grey of the sand-and-binder matrix for a grain noise value g ~ N(0, 1): a weak linear
/// texture plus bright grains where g is high and dark pits where it is low, so that the
/// matrix looks like separate grains rather than cloud.
inline float Sand(float g) {
  return 0.45F * g + 1.7F * SmoothStepF(0.8F, 1.6F, g) - 1.4F * SmoothStepF(1.0F, 1.6F, -g);
}

inline double SmoothStep(double edge0, double edge1, double x) {
  const double t = std::clamp((x - edge0) / (edge1 - edge0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

/// Distance from value to the interval [lo, hi] (0 inside).
inline double DistanceToInterval(double value, double lo, double hi) {
  return value < lo ? lo - value : (value > hi ? value - hi : 0.0);
}

/// Normalises amplitudes so that the pyramid's sum has unit variance: level n above the
/// bottom goes through n cubic upsamplings.
void NormaliseAmplitudes(std::vector<float>& amplitudes) {
  double variance = 0.0;
  for (std::size_t n = 0; n < amplitudes.size(); ++n) {
    const double a = amplitudes[n];
    variance +=
        a * a * kCubicChainVariance[std::min<std::size_t>(n, kCubicChainVariance.size() - 1)];
  }
  if (variance <= 0.0) return;
  const auto scale = static_cast<float>(1.0 / std::sqrt(variance));
  for (float& a : amplitudes) a *= scale;
}

/// Relative strength of the grain lattice whose spacing is spacing_mm.
float GrainWeight(double spacing_mm) {
  if (spacing_mm < 0.2) return 0.3F;
  if (spacing_mm < 0.4) return 0.8F;
  if (spacing_mm < 0.8) return 1.0F;
  return 0.8F;
}

/// Relative strength of the mottling lattice whose spacing is spacing_mm.
float MottleWeight(double spacing_mm) {
  if (spacing_mm < 12.0) return 0.3F;
  if (spacing_mm < 24.0) return 0.45F;
  if (spacing_mm < 48.0) return 0.6F;
  return 1.0F;
}

/// Relative strength of the stain-outline noise lattice.
float StainShapeWeight(double spacing_mm) {
  return spacing_mm >= 12.0 && spacing_mm <= 300.0 ? 1.0F : 0.0F;
}

/// The tile being generated: its texel and mm extents, and the frame of its drawing
/// canvases, which extend `margin` texels beyond the tile on every side so that no feature
/// touching the tile is clipped (clipping would change its rasterisation).
struct TileFrame {
  std::int64_t col0 = 0;
  std::int64_t row0 = 0;
  int margin = 0;
  double mm_per_texel = 1.0;
  double u_lo = 0.0, u_hi = 0.0, v_lo = 0.0, v_hi = 0.0;  // tile extent, mm

  /// Fixed-point canvas coordinates of the point (u, v) mm.
  cv::Point ToCanvas(double u_mm, double v_mm) const {
    const double x = u_mm / mm_per_texel - 0.5 - static_cast<double>(col0 - margin);
    const double y = v_mm / mm_per_texel - 0.5 - static_cast<double>(row0 - margin);
    return {static_cast<int>(std::lround(x * kDrawScale)),
            static_cast<int>(std::lround(y * kDrawScale))};
  }
  /// True if the disc of radius reach_mm around (u, v), widened by the anti-aliasing
  /// fringe, touches the tile.
  bool Touches(double u_mm, double v_mm, double reach_mm) const {
    const double du = DistanceToInterval(u_mm, u_lo, u_hi);
    const double dv = DistanceToInterval(v_mm, v_lo, v_hi);
    const double r = reach_mm + kFringeTexels * mm_per_texel;
    return du * du + dv * dv <= r * r;
  }
};

/// The world cells of side cell_mm that hold features reaching up to reach_mm into a tile.
struct CellRange {
  std::int64_t x_lo, x_hi, y_lo, y_hi;  // inclusive
  CellRange(const TileFrame& frame, double cell_mm, double reach_mm)
      : x_lo(static_cast<std::int64_t>(std::floor((frame.u_lo - reach_mm) / cell_mm))),
        x_hi(static_cast<std::int64_t>(std::floor((frame.u_hi + reach_mm) / cell_mm))),
        y_lo(static_cast<std::int64_t>(std::floor((frame.v_lo - reach_mm) / cell_mm))),
        y_hi(static_cast<std::int64_t>(std::floor((frame.v_hi + reach_mm) / cell_mm))) {}
};

/// One straight piece of a crack, in canvas fixed-point coordinates.
struct CrackSegment {
  cv::Point from;
  cv::Point to;
  double width_texels = 0.0;
};

class ProceduralFloor final : public Floor {
 public:
  explicit ProceduralFloor(const ProceduralFloorOptions& options);

  double mm_per_texel() const override { return options_.mm_per_texel; }

  cv::Mat Render(std::int64_t col0, std::int64_t row0, int cols, int rows) const override {
    return internal::AssembleFromTiles(cache_, kTileTexels, col0, row0, cols, rows);
  }

  std::string Describe() const override;

 private:
  cv::Mat GenerateTile(std::int64_t tile_col, std::int64_t tile_row) const;
  void AddStains(const TileFrame& frame, Grid& smooth) const;
  // `paint` is CV_8UC2: premultiplied grey (DN) and opacity (0-255).
  void DrawPores(const TileFrame& frame, cv::Mat& paint) const;
  void DrawStones(const TileFrame& frame, cv::Mat& paint) const;
  void DrawCracks(const TileFrame& frame, cv::Mat& crack) const;
  void TraceCrack(const TileFrame& frame, CellRandom& random, double u_mm, double v_mm,
                  double heading_rad, double length_mm, double width_mm, bool main_crack,
                  std::uint64_t branch_key, std::vector<CrackSegment>& segments) const;

  ProceduralFloorOptions options_;
  int smooth_level_ = 0;  // lattice level of the finest smooth octave
  std::vector<float> grain_amplitudes_;
  std::vector<float> mottle_amplitudes_;
  std::vector<float> stain_shape_amplitudes_;
  double stone_cell_mm_ = 0.0;
  double stones_per_cell_ = 0.0;
  double stone_reach_mm_ = 0.0;
  double crack_cell_mm_ = 0.0;
  int margin_texels_ = 0;
  std::uint64_t grain_key_ = 0, mottle_key_ = 0, stain_shape_key_ = 0, stone_key_ = 0,
                pore_key_ = 0, stain_key_ = 0, crack_key_ = 0, branch_key_ = 0;
  internal::TileCache cache_;  // last: its generator uses everything above
};

ProceduralFloor::ProceduralFloor(const ProceduralFloorOptions& options)
    : options_(options),
      cache_(options.cache_bytes, static_cast<std::size_t>(kTileTexels) * kTileTexels,
             [this](std::int64_t tile_col, std::int64_t tile_row) {
               return GenerateTile(tile_col, tile_row);
             }) {
  const double s = options_.mm_per_texel;
  smooth_level_ = std::max(1, static_cast<int>(std::lround(std::log2(kSmoothFinestMm / s))));
  for (int level = 0; level < smooth_level_; ++level) {
    grain_amplitudes_.push_back(GrainWeight(s * std::ldexp(1.0, level)));
  }
  for (int level = smooth_level_; level <= smooth_level_ + 30; ++level) {
    const double spacing_mm = s * std::ldexp(1.0, level);
    if (spacing_mm > kMottleCoarsestMm && level > smooth_level_) break;
    mottle_amplitudes_.push_back(MottleWeight(spacing_mm));
    stain_shape_amplitudes_.push_back(StainShapeWeight(spacing_mm));
  }
  NormaliseAmplitudes(grain_amplitudes_);
  NormaliseAmplitudes(mottle_amplitudes_);
  NormaliseAmplitudes(stain_shape_amplitudes_);
  for (float& a : mottle_amplitudes_) a *= static_cast<float>(options_.mottle_contrast_dn);

  const double d_min = options_.stone_min_diameter_mm;
  const double d_max = options_.stone_max_diameter_mm;
  // Mean of d^2 for d log-uniform in [d_min, d_max].
  const double mean_d2 = d_max > d_min
                             ? (d_max * d_max - d_min * d_min) / (2.0 * std::log(d_max / d_min))
                             : d_min * d_min;
  const double mean_area_mm2 = std::numbers::pi / 4.0 * mean_d2 * kStoneMeanAspect;
  stone_cell_mm_ = std::max(d_max, 2.0);
  stones_per_cell_ = options_.stone_area_fraction / mean_area_mm2 * stone_cell_mm_ * stone_cell_mm_;
  // The rim (shifted by half its width) stays within 2 rim widths of the outline.
  stone_reach_mm_ = d_max / 2.0 * (kStoneReach + 2.0 * kRimPerRadius) + 2.0 * kRimMaxMm;
  crack_cell_mm_ = std::max(options_.crack_max_length_mm, 100.0);

  const double reach_mm = std::max({stone_reach_mm_, kPoreMaxDiameterMm / 2.0,
                                    kCrackStepMm + kCrackHaloScale * kCrackMaxWidthMm});
  margin_texels_ = static_cast<int>(std::ceil(reach_mm / s)) + kFringeTexels + 1;

  const std::uint64_t seed = options_.seed;
  grain_key_ = LayerKey(seed, kLayerGrain);
  mottle_key_ = LayerKey(seed, kLayerMottle);
  stain_shape_key_ = LayerKey(seed, kLayerStainShape);
  stone_key_ = LayerKey(seed, kLayerStones);
  pore_key_ = LayerKey(seed, kLayerPores);
  stain_key_ = LayerKey(seed, kLayerStains);
  crack_key_ = LayerKey(seed, kLayerCracks);
  branch_key_ = LayerKey(seed, kLayerCrackBranches);
}

std::string ProceduralFloor::Describe() const {
  const ProceduralFloorOptions& o = options_;
  std::ostringstream text;
  text.precision(10);
  text << "procedural seed=" << o.seed << " mm_per_texel=" << o.mm_per_texel
       << " matrix_dn=" << o.matrix_dn << " grain_contrast_dn=" << o.grain_contrast_dn
       << " mottle_contrast_dn=" << o.mottle_contrast_dn
       << " stone_area_fraction=" << o.stone_area_fraction
       << " stone_min_diameter_mm=" << o.stone_min_diameter_mm
       << " stone_max_diameter_mm=" << o.stone_max_diameter_mm
       << " pore_density_per_cm2=" << o.pore_density_per_cm2
       << " stain_density_per_m2=" << o.stain_density_per_m2
       << " stain_contrast_dn=" << o.stain_contrast_dn
       << " crack_density_per_m2=" << o.crack_density_per_m2
       << " crack_max_length_mm=" << o.crack_max_length_mm;
  return text.str();
}

cv::Mat ProceduralFloor::GenerateTile(std::int64_t tile_col, std::int64_t tile_row) const {
  TileFrame frame;
  frame.col0 = tile_col * kTileTexels;
  frame.row0 = tile_row * kTileTexels;
  frame.margin = margin_texels_;
  frame.mm_per_texel = options_.mm_per_texel;
  frame.u_lo = static_cast<double>(frame.col0) * frame.mm_per_texel;
  frame.u_hi = static_cast<double>(frame.col0 + kTileTexels) * frame.mm_per_texel;
  frame.v_lo = static_cast<double>(frame.row0) * frame.mm_per_texel;
  frame.v_hi = static_cast<double>(frame.row0 + kTileTexels) * frame.mm_per_texel;

  const IndexRange tile_cols{frame.col0, frame.col0 + kTileTexels - 1};
  const IndexRange tile_rows{frame.row0, frame.row0 + kTileTexels - 1};
  const Grid grain = NoisePyramid(grain_key_, 0, grain_amplitudes_, tile_cols, tile_rows);

  const int factor = 1 << smooth_level_;
  Grid smooth = NoisePyramid(mottle_key_, smooth_level_, mottle_amplitudes_,
                             SourceRange(tile_cols, factor, cv::INTER_LINEAR),
                             SourceRange(tile_rows, factor, cv::INTER_LINEAR));
  AddStains(frame, smooth);
  const Grid smooth_texels =
      Upsample(smooth, smooth_level_, cv::INTER_LINEAR, tile_cols, tile_rows);

  const int canvas_side = kTileTexels + 2 * frame.margin;
  cv::Mat paint = cv::Mat::zeros(canvas_side, canvas_side, CV_8UC2);
  cv::Mat crack = cv::Mat::zeros(canvas_side, canvas_side, CV_8UC1);
  DrawPores(frame, paint);
  DrawStones(frame, paint);
  DrawCracks(frame, crack);
  std::array<cv::Mat, 2> colour_alpha;
  cv::split(paint, colour_alpha.data());
  const cv::Mat& colour = colour_alpha[0];
  const cv::Mat& alpha = colour_alpha[1];

  const auto grain_dn = static_cast<float>(options_.grain_contrast_dn * kGrainGain);
  const auto matrix_dn = static_cast<float>(options_.matrix_dn);
  const float stone_grain_dn = grain_dn * kStoneTextureGain;
  constexpr float kInv255 = 1.0F / 255.0F;
  cv::Mat value(kTileTexels, kTileTexels, CV_32F);
  for (int y = 0; y < kTileTexels; ++y) {
    const float* g = grain.values.ptr<float>(y);
    const float* m = smooth_texels.values.ptr<float>(y);
    const std::uint8_t* stone = colour.ptr<std::uint8_t>(y + frame.margin) + frame.margin;
    const std::uint8_t* cover = alpha.ptr<std::uint8_t>(y + frame.margin) + frame.margin;
    const std::uint8_t* line = crack.ptr<std::uint8_t>(y + frame.margin) + frame.margin;
    float* out = value.ptr<float>(y);
    MOSAICLOC_IVDEP
    for (int x = 0; x < kTileTexels; ++x) {
      const float a = static_cast<float>(cover[x]) * kInv255;
      const float v = static_cast<float>(stone[x]) + a * stone_grain_dn * g[x] +
                      (1.0F - a) * (matrix_dn + grain_dn * Sand(g[x])) + m[x];
      const float c = static_cast<float>(line[x]) * kInv255;
      out[x] = v + c * (static_cast<float>(kCrackDn) - v);
    }
  }
  cv::Mat tile;
  value.convertTo(tile, CV_8U);
  return tile;
}

void ProceduralFloor::AddStains(const TileFrame& frame, Grid& smooth) const {
  if (options_.stain_density_per_m2 <= 0.0 || options_.stain_contrast_dn <= 0.0) return;
  const double reach_mm = kStainReach * kStainMaxRadiusMm;
  const CellRange cells(frame, kStainCellMm, reach_mm);
  const double stains_per_cell = options_.stain_density_per_m2 * kStainCellMm * kStainCellMm * 1e-6;
  const double spacing_mm = options_.mm_per_texel * std::ldexp(1.0, smooth.level);
  Grid shape;
  for (std::int64_t cy = cells.y_lo; cy <= cells.y_hi; ++cy) {
    for (std::int64_t cx = cells.x_lo; cx <= cells.x_hi; ++cx) {
      CellRandom random(CellKey(stain_key_, cx, cy));
      const int count = random.Poisson(stains_per_cell);
      for (int n = 0; n < count; ++n) {
        const double u0 = (static_cast<double>(cx) + random.Uniform()) * kStainCellMm;
        const double v0 = (static_cast<double>(cy) + random.Uniform()) * kStainCellMm;
        const double radius = random.LogUniform(kStainMinRadiusMm, kStainMaxRadiusMm);
        const bool dark = random.Uniform() < 0.6;
        const double depth =
            options_.stain_contrast_dn * random.Uniform(0.4, 1.4) * (dark ? -1.0 : 0.7);
        const double core = random.Uniform(0.2, 0.75);  // fraction of the radius at full depth
        const double ring = random.Uniform() < 0.3 ? random.Uniform(0.3, 0.8) * depth : 0.0;
        std::array<double, 6> harmonics{};
        for (double& h : harmonics) h = random.Uniform(-0.12, 0.12);
        if (!frame.Touches(u0, v0, radius * kStainReach)) continue;
        if (shape.values.empty()) {
          shape = NoisePyramid(stain_shape_key_, smooth.level, stain_shape_amplitudes_,
                               {smooth.i0, smooth.i0 + smooth.values.cols - 1},
                               {smooth.j0, smooth.j0 + smooth.values.rows - 1});
        }
        const double reach2 = radius * radius * kStainReach * kStainReach;
        for (int r = 0; r < smooth.values.rows; ++r) {
          const double dv = (static_cast<double>(smooth.j0 + r) + 0.5) * spacing_mm - v0;
          float* out = smooth.values.ptr<float>(r);
          const float* wobble = shape.values.ptr<float>(r);
          for (int c = 0; c < smooth.values.cols; ++c) {
            const double du = (static_cast<double>(smooth.i0 + c) + 0.5) * spacing_mm - u0;
            const double d2 = du * du + dv * dv;
            if (d2 > reach2) continue;
            const double d = std::sqrt(d2);
            double cos1 = 1.0, sin1 = 0.0;
            if (d > 0.0) {
              cos1 = du / d;
              sin1 = dv / d;
            }
            const double cos2 = cos1 * cos1 - sin1 * sin1, sin2 = 2.0 * sin1 * cos1;
            const double cos3 = cos1 * cos2 - sin1 * sin2, sin3 = sin1 * cos2 + cos1 * sin2;
            const double outline =
                radius * (1.0 + harmonics[0] * cos1 + harmonics[1] * sin1 + harmonics[2] * cos2 +
                          harmonics[3] * sin2 + harmonics[4] * cos3 + harmonics[5] * sin3);
            const double t = d / outline + 0.22 * wobble[c];
            double value = depth * (1.0 - SmoothStep(core, 1.0, t));
            if (ring != 0.0) {
              const double e = (t - 0.97) / 0.05;
              value += ring * std::exp(-e * e);
            }
            out[c] += static_cast<float>(value);
          }
        }
      }
    }
  }
}

void ProceduralFloor::DrawPores(const TileFrame& frame, cv::Mat& paint) const {
  if (options_.pore_density_per_cm2 <= 0.0) return;
  const double per_cell = options_.pore_density_per_cm2 * kPoreCellMm * kPoreCellMm * 0.01;
  const double reach_mm = kPoreMaxDiameterMm / 2.0;
  const double s = frame.mm_per_texel;
  const CellRange cells(frame, kPoreCellMm, reach_mm);
  for (std::int64_t cy = cells.y_lo; cy <= cells.y_hi; ++cy) {
    for (std::int64_t cx = cells.x_lo; cx <= cells.x_hi; ++cx) {
      CellRandom random(CellKey(pore_key_, cx, cy));
      const int count = random.Poisson(per_cell);
      for (int n = 0; n < count; ++n) {
        const double u = (static_cast<double>(cx) + random.Uniform()) * kPoreCellMm;
        const double v = (static_cast<double>(cy) + random.Uniform()) * kPoreCellMm;
        const double radius = random.LogUniform(kPoreMinDiameterMm, kPoreMaxDiameterMm) / 2.0;
        const double aspect = random.Uniform(0.55, 1.0);
        const double angle_deg = random.Uniform(0.0, 180.0);
        const double darkness = random.Uniform(0.6, 1.0);
        if (!frame.Touches(u, v, radius)) continue;
        const cv::Point centre = frame.ToCanvas(u, v);
        const cv::Size axes(static_cast<int>(std::lround(radius / s * kDrawScale)),
                            static_cast<int>(std::lround(radius * aspect / s * kDrawScale)));
        cv::ellipse(paint, centre, axes, angle_deg, 0.0, 360.0,
                    cv::Scalar(kPoreDn * darkness, 255.0 * darkness), cv::FILLED, cv::LINE_AA,
                    kDrawShift);
      }
    }
  }
}

void ProceduralFloor::DrawStones(const TileFrame& frame, cv::Mat& paint) const {
  if (stones_per_cell_ <= 0.0) return;
  const double cell = stone_cell_mm_;
  const CellRange cells(frame, cell, stone_reach_mm_);
  const double rim_dn = std::max(0.0, options_.matrix_dn - kRimDarkeningDn);
  std::vector<std::vector<cv::Point>> outline(1);
  std::vector<std::vector<cv::Point>> rim(1);
  std::vector<std::vector<cv::Point>> facet(1);
  std::array<double, 16> vertex_angle{};
  std::array<double, 16> vertex_radius{};
  for (std::int64_t cy = cells.y_lo; cy <= cells.y_hi; ++cy) {
    for (std::int64_t cx = cells.x_lo; cx <= cells.x_hi; ++cx) {
      CellRandom random(CellKey(stone_key_, cx, cy));
      const int count = random.Poisson(stones_per_cell_);
      for (int n = 0; n < count; ++n) {
        const double u = (static_cast<double>(cx) + random.Uniform()) * cell;
        const double v = (static_cast<double>(cy) + random.Uniform()) * cell;
        const double radius =
            random.LogUniform(options_.stone_min_diameter_mm, options_.stone_max_diameter_mm) / 2.0;
        const double aspect = random.Uniform(0.5, 1.0);
        const double orientation = random.Uniform(0.0, std::numbers::pi);
        const double kind = random.Uniform();
        const double shade = random.Normal();
        double brightness = 0.0;  // mixture: mid-grey majority, some bright quartz, some dark
        if (kind < 0.55) {
          brightness = 145.0 + 25.0 * shade;
        } else if (kind < 0.8) {
          brightness = 192.0 + 20.0 * shade;
        } else {
          brightness = 85.0 + 15.0 * shade;
        }
        brightness = std::clamp(brightness, 30.0, 245.0);
        const double rim_mm = random.Uniform(kRimMinMm, kRimMaxMm) + kRimPerRadius * radius;
        const double rim_opacity = random.Uniform(0.3, 0.8);
        const double facet_scale = random.Uniform(0.35, 0.55);
        const double facet_dn = random.Uniform(6.0, 22.0);
        const int vertices = 6 + static_cast<int>(random.Next() % 7);
        const double start = random.Uniform(0.0, 2.0 * std::numbers::pi);
        for (int k = 0; k < vertices; ++k) {
          vertex_angle[static_cast<std::size_t>(k)] =
              start + 2.0 * std::numbers::pi * (k + random.Uniform(-0.3, 0.3)) / vertices;
          vertex_radius[static_cast<std::size_t>(k)] = radius * random.Uniform(0.7, 1.15);
        }
        if (!frame.Touches(u, v, radius * kStoneReach + 2.0 * rim_mm)) continue;

        const double cos_o = std::cos(orientation);
        const double sin_o = std::sin(orientation);
        // Light comes from -u -v: the shadow rim shifts towards +u +v, the highlight facet
        // towards the light.
        const double shadow_shift = 0.5 * rim_mm;
        const double highlight_shift = -0.12 * radius;
        outline[0].clear();
        rim[0].clear();
        facet[0].clear();
        for (int k = 0; k < vertices; ++k) {
          const double a = vertex_angle[static_cast<std::size_t>(k)];
          const double rho = vertex_radius[static_cast<std::size_t>(k)];
          const double ca = std::cos(a);
          const double sa = std::sin(a) * aspect;
          const auto place = [&](double scale, double shift) {
            const double px = scale * ca;
            const double py = scale * sa;
            return frame.ToCanvas(u + cos_o * px - sin_o * py + shift,
                                  v + sin_o * px + cos_o * py + shift);
          };
          outline[0].push_back(place(rho, 0.0));
          rim[0].push_back(place(rho + rim_mm, shadow_shift));
          facet[0].push_back(place(rho * facet_scale, highlight_shift));
        }
        cv::fillPoly(paint, rim, cv::Scalar(rim_dn * rim_opacity, 255.0 * rim_opacity), cv::LINE_AA,
                     kDrawShift);
        cv::fillPoly(paint, outline, cv::Scalar(brightness, 255.0), cv::LINE_AA, kDrawShift);
        cv::fillPoly(paint, facet, cv::Scalar(std::min(brightness + facet_dn, 250.0), 255.0),
                     cv::LINE_AA, kDrawShift);
      }
    }
  }
}

void ProceduralFloor::DrawCracks(const TileFrame& frame, cv::Mat& crack) const {
  if (options_.crack_density_per_m2 <= 0.0) return;
  const double cell = crack_cell_mm_;
  const double per_cell = options_.crack_density_per_m2 * cell * cell * 1e-6;
  const double halo_mm = kCrackHaloScale * kCrackMaxWidthMm;
  const double reach_mm = options_.crack_max_length_mm * kCrackBranchReach + halo_mm;
  const CellRange cells(frame, cell, reach_mm);
  std::vector<CrackSegment> segments;
  for (std::int64_t cy = cells.y_lo; cy <= cells.y_hi; ++cy) {
    for (std::int64_t cx = cells.x_lo; cx <= cells.x_hi; ++cx) {
      CellRandom random(CellKey(crack_key_, cx, cy));
      const int count = random.Poisson(per_cell);
      for (int n = 0; n < count; ++n) {
        const double u = (static_cast<double>(cx) + random.Uniform()) * cell;
        const double v = (static_cast<double>(cy) + random.Uniform()) * cell;
        const double length = options_.crack_max_length_mm * random.Uniform(0.4, 1.0);
        const double heading = random.Uniform(0.0, 2.0 * std::numbers::pi);
        const double width = random.Uniform(0.2, 1.0);
        const std::uint64_t path_key = random.Next();
        if (!frame.Touches(u, v, length * kCrackBranchReach + halo_mm)) continue;
        CellRandom path(path_key);
        segments.clear();
        TraceCrack(frame, path, u, v, heading, length, width, true, path_key, segments);
        // All of the halo first, so that no halo covers the dark core at a joint.
        for (const CrackSegment& segment : segments) {
          const int thickness =
              std::max(1, static_cast<int>(std::lround(kCrackHaloScale * segment.width_texels)));
          cv::line(crack, segment.from, segment.to, cv::Scalar(255.0 * kCrackHaloOpacity),
                   thickness, cv::LINE_AA, kDrawShift);
        }
        for (const CrackSegment& segment : segments) {
          const int thickness = std::max(1, static_cast<int>(std::lround(segment.width_texels)));
          const double opacity = 0.9 * std::clamp(segment.width_texels, 0.4, 1.0);
          cv::line(crack, segment.from, segment.to, cv::Scalar(255.0 * opacity), thickness,
                   cv::LINE_AA, kDrawShift);
        }
      }
    }
  }
}

// A crack is a walk of 1 mm steps. Its course bends slowly (a mean-reverting curvature, so
// it stays roughly straight over its length); each step deviates from the course by a
// short-memory zigzag that does not accumulate. Its width swells and tapers to the ends, and
// it sprouts short branches.
void ProceduralFloor::TraceCrack(const TileFrame& frame, CellRandom& random, double u_mm,
                                 double v_mm, double heading_rad, double length_mm, double width_mm,
                                 bool main_crack, std::uint64_t branch_key,
                                 std::vector<CrackSegment>& segments) const {
  const double s = frame.mm_per_texel;
  const int steps = std::max(1, static_cast<int>(std::lround(length_mm / kCrackStepMm)));
  const double taper_mm = 0.15 * length_mm;
  double curvature = 0.0;  // rad per step
  double zigzag = 0.0;     // rad
  double swell = 0.0;      // slow relative width change
  double u = u_mm;
  double v = v_mm;
  double course = heading_rad;
  for (int k = 0; k < steps; ++k) {
    curvature = 0.97 * curvature + 0.0012 * random.Normal();
    zigzag = 0.5 * zigzag + 0.4 * random.Normal();
    swell = 0.9 * swell + 0.15 * random.Normal();
    course += curvature;
    const double heading = course + zigzag;
    const double next_u = u + kCrackStepMm * std::cos(heading);
    const double next_v = v + kCrackStepMm * std::sin(heading);
    const double along_mm = (k + 0.5) * kCrackStepMm;
    const double taper =
        std::sqrt(std::clamp(std::min(along_mm, length_mm - along_mm) / taper_mm, 0.0, 1.0));
    const double w_mm = std::clamp(width_mm * (1.0 + 0.5 * swell) * taper, 0.05, kCrackMaxWidthMm);
    const bool branch = main_crack && random.Uniform() < kCrackStepMm / 60.0;
    const double branch_turn = random.Uniform(0.35, 1.1) * (random.Uniform() < 0.5 ? -1.0 : 1.0);
    const double branch_length = length_mm * random.Uniform(0.05, 0.35);

    const double reach_mm = 0.5 * kCrackHaloScale * w_mm + 2.0 * s;
    if (std::max(u, next_u) + reach_mm >= frame.u_lo &&
        std::min(u, next_u) - reach_mm <= frame.u_hi &&
        std::max(v, next_v) + reach_mm >= frame.v_lo &&
        std::min(v, next_v) - reach_mm <= frame.v_hi) {
      segments.push_back({frame.ToCanvas(u, v), frame.ToCanvas(next_u, next_v), w_mm / s});
    }
    if (branch) {
      CellRandom branch_random(
          internal::Mix64(branch_key ^ branch_key_ ^ static_cast<std::uint64_t>(k)));
      TraceCrack(frame, branch_random, next_u, next_v, course + branch_turn, branch_length,
                 0.6 * width_mm, false, 0, segments);
    }
    u = next_u;
    v = next_v;
  }
}

}  // namespace

bool ProceduralFloorOptions::Check(std::string* why) const {
  auto fail = [why](const std::string& reason) {
    if (why != nullptr) *why = "procedural floor: " + reason;
    return false;
  };
  auto in_range = [](double value, double lo, double hi) {
    return std::isfinite(value) && value >= lo && value <= hi;
  };
  struct Bound {
    const char* name;
    double value;
    double lo;
    double hi;
  };
  const Bound bounds[] = {
      {"mm_per_texel", mm_per_texel, 0.02, 5.0},
      {"matrix_dn", matrix_dn, 0.0, 255.0},
      {"grain_contrast_dn", grain_contrast_dn, 0.0, 128.0},
      {"mottle_contrast_dn", mottle_contrast_dn, 0.0, 128.0},
      {"stone_area_fraction", stone_area_fraction, 0.0, 1.5},
      {"stone_min_diameter_mm", stone_min_diameter_mm, 0.3, 40.0},
      {"stone_max_diameter_mm", stone_max_diameter_mm, 0.3, 40.0},
      {"pore_density_per_cm2", pore_density_per_cm2, 0.0, 50.0},
      {"stain_density_per_m2", stain_density_per_m2, 0.0, 100.0},
      {"stain_contrast_dn", stain_contrast_dn, 0.0, 100.0},
      {"crack_density_per_m2", crack_density_per_m2, 0.0, 50.0},
      {"crack_max_length_mm", crack_max_length_mm, 10.0, 2000.0},
  };
  for (const Bound& bound : bounds) {
    if (!in_range(bound.value, bound.lo, bound.hi)) {
      std::ostringstream text;
      text << bound.name << " = " << bound.value << ": must be in [" << bound.lo << ", " << bound.hi
           << "]";
      return fail(text.str());
    }
  }
  if (stone_min_diameter_mm > stone_max_diameter_mm) {
    std::ostringstream text;
    text << "stone_min_diameter_mm = " << stone_min_diameter_mm
         << " exceeds stone_max_diameter_mm = " << stone_max_diameter_mm;
    return fail(text.str());
  }
  if (cache_bytes < (std::size_t{1} << 20)) {
    return fail("cache_bytes = " + std::to_string(cache_bytes) +
                ": must be at least 1 MiB (1048576)");
  }
  return true;
}

std::unique_ptr<Floor> MakeProceduralFloor(const ProceduralFloorOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  return std::make_unique<ProceduralFloor>(options);
}

}  // namespace mosaicloc::sim
