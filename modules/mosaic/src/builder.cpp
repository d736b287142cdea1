#include "mosaicloc/mosaic/builder.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
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

const cv::Mat& MapBuilder::WeightMap(int width, int height) {
  if (weight_map_.cols != width || weight_map_.rows != height) {
    // Tent: distance to the nearest edge (in pixels, at pixel centres), so neighbouring
    // frames fade into each other and the frame centre wins a best-view contest.
    weight_map_.create(height, width, CV_32F);
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < width; ++u) {
        const float d = static_cast<float>(std::min({u + 0.5, width - u - 0.5, v + 0.5, height - v - 0.5}));
        weight_map_.at<float>(v, u) = d;
      }
    }
  }
  return weight_map_;
}

void MapBuilder::AddFrame(const cv::Mat& image, const core::Pose2& world_from_camera, double mm_per_px) {
  if (image.type() != CV_8UC1 || image.empty()) core::ThrowInvalidInput("map builder: frames must be 8-bit grey");
  ++frames_;
  // Warp (value x weight, weight) in one two-channel pass: interpolating both with the same
  // kernel keeps value = channel 0 / channel 1 right even where the frame's edge is sampled.
  // Bicubic, not bilinear: the map is rendered by a second (bilinear) interpolation, and two
  // bilinear passes blur pixel-scale texture (real asphalt: frame-to-view ZNCC 0.970 -> 0.997).
  const cv::Mat& weights = WeightMap(image.cols, image.rows);
  cv::Mat values;
  image.convertTo(values, CV_32F);
  cv::Mat weighted[2] = {values.mul(weights), weights};
  cv::Mat prepared;
  cv::merge(weighted, 2, prepared);

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
  const std::int64_t t = grid_.tile_size_px;
  for (std::int64_t tr = FloorDiv(r0, t); tr <= FloorDiv(r1, t); ++tr) {
    for (std::int64_t tc = FloorDiv(c0, t); tc <= FloorDiv(c1, t); ++tc) {
      const std::int64_t x0 = std::max(c0, tc * t);
      const std::int64_t y0 = std::max(r0, tr * t);
      const std::int64_t x1 = std::min(c1 + 1, (tc + 1) * t);
      const std::int64_t y1 = std::min(r1 + 1, (tr + 1) * t);
      if (x1 <= x0 || y1 <= y0) continue;
      const cv::Rect roi(static_cast<int>(x0 - tc * t), static_cast<int>(y0 - tr * t), static_cast<int>(x1 - x0),
                         static_cast<int>(y1 - y0));
      cv::Mat map(2, 3, CV_64F);
      const Eigen::Vector2d shifted = offset + linear * Eigen::Vector2d(static_cast<double>(x0), static_cast<double>(y0));
      map.at<double>(0, 0) = linear(0, 0);
      map.at<double>(0, 1) = linear(0, 1);
      map.at<double>(0, 2) = shifted.x();
      map.at<double>(1, 0) = linear(1, 0);
      map.at<double>(1, 1) = linear(1, 1);
      map.at<double>(1, 2) = shifted.y();
      cv::Mat warped;
      cv::warpAffine(prepared, warped, map, roi.size(), cv::INTER_CUBIC | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                     cv::Scalar(0, 0));
      auto [it, inserted] = accumulators_.try_emplace(TileKey{0, tc, tr});
      if (inserted) it->second = cv::Mat::zeros(static_cast<int>(t), static_cast<int>(t), CV_32FC2);
      cv::Mat accumulator = it->second(roi);
      if (blend_ == Blend::kFeather) {
        accumulator += warped;
        continue;
      }
      for (int y = 0; y < roi.height; ++y) {
        auto* best = accumulator.ptr<cv::Vec2f>(y);
        const auto* candidate = warped.ptr<cv::Vec2f>(y);
        for (int x = 0; x < roi.width; ++x) {
          if (candidate[x][1] > best[x][1]) best[x] = cv::Vec2f(candidate[x][0] / candidate[x][1], candidate[x][1]);
        }
      }
    }
  }
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

void WriteWithPyramid(TileStore& store, const std::vector<TileWrite>& level0) {
  const MapGrid& grid = store.grid();
  std::vector<TileWrite> all = level0;
  // The tiles of the level being processed, new content first, then the store's.
  std::map<std::pair<std::int64_t, std::int64_t>, cv::Mat> changed;
  for (const auto& tile : level0) {
    if (tile.key.level != 0) core::ThrowInvalidInput("WriteWithPyramid takes level-0 tiles only");
    changed[{tile.key.col, tile.key.row}] = tile.pixels;
  }
  for (int k = 1; k < grid.levels; ++k) {
    std::set<std::pair<std::int64_t, std::int64_t>> parent_keys;
    for (const auto& [index, pixels] : changed) parent_keys.insert({FloorDiv(index.first, 2), FloorDiv(index.second, 2)});
    std::map<std::pair<std::int64_t, std::int64_t>, cv::Mat> parents;
    for (const auto& parent : parent_keys) {
      std::array<cv::Mat, 4> children;
      for (int i = 0; i < 4; ++i) {
        const std::pair<std::int64_t, std::int64_t> child{2 * parent.first + i % 2, 2 * parent.second + i / 2};
        if (const auto it = changed.find(child); it != changed.end()) {
          children[static_cast<std::size_t>(i)] = it->second;
        } else if (const TileRead read = store.Read(TileKey{k - 1, child.first, child.second});
                   read.status == TileStatus::kOk) {
          children[static_cast<std::size_t>(i)] = read.pixels;
        }
      }
      parents[parent] = internal::Downsample(children, grid.tile_size_px);
      all.push_back({TileKey{k, parent.first, parent.second}, parents[parent]});
    }
    changed = std::move(parents);
  }
  store.Write(all);  // one transaction: level 0 and the pyramid change together or not at all
}

}  // namespace mosaicloc::mosaic
