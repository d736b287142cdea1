// Map benchmarks: a camera's view rendered from a warm cache as the tracker renders its
// windows (tracking::RenderWindow over tracking::MapReference; against one cv::warpAffine of
// an already assembled image, the floor of what rendering can cost), cold tile loads, and
// painting throughput. Run: build/.../benchmarks/mosaicloc_mosaic_benchmark
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/sim/floor.hpp"
#include "mosaicloc/tracking/reference.hpp"
#include "mosaicloc/tracking/render_window.hpp"

namespace mosaicloc {
namespace {

constexpr int kTiles = 24;  // 24 x 24 tiles of 256 px: 6144 px = 1.5 m square at 0.25 mm/px

// A map of procedural concrete written straight into a store, shared by the benchmarks.
struct Fixture {
  Fixture() {
    directory = std::filesystem::temp_directory_path() / ("mosaicloc-bench-" + std::to_string(::getpid()));
    std::filesystem::create_directories(directory);
    mosaic::MapGrid grid;
    store = mosaic::TileStore::Create(directory / "bench.mosaic", grid);
    sim::ProceduralFloorOptions floor_options;
    floor_options.mm_per_texel = grid.mm_per_px;
    const auto floor = sim::MakeProceduralFloor(floor_options);
    for (int r = 0; r < kTiles; ++r) {
      std::vector<mosaic::TileWrite> row;
      for (int c = 0; c < kTiles; ++c) {
        cv::Mat pixels = floor->Render(c * 256, r * 256, 256, 256);
        cv::max(pixels, 1, pixels);
        row.push_back({mosaic::TileKey{0, c, r}, pixels});
      }
      store->Write(row);
    }
    whole = floor->Render(0, 0, kTiles * 256, kTiles * 256);
  }
  ~Fixture() {
    store.reset();
    std::filesystem::remove_all(directory);
  }
  std::filesystem::path directory;
  std::unique_ptr<mosaic::TileStore> store;
  cv::Mat whole;
};

Fixture& Shared() {
  static Fixture fixture;
  return fixture;
}

// Random camera poses whose 640x480 view stays inside the map.
std::vector<core::Pose2> Poses(int count) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> position(200.0, kTiles * 64.0 - 200.0);
  std::uniform_real_distribution<double> yaw(-3.14, 3.14);
  std::vector<core::Pose2> poses;
  for (int i = 0; i < count; ++i) poses.emplace_back(position(rng), -position(rng), yaw(rng));
  return poses;
}

void BM_RenderCameraView640x480Warm(benchmark::State& state) {
  Fixture& fixture = Shared();
  mosaic::TileCache cache(*fixture.store);
  const mosaic::MapRenderer renderer(cache);
  const tracking::MapReference reference(renderer, 0);
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};  // 640 x 480 px of 0.25 mm
  const auto poses = Poses(64);
  cv::Mat mask;
  for (const auto& pose : poses) tracking::RenderCameraView(reference, camera, pose, &mask);  // warm up
  std::size_t i = 0;
  for (auto _ : state) {
    const cv::Mat view = tracking::RenderCameraView(reference, camera, poses[i++ % poses.size()], &mask);
    benchmark::DoNotOptimize(view.data);
  }
}
BENCHMARK(BM_RenderCameraView640x480Warm)->Unit(benchmark::kMicrosecond);

