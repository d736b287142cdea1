#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include <opencv2/core/mat.hpp>

namespace mosaicloc::sim {

/// A floor texture defined over the whole plane, sampled on a global texel grid.
///
/// Texel (col, row) covers the square whose centre is at world
///   x = (col + 0.5) * mm_per_texel,  y = -(row + 0.5) * mm_per_texel
/// (row grows towards -y like image rows; col and row may be negative). This is the mosaic
/// raster convention (design.md section 3) with origin (0, 0) and r = mm_per_texel.
class Floor {
 public:
  virtual ~Floor() = default;

  /// Side of one texel on the floor, mm.
  virtual double mm_per_texel() const = 0;

  /// Renders texels [col0, col0 + cols) x [row0, row0 + rows) as CV_8UC1 (rows x cols).
  /// Deterministic: a texel has the same value whatever the window it is rendered in.
  /// Thread-safe. A zero size gives an empty Mat; a negative size is a programming error
  /// and throws std::invalid_argument.
  virtual cv::Mat Render(std::int64_t col0, std::int64_t row0, int cols, int rows) const = 0;

  /// One line for dataset provenance, enough to rebuild the same floor,
  /// e.g. "procedural seed=7 mm_per_texel=0.125 ...".
  virtual std::string Describe() const = 0;
};

/// A synthetic concrete/asphalt floor: aggregate grains (0.2-1 mm) and stones, air pores,
/// low-frequency mottling, stains and cracks. Every feature comes from a hash of
/// (seed, layer, world cell), so the floor never repeats and has no seams at any scale.
/// Physical sizes are in mm: changing mm_per_texel renders the same stones, stains and
/// cracks at another resolution (the fine noise octaves follow the texel grid).
/// Renders are bit-identical for the same options with the same build; another OpenCV
/// version or CPU (SIMD path) may change a few texels by 1 DN.
struct ProceduralFloorOptions {
  /// Floor seed (separate from the simulator's noise seed).
  std::uint64_t seed = 1;
  /// Texel side, mm. Valid range [0.02, 5].
  double mm_per_texel = 0.125;

  /// Mean grey of the cement/binder between stones, DN.
  double matrix_dn = 128.0;
  /// Strength of the sand speckle (0.2-1 mm grains) in the matrix, DN (about its std).
  double grain_contrast_dn = 22.0;
  /// Standard deviation of the mottling (2-500 mm blotchiness), DN.
  double mottle_contrast_dn = 9.0;

  /// Fraction of the floor covered by stones (sum of stone areas / floor area, overlaps
  /// counted twice), in [0, 1.5].
  double stone_area_fraction = 0.45;
  /// Stone diameters are log-uniform in [min, max], mm; 0.3 <= min <= max <= 40.
  /// Small stones are many: their count per area grows as 1 / min^2, and so does the cost.
  double stone_min_diameter_mm = 1.0;
  double stone_max_diameter_mm = 8.0;

  /// Dark air voids, 0.3-2 mm across, per cm^2, in [0, 50].
  double pore_density_per_cm2 = 3.0;

  /// Soft dark or light blotches 50-500 mm across, per m^2, in [0, 100].
  double stain_density_per_m2 = 3.0;
  /// Typical stain depth, DN, in [0, 100].
  double stain_contrast_dn = 22.0;

  /// Thin dark meandering cracks, per m^2 (counted by start point), in [0, 50]. A tile
  /// traces every crack that may reach it: the cost grows as density * max_length^3.
  double crack_density_per_m2 = 1.0;
  /// Longest crack (a crack is 40-100 % of this, plus short branches), mm, in [10, 2000].
  double crack_max_length_mm = 600.0;

  /// Budget of the generated-tile cache (256 x 256 texel tiles, 64 KiB each), bytes;
  /// at least 1 MiB. Each thread generating a tile also holds about 1 MiB of scratch.
  std::size_t cache_bytes = std::size_t{64} << 20;

  /// True if every field is in range; otherwise false with the first problem in *why.
  bool Check(std::string* why) const;
};

/// Throws core::Error (invalid input) with Check()'s reason if the options are invalid.
/// The floor keeps a thread-safe LRU cache of generated tiles bounded by cache_bytes; a
/// missing tile is generated once even when several threads ask for it at the same time.
std::unique_ptr<Floor> MakeProceduralFloor(const ProceduralFloorOptions& options);

struct ImageFloorOptions {
  /// Any image OpenCV reads; colour is converted to grey, 16-bit and float to 8-bit.
  std::filesystem::path image;
  /// Size of one image pixel on the floor, mm; in (0, 100].
  double mm_per_texel = 0.25;
  /// How the picture covers the plane:
  /// - "repeat": tiled, texel (c, r) = image pixel (c mod W, r mod H). The floor repeats with
  ///   the picture's size as its period, as printed vinyl or tiles do.
  /// - "patches": a floor that never repeats, made from the picture as a real floor of the same
  ///   material would be: squares of `patch_mm` centred on a grid, each cut from the picture at
  ///   a place drawn from (seed, square) and turned by a multiple of 90 degrees and perhaps
  ///   mirrored (also drawn), overlapping their neighbours by a quarter of their side, where
  ///   they are blended with weights that keep the picture's mean and variance (the
  ///   histogram-preserving blend of Heitz and Neyret, 2018). The middle of each square is the
  ///   picture's own texels. Suits textures without a direction (asphalt, concrete); a picture
  ///   with a regular pattern (brick) or a light from one side shows its seams. A square is
  ///   much smaller than a camera's view, so that a view holds many, and no place but its own
  ///   holds them as they lie: with the asphalt picture (512 mm) over 85 m of lanes, squares of
  ///   64 mm laid unturned gave 17 % of the views a second place that verified.
  std::string layout = "repeat";
  /// "patches": the grid's spacing, mm. The picture must be at least 1.25 times as large in texels.
  double patch_mm = 32.0;
  /// "patches": where each square is cut from; the same seed gives the same floor.
  std::uint64_t seed = 1;

  /// True if a file is named and every value is in range; otherwise false with the reason
  /// in *why. Does not open the file.
  bool Check(std::string* why) const;
};

/// The image over the whole plane, laid out as options.layout says. Throws core::Error
/// (invalid input) naming the file if it cannot be read, or is smaller than 16 x 16 pixels
/// (for "patches", than a square and its blend), or if the options are invalid.
std::unique_ptr<Floor> MakeImageFloor(const ImageFloorOptions& options);

}  // namespace mosaicloc::sim
