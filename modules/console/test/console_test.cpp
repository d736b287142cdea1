#include "mosaicloc/console/console.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include <opencv2/core.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/fixes.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/test/test_support.hpp"

// Last: it brings <resolv.h>, whose _res macro breaks Eigen headers included after it.
#include <httplib.h>

namespace mosaicloc::console {
namespace {

namespace fs = std::filesystem;

// A small map: level 0 tiles (0,0) and (1,0), level 1 tile (0,0); a replay report of 30 frames.
class ConsoleTest : public ::testing::Test {
 protected:
  void SetUp() override {
    mosaic::MapGrid grid;
    grid.tile_size_px = 64;
    grid.levels = 2;
    map_ = scratch_ / "site.mosaic";
    auto store = mosaic::TileStore::Create(map_, grid);
    std::vector<mosaic::TileWrite> tiles;
    for (const mosaic::TileKey key : {mosaic::TileKey{0, 0, 0}, mosaic::TileKey{0, 1, 0}, mosaic::TileKey{1, 0, 0}}) {
      cv::Mat pixels(64, 64, CV_8UC1);
      cv::randu(pixels, 1, 255);
      tiles.push_back({key, pixels});
    }
    store->Write(tiles);
    stored_tile_ = store->ReadEncoded({0, 1, 0}).png;

    report_ = scratch_ / "replay";
    fs::create_directories(report_);
    std::string fixes = dataset::FixesCsvHeader();
    for (int i = 0; i < 30; ++i) {
      dataset::FrameReport row;
      row.time = core::Timestamp::FromNanoseconds(1'000'000'000LL + i * 33'000'000LL);
      row.world_from_vehicle = core::Pose2(10.0 * i, 5.0, 0.0);
      row.status = i < 20 ? 1 : 4;
      row.fixed = i < 20;
      row.quality = i < 20 ? 0.9 : 0.0;
      row.sigma_mm = 0.01;
      row.reason = i < 20 ? "" : "off-map";
      fixes += dataset::FixesCsvRow(row);
    }
    test::WriteFile(report_ / "fixes.csv", fixes);
    test::WriteFile(report_ / "metrics.json", R"({"frames": 30, "wrong_fixes": 0})");
  }

  ConsoleOptions Options() const {
    ConsoleOptions options;
    options.listen = "127.0.0.1:0";
    options.reports = {report_};
    return options;
  }

  test::ScratchDir scratch_;
  fs::path map_;
  fs::path report_;
  std::vector<unsigned char> stored_tile_;
};

TEST_F(ConsoleTest, ServesTheMapsTilesAsStoredAndItsLayout) {
  Console console(Options(), map_);
  httplib::Client client("127.0.0.1", console.Start());
  auto info = client.Get("/api/map");
  ASSERT_TRUE(info);
  ASSERT_EQ(info->status, 200);
  const nlohmann::json map = nlohmann::json::parse(info->body);
  EXPECT_EQ(map["tile_size_px"], 64);
  EXPECT_EQ(map["levels"].size(), 2u);
  EXPECT_EQ(map["levels"][0]["tiles"], 2);
  // Level 0 tiles (0,0) and (1,0) of 64 px at 0.25 mm: x in [0, 32], y in [-16, 0].
  EXPECT_EQ(map["bounds_mm"], nlohmann::json({0.0, -16.0, 32.0, 0.0}));

  auto tile = client.Get("/api/tiles/0/1/0.png");
  ASSERT_TRUE(tile);
  ASSERT_EQ(tile->status, 200);
  EXPECT_EQ(tile->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(tile->body, std::string(stored_tile_.begin(), stored_tile_.end()));
  // A tile may be cached for a minute, and says only that.
  EXPECT_EQ(tile->get_header_value_count("Cache-Control"), 1U);
  EXPECT_EQ(tile->get_header_value("Cache-Control"), "max-age=60");
  auto again = client.Get("/api/tiles/0/1/0.png");  // from the cache
  ASSERT_TRUE(again);
  EXPECT_EQ(again->body, tile->body);
  EXPECT_EQ(client.Get("/api/tiles/0/5/-3.png")->status, 404);   // unmapped
  EXPECT_EQ(client.Get("/api/tiles/7/0/0.png")->status, 404);    // no such level
  EXPECT_EQ(client.Get("/api/tiles/0/x/0.png")->status, 404);

  auto page = client.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->get_header_value_count("Cache-Control"), 1U);
  EXPECT_EQ(page->get_header_value("Cache-Control"), "no-store");
  EXPECT_NE(page->body.find("console.js"), std::string::npos);
  auto viewer = client.Get("/leaflet/leaflet.js");
  ASSERT_TRUE(viewer);
  EXPECT_EQ(viewer->status, 200);
  EXPECT_GT(viewer->body.size(), 100000u);
  // Never brotli on the fly (slow for large answers): gzip when the client takes it.
  auto br = client.Get("/leaflet/leaflet.js", {{"Accept-Encoding", "br"}});
  ASSERT_TRUE(br);
  EXPECT_EQ(br->get_header_value("Content-Encoding"), "");
  auto gz = client.Get("/leaflet/leaflet.js", {{"Accept-Encoding", "gzip, deflate, br"}});
  ASSERT_TRUE(gz);
  EXPECT_EQ(gz->get_header_value("Content-Encoding"), "gzip");
}

// A connection's bytes handed to Answer get what a socket would: the same parsing, token
// check and routes, pipelined requests one after another, and garbage an error or nothing.
TEST_F(ConsoleTest, AnswersAConnectionsBytesAsTheServerDoes) {
  ConsoleOptions options = Options();
  options.token = "a-token-of-sixteen-or-more";
  Console console(options, map_);
  const std::string tile = console.Answer(
      "GET /api/tiles/0/1/0.png HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer a-token-of-sixteen-or-more\r\n\r\n"
      "GET /api/map HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_TRUE(tile.starts_with("HTTP/1.1 200 OK\r\n")) << tile.substr(0, 200);
  EXPECT_NE(tile.find(std::string(stored_tile_.begin(), stored_tile_.end())), std::string::npos);
  EXPECT_NE(tile.find("HTTP/1.1 401"), std::string::npos);  // the second request had no token
  EXPECT_TRUE(console.Answer("GET /api/map HTTP/1.1\r\n\r\n").starts_with("HTTP/1.1 401"));
  const std::string garbage = console.Answer(std::string("\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03", 11));
  EXPECT_TRUE(garbage.empty() || garbage.starts_with("HTTP/1.1 400")) << garbage.substr(0, 100);
  EXPECT_EQ(console.counters().unauthorized, 2);
}

TEST_F(ConsoleTest, ServesNothingOutsideItsMapReportsAndViewer) {
  Console console(Options(), map_);
  httplib::Client client("127.0.0.1", console.Start());
  for (const char* path : {"/leaflet/../../../../etc/passwd", "/leaflet/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
                           "/leaflet/..%2f..%2f..%2fetc%2fpasswd", "/../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd",
                           "/api/tiles/0/0/../../../../etc/passwd", "/api/reports/0/../../fixes.csv",
                           "/api/reports/0/fixes.csv", "/leaflet/leaflet-src.js", "/site.mosaic", "//etc/passwd"}) {
    auto response = client.Get(path);
    ASSERT_TRUE(response) << path;
    EXPECT_TRUE(response->status == 404 || response->status == 400) << path << ": " << response->status;
    EXPECT_EQ(response->body.find("root:"), std::string::npos) << path;
  }
  // Read-only: nothing but GET (and HEAD) is answered.
  auto post = client.Post("/api/map", "{}", "application/json");
  ASSERT_TRUE(post);
  EXPECT_EQ(post->status, 405);
  auto del = client.Delete("/api/tiles/0/0/0.png");
  ASSERT_TRUE(del);
  EXPECT_EQ(del->status, 405);
  // A body beyond the bound is refused before any handler.
  auto big = client.Post("/api/map", std::string(100000, 'x'), "text/plain");
  ASSERT_TRUE(big);
  EXPECT_TRUE(big->status == 413 || big->status == 405) << big->status;
}

TEST_F(ConsoleTest, ATokenIsRequiredForEveryRequestWhenGiven) {
  ConsoleOptions options = Options();
  options.token = "s3cret-token-0123456789";
  Console console(options, map_);
  httplib::Client client("127.0.0.1", console.Start());
  EXPECT_EQ(client.Get("/")->status, 401);
  EXPECT_EQ(client.Get("/api/tiles/0/0/0.png")->status, 401);
  EXPECT_EQ(client.Get("/api/map?token=s3cret-token-0123456780")->status, 401);
  EXPECT_EQ(client.Get("/api/map?token=s3cret")->status, 401);
  EXPECT_EQ(client.Get("/api/map?token=s3cret-token-0123456789")->status, 200);
  EXPECT_EQ(client.Get("/api/map", {{"Authorization", "Bearer s3cret-token-0123456789"}})->status, 200);
  // A browser brings the token once in the address; the page's own requests carry the cookie.
  auto page = client.Get("/?token=s3cret-token-0123456789");
  ASSERT_TRUE(page);
  EXPECT_NE(page->get_header_value("Set-Cookie").find("mosaicloc_token=s3cret-token-0123456789"), std::string::npos);
  EXPECT_NE(page->get_header_value("Set-Cookie").find("HttpOnly"), std::string::npos);
  EXPECT_EQ(client.Get("/console.js", {{"Cookie", "other=1; mosaicloc_token=s3cret-token-0123456789"}})->status, 200);
  EXPECT_EQ(client.Get("/console.js", {{"Cookie", "xmosaicloc_token=s3cret-token-0123456789"}})->status, 401);
  EXPECT_EQ(client.Get("/console.js", {{"Cookie", "mosaicloc_token=s3cret-token-01234567"}})->status, 401);
  EXPECT_EQ(console.counters().unauthorized, 6);
  EXPECT_NE(console.Url().find("?token=s3cret-token-0123456789"), std::string::npos);
}

TEST_F(ConsoleTest, ListeningBeyondLoopbackNeedsTheFlagAndAToken) {
  std::string why;
  ConsoleOptions options;
  options.listen = "0.0.0.0:8080";
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("allow_remote"), std::string::npos) << why;
  options.allow_remote = true;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("token"), std::string::npos) << why;
  options.token = "short";
  EXPECT_FALSE(options.Check(&why));
  options.token = "a-long-enough-token-1234";
  EXPECT_TRUE(options.Check(&why)) << why;
  options.token = "a long token with spaces!";
  EXPECT_FALSE(options.Check(&why));
  EXPECT_TRUE(ParseListen("localhost:80").loopback);
  EXPECT_TRUE(ParseListen("[::1]:80").loopback);
  EXPECT_FALSE(ParseListen("192.168.1.4:80").loopback);
  EXPECT_THROW(ParseListen("127.0.0.1"), core::Error);
  EXPECT_THROW(ParseListen("127.0.0.1:70000"), core::Error);
  EXPECT_THROW(ParseListen("127.0.0.1:80x"), core::Error);
  EXPECT_THROW(ParseListen("a/b:80"), core::Error);
  // A console that cannot listen says where.
  ConsoleOptions taken = Options();
  Console first(taken, map_);
  const int port = first.Start();
  taken.listen = "127.0.0.1:" + std::to_string(port);
  Console second(taken, map_);
  try {
    second.Start();
    FAIL() << "a second console listened on a taken port";
  } catch (const core::Error& error) {
    EXPECT_NE(std::string(error.what()).find(taken.listen), std::string::npos) << error.what();
  }
}

TEST_F(ConsoleTest, AClientBeyondItsRateIsRefused) {
  ConsoleOptions options = Options();
  options.requests_per_s = 1.0;
  options.burst = 5.0;
  Console console(options, map_);
  httplib::Client client("127.0.0.1", console.Start());
  int refused = 0;
  for (int i = 0; i < 8; ++i) refused += client.Get("/api/map")->status == 429 ? 1 : 0;
  EXPECT_GE(refused, 2);
  EXPECT_LE(refused, 3);
  EXPECT_EQ(console.counters().rate_limited, refused);
}

TEST_F(ConsoleTest, ReportsAreServedAsLayers) {
  Console console(Options(), map_);
  httplib::Client client("127.0.0.1", console.Start());
  const nlohmann::json list = nlohmann::json::parse(client.Get("/api/reports")->body);
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0]["name"], "replay");
  EXPECT_EQ(list[0]["kind"], "replay");
  const nlohmann::json layer = nlohmann::json::parse(client.Get("/api/reports/0")->body);
  EXPECT_EQ(layer["frames"], 30);
  EXPECT_EQ(layer["fixes"], 20);
  ASSERT_EQ(layer["points"].size(), 30u);
  EXPECT_EQ(layer["points"][25], nlohmann::json({250.0, 5.0, 4, 0, 0, 0.01}));
  EXPECT_EQ(layer["metrics"]["wrong_fixes"], 0);
  EXPECT_EQ(client.Get("/api/reports/1")->status, 404);
  EXPECT_EQ(layer["columns"].size(), 6u);  // no errors.csv: no ground truth