// The peer: the same bilinear warp from one contiguous image (no tiles, no mask).
void BM_WarpAffine640x480Contiguous(benchmark::State& state) {
  Fixture& fixture = Shared();
  const auto poses = Poses(64);
  std::size_t i = 0;
  cv::Mat out;
  for (auto _ : state) {
    const core::Pose2& pose = poses[i++ % poses.size()];
    const Eigen::Matrix2d r = pose.Rotation();
    const double cu = pose.x_mm() / 0.25 - 0.5, cv_ = -pose.y_mm() / 0.25 - 0.5;
    cv::Mat map = (cv::Mat_<double>(2, 3) << r(0, 0), -r(0, 1), 0, -r(1, 0), r(1, 1), 0);
    map.at<double>(0, 2) = cu - r(0, 0) * 319.5 + r(0, 1) * 239.5;
    map.at<double>(1, 2) = cv_ + r(1, 0) * 319.5 - r(1, 1) * 239.5;
    cv::warpAffine(fixture.whole, out, map, cv::Size(640, 480), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
    benchmark::DoNotOptimize(out.data);
  }
}
BENCHMARK(BM_WarpAffine640x480Contiguous)->Unit(benchmark::kMicrosecond);

void BM_ColdTileLoadAndDecode(benchmark::State& state) {
  Fixture& fixture = Shared();
  mosaic::TileCache cache(*fixture.store);
  int i = 0;
  for (auto _ : state) {
    state.PauseTiming();
    cache.Clear();
    state.ResumeTiming();
    const auto tile = cache.Get(mosaic::TileKey{0, i % kTiles, (i / kTiles) % kTiles});
    ++i;
    benchmark::DoNotOptimize(tile.get());
  }
}
BENCHMARK(BM_ColdTileLoadAndDecode)->Unit(benchmark::kMicrosecond);

// The 16 tiles the PNG benchmarks decode: 256 px squares of the benchmark's procedural
// floor, or of the image named by MOSAICLOC_BENCH_TEXTURE (8-bit grey).
std::vector<cv::Mat> DecodeBenchmarkTiles() {
  cv::Mat texture = Shared().whole;
  if (const char* file = std::getenv("MOSAICLOC_BENCH_TEXTURE"); file && *file) texture = cv::imread(file, cv::IMREAD_GRAYSCALE);
  std::vector<cv::Mat> tiles;
  for (int r = 0; r + 256 <= texture.rows && tiles.size() < 16; r += 256) {
    for (int c = 0; c + 256 <= texture.cols && tiles.size() < 16; c += 256) {
      cv::Mat tile;
      cv::max(texture(cv::Rect(c, r, 256, 256)), 1, tile);
      tiles.push_back(tile);
    }
  }
  return tiles;
}

// Decoding one 256 px tile's PNG as the store encodes it at zlib level range(0), with the
// store's decoder (libpng directly). Counters: stored bytes and encode time per tile.
void BM_TilePngDecode(benchmark::State& state) {
  const std::vector<cv::Mat> tiles = DecodeBenchmarkTiles();
  if (tiles.empty()) {
    state.SkipWithError("MOSAICLOC_BENCH_TEXTURE is not a readable image of at least 256 x 256 px");
    return;
  }
  std::vector<std::vector<unsigned char>> encoded(tiles.size());
  const auto start = std::chrono::steady_clock::now();
  std::size_t bytes = 0;
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    encoded[i] = mosaic::TileStore::Encode(tiles[i], static_cast<int>(state.range(0)));
    bytes += encoded[i].size();
  }
  const double encode_us =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count() / tiles.size();
  cv::Mat pixels(256, 256, CV_8UC1);
  std::size_t i = 0;
  for (auto _ : state) {
    const std::string problem = mosaic::TileStore::Decode(encoded[i++ % encoded.size()], 256, pixels);
    if (!problem.empty()) state.SkipWithError(problem.c_str());
    benchmark::DoNotOptimize(pixels.data);
  }
  state.counters["bytes_per_tile"] = static_cast<double>(bytes) / static_cast<double>(tiles.size());
  state.counters["encode_us"] = encode_us;
}
BENCHMARK(BM_TilePngDecode)->ArgName("level")->Arg(0)->Arg(1)->Arg(3)->Arg(6)->Arg(9)->Unit(benchmark::kMicrosecond);

// The peer: OpenCV's imdecode of the same PNG bytes into a reused buffer.
void BM_TilePngDecodeOpenCv(benchmark::State& state) {
  const std::vector<cv::Mat> tiles = DecodeBenchmarkTiles();
  if (tiles.empty()) {
    state.SkipWithError("MOSAICLOC_BENCH_TEXTURE is not a readable image of at least 256 x 256 px");
    return;
  }
  std::vector<std::vector<unsigned char>> encoded;
  for (const auto& tile : tiles) encoded.push_back(mosaic::TileStore::Encode(tile, static_cast<int>(state.range(0))));
  cv::Mat buffer(256, 256, CV_8UC1);
  std::size_t i = 0;
  for (auto _ : state) {
    cv::Mat pixels = buffer;
    cv::imdecode(encoded[i++ % encoded.size()], cv::IMREAD_UNCHANGED, &pixels);
    benchmark::DoNotOptimize(pixels.data);
  }
}
BENCHMARK(BM_TilePngDecodeOpenCv)->ArgName("level")->Arg(0)->Arg(3)->Unit(benchmark::kMicrosecond);

void BM_PaintFrame640x480(benchmark::State& state) {
  Fixture& fixture = Shared();
  mosaic::MapBuilder builder(mosaic::MapGrid{}, state.range(0) == 0 ? mosaic::Blend::kFeather : mosaic::Blend::kBestView);
  const cv::Mat frame = fixture.whole(cv::Rect(1000, 1000, 640, 480)).clone();
  double x_mm = 0.0;
  for (auto _ : state) {
    // A vehicle at 1 m/s and 30 Hz: 33 mm between frames, a slight turn.
    builder.AddFrame(frame, core::Pose2(x_mm, 0.2 * x_mm, 0.0001 * x_mm), 0.25);
    x_mm += 33.3;
  }
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_PaintFrame640x480)->Arg(0)->Arg(1)->ArgName("best_view")->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mosaicloc

BENCHMARK_MAIN();
