#include "mosaicloc/sim/floor_changes.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include <opencv2/core.hpp>

#include "floor_internal.hpp"
#include "mosaicloc/core/error.hpp"

namespace mosaicloc::sim {
namespace {

using internal::CellKey;
using internal::CellRandom;
using internal::FloorDiv;
using internal::LayerKey;
using internal::Mix64;

constexpr std::uint64_t kGrimeLayer = 101;
constexpr std::uint64_t kStainLayer = 102;
constexpr std::uint64_t kTileLayer = 103;
constexpr std::uint64_t kPaintLayer = 104;
constexpr double kGrimeCellMm = 150.0;
constexpr double kStainCellMm = 1000.0;
constexpr double kStainMaxRadiusMm = 100.0;
constexpr int kGrimeNodeTexels = 8;  // grime is exact on texels that are multiples of this, bilinear between
constexpr double kMid = 128.0;      // the grey that flattened texture tends to

double SmoothStep(double edge0, double edge1, double x) {
  const double t = std::clamp((x - edge0) / (edge1 - edge0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

double DistanceToSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double length2 = ab.squaredNorm();
  const double t = length2 > 0.0 ? std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

class Changed : public Floor {
 public:
  Changed(std::unique_ptr<Floor> base, const FloorChangeOptions& options,
          std::vector<std::vector<Eigen::Vector2d>> wheel_paths)
      : base_(std::move(base)), options_(options), wheel_paths_(std::move(wheel_paths)) {
    grime_key_ = LayerKey(options_.seed, kGrimeLayer);
    stain_key_ = LayerKey(options_.seed, kStainLayer);
    paint_key_ = static_cast<std::uint32_t>(LayerKey(options_.seed, kPaintLayer));
    if (options_.grime_fraction > 0.0) {
      // The noise level above which the wanted share of the floor lies, from samples.
      CellRandom random(LayerKey(options_.seed, 999));
      std::vector<double> samples(20000);
      for (double& s : samples) s = GrimeNoise(random.Uniform(-1e5, 1e5), random.Uniform(-1e5, 1e5));
      std::sort(samples.begin(), samples.end());
      const auto index = static_cast<std::size_t>(
          std::clamp((1.0 - options_.grime_fraction) * static_cast<double>(samples.size()), 0.0,
                     static_cast<double>(samples.size() - 1)));
      grime_threshold_ = options_.grime_fraction >= 1.0 ? -1.0 : samples[index];
    }
    const std::uint64_t tile = LayerKey(options_.seed, kTileLayer);
    tile_offset_col_ = 100003 + 2 * static_cast<std::int64_t>(Mix64(tile) % 4999);
    tile_offset_row_ = 200009 + 2 * static_cast<std::int64_t>(Mix64(tile + 1) % 4999);
  }

  double mm_per_texel() const override { return base_->mm_per_texel(); }

  std::string Describe() const override {
    std::ostringstream out;
    out << base_->Describe() << " changed: seed=" << options_.seed << " grime=" << options_.grime_fraction << "/"
        << options_.grime_strength << " stains_per_m2=" << options_.stains_per_m2 << " tyre_marks=" << options_.tyre_marks
        << " wet_radius_mm=" << options_.wet_radius_mm << " tile_size_mm=" << options_.tile_size_mm
        << " lane_width_mm=" << options_.lane_width_mm;
    return out.str();
  }

  cv::Mat Render(std::int64_t col0, std::int64_t row0, int cols, int rows) const override {
    if (cols < 0 || rows < 0) throw std::invalid_argument("Floor::Render: negative window size");
    cv::Mat base = base_->Render(col0, row0, cols, rows);
    if (cols == 0 || rows == 0) return base;
    cv::Mat value;
    base.convertTo(value, CV_32F);
    const double t = mm_per_texel();
    const auto world = [&](int c, int r) {
      return Eigen::Vector2d((static_cast<double>(col0 + c) + 0.5) * t, -(static_cast<double>(row0 + r) + 0.5) * t);
    };
    // The window's extent in the world, and a texel range of a world box within it.
    const double x_lo = (static_cast<double>(col0) + 0.5) * t, x_hi = (static_cast<double>(col0 + cols) - 0.5) * t;
    const double y_hi = -(static_cast<double>(row0) + 0.5) * t, y_lo = -(static_cast<double>(row0 + rows) - 0.5) * t;
    const auto texels_of = [&](double bx_lo, double bx_hi, double by_lo, double by_hi, cv::Rect* rect) {
      if (bx_hi < x_lo || bx_lo > x_hi || by_hi < y_lo || by_lo > y_hi) return false;
      const int c_lo = std::max(0, static_cast<int>(std::floor(bx_lo / t - 0.5 - static_cast<double>(col0))));
      const int c_hi = std::min(cols - 1, static_cast<int>(std::ceil(bx_hi / t - 0.5 - static_cast<double>(col0))));
      const int r_lo = std::max(0, static_cast<int>(std::floor(-by_hi / t - 0.5 - static_cast<double>(row0))));
      const int r_hi = std::min(rows - 1, static_cast<int>(std::ceil(-by_lo / t - 0.5 - static_cast<double>(row0))));
      if (c_hi < c_lo || r_hi < r_lo) return false;
      *rect = cv::Rect(c_lo, r_lo, c_hi - c_lo + 1, r_hi - r_lo + 1);
      return true;
    };

    // A replaced tile: new floor of the same kind (the base mirrored, from far away).
    cv::Rect rect;
    if (options_.tile_size_mm > 0.0) {
      const double h = 0.5 * options_.tile_size_mm;
      if (texels_of(options_.tile_x_mm - h, options_.tile_x_mm + h, options_.tile_y_mm - h, options_.tile_y_mm + h,
                    &rect)) {
        cv::Mat other = base_->Render(col0 + tile_offset_col_, tile_offset_row_ - (row0 + rows - 1), cols, rows);
        cv::flip(other, other, 0);
        for (int r = rect.y; r < rect.br().y; ++r) {
          for (int c = rect.x; c < rect.br().x; ++c) {
            const Eigen::Vector2d p = world(c, r);
            if (std::abs(p.x() - options_.tile_x_mm) <= h && std::abs(p.y() - options_.tile_y_mm) <= h) {
              value.at<float>(r, c) = other.at<std::uint8_t>(r, c);
            }
          }
        }
      }
    }
    if (options_.grime_fraction > 0.0) ApplyGrime(col0, row0, cols, rows, &value);
    if (options_.stains_per_m2 > 0.0) {
      const std::int64_t cx0 = FloorDiv(static_cast<std::int64_t>(std::floor(x_lo - kStainMaxRadiusMm)), 1000);
      const std::int64_t cx1 = FloorDiv(static_cast<std::int64_t>(std::floor(x_hi + kStainMaxRadiusMm)), 1000);
      const std::int64_t cy0 = FloorDiv(static_cast<std::int64_t>(std::floor(y_lo - kStainMaxRadiusMm)), 1000);
      const std::int64_t cy1 = FloorDiv(static_cast<std::int64_t>(std::floor(y_hi + kStainMaxRadiusMm)), 1000);
      for (std::int64_t cy = cy0; cy <= cy1; ++cy) {
        for (std::int64_t cx = cx0; cx <= cx1; ++cx) {
          CellRandom random(CellKey(stain_key_, cx, cy));
          const int n = random.Poisson(options_.stains_per_m2 * kStainCellMm * kStainCellMm * 1e-6);
          for (int i = 0; i < n; ++i) {
            const Eigen::Vector2d centre((static_cast<double>(cx) + random.Uniform()) * kStainCellMm,
                                         (static_cast<double>(cy) + random.Uniform()) * kStainCellMm);
            const double radius = random.LogUniform(10.0, kStainMaxRadiusMm);
            const double darkness = random.Uniform() < 0.75 ? -random.Uniform(0.15, 0.45) : random.Uniform(0.1, 0.3);
            const double phase1 = random.Uniform(0.0, 2.0 * std::numbers::pi);
            const double phase2 = random.Uniform(0.0, 2.0 * std::numbers::pi);
            const double reach = 1.4 * radius;
            if (!texels_of(centre.x() - reach, centre.x() + reach, centre.y() - reach, centre.y() + reach, &rect)) continue;
            for (int r = rect.y; r < rect.br().y; ++r) {
              for (int c = rect.x; c < rect.br().x; ++c) {
                const Eigen::Vector2d d = world(c, r) - centre;
                const double angle = std::atan2(d.y(), d.x());
                // An irregular outline: the radius wanders with the direction.
                const double edge = radius * (1.0 + 0.25 * std::sin(3.0 * angle + phase1) + 0.12 * std::sin(5.0 * angle + phase2));
                const double w = 1.0 - SmoothStep(0.6 * edge, edge, d.norm());
                if (w > 0.0) value.at<float>(r, c) *= static_cast<float>(1.0 + darkness * w);
              }
            }
          }
        }
      }
    }
    if (options_.tyre_marks > 0.0) {
      const double half = 0.5 * options_.tyre_mark_width_mm;
      cv::Mat mark = cv::Mat::zeros(rows, cols, CV_32F);
      for (const auto& path : wheel_paths_) {
        for (std::size_t i = 1; i < path.size(); ++i) {
          const Eigen::Vector2d& a = path[i - 1];
          const Eigen::Vector2d& b = path[i];
          if (!texels_of(std::min(a.x(), b.x()) - half, std::max(a.x(), b.x()) + half, std::min(a.y(), b.y()) - half,
                         std::max(a.y(), b.y()) + half, &rect)) {
            continue;
          }
          for (int r = rect.y; r < rect.br().y; ++r) {
            for (int c = rect.x; c < rect.br().x; ++c) {
              const double w = 1.0 - SmoothStep(0.4 * half, half, DistanceToSegment(world(c, r), a, b));
              float& m = mark.at<float>(r, c);
              m = std::max(m, static_cast<float>(w));
            }
          }
        }
      }
      const double s = options_.tyre_marks;
      for (int r = 0; r < rows; ++r) {
        for (int c = 0; c < cols; ++c) {
          const double w = s * mark.at<float>(r, c);
          if (w <= 0.0) continue;
          float& v = value.at<float>(r, c);
          v = static_cast<float>((kMid + (v - kMid) * (1.0 - 0.4 * w)) * (1.0 - 0.5 * w));
        }
      }
    }
    if (options_.wet_radius_mm > 0.0) {
      const double radius = options_.wet_radius_mm;
      const Eigen::Vector2d centre(options_.wet_x_mm, options_.wet_y_mm);
      if (texels_of(centre.x() - radius, centre.x() + radius, centre.y() - radius, centre.y() + radius, &rect)) {
        const double feather = std::min(30.0, 0.5 * radius);
        for (int r = rect.y; r < rect.br().y; ++r) {
          for (int c = rect.x; c < rect.br().x; ++c) {
            const double w = options_.wet_strength * (1.0 - SmoothStep(radius - feather, radius, (world(c, r) - centre).norm()));
            if (w <= 0.0) continue;
            float& v = value.at<float>(r, c);
            v = static_cast<float>((kMid + (v - kMid) * (1.0 - 0.6 * w)) * (1.0 - 0.35 * w));
          }
        }
      }
    }
    if (options_.lane_width_mm > 0.0) {
      const Eigen::Vector2d a(options_.lane_x0_mm, options_.lane_y0_mm), b(options_.lane_x1_mm, options_.lane_y1_mm);
      const double half = 0.5 * options_.lane_width_mm;
      if (texels_of(std::min(a.x(), b.x()) - half, std::max(a.x(), b.x()) + half, std::min(a.y(), b.y()) - half,
                    std::max(a.y(), b.y()) + half, &rect)) {
        for (int r = rect.y; r < rect.br().y; ++r) {
          for (int c = rect.x; c < rect.br().x; ++c) {
            const double w = 1.0 - SmoothStep(half - 1.5, half, DistanceToSegment(world(c, r), a, b));
            if (w <= 0.0) continue;
            float& v = value.at<float>(r, c);
            // Paint: its own grey and grain, with a little of the floor's relief showing through.
            const std::uint32_t h = internal::Mix32(static_cast<std::uint32_t>(col0 + c) * 0x9e3779b1U ^
                                                    static_cast<std::uint32_t>(row0 + r) * 0x85ebca77U ^ paint_key_);
            const double grain = 12.0 * (static_cast<double>(h) / 4294967296.0 - 0.5);
            v = static_cast<float>((1.0 - w) * v + w * (options_.lane_dn + 0.15 * (v - kMid) + grain));
          }
        }
      }
    }
    cv::Mat out;
    value.convertTo(out, CV_8U);
    return out;
  }

 private:
  // Smooth value noise in [0, 1): two octaves of a hashed lattice, smoothstep-interpolated.
  double GrimeNoise(double x_mm, double y_mm) const {
    double sum = 0.0;
    double weight = 0.0;
    for (int octave = 0; octave < 2; ++octave) {
      const double cell = octave == 0 ? kGrimeCellMm : kGrimeCellMm / 2.3;
      const double amplitude = octave == 0 ? 0.7 : 0.3;
      const double gx = x_mm / cell, gy = y_mm / cell;
      const auto ix = static_cast<std::int64_t>(std::floor(gx));
      const auto iy = static_cast<std::int64_t>(std::floor(gy));
      const double fx = SmoothStep(0.0, 1.0, gx - static_cast<double>(ix));
      const double fy = SmoothStep(0.0, 1.0, gy - static_cast<double>(iy));
      const std::uint64_t key = grime_key_ + static_cast<std::uint64_t>(octave);
      const auto corner = [&](std::int64_t dx, std::int64_t dy) {
        return static_cast<double>(CellKey(key, ix + dx, iy + dy) >> 11) * 0x1.0p-53;
      };
      const double v = (1 - fy) * ((1 - fx) * corner(0, 0) + fx * corner(1, 0)) +
                       fy * ((1 - fx) * corner(0, 1) + fx * corner(1, 1));
      sum += amplitude * v;
      weight += amplitude;
    }
    return sum / weight;
  }

  // The grime's weight (0..1) at every texel: exact on the texels whose indices are multiples
  // of kGrimeNodeTexels (a grid fixed to the floor, so windows agree), bilinear between.
  void ApplyGrime(std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat* value) const {
    const double t = mm_per_texel();
    const std::int64_t n = kGrimeNodeTexels;
    const std::int64_t node_c0 = FloorDiv(col0, n), node_r0 = FloorDiv(row0, n);
    const std::int64_t node_c1 = FloorDiv(col0 + cols - 1, n) + 1, node_r1 = FloorDiv(row0 + rows - 1, n) + 1;
    const int node_cols = static_cast<int>(node_c1 - node_c0 + 1), node_rows = static_cast<int>(node_r1 - node_r0 + 1);
    cv::Mat nodes(node_rows, node_cols, CV_64F);
    const double soft = 0.03;
    for (int j = 0; j < node_rows; ++j) {
      for (int i = 0; i < node_cols; ++i) {
        const double x = (static_cast<double>((node_c0 + i) * n) + 0.5) * t;
        const double y = -(static_cast<double>((node_r0 + j) * n) + 0.5) * t;
        nodes.at<double>(j, i) = SmoothStep(grime_threshold_ - soft, grime_threshold_ + soft, GrimeNoise(x, y));
      }
    }
    const double s = options_.grime_strength;
    for (int r = 0; r < rows; ++r) {
      const std::int64_t row = row0 + r;
      const int j = static_cast<int>(FloorDiv(row, n) - node_r0);
      const double fy = static_cast<double>(row - FloorDiv(row, n) * n) / static_cast<double>(n);
      for (int c = 0; c < cols; ++c) {
        const std::int64_t col = col0 + c;
        const int i = static_cast<int>(FloorDiv(col, n) - node_c0);
        const double fx = static_cast<double>(col - FloorDiv(col, n) * n) / static_cast<double>(n);
        const double g = (1 - fy) * ((1 - fx) * nodes.at<double>(j, i) + fx * nodes.at<double>(j, i + 1)) +
                         fy * ((1 - fx) * nodes.at<double>(j + 1, i) + fx * nodes.at<double>(j + 1, i + 1));
        const double w = s * g;
        if (w <= 0.0) continue;
        float& v = value->at<float>(r, c);
        v = static_cast<float>((kMid + (v - kMid) * (1.0 - 0.7 * w)) * (1.0 - 0.35 * w));
      }
    }
  }

  std::unique_ptr<Floor> base_;
  FloorChangeOptions options_;
  std::vector<std::vector<Eigen::Vector2d>> wheel_paths_;
  std::uint64_t grime_key_ = 0;
  std::uint64_t stain_key_ = 0;
  std::uint32_t paint_key_ = 0;
  double grime_threshold_ = 2.0;
  std::int64_t tile_offset_col_ = 0;
  std::int64_t tile_offset_row_ = 0;
};

}  // namespace

bool FloorChangeOptions::any() const {
  return grime_fraction > 0.0 || stains_per_m2 > 0.0 || tyre_marks > 0.0 || wet_radius_mm > 0.0 || tile_size_mm > 0.0 ||
         lane_width_mm > 0.0;
}

bool FloorChangeOptions::Check(std::string* why) const {
  const auto fail = [why](const char* message) {
    *why = message;
    return false;
  };
  if (!(grime_fraction >= 0.0 && grime_fraction <= 1.0)) return fail("grime_fraction must be in [0, 1]");
  if (!(grime_strength >= 0.0 && grime_strength <= 1.0)) return fail("grime_strength must be in [0, 1]");
  if (!(stains_per_m2 >= 0.0 && stains_per_m2 <= 100.0)) return fail("stains_per_m2 must be in [0, 100]");
  if (!(tyre_marks >= 0.0 && tyre_marks <= 1.0)) return fail("tyre_marks must be in [0, 1]");
  if (!(tyre_mark_width_mm > 0.0 && tyre_mark_width_mm <= 500.0)) return fail("tyre_mark_width_mm must be in (0, 500]");
  if (!(tyre_track_width_mm >= 0.0 && tyre_track_width_mm <= 5000.0)) return fail("tyre_track_width_mm must be in [0, 5000]");
  if (!(wet_radius_mm >= 0.0 && wet_radius_mm <= 1e5)) return fail("wet_radius_mm must be in [0, 1e5]");
  if (!(wet_strength >= 0.0 && wet_strength <= 1.0)) return fail("wet_strength must be in [0, 1]");
  if (!(tile_size_mm >= 0.0 && tile_size_mm <= 1e5)) return fail("tile_size_mm must be in [0, 1e5]");
  if (!(lane_width_mm >= 0.0 && lane_width_mm <= 1000.0)) return fail("lane_width_mm must be in [0, 1000]");
  if (!(lane_dn >= 0.0 && lane_dn <= 255.0)) return fail("lane_dn must be in [0, 255]");
  for (const double v : {wet_x_mm, wet_y_mm, tile_x_mm, tile_y_mm, lane_x0_mm, lane_y0_mm, lane_x1_mm, lane_y1_mm}) {
    if (!std::isfinite(v)) return fail("positions must be finite");
  }
  return true;
}

std::unique_ptr<Floor> ChangedFloor(std::unique_ptr<Floor> base, const FloorChangeOptions& options,
                                    std::vector<std::vector<Eigen::Vector2d>> wheel_paths) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("floor changes: " + why);
  return std::make_unique<Changed>(std::move(base), options, std::move(wheel_paths));
}

}  // namespace mosaicloc::sim