  // With the replay's errors against the truth, a seventh column; a file that does not match
  // fixes.csv is named.
  std::string errors = "#timestamp_ns,error_mm\n";
  for (int i = 0; i < 30; ++i) {
    errors += std::to_string(1'000'000'000LL + i * 33'000'000LL) + "," + (i == 7 ? "" : std::to_string(0.01 * i)) + "\n";
  }
  test::WriteFile(report_ / "errors.csv", errors);
  {
    Console with_errors(Options(), map_);
    httplib::Client c("127.0.0.1", with_errors.Start());
    const nlohmann::json l = nlohmann::json::parse(c.Get("/api/reports/0")->body);
    EXPECT_EQ(l["columns"].back(), "error_mm");
    EXPECT_DOUBLE_EQ(l["points"][3][6].get<double>(), 0.03);
    EXPECT_TRUE(l["points"][7][6].is_null());
  }
  test::WriteFile(report_ / "errors.csv", "#timestamp_ns,error_mm\n5,0.1\n");
  try {
    Console mismatched(Options(), map_);
    FAIL() << "errors.csv that does not match fixes.csv was served";
  } catch (const core::Error& error) {
    EXPECT_NE(std::string(error.what()).find("errors.csv:2: does not match fixes.csv's row 1"), std::string::npos)
        << error.what();
  }
  std::filesystem::remove(report_ / "errors.csv");

  // A folder that is not a report, and a damaged one, are named.
  ConsoleOptions bad = Options();
  bad.reports = {scratch_.path()};
  EXPECT_THROW(Console(bad, map_), core::Error);
  test::WriteFile(report_ / "fixes.csv", dataset::FixesCsvHeader() + "12,not,a,row\n");
  try {
    Console console2(Options(), map_);
    FAIL() << "a damaged fixes.csv was served";
  } catch (const core::Error& error) {
    EXPECT_NE(std::string(error.what()).find("fixes.csv:2"), std::string::npos) << error.what();
  }
}

// The map's history as a layer, and a map written by another connection while the console
// serves it (a live run's automatic mapping, `map revert`): after at most half a second the
// console serves the new tiles, the new layout and the new history.
TEST_F(ConsoleTest, TheMapsHistoryIsServedAndAMapWrittenSinceIsReadAnew) {
  Console console(Options(), map_);
  httplib::Client client("127.0.0.1", console.Start());
  nlohmann::json history = nlohmann::json::parse(client.Get("/api/history")->body);
  EXPECT_EQ(history["count"], 0);
  EXPECT_EQ(history["updates"].size(), 0u);
  EXPECT_DOUBLE_EQ(history["tile_mm"].get<double>(), 16.0);
  const std::int64_t version = history["map_version"];
  const std::string old_tile = client.Get("/api/tiles/0/1/0.png")->body;  // now in the cache

  cv::Mat floor(64, 64, CV_8UC1);
  cv::randu(floor, 1, 255);
  auto writer = mosaic::TileStore::Open(map_, true);
  const auto mapped = mosaic::WriteWithPyramid(*writer, {{{0, 2, 0}, floor}}, "automatic mapping: 3 frames");
  const auto updated = mosaic::WriteWithPyramid(*writer, {{{0, 1, 0}, floor}}, "map update: 4 cells");
  ASSERT_TRUE(mapped && updated);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  const std::string new_tile = client.Get("/api/tiles/0/1/0.png")->body;  // not the cached one
  EXPECT_NE(new_tile, old_tile);
  EXPECT_EQ(new_tile, client.Get("/api/tiles/0/2/0.png")->body);  // the same floor
  mosaic::RevertUpdate(*writer, *updated);
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  history = nlohmann::json::parse(client.Get("/api/history")->body);
  EXPECT_GT(history["map_version"].get<std::int64_t>(), version);
  EXPECT_EQ(history["count"], 2);
  EXPECT_EQ(history["in_force"], 1);
  ASSERT_EQ(history["updates"].size(), 2u);
  EXPECT_EQ(history["updates"][0]["kind"], "mapping");
  EXPECT_EQ(history["updates"][0]["cells"], nlohmann::json::parse("[[2, 0]]"));
  EXPECT_TRUE(history["updates"][0]["reverted"].is_null());
  EXPECT_EQ(history["updates"][1]["kind"], "update");
  EXPECT_EQ(history["updates"][1]["reason"], "map update: 4 cells");
  EXPECT_FALSE(history["updates"][1]["reverted"].is_null());
  const nlohmann::json map = nlohmann::json::parse(client.Get("/api/map")->body);
  EXPECT_EQ(map["levels"][0]["tiles"], 3);
  EXPECT_EQ(map["map_version"], history["map_version"]);
  // The new tile is served; the reverted one is as it was before the update.
  auto added = client.Get("/api/tiles/0/2/0.png");
  ASSERT_TRUE(added);
  EXPECT_EQ(added->status, 200);
  EXPECT_EQ(client.Get("/api/tiles/0/1/0.png")->body, old_tile);
}

TEST_F(ConsoleTest, TheLiveStateIsServedAndStreamed) {
  ConsoleOptions options = Options();
  options.stream_hz = 50.0;
  Console console(options, map_);
  httplib::Client client("127.0.0.1", console.Start());
  EXPECT_EQ(nlohmann::json::parse(client.Get("/api/live")->body)["live"], false);
  LivePose pose;
  for (int i = 0; i < 10; ++i) {
    pose.t_s = 0.1 * i;
    pose.known = true;
    pose.x_mm = 100.0 + 10.0 * i;
    pose.y_mm = -20.0;
    pose.cov_xx = pose.cov_yy = 1e-4;
    pose.lock = 1;
    pose.frames = i + 1;
    console.PublishPose(pose);
  }
  console.PublishStatus({{"plc", "connected"}, {"frames_per_s", 30}});
  const nlohmann::json live = nlohmann::json::parse(client.Get("/api/live")->body);
  EXPECT_EQ(live["live"], true);
  EXPECT_DOUBLE_EQ(live["x_mm"].get<double>(), 190.0);
  EXPECT_EQ(live["frames"], 10);
  EXPECT_EQ(live["path"].size(), 10u);
  EXPECT_EQ(live["status"]["plc"], "connected");

  // The stream delivers the newest state; the client ends it.
  std::string received;
  auto stream = client.Get("/api/live/stream", [&](const char* data, std::size_t length) {
    received.append(data, length);
    return received.find("\n\n") == std::string::npos;
  });
  EXPECT_EQ(received.rfind("data: ", 0), 0u) << received;
  const nlohmann::json event = nlohmann::json::parse(received.substr(6, received.find("\n\n") - 6));
  EXPECT_DOUBLE_EQ(event["x_mm"].get<double>(), 190.0);
}

TEST_F(ConsoleTest, LiveStreamsBeyondTheLimitAreRefusedAndTheRestStillAnswers) {
  ConsoleOptions options = Options();
  options.max_streams = 2;
  options.threads = 4;
  Console console(options, map_);
  const int port = console.Start();
  std::atomic<bool> stop{false};
  std::atomic<int> open{0};
  std::vector<std::thread> holders;
  for (int i = 0; i < 2; ++i) {
    holders.emplace_back([&] {
      httplib::Client holder("127.0.0.1", port);
      bool counted = false;
      holder.Get("/api/live/stream", [&](const char*, std::size_t) {
        if (!counted) ++open;
        counted = true;
        return !stop.load();
      });
    });
  }
  // Both streams are open once each has had its first event.
  for (int i = 0; i < 500 && open.load() < 2; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(open.load(), 2);
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(2, 0);  // a stream accepted by mistake would never end
  auto third = client.Get("/api/live/stream");
  ASSERT_TRUE(third);
  EXPECT_EQ(third->status, 503);
  EXPECT_EQ(client.Get("/api/map")->status, 200);
  stop = true;
  for (auto& holder : holders) holder.join();
  EXPECT_GE(console.counters().streams_refused, 1);
}

}  // namespace
}  // namespace mosaicloc::console
