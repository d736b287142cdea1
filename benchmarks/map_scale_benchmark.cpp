// Map at scale: writes a map of several gigapixels of procedural concrete straight into the
// store, then drives a long lawnmower route over it rendering a 640x480 view every frame, as
// the tracker renders from the map (tracking::RenderWindow over the blocks tracking::MapReference
// reads), while the prefetcher loads ahead. Reports the share of renders that had to wait for
// a tile and the peak resident memory against the cache budget.
//
//   mosaicloc_map_scale_benchmark --map /tmp/big.mosaic --tiles-per-side 248   (4.03 gigapixels)
//   mosaicloc_map_scale_benchmark --map /tmp/big.mosaic --drive-km 10
//   mosaicloc_map_scale_benchmark --map /tmp/m64.mosaic --tiles-per-side 64 --drive-km 1 --time-scale 1 --budget-mib 16
//     (a smaller map, quicker to build, that still overflows the cache every lap)
// The drive is best run as its own process (an existing --map is reused), so its peak
// memory is not the build's.
#include <algorithm>
#include <cmath>
#include <optional>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <future>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <malloc.h>

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>

#include "mosaicloc/mosaic/prefetcher.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/sim/route.hpp"
#include "mosaicloc/tracking/reference.hpp"
#include "mosaicloc/tracking/render_window.hpp"

namespace {

using namespace mosaicloc;
using Clock = std::chrono::steady_clock;

// Resident set size now and at its peak, from /proc/self/status, MiB.
std::pair<double, double> ResidentMib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  double rss = 0, peak = 0;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) rss = std::stod(line.substr(6)) / 1024.0;
    if (line.rfind("VmHWM:", 0) == 0) peak = std::stod(line.substr(6)) / 1024.0;
  }
  return {rss, peak};
}

void Build(const std::filesystem::path& file, int tiles_per_side, int threads, int png_compression) {
  const auto start = Clock::now();
  mosaic::MapGrid grid;
  grid.levels = 1;
  auto store = mosaic::TileStore::Create(file, grid);
  store->SetPngCompression(png_compression);
  sim::ProceduralFloorOptions floor_options;
  floor_options.mm_per_texel = grid.mm_per_px;
  floor_options.cache_bytes = std::size_t{8} << 20;
  const auto floor = sim::MakeProceduralFloor(floor_options);
  // One row is encoded and written while the next is generated.
  std::future<void> writer;
  for (int row = 0; row < tiles_per_side; ++row) {
    std::vector<mosaic::TileWrite> tiles(static_cast<std::size_t>(tiles_per_side));
    std::vector<std::future<void>> workers;
    for (int w = 0; w < threads; ++w) {
      workers.push_back(std::async(std::launch::async, [&, w] {
        for (int col = w; col < tiles_per_side; col += threads) {
          cv::Mat pixels = floor->Render(static_cast<std::int64_t>(col) * 256, static_cast<std::int64_t>(row) * 256, 256, 256);
          cv::max(pixels, 1, pixels);
          tiles[static_cast<std::size_t>(col)] = {mosaic::TileKey{0, col, row}, pixels};
        }
      }));
    }
    for (auto& worker : workers) worker.get();
    if (writer.valid()) writer.get();
    writer = std::async(std::launch::async, [&store, tiles = std::move(tiles)] { store->Write(tiles); });
    if (row % 16 == 15) {
      std::fprintf(stderr, "build: %d / %d rows, %.0f s\n", row + 1, tiles_per_side,
                   std::chrono::duration<double>(Clock::now() - start).count());
    }
  }
  if (writer.valid()) writer.get();
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  const double gigapixels = static_cast<double>(tiles_per_side) * tiles_per_side * 65536.0 / 1e9;
  std::printf("built %s: %d x %d tiles = %.2f gigapixels (%.1f x %.1f m), PNG level %d, %.2f GiB on disk, %.0f s\n",
              file.c_str(), tiles_per_side, tiles_per_side, gigapixels, tiles_per_side * 0.064, tiles_per_side * 0.064,
              png_compression, static_cast<double>(std::filesystem::file_size(file)) / (1 << 30), seconds);
}

// Level 0 of the map as the tracker reads it, counting the tiles its reads had to wait for.
class CountingMapReference final : public tracking::ReferenceRaster {
 public:
  explicit CountingMapReference(const mosaic::MapRenderer& renderer) : map_(renderer, 0) {}
  Eigen::Matrix<double, 2, 3> RasterToWorld() const override { return map_.RasterToWorld(); }
  using ReferenceRaster::Region;
  void Region(std::int64_t col0, std::int64_t row0, int cols, int rows, cv::Mat& store,
              mosaic::RasterPatch* patch) const override {
    map_.Region(col0, row0, cols, rows, store, patch);
    tiles_loaded_ += patch->tiles_loaded;
  }
  std::unique_ptr<const tracking::ReferenceRaster> Coarser() const override { return map_.Coarser(); }
  // The tiles waited for since the last call.
  int TakeTilesLoaded() { return std::exchange(tiles_loaded_, 0); }

 private:
  tracking::MapReference map_;
  mutable int tiles_loaded_ = 0;
};

