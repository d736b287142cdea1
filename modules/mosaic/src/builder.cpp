#include "mosaicloc/mosaic/builder.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "paint.hpp"
#include "pyramid.hpp"

namespace mosaicloc::mosaic {

Blend ParseBlend(const std::string& name) {
  if (name == "feather") return Blend::kFeather;
  if (name == "best-view") return Blend::kBestView;
  core::ThrowInvalidInput("blend must be 'feather' or 'best-view', got '" + name + "'");
}

MapBuilder::MapBuilder(const MapGrid& grid, Blend blend) : grid_(grid), blend_(blend) {
  std::string why;
  if (!grid_.Check(&why)) core::ThrowInvalidInput("map grid: " + why);
}

internal::PaintSource MapBuilder::Pad(const cv::Mat& image) {
  if (image.type() != CV_8UC1 || image.empty()) core::ThrowInvalidInput("map builder: frames must be 8-bit grey");
  ++frames_;
  cv::copyMakeBorder(image, padded_, internal::kPaintBorderPx, internal::kPaintBorderPx, internal::kPaintBorderPx,
                     internal::kPaintBorderPx, cv::BORDER_REPLICATE);
  return {padded_.ptr<std::uint8_t>(internal::kPaintBorderPx) + internal::kPaintBorderPx,
          static_cast<std::ptrdiff_t>(padded_.step[0]), image.cols, image.rows};
}

template <class PaintRun>
void MapBuilder::PaintFootprint(std::int64_t c0, std::int64_t c1, std::int64_t r0, std::int64_t r1,
                                const PaintRun& paint_row) {
  const std::int64_t t = grid_.tile_size_px;
  for (std::int64_t tr = FloorDiv(r0, t); tr <= FloorDiv(r1, t); ++tr) {
    for (std::int64_t tc = FloorDiv(c0, t); tc <= FloorDiv(c1, t); ++tc) {
      const std::int64_t x0 = std::max(c0, tc * t);
      const std::int64_t y0 = std::max(r0, tr * t);
      const std::int64_t x1 = std::min(c1 + 1, (tc + 1) * t);
      const std::int64_t y1 = std::min(r1 + 1, (tr + 1) * t);
      if (x1 <= x0 || y1 <= y0) continue;
      auto [it, inserted] = accumulators_.try_emplace(TileKey{0, tc, tr});
      if (inserted) it->second = cv::Mat::zeros(static_cast<int>(t), static_cast<int>(t), CV_32FC2);
      changed_.insert(it->first);
      for (std::int64_t row = y0; row < y1; ++row) {
        paint_row(row, x0, x1, it->second.ptr<float>(static_cast<int>(row - tr * t)) + 2 * (x0 - tc * t));
      }
    }
  }
}

void MapBuilder::AddFrame(const cv::Mat& image, const core::Pose2& world_from_camera, double mm_per_px) {
  const internal::PaintSource source = Pad(image);
  // Each map pixel takes the frame's bicubic (Catmull-Rom) value at its centre (in float) and
  // the frame's tent weight evaluated there (internal::PaintRow). Bicubic, not bilinear: the map is
  // rendered by a second (bilinear) interpolation, and two bilinear passes blur pixel-scale
  // texture (real asphalt: frame-to-view ZNCC 0.970 -> 0.997).
  // The tent reaches zero half a pixel beyond the frame's edge, not at it: a view rendered
  // at a frame's pose samples the map up to one pixel beyond the frame's outer pixel
  // centres, and a map that stops at the edge leaves the view an unmapped rim wherever no
  // other frame reaches (round trip, worst frame: asphalt 0.9930 and brick 0.9917 with the
  // tent ending at the edge, 0.9977 and 0.9985 with it half a pixel beyond).

  // Level-0 raster (col, row) -> world -> image pixel: an affine map.
  const double res = grid_.mm_per_px;
  const double cx = 0.5 * (image.cols - 1);
  const double cy = 0.5 * (image.rows - 1);
  const core::Pose2 camera_from_world = world_from_camera.Inverse();
  const Eigen::Matrix2d r = camera_from_world.Rotation();
  // world = (x0 + (c + 0.5) res, y0 - (r + 0.5) res); p_C = R world + t; u = cx + p_C.x / s, v = cy - p_C.y / s.
  Eigen::Matrix2d linear;
  linear << r(0, 0) * res / mm_per_px, -r(0, 1) * res / mm_per_px, -r(1, 0) * res / mm_per_px, r(1, 1) * res / mm_per_px;
  const Eigen::Vector2d world00(grid_.origin_x_mm + 0.5 * res, grid_.origin_y_mm - 0.5 * res);
  const Eigen::Vector2d camera00 = camera_from_world * world00;
  const Eigen::Vector2d offset(cx + camera00.x() / mm_per_px, cy - camera00.y() / mm_per_px);

  // Footprint of the frame in level-0 raster pixels.
  double min_c = 1e300, min_r = 1e300, max_c = -1e300, max_r = -1e300;
  for (const double u : {-0.5, image.cols - 0.5}) {
    for (const double v : {-0.5, image.rows - 0.5}) {
      const Eigen::Vector2d world = world_from_camera * Eigen::Vector2d((u - cx) * mm_per_px, -(v - cy) * mm_per_px);
      const Eigen::Vector2d raster = grid_.WorldToRaster(world, 0);
      min_c = std::min(min_c, raster.x());
      max_c = std::max(max_c, raster.x());
      min_r = std::min(min_r, raster.y());
      max_r = std::max(max_r, raster.y());
    }
  }
  const auto c0 = static_cast<std::int64_t>(std::floor(min_c));
  const auto c1 = static_cast<std::int64_t>(std::ceil(max_c));
  const auto r0 = static_cast<std::int64_t>(std::floor(min_r));
  const auto r1 = static_cast<std::int64_t>(std::ceil(max_r));
  // Along a raster row, the columns whose frame position (u, v) has weight:
  // -1 < u0 + du c < width and likewise v (a column wider each side; PaintRow tests exactly).
  const auto columns_inside = [&](double u_row, double v_row, std::int64_t from, std::int64_t to) {
    double low = static_cast<double>(from), high = static_cast<double>(to);
    const auto clip = [&](double start, double step, double limit) {
      if (std::abs(step) < 1e-12) {
        if (start <= -1.0 - 1e-9 || start >= limit + 1e-9) high = low - 1.0;
        return;
      }
      const double a = (-1.0 - start) / step, b = (limit - start) / step;
      low = std::max(low, std::floor(std::min(a, b)) - 1.0);
      high = std::min(high, std::ceil(std::max(a, b)) + 1.0);
    };
    clip(u_row, linear(0, 0), image.cols);
    clip(v_row, linear(1, 0), image.rows);
    return std::pair<std::int64_t, std::int64_t>(static_cast<std::int64_t>(low), static_cast<std::int64_t>(high));
  };
  PaintFootprint(c0, c1, r0, r1, [&](std::int64_t row, std::int64_t x0, std::int64_t x1, float* pairs) {
    // Frame position of raster (x, row) = offset + linear (x, row).
    const double u_row = offset.x() + linear(0, 1) * static_cast<double>(row);
    const double v_row = offset.y() + linear(1, 1) * static_cast<double>(row);
    const auto [from, to] = columns_inside(u_row, v_row, x0, x1 - 1);
    if (to < from) return;
    internal::PaintRow(source, u_row + linear(0, 0) * static_cast<double>(from),
                       v_row + linear(1, 0) * static_cast<double>(from), linear(0, 0), linear(1, 0),
                       static_cast<int>(to - from + 1), pairs + 2 * (from - x0), blend_ == Blend::kBestView);
  });
}

void MapBuilder::AddFrame(const cv::Mat& image, const core::Pose2& world_from_view, double mm_per_px,
                          double focal_px, double tilt_x_rad, double tilt_y_rad) {
  if (tilt_x_rad == 0.0 && tilt_y_rad == 0.0) return AddFrame(image, world_from_view, mm_per_px);
  if (!(std::abs(tilt_x_rad) < 0.5 && std::abs(tilt_y_rad) < 0.5) || !(focal_px > 0.0)) {
    core::ThrowInvalidInput("map builder: a tilted camera needs a focal length > 0 and a tilt within 0.5 rad");
  }
  // In camera axes (x right, y up the image, z back to the lens), pixel (u, v) is the ray
  // d = (u - cx, -(v - cy), -f) and the floor the points P with n.P = -h, h = mm_per_px f. Q
  // turns n onto z: in its axes the floor is z = -h and (x, y) are floor millimetres, the
  // optical axis's foot q0 where world_from_view puts the view's centre.
  const Eigen::Vector3d n = Eigen::Vector3d(-std::tan(tilt_y_rad), std::tan(tilt_x_rad), 1.0).normalized();
  const Eigen::Matrix3d q = Eigen::Quaterniond::FromTwoVectors(n, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const double h = mm_per_px * focal_px;
  const Eigen::Vector2d q0 = (q * Eigen::Vector3d(0.0, 0.0, -h / n.z())).head<2>();
  const double cx = 0.5 * (image.cols - 1);
  const double cy = 0.5 * (image.rows - 1);
  // Level-0 raster (c, r) -> world -> view's floor axes -> camera -> (u w, v w, w): linear
  // in (c, r, 1).
  const double res = grid_.mm_per_px;
  const Eigen::Matrix2d view_from_world = world_from_view.Rotation().transpose();
  const Eigen::Vector2d world00(grid_.origin_x_mm + 0.5 * res, grid_.origin_y_mm - 0.5 * res);
  Eigen::Matrix<double, 3, 3> floor_from_raster;  // columns: per c, per r, at (0, 0)
  floor_from_raster.block<2, 1>(0, 0) = view_from_world * Eigen::Vector2d(res, 0.0);
  floor_from_raster.block<2, 1>(0, 1) = view_from_world * Eigen::Vector2d(0.0, -res);
  floor_from_raster.block<2, 1>(0, 2) = view_from_world * (world00 - world_from_view.translation_mm()) + q0;
  floor_from_raster.row(2) << 0.0, 0.0, -h;
  const Eigen::Matrix3d camera_from_raster = q.transpose() * floor_from_raster;
  Eigen::Matrix3d image_from_camera;  // (u w, v w, w) from camera P, w = -P.z
  image_from_camera << focal_px, 0.0, -cx, 0.0, -focal_px, -cy, 0.0, 0.0, -1.0;
  const Eigen::Matrix3d image_from_raster = image_from_camera * camera_from_raster;

  // Footprint: the frame's corners (a pixel beyond, where the weight ends) through the inverse.
  const Eigen::Matrix3d raster_from_image = image_from_raster.inverse();
  double min_c = 1e300, min_r = 1e300, max_c = -1e300, max_r = -1e300;
  for (const double u : {-1.0, static_cast<double>(image.cols)}) {
    for (const double v : {-1.0, static_cast<double>(image.rows)}) {
      const Eigen::Vector3d raster = raster_from_image * Eigen::Vector3d(u, v, 1.0);
      if (!(raster.z() > 0.0)) core::ThrowInvalidInput("map builder: the tilted camera does not see the floor whole");
      min_c = std::min(min_c, raster.x() / raster.z());
      max_c = std::max(max_c, raster.x() / raster.z());
      min_r = std::min(min_r, raster.y() / raster.z());
      max_r = std::max(max_r, raster.y() / raster.z());
    }
  }
  const auto c0 = static_cast<std::int64_t>(std::floor(min_c));
  const auto c1 = static_cast<std::int64_t>(std::ceil(max_c));
  const auto r0 = static_cast<std::int64_t>(std::floor(min_r));
  const auto r1 = static_cast<std::int64_t>(std::ceil(max_r));

  const internal::PaintSource source = Pad(image);
  const Eigen::Vector3d step = image_from_raster.col(0);
  PaintFootprint(c0, c1, r0, r1, [&](std::int64_t row, std::int64_t x0, std::int64_t x1, float* pairs) {
    const Eigen::Vector3d start =
        image_from_raster * Eigen::Vector3d(static_cast<double>(x0), static_cast<double>(row), 1.0);
    internal::PaintRowProjective(source, start.x(), start.y(), start.z(), step.x(), step.y(), step.z(),
                                 static_cast<int>(x1 - x0), pairs, blend_ == Blend::kBestView);
  });
}

std::size_t MapBuilder::unsaved_bytes() const {
  const auto side = static_cast<std::size_t>(grid_.tile_size_px);
  return changed_.size() * side * side * 2 * sizeof(float);
}

std::vector<TileKey> MapBuilder::TileKeys() const {
  std::vector<TileKey> keys;
  keys.reserve(accumulators_.size());
  for (const auto& [key, accumulator] : accumulators_) keys.push_back(key);
  return keys;
}

cv::Mat MapBuilder::FinishTile(const TileKey& key) const {
  cv::Mat channels[2];
  cv::split(accumulators_.at(key), channels);
  cv::Mat mean;
  if (blend_ == Blend::kFeather) {
    cv::divide(channels[0], cv::max(channels[1], 1e-12), mean);
  } else {
    mean = channels[0];
  }
  cv::Mat out;
  mean.convertTo(out, CV_8U);
  cv::max(out, 1, out);  // 0 means unmapped
  out.setTo(cv::Scalar(kUnmapped), channels[1] <= 1e-6);
  return out;
}

void MapBuilder::Write(TileStore& store, const std::function<void(double)>& progress, int batch) const {
  const std::int64_t t = grid_.tile_size_px;
  std::map<std::pair<std::int64_t, std::int64_t>, cv::Mat> level;
  for (const auto& [key, acc] : accumulators_) level[{key.col, key.row}] = FinishTile(key);
  // Tiles per level shrink about fourfold: the total is about 4/3 of level 0.
  const std::size_t total = level.size() * 4 / 3 + static_cast<std::size_t>(grid_.levels);
  std::size_t done = 0;
  for (int k = 0; k < grid_.levels; ++k) {
    std::vector<TileWrite> pending;
    for (const auto& [index, pixels] : level) {
      pending.push_back({TileKey{k, index.first, index.second}, pixels});
      if (static_cast<int>(pending.size()) == batch) {
        store.Write(pending);
        done += pending.size();
        pending.clear();
        if (progress) progress(std::min(1.0, static_cast<double>(done) / static_cast<double>(total)));
      }
    }
    store.Write(pending);
    done += pending.size();
    if (progress) progress(std::min(1.0, static_cast<double>(done) / static_cast<double>(total)));
    if (k + 1 == grid_.levels) break;

    // Next level: each pixel is the mean of the mapped ones among its 2x2 children.
    std::map<std::pair<std::int64_t, std::int64_t>, cv::Mat> parents;
    std::set<std::pair<std::int64_t, std::int64_t>> parent_keys;
    for (const auto& [index, pixels] : level) parent_keys.insert({FloorDiv(index.first, 2), FloorDiv(index.second, 2)});
    for (const auto& parent : parent_keys) {
      std::array<cv::Mat, 4> children;
      for (int i = 0; i < 4; ++i) {
        const auto it = level.find({2 * parent.first + i % 2, 2 * parent.second + i / 2});
        if (it != level.end()) children[static_cast<std::size_t>(i)] = it->second;
      }
      parents[parent] = internal::Downsample(children, static_cast<int>(t));
    }
    level = std::move(parents);
  }
  if (progress) progress(1.0);
}

}  // namespace mosaicloc::mosaic

namespace mosaicloc::mosaic {

namespace {

using TileIndex = std::pair<std::int64_t, std::int64_t>;

// Every pyramid tile above changed level-0 tiles (an empty Mat: a tile removed), recomputed
// from them and their unchanged siblings in the store. Tiles left with nothing mapped are
// listed in `removed` instead.
void PyramidAbove(const TileStore& store, std::map<TileIndex, cv::Mat> changed, std::vector<TileWrite>* writes,
                  std::vector<TileKey>* removed) {
  const MapGrid& grid = store.grid();
  for (int k = 1; k < grid.levels; ++k) {
    std::set<TileIndex> parent_keys;
    for (const auto& [index, pixels] : changed) parent_keys.insert({FloorDiv(index.first, 2), FloorDiv(index.second, 2)});
    std::map<TileIndex, cv::Mat> parents;
    for (const auto& parent : parent_keys) {
      std::array<cv::Mat, 4> children;
      bool any = false;
      for (int i = 0; i < 4; ++i) {
        const TileIndex child{2 * parent.first + i % 2, 2 * parent.second + i / 2};
        if (const auto it = changed.find(child); it != changed.end()) {
          children[static_cast<std::size_t>(i)] = it->second;
        } else if (const TileRead read = store.Read(TileKey{k - 1, child.first, child.second});
                   read.status == TileStatus::kOk) {
          children[static_cast<std::size_t>(i)] = read.pixels;
        }
        any = any || !children[static_cast<std::size_t>(i)].empty();
      }
      const TileKey key{k, parent.first, parent.second};
      if (any) {
        parents[parent] = internal::Downsample(children, grid.tile_size_px);
        writes->push_back({key, parents[parent]});
      } else {
        parents[parent] = cv::Mat();
        if (removed != nullptr) removed->push_back(key);
      }
    }
    changed = std::move(parents);
  }
}

}  // namespace

std::optional<std::int64_t> WriteWithPyramid(TileStore& store, const std::vector<TileWrite>& level0,
                                             const std::string& reason) {
  std::vector<TileWrite> all = level0;
  std::map<TileIndex, cv::Mat> changed;
  for (const auto& tile : level0) {
    if (tile.key.level != 0) core::ThrowInvalidInput("WriteWithPyramid takes level-0 tiles only");
    changed[{tile.key.col, tile.key.row}] = tile.pixels;
  }
  PyramidAbove(store, std::move(changed), &all, nullptr);
  // One transaction: level 0 and the pyramid change together or not at all.
  if (reason.empty()) {
    store.Write(all);
    return std::nullopt;
  }
  return store.WriteRecorded(all, reason);
}

RevertSummary RevertUpdate(TileStore& store, std::int64_t id) {
  const std::vector<MapUpdate> history = store.History();
  const auto it = std::find_if(history.begin(), history.end(), [id](const MapUpdate& u) { return u.id == id; });
  const std::string name = store.file().string() + ": update " + std::to_string(id);
  if (it == history.end()) core::ThrowInvalidInput(name + ": no such update (`map history` lists them)");
  if (!it->reverted.empty()) core::ThrowInvalidInput(name + ": already reverted at " + it->reverted);
  const std::vector<ReplacedTile> replaced = store.Replaced(id);
  std::set<TileIndex> mine;
  for (const ReplacedTile& tile : replaced) mine.insert({tile.key.col, tile.key.row});
  // A later update in force over the same floor was made on top of this one: undoing this one
  // alone would throw the later one away with it.
  for (auto later = std::next(it); later != history.end(); ++later) {
    if (!later->reverted.empty()) continue;
    for (const ReplacedTile& tile : store.Replaced(later->id)) {
      if (mine.count({tile.key.col, tile.key.row}) > 0) {
        core::ThrowInvalidInput(name + ": update " + std::to_string(later->id) + " (" + later->time +
                                ") changed tile " + tile.key.ToString() + " after it; revert that one first");
      }
    }
  }
  RevertSummary summary;
  std::vector<TileWrite> writes;
  std::vector<TileKey> removed;
  std::map<TileIndex, cv::Mat> changed;
  for (const ReplacedTile& tile : replaced) {
    if (tile.pixels) {
      writes.push_back({tile.key, *tile.pixels});
      ++summary.restored;
    } else {
      removed.push_back(tile.key);
      ++summary.removed;
    }
    changed[{tile.key.col, tile.key.row}] = tile.pixels ? *tile.pixels : cv::Mat();
  }
  PyramidAbove(store, std::move(changed), &writes, &removed);
  store.WriteRevert(id, writes, removed);
  summary.id = id;
  summary.reason = it->reason;
  return summary;
}

}  // namespace mosaicloc::mosaic
