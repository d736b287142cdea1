// The console on a large map, over loopback, as a browser would use it:
//  - start: opening the map and reading what the page needs (Console's constructor);
//  - the first view: the page's files, /api/map, /api/quality, /api/reports and every tile of
//    the level that shows the whole map in a 900 x 800 view, on 6 connections as a browser
//    opens them, from a cold server;
//  - tile requests: random tiles of levels 0-2 (where an integrator zooms in), each asked
//    twice; the times of the second asks (warm cache) and of the first (cold), p50 and p99;
//  - the frame loop's side: PublishPose while 4 clients read the live state as fast as they
//    can, against PublishPose alone (ns per call, medians of rounds).
//
//   mosaicloc_console_benchmark --map /tmp/lanes-1000.mosaic [--tiles 2000]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "mosaicloc/console/console.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"

// Last: it brings <resolv.h>, whose _res macro breaks Eigen headers included after it.
#include <httplib.h>

namespace {

using namespace mosaicloc;
using Clock = std::chrono::steady_clock;

double Ms(Clock::time_point since) { return std::chrono::duration<double, std::milli>(Clock::now() - since).count(); }

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p / 100.0 * static_cast<double>(v.size())))];
}

// GETs `paths` on `connections` keep-alive connections at once; every answer must be 200 (or
// 404 for an unmapped tile). Returns the wall time, ms.
double FetchAll(int port, const std::vector<std::string>& paths, int connections) {
  std::atomic<std::size_t> next{0};
  std::atomic<int> failures{0};
  const Clock::time_point start = Clock::now();
  std::vector<std::thread> threads;
  for (int c = 0; c < connections; ++c) {
    threads.emplace_back([&] {
      httplib::Client client("127.0.0.1", port);
      client.set_keep_alive(true);
      for (std::size_t i = next++; i < paths.size(); i = next++) {
        auto result = client.Get(paths[i]);
        if (!result || (result->status != 200 && result->status != 404)) ++failures;
      }
    });
  }
  for (auto& t : threads) t.join();
  if (failures > 0) std::fprintf(stderr, "%d requests failed\n", failures.load());
  return Ms(start);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("The console on a large map over loopback");
  std::filesystem::path map;
  int tiles = 2000;
  app.add_option("--map", map, "Map file")->required()->check(CLI::ExistingFile);
  app.add_option("--tiles", tiles, "Tiles asked twice for the warm and cold times");
  CLI11_PARSE(app, argc, argv);

  console::ConsoleOptions options;
  options.listen = "127.0.0.1:0";
  options.requests_per_s = 1e9;  // the benchmark is one client asking as fast as it can
  options.burst = 1e9;
  const Clock::time_point open = Clock::now();
  console::Console console(options, map);
  const double open_ms = Ms(open);
  const int port = console.Start();

  // The view's level: the finest whose mapped extent fits in 900 x 800 screen pixels (the page
  // fits the map's bounds), and its tiles.
  httplib::Client client("127.0.0.1", port);
  const nlohmann::json info = nlohmann::json::parse(client.Get("/api/map")->body);
  const auto store = mosaic::TileStore::Open(map, false);
  const mosaic::MapGrid& grid = store->grid();
  const std::vector<double> bounds = info["bounds_mm"].get<std::vector<double>>();
  int view_level = grid.levels - 1;
  for (int k = 0; k < grid.levels; ++k) {
    if ((bounds[2] - bounds[0]) / grid.LevelMmPerPx(k) <= 900 && (bounds[3] - bounds[1]) / grid.LevelMmPerPx(k) <= 800) {
      view_level = k;
      break;
    }
  }
  std::vector<std::string> first_view = {"/", "/console.js", "/console.css", "/leaflet/leaflet.js",
                                         "/leaflet/leaflet.css", "/api/map", "/api/quality", "/api/reports"};
  for (const mosaic::TileKey& k : store->List(view_level)) {
    first_view.push_back("/api/tiles/" + std::to_string(k.level) + "/" + std::to_string(k.col) + "/" +
                         std::to_string(k.row) + ".png");
  }
  // A fresh console for a cold first view (the one above has answered /api/map).
  console::Console cold(options, map);
  const int cold_port = cold.Start();
  const double first_view_ms = FetchAll(cold_port, first_view, 6);

  std::vector<mosaic::TileKey> keys;
  for (int level = 0; level <= std::min(2, grid.levels - 1); ++level) {
    const std::vector<mosaic::TileKey> level_keys = store->List(level);
    keys.insert(keys.end(), level_keys.begin(), level_keys.end());
  }
  std::mt19937 rng(1);
  std::shuffle(keys.begin(), keys.end(), rng);
  keys.resize(std::min<std::size_t>(keys.size(), static_cast<std::size_t>(tiles)));
  std::vector<double> cold_ms, warm_ms;
  std::int64_t bytes = 0;
  for (int pass = 0; pass < 2; ++pass) {
    for (const mosaic::TileKey& k : keys) {
      const std::string path = "/api/tiles/" + std::to_string(k.level) + "/" + std::to_string(k.col) + "/" +
                               std::to_string(k.row) + ".png";
      const Clock::time_point start = Clock::now();
      auto result = client.Get(path);
      (pass == 0 ? cold_ms : warm_ms).push_back(Ms(start));
      if (!result || result->status != 200) std::fprintf(stderr, "%s failed\n", path.c_str());
      if (pass == 0 && result) bytes += static_cast<std::int64_t>(result->body.size());
    }
  }

  // The frame loop's side: PublishPose alone, and while 4 clients read /api/live flat out.
  const auto publish_ns = [&](int calls) {
    console::LivePose pose;
    pose.known = true;
    const Clock::time_point start = Clock::now();
    for (int i = 0; i < calls; ++i) {
      pose.x_mm = 0.01 * i;
      pose.frames = i;
      console.PublishPose(pose);
    }
    return std::chrono::duration<double, std::nano>(Clock::now() - start).count() / calls;
  };
  std::vector<double> alone, read;
  for (int round = 0; round < 5; ++round) alone.push_back(publish_ns(200000));
  std::atomic<bool> stop{false};
  std::atomic<std::int64_t> reads{0};
  std::vector<std::thread> readers;
  for (int r = 0; r < 4; ++r) {
    readers.emplace_back([&] {
      httplib::Client reader("127.0.0.1", port);
      while (!stop) {
        if (reader.Get("/api/live")) ++reads;
      }
    });
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  for (int round = 0; round < 5; ++round) read.push_back(publish_ns(200000));
  stop = true;
  for (auto& t : readers) t.join();

  std::printf("map %s: %lld tiles; console start (map info, quality layer, viewer files) %.1f ms\n", map.c_str(),
              static_cast<long long>(store->Count()), open_ms);
  std::printf("first view: %zu requests (page, API, %zu tiles of level %d), 6 connections, cold: %.1f ms\n",
              first_view.size(), first_view.size() - 8, view_level, first_view_ms);
  std::printf("tiles of levels 0-2, %zu asked twice (%.0f KiB each on average): cold p50 %.3f p99 %.3f ms, "
              "warm p50 %.3f p99 %.3f ms\n",
              keys.size(), static_cast<double>(bytes) / 1024.0 / static_cast<double>(std::max<std::size_t>(1, keys.size())),
              Percentile(cold_ms, 50), Percentile(cold_ms, 99), Percentile(warm_ms, 50), Percentile(warm_ms, 99));
  std::printf("PublishPose: %.1f ns alone, %.1f ns while 4 clients read the live state (%lld reads), medians of 5 "
              "rounds of 200000\n",
              Percentile(alone, 50), Percentile(read, 50), static_cast<long long>(reads.load()));
  return 0;
}