void Drive(const std::filesystem::path& file, double drive_km, double speed_mps, double frame_rate_hz,
           double time_scale, std::size_t budget_mib, bool prefetch, const mosaic::PrefetchOptions& options) {
  const auto store = mosaic::TileStore::Open(file, false);
  const double baseline_mib = ResidentMib().first;
  std::int64_t max_col = 0;
  for (const auto& key : store->List(0)) max_col = std::max(max_col, key.col);
  const double side_mm = static_cast<double>(max_col + 1) * 64.0;
  mosaic::TileCache cache(*store, budget_mib << 20);
  const mosaic::MapRenderer renderer(cache);
  CountingMapReference reference(renderer);
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};  // 640 x 480 px of 0.25 mm
  cv::Mat mask;
  std::optional<mosaic::TilePrefetcher> prefetcher;
  if (prefetch) prefetcher.emplace(cache, options);

  // A serpentine survey of the map: rows 1 m apart, 0.5 m in from the edges, closed by a
  // return leg, driven lap after lap; speed drops in the 0.5 m radius turns.
  sim::RouteOptions route;
  route.name = "serpentine";
  route.serpentine_spacing_m = 1.0;
  route.serpentine_length_m = side_mm / 1000.0 - 2.0;
  route.serpentine_rows = std::max(2, 2 * static_cast<int>((side_mm / 1000.0 - 1.5) / 2.0));
  route.speed_mps = speed_mps;
  route.lateral_deviation_mm = 3.0;
  route.stop_s = 0.0;
  // One lap, driven again and again (storing every lap's samples would cost the harness
  // more memory than the cache budget).
  const sim::Drive drive(route, 1, 1);
  // The route starts at (0, 0) heading +x: put its first row 1 m inside the map's top-left corner.
  const core::Pose2 world_from_route(1000.0, -1000.0, 0.0);
  const auto frames = static_cast<std::int64_t>(drive_km * 1000.0 / speed_mps * 10.0 * frame_rate_hz);
  std::vector<double> render_ms;
  render_ms.reserve(static_cast<std::size_t>(frames));
  std::int64_t waited = 0, tiles_waited = 0, waited_turning = 0, frames_turning = 0;
  if (prefetcher) {
    // A vehicle is switched on before it drives: the tiles around the start are loaded
    // while it stands, so the first render does not count as a wait.
    prefetcher->Predict(world_from_route * drive.At(0.0).world_from_vehicle, Eigen::Vector2d::Zero(), 0.0);
    prefetcher->WaitIdle();
  }
  const auto period = std::chrono::duration<double>(1.0 / (frame_rate_hz * time_scale));
  auto next = Clock::now();
  double peak_mib = 0, driven_m = 0;
  std::int64_t i = 0;
  for (; i < frames && driven_m < drive_km * 1000.0; ++i) {
    const double elapsed_s = static_cast<double>(i) / frame_rate_hz;
    const double lap = std::floor(elapsed_s / drive.duration_s());
    const double t = elapsed_s - lap * drive.duration_s();
    const sim::VehicleState state = drive.At(t);
    const sim::VehicleState later = drive.At(t + 0.01);
    driven_m = lap * drive.length_m() + state.path_distance_m;
    const core::Pose2 pose = world_from_route * state.world_from_vehicle;
    const core::Pose2 pose_later = world_from_route * later.world_from_vehicle;
    const Eigen::Vector2d velocity = (pose_later.translation_mm() - pose.translation_mm()) / 0.01;
    const double yaw_rate = core::YawDifference(pose_later, pose) / 0.01;
    if (prefetcher) prefetcher->Predict(pose, velocity, yaw_rate);
    const auto start = Clock::now();
    const cv::Mat view = tracking::RenderCameraView(reference, camera, pose, &mask);
    render_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
    const int tiles_loaded = reference.TakeTilesLoaded();
    const bool turning = std::abs(yaw_rate) > 0.05;
    frames_turning += turning ? 1 : 0;
    if (tiles_loaded > 0) {
      ++waited;
      waited_turning += turning ? 1 : 0;
      tiles_waited += tiles_loaded;
      if (waited <= 200) {
        std::fprintf(stderr, "waited: frame %lld at %.3f km (lap time %.2f s), %.2f m/s, yaw rate %.2f rad/s, %d tiles\n",
                     static_cast<long long>(i), driven_m / 1000.0, t, velocity.norm() / 1000.0, yaw_rate, tiles_loaded);
      }
    }
    if (i % 1000 == 0) {
      peak_mib = std::max(peak_mib, ResidentMib().first);
      if (i % 20000 == 0) std::fprintf(stderr, "drive: %.2f km, rss %.0f MiB\n", driven_m / 1000.0, ResidentMib().first);
    }
    next += std::chrono::duration_cast<Clock::duration>(period);
    std::this_thread::sleep_until(next);
  }
  const std::int64_t rendered = i;
  std::sort(render_ms.begin(), render_ms.end());
  const auto stats = cache.stats();
  const auto [rss, hwm] = ResidentMib();
  std::printf("drove %.2f km (serpentine, %d rows of %.1f m, cruise %.1f m/s), %lld frames at %.0f Hz (paced %.1fx real time)\n",
              driven_m / 1000.0, route.serpentine_rows, route.serpentine_length_m, speed_mps,
              static_cast<long long>(rendered), frame_rate_hz, time_scale);
  if (prefetch) {
    const std::string branches =
        options.min_turn_radius_mm > 0
            ? "to " + std::to_string(static_cast<int>(options.branch_mm)) + " mm for turns of radius " +
                  std::to_string(static_cast<int>(options.min_turn_radius_mm)) + " mm"
            : std::string("off");
    std::printf("prefetch: %d loaders, horizon %.1f s, radius %.0f mm, branches %s\n", options.threads, options.horizon_s,
                options.view_radius_mm, branches.c_str());
  } else {
    std::printf("prefetch: off\n");
  }
  std::printf("renders that waited for a tile: %lld of %lld (%.3f %%), %lld tiles; %lld of them of the %lld frames in turns\n",
              static_cast<long long>(waited), static_cast<long long>(rendered),
              100.0 * static_cast<double>(waited) / static_cast<double>(rendered), static_cast<long long>(tiles_waited),
              static_cast<long long>(waited_turning), static_cast<long long>(frames_turning));
  std::printf("render 640x480: p50 %.3f ms, p99 %.3f ms, max %.3f ms\n", render_ms[render_ms.size() / 2],
              render_ms[render_ms.size() * 99 / 100], render_ms.back());
  std::printf("cache: budget %zu MiB, %zu tiles, %.1f MiB, %lld loads (mean %.2f ms, max %.2f ms), %lld evictions\n",
              budget_mib, stats.tiles, static_cast<double>(stats.bytes) / (1 << 20), static_cast<long long>(stats.loads),
              stats.load_ms_total / std::max<std::int64_t>(stats.loads, 1), stats.load_ms_max,
              static_cast<long long>(stats.evictions));
  const struct mallinfo2 heap = mallinfo2();
  std::printf("heap: %.1f MiB in use, %.1f MiB free in arenas, %.1f MiB in mmapped blocks\n",
              static_cast<double>(heap.uordblks) / (1 << 20), static_cast<double>(heap.fordblks) / (1 << 20),
              static_cast<double>(heap.hblkhd) / (1 << 20));
  std::printf("resident memory: before the drive %.0f MiB, now %.0f MiB, sampled max %.0f MiB, peak (VmHWM) %.0f MiB;"
              " bound budget + 64 = %zu MiB: %s\n",
              baseline_mib, rss, peak_mib, hwm, budget_mib + 64, hwm <= static_cast<double>(budget_mib + 64) ? "held" : "EXCEEDED");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Map scale benchmark: a multi-gigapixel map and a long drive with prefetch"};
  std::filesystem::path map = "/tmp/mosaicloc-scale.mosaic";
  int tiles_per_side = 248;
  int threads = 2;
  int png_compression = mosaic::kDefaultTilePngCompression;
  double drive_km = 10.0, speed_mps = 3.0, frame_rate_hz = 30.0, time_scale = 10.0;
  std::size_t budget_mib = 256;
  bool no_prefetch = false;
  mosaic::PrefetchOptions prefetch;
  prefetch.view_radius_mm = 150.0;  // half diagonal of the 160 x 120 mm view plus turn-entry margin
  prefetch.horizon_s = 1.0;
  prefetch.min_turn_radius_mm = 500.0;  // the route's turns
  app.add_option("--map", map, "Map file; built when missing");
  app.add_option("--tiles-per-side", tiles_per_side, "Tiles per side of the square map built (248: 4.03 gigapixels)");
  app.add_option("--threads", threads, "Tile generation threads for the build");
  app.add_option("--png-compression", png_compression, "zlib level of the tiles built")->check(CLI::Range(0, 9));
  app.add_option("--drive-km", drive_km, "Route length (0: build only)");
  app.add_option("--speed-mps", speed_mps, "Vehicle speed");
  app.add_option("--frame-rate-hz", frame_rate_hz, "Camera frame rate");
  app.add_option("--time-scale", time_scale, "Run this many times faster than real time");
  app.add_option("--budget-mib", budget_mib, "Tile cache budget");
  app.add_flag("--no-prefetch", no_prefetch, "Drive without the prefetcher (the baseline)");
  app.add_option("--prefetch-threads", prefetch.threads, "Prefetch loader threads");
  app.add_option("--prefetch-horizon-s", prefetch.horizon_s, "Prefetch horizon along the predicted path");
  app.add_option("--prefetch-turn-radius-mm", prefetch.min_turn_radius_mm,
                 "Also prefetch the branches turning this tightly and straight (0: only the predicted path)");
  app.add_option("--prefetch-branch-mm", prefetch.branch_mm, "How far along the branches");
  CLI11_PARSE(app, argc, argv);
  if (!std::filesystem::exists(map)) Build(map, tiles_per_side, threads, png_compression);
  if (drive_km > 0) Drive(map, drive_km, speed_mps, frame_rate_hz, time_scale, budget_mib, !no_prefetch, prefetch);
  return 0;
}
