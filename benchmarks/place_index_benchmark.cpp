// Global relocalization against maps of growing size: writes a map of straight lanes of the
// simulator's procedural floor (which never repeats) straight into the store, with its pyramid,
// builds its place index, then looks up frames taken anywhere on the lanes at any heading
// (tracking::Relocalizer::SearchEverywhere: the index's candidates verified by the tracker).
// Reports the index's size and build time, its load time and memory, and per frame the
// outcome, the error against the truth and the time from frame to verified pose.
//
//   mosaicloc_place_index_benchmark --map /tmp/lanes-85.mosaic --lane-m 85
//   mosaicloc_place_index_benchmark --map /tmp/lanes-1000.mosaic --lane-m 1000 --frames 500
// An existing --map of the same --lane-m is reused (its index too).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "resident_memory.hpp"
#include <opencv2/core.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/sim/imaging.hpp"
#include "mosaicloc/tracking/place_index.hpp"
#include "mosaicloc/tracking/relocalize.hpp"

namespace {

using namespace mosaicloc;
using Clock = std::chrono::steady_clock;

// Lanes run along x, 10 m long (156 tiles of 64 mm), 3 tiles (192 mm) wide, one empty tile row
// between them.
constexpr int kLaneTiles = 156;
constexpr int kLaneRows = 3;

using bench::PeakResidentMib;

double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Global relocalization against maps of growing size");
  std::filesystem::path map;
  double lane_m = 85.0;
  int frames = 300;
  app.add_option("--map", map, "Map file (written when absent)")->required();
  app.add_option("--lane-m", lane_m, "Metres of lanes (10 m each)");
  app.add_option("--frames", frames, "Frames looked up");
  tracking::PlaceIndexOptions index;
  bool reindex = false;
  app.add_option("--features-per-tile", index.features_per_tile, "Place index: corners per tile");
  app.add_option("--lsh-tables", index.lsh_tables, "Place index: hash tables");
  app.add_option("--lsh-key-bits", index.lsh_key_bits, "Place index: bits per key");
  app.add_flag("--reindex", reindex, "Rebuild the index of an existing map");
  CLI11_PARSE(app, argc, argv);
  const int lanes = std::max(1, static_cast<int>(std::lround(lane_m / (kLaneTiles * 0.064))));

  sim::ProceduralFloorOptions floor_options;
  floor_options.mm_per_texel = 0.25;
  const auto floor = sim::MakeProceduralFloor(floor_options);
  const bool exists = std::filesystem::exists(map);
  if (!exists) {
    const auto start = Clock::now();
    auto store = mosaic::TileStore::Create(map, mosaic::MapGrid{});
    for (int lane = 0; lane < lanes; ++lane) {
      std::vector<mosaic::TileWrite> tiles;
      for (int r = 0; r < kLaneRows; ++r) {
        for (int col = 0; col < kLaneTiles; ++col) {
          const int row = lane * (kLaneRows + 1) + r;
          cv::Mat pixels = floor->Render(static_cast<std::int64_t>(col) * 256, static_cast<std::int64_t>(row) * 256, 256, 256);
          cv::max(pixels, 1, pixels);
          tiles.push_back({mosaic::TileKey{0, col, row}, pixels});
        }
      }
      mosaic::WriteWithPyramid(*store, tiles);
    }
    std::printf("built %s: %d lanes of 10 m (%.0f m), painted in %.0f s\n", map.c_str(), lanes,
                lanes * kLaneTiles * 0.064, Seconds(start));
  }
  if (!exists || reindex) {
    auto store = mosaic::TileStore::Open(map, true);
    const auto index_start = Clock::now();
    const auto cells = tracking::BuildPlaceCells(*store, index);
    store->WritePlaces(tracking::PlaceIndexInfoFor(index), cells);
    store->Checkpoint();
    std::printf("indexed in %.1f s (%d corners a tile)\n", Seconds(index_start), index.features_per_tile);
  }

  const auto store = mosaic::TileStore::Open(map, false);
  const auto info = store->Places();
  mosaic::TileCache cache(*store, std::size_t{256} << 20);
  const mosaic::MapRenderer renderer(cache);
  const tracking::MapReference reference(renderer, 0);
  const tracking::PlaceIndex places(*store, index);
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};
  const tracking::Tracker tracker(camera, tracking::TrackerOptions{});
  const tracking::Relocalizer relocalizer(tracker, reference, tracking::RelocalizeOptions{});
  const double before_mib = PeakResidentMib();
  if (!places.Load()) {
    std::fprintf(stderr, "%s\n", places.problem().c_str());
    return 1;
  }
  sim::ImagingOptions imaging;
  const sim::Imager imager(*floor, camera, imaging, 11);
  std::mt19937 random(5);
  std::uniform_int_distribution<int> pick_lane(0, lanes - 1);
  std::uniform_real_distribution<double> along(200.0, kLaneTiles * 64.0 - 200.0);
  std::uniform_real_distribution<double> across(-20.0, 20.0);
  std::uniform_real_distribution<double> heading(-std::numbers::pi, std::numbers::pi);
  std::vector<double> times_ms;
  int found = 0, within = 0, wrong = 0, ambiguous = 0;
  for (int i = 0; i < frames; ++i) {
    const int lane = pick_lane(random);
    // The lane's middle row's centre line; a view 160 x 120 mm stays on its 192 mm width
    // only along the lane, so headings across it see the lane's edges (the tracker's part).
    const double y = -(lane * (kLaneRows + 1) + 1.5) * 64.0 + across(random);
    const core::Pose2 truth(along(random), y, heading(random));
    const cv::Mat frame = imager.Render(truth, Eigen::Vector2d::Zero(), 0.0, static_cast<std::uint64_t>(i));
    const auto start = Clock::now();
    const tracking::TrackResult r = relocalizer.SearchEverywhere(frame, places, 1.0);
    times_ms.push_back(1e3 * Seconds(start));
    if (r.ok()) {
      ++found;
      const double error = core::Distance(r.world_from_camera, truth);
      within += error <= 0.05 ? 1 : 0;
      wrong += error > 1.0 ? 1 : 0;
    } else if (r.failure == tracking::TrackFailure::kAmbiguous) {
      ++ambiguous;
    }
  }
  std::sort(times_ms.begin(), times_ms.end());
  const auto percentile = [&](double p) {
    return times_ms[std::min(times_ms.size() - 1, static_cast<std::size_t>(p * static_cast<double>(times_ms.size())))];
  };
  const double metres = lanes * kLaneTiles * 0.064;
  std::printf("%.0f m of lanes: index %lld features, %.1f MiB on disk (%.1f KiB/m), %.1f MiB in memory (%.1f KiB/m), "
              "loaded in %.2f s; peak RSS %.0f MiB (%.0f before loading)\n",
              metres, static_cast<long long>(places.features()), static_cast<double>(info->bytes) / (1 << 20),
              static_cast<double>(info->bytes) / 1024.0 / metres, static_cast<double>(places.memory_bytes()) / (1 << 20),
              static_cast<double>(places.memory_bytes()) / 1024.0 / metres, places.load_seconds(), PeakResidentMib(),
              before_mib);
  std::printf("%d frames anywhere on the lanes, any heading: %d found (%.1f %%), %d within 0.05 mm, %d wrong (> 1 mm), "
              "%d ambiguous; %.1f ms p50, %.1f ms p99, %.1f ms max\n",
              frames, found, 100.0 * found / frames, within, wrong, ambiguous, percentile(0.5), percentile(0.99),
              times_ms.back());
  return 0;
}
