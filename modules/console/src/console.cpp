#include "mosaicloc/console/console.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <list>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <string_view>
#include <thread>
#include <unordered_map>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/mosaic/quality.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "reports.hpp"
#include "web_assets.hpp"

// Last: it brings <resolv.h>, whose _res macro breaks Eigen headers included after it.
#include <httplib.h>

namespace mosaicloc::console {
namespace fs = std::filesystem;

bool ConsoleOptions::Check(std::string* why) const {
  const auto fail = [&](const std::string& text) {
    *why = text;
    return false;
  };
  ListenAddress address;
  try {
    address = ParseListen(listen);
  } catch (const core::Error& error) {
    return fail(error.what());
  }
  if (!address.loopback && !allow_remote) {
    return fail("listen " + listen +
                " is not a loopback address; listening on another interface needs allow_remote (--allow-remote) and a "
                "token");
  }
  if (allow_remote && token.size() < 16) {
    return fail("token of at least 16 characters is needed for every request when listening beyond loopback");
  }
  for (const char c : token) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') {
      return fail("token may hold only letters, digits, '-', '_' and '.' (it travels in URLs and headers)");
    }
  }
  if (threads < 2 || threads > 64) return fail("threads must be in [2, 64]");
  if (max_streams < 1 || max_streams >= threads) return fail("max_streams must be in [1, threads - 1]");
  if (!(requests_per_s > 0.0)) return fail("requests_per_s must be > 0");
  if (!(burst >= 1.0)) return fail("burst must be >= 1");
  if (!(stream_hz > 0.0 && stream_hz <= 100.0)) return fail("stream_hz must be in (0, 100]");
  if (tile_cache_bytes < 0) return fail("tile_cache_bytes must be >= 0");
  return true;
}

ListenAddress ParseListen(const std::string& text) {
  const std::size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size()) {
    core::ThrowInvalidInput("listen '" + text + "' is not HOST:PORT (e.g. 127.0.0.1:8080)");
  }
  ListenAddress address;
  address.host = text.substr(0, colon);
  if (address.host.size() > 2 && address.host.front() == '[' && address.host.back() == ']') {
    address.host = address.host.substr(1, address.host.size() - 2);
  }
  const std::string port = text.substr(colon + 1);
  if (port.size() > 5 || !std::all_of(port.begin(), port.end(), [](char c) { return c >= '0' && c <= '9'; }) ||
      std::stoi(port) > 65535) {
    core::ThrowInvalidInput("listen '" + text + "': the port must be a number in [0, 65535]");
  }
  address.port = std::stoi(port);
  for (const char c : address.host) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != ':' && c != '-') {
      core::ThrowInvalidInput("listen '" + text + "': the host must be an IP address or a name");
    }
  }
  address.loopback = address.host == "localhost" || address.host == "::1" || address.host.rfind("127.", 0) == 0;
  return address;
}

std::string ReadTokenFile(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  if (!in || !std::getline(in, line)) core::ThrowInvalidInput(file.string() + ": cannot be read (a token file was expected)");
  const auto blank = [](unsigned char c) { return std::isspace(c) != 0; };
  line.erase(line.begin(), std::find_if_not(line.begin(), line.end(), blank));
  line.erase(std::find_if_not(line.rbegin(), line.rend(), blank).base(), line.end());
  if (line.empty()) core::ThrowInvalidInput(file.string() + ": the first line (the token) is empty");
  return line;
}

namespace internal {

using Clock = std::chrono::steady_clock;

struct StaticFile {
  std::string content_type;
  std::string body;
};

// Token buckets per client address, in a bounded table (the stalest entries go first).
class RateLimiter {
 public:
  RateLimiter(double per_s, double burst) : per_s_(per_s), burst_(burst) {}
  bool Allow(const std::string& client) {
    const Clock::time_point now = Clock::now();
    const std::lock_guard lock(mutex_);
    auto it = buckets_.find(client);
    if (it == buckets_.end()) {
      if (buckets_.size() >= kMaxClients) {
        // Forget every bucket that has refilled: it would allow a burst anyway.
        for (auto b = buckets_.begin(); b != buckets_.end();) {
          b = Refilled(b->second, now) >= burst_ ? buckets_.erase(b) : std::next(b);
        }
        if (buckets_.size() >= kMaxClients) buckets_.clear();
      }
      it = buckets_.emplace(client, Bucket{burst_, now}).first;
    }
    Bucket& bucket = it->second;
    bucket.tokens = Refilled(bucket, now);
    bucket.time = now;
    if (bucket.tokens < 1.0) return false;
    bucket.tokens -= 1.0;
    return true;
  }

 private:
  struct Bucket {
    double tokens;
    Clock::time_point time;
  };
  static constexpr std::size_t kMaxClients = 256;
  double Refilled(const Bucket& bucket, Clock::time_point now) const {
    return std::min(burst_, bucket.tokens + per_s_ * std::chrono::duration<double>(now - bucket.time).count());
  }
  double per_s_;
  double burst_;
  std::mutex mutex_;
  std::unordered_map<std::string, Bucket> buckets_;
};

// Encoded tiles by key, least recently used first out, bounded in bytes.
class EncodedTileCache {
 public:
  explicit EncodedTileCache(std::int64_t max_bytes) : max_bytes_(max_bytes) {}
  std::shared_ptr<const std::string> Find(const mosaic::TileKey& key) {
    const std::lock_guard lock(mutex_);
    const auto it = index_.find(key);
    if (it == index_.end()) return nullptr;
    order_.splice(order_.begin(), order_, it->second);
    return it->second->second;
  }
  void Clear() {
    const std::lock_guard lock(mutex_);
    order_.clear();
    index_.clear();
    bytes_ = 0;
  }
  void Put(const mosaic::TileKey& key, std::shared_ptr<const std::string> png) {
    const auto size = static_cast<std::int64_t>(png->size());
    if (size > max_bytes_) return;
    const std::lock_guard lock(mutex_);
    if (index_.count(key) != 0) return;
    order_.emplace_front(key, std::move(png));
    index_[key] = order_.begin();
    bytes_ += size;
    while (bytes_ > max_bytes_ && !order_.empty()) {
      bytes_ -= static_cast<std::int64_t>(order_.back().second->size());
      index_.erase(order_.back().first);
      order_.pop_back();
    }
  }

 private:
  using Entry = std::pair<mosaic::TileKey, std::shared_ptr<const std::string>>;
  std::int64_t max_bytes_;
  std::int64_t bytes_ = 0;
  std::mutex mutex_;
  std::list<Entry> order_;
  std::unordered_map<mosaic::TileKey, std::list<Entry>::iterator, mosaic::TileKeyHash> index_;
};

}  // namespace internal

namespace {

std::string ReadWhole(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    core::ThrowInvalidInput(file.string() +
                            ": cannot be read (the console's map viewer comes from the Debian package libjs-leaflet: "
                            "scripts/install-deps.sh installs it)");
  }
  std::ostringstream content;
  content << in.rdbuf();
  return content.str();
}

bool SameSecret(const std::string& a, const std::string& b) {
  // Constant time in the secret's length: a wrong token's first wrong character is not timed.
  unsigned char difference = a.size() == b.size() ? 0 : 1;
  for (std::size_t i = 0; i < b.size(); ++i) {
    difference |= static_cast<unsigned char>(static_cast<unsigned char>(i < a.size() ? a[i] : 0) ^
                                             static_cast<unsigned char>(b[i]));
  }
  return difference == 0;
}

void SendJson(httplib::Response& response, const std::string& body) {
  response.set_content(body, "application/json");
}

void SendError(httplib::Response& response, int status, const std::string& message) {
  response.status = status;
  response.set_content(nlohmann::json{{"error", message}}.dump(), "application/json");
}

}  // namespace

namespace internal {

// The console's server, which can also answer a connection's bytes handed to it (Answer): the
// same request parsing, token check, rate limit and routes, without a socket.
class ConsoleServer final : public httplib::Server {
 public:
  std::string Answer(std::string_view request) {
    BufferStream stream(request);
    // As a connection would be served: requests one after another (pipelined) until the input
    // ends or a response closes the connection; at most keep-alive's count of them.
    for (int i = 0; i < 100 && stream.is_readable(); ++i) {
      bool closed = false;
      if (!process_request(stream, false, closed, nullptr) || closed) break;
    }
    return std::move(stream.written);
  }

 private:
  class BufferStream final : public httplib::Stream {
   public:
    explicit BufferStream(std::string_view input) : input_(input) {}
    bool is_readable() const override { return !input_.empty(); }
    // A client that stops reading after 1 MiB or a tenth of a second: a live stream ends there.
    bool is_writable() const override {
      return written.size() < (1U << 20) && std::chrono::steady_clock::now() - opened_ < std::chrono::milliseconds(100);
    }
    ssize_t read(char* ptr, size_t size) override {
      const std::size_t n = std::min(size, input_.size());
      std::copy_n(input_.data(), n, ptr);
      input_.remove_prefix(n);
      return static_cast<ssize_t>(n);
    }
    ssize_t write(const char* ptr, size_t size) override {
      if (!is_writable()) return -1;
      written.append(ptr, size);
      return static_cast<ssize_t>(size);
    }
    void get_remote_ip_and_port(std::string& ip, int& port) const override {
      ip = "127.0.0.1";
      port = 40000;
    }
    void get_local_ip_and_port(std::string& ip, int& port) const override {
      ip = "127.0.0.1";
      port = 8080;
    }
    socket_t socket() const override { return INVALID_SOCKET; }
    std::string written;

   private:
    std::string_view input_;
    std::chrono::steady_clock::time_point opened_ = std::chrono::steady_clock::now();
  };
};

}  // namespace internal

class Console::Impl {
 public:
  Impl(const ConsoleOptions& options, const fs::path& map)
      : options_(options),
        address_(ParseListen(options.listen)),
        limiter_(options.requests_per_s, options.burst),
        cache_(options.tile_cache_bytes) {
    std::string why;
    if (!options.Check(&why)) core::ThrowInvalidInput("console: " + why);
    store_ = mosaic::TileStore::Open(map, false);
    data_version_ = store_->DataVersion();
    ReadMap();
    nlohmann::json reports = nlohmann::json::array();
    for (std::size_t i = 0; i < options.reports.size(); ++i) {
      internal::ReportLayer report = internal::ReadReportLayer(options.reports[i]);
      nlohmann::json layer = std::move(report.layer);
      layer["id"] = i;
      layer["name"] = report.name;
      layer["kind"] = report.kind;
      reports.push_back({{"id", i}, {"name", report.name}, {"kind", report.kind},
                         {"frames", layer.value("frames", 0)}});
      report_layers_.push_back(layer.dump());
    }
    reports_ = reports.dump();
    for (const char* name : {"leaflet.js", "leaflet.css", "images/layers.png", "images/layers-2x.png",
                             "images/marker-icon.png", "images/marker-icon-2x.png", "images/marker-shadow.png"}) {
      const std::string file = name;
      const std::string type = file.ends_with(".js")    ? "text/javascript"
                               : file.ends_with(".css") ? "text/css"
                                                        : "image/png";
      viewer_files_["/leaflet/" + file] = internal::StaticFile{type, ReadWhole(options.leaflet_dir / file)};
    }
    Routes();
  }

  ~Impl() { Stop(); }

  int Start() {
    if (thread_.joinable()) return port_;
    port_ = address_.port == 0 ? server_.bind_to_any_port(address_.host)
                               : (server_.bind_to_port(address_.host, address_.port) ? address_.port : -1);
    if (port_ < 0) {
      core::ThrowRuntime("console: cannot listen on " + options_.listen +
                         " (the port is in use, or the address is not this machine's)");
    }
    thread_ = std::thread([this] { server_.listen_after_bind(); });
    // Until the server runs: a stop asked for before it does would find nothing to stop, and the
    // listening thread would never end.
    for (int i = 0; i < 5000 && !server_.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    if (!server_.is_running()) {
      server_.stop();
      thread_.join();
      core::ThrowRuntime("console: the server on " + options_.listen + " did not start");
    }
    core::Log().info("console: {}", Url());
    return port_;
  }

  std::string Answer(std::string_view request) { return server_.Answer(request); }

  void Stop() {
    stopping_ = true;
    server_.stop();
    if (thread_.joinable()) thread_.join();
  }

  std::string Url() const {
    const bool v6 = address_.host.find(':') != std::string::npos;
    std::string url = "http://" + (v6 ? "[" + address_.host + "]" : address_.host) + ":" + std::to_string(port_) + "/";
    if (!options_.token.empty()) url += "?token=" + options_.token;
    return url;
  }

  void PublishPose(const LivePose& pose) noexcept {
    const std::unique_lock lock(live_mutex_, std::try_to_lock);
    if (!lock.owns_lock()) return;  // a reader holds it: this frame is dropped, the next one goes
    live_ = pose;
    has_live_ = true;
    ++live_serial_;
    // The path behind the vehicle: a point every kPathStepMm, in a fixed ring (no allocation).
    if (pose.known) {
      const auto& last = path_[(path_next_ + kPathPoints - 1) % kPathPoints];
      if (path_count_ == 0 || std::hypot(pose.x_mm - last[0], pose.y_mm - last[1]) >= kPathStepMm) {
        path_[path_next_] = {pose.x_mm, pose.y_mm};
        path_next_ = (path_next_ + 1) % kPathPoints;
        path_count_ = std::min(path_count_ + 1, kPathPoints);
      }
    }
  }

  void PublishStatus(const nlohmann::json& status) {
    const std::lock_guard lock(status_mutex_);
    status_ = status;
  }

  Counters counters() const {
    return {requests_.load(), rate_limited_.load(), unauthorized_.load(), streams_refused_.load()};
  }

 private:
  // What is read from the map, read again when another connection has written to it.
  struct MapState {
    std::string map_info, quality, history;
  };
  static constexpr std::size_t kPathPoints = 4096;
  static constexpr std::string_view kTokenCookie = "mosaicloc_token=";
  static constexpr double kPathStepMm = 5.0;

  // What the page needs to place the map: the grid, the levels with their tile counts, and
  // the mapped area's bounds.
  std::string MapInfo() const {
    const mosaic::MapGrid& grid = store_->grid();
    nlohmann::json levels = nlohmann::json::array();
    int bounds_level = grid.levels - 1;
    for (int level = 0; level < grid.levels; ++level) {
      const std::int64_t count = store_->Count(level);
      levels.push_back({{"level", level}, {"mm_per_px", grid.LevelMmPerPx(level)}, {"tiles", count}});
      if (count <= 4096 && level < bounds_level) bounds_level = level;
    }
    nlohmann::json bounds = nullptr;
    const std::vector<mosaic::TileKey> keys = store_->List(bounds_level);
    if (!keys.empty()) {
      std::int64_t c0 = keys[0].col, c1 = keys[0].col, r0 = keys[0].row, r1 = keys[0].row;
      for (const mosaic::TileKey& k : keys) {
        c0 = std::min(c0, k.col);
        c1 = std::max(c1, k.col);
        r0 = std::min(r0, k.row);
        r1 = std::max(r1, k.row);
      }
      const double tile_mm = grid.LevelMmPerPx(bounds_level) * grid.tile_size_px;
      bounds = {grid.origin_x_mm + static_cast<double>(c0) * tile_mm,
                grid.origin_y_mm - static_cast<double>(r1 + 1) * tile_mm,
                grid.origin_x_mm + static_cast<double>(c1 + 1) * tile_mm,
                grid.origin_y_mm - static_cast<double>(r0) * tile_mm};
    }
    // Mapped tiles of a coarse level, for the "lanes mapped" outline.
    int lanes_level = grid.levels - 1;
    for (int level = 0; level < grid.levels; ++level) {
      if (levels[static_cast<std::size_t>(level)]["tiles"].get<std::int64_t>() <= 2000) {
        lanes_level = level;
        break;
      }
    }
    nlohmann::json lanes = nlohmann::json::array();
    for (const mosaic::TileKey& k : store_->List(lanes_level)) lanes.push_back({k.col, k.row});
    const std::optional<mosaic::PlaceIndexInfo> places = store_->Places();
    return nlohmann::json{{"file", store_->file().filename().string()},
                          {"mm_per_px", grid.mm_per_px},
                          {"origin_x_mm", grid.origin_x_mm},
                          {"origin_y_mm", grid.origin_y_mm},
                          {"tile_size_px", grid.tile_size_px},
                          {"live_run", options_.live_run},
                          {"map_version", map_version_},
                          {"levels", levels},
                          {"bounds_mm", bounds},
                          {"mapped_tiles", {{"level", lanes_level}, {"tiles", lanes}}},
                          {"place_index", places ? nlohmann::json{{"cells", places->cells}, {"bytes", places->bytes}}
                                                 : nlohmann::json(nullptr)}}
        .dump();
  }

  // The map's quality layer (map build computes it) with the verdict of each cell by the
  // default thresholds: [col, row, mapped, texture, ambiguity, verdict] with verdict 0 good,
  // 1 little texture, 2 repeats, 3 not judged in full (a lane's edge: no template-sized square
  // of floor), -1 too little floor to judge.
  std::string QualityLayer() const {
    const std::optional<mosaic::QualityInfo> info = store_->Quality();
    if (!info) return nlohmann::json{{"available", false}}.dump();
    const mosaic::QualityThresholds thresholds;
    nlohmann::json cells = nlohmann::json::array();
    for (const mosaic::QualityCell& c : store_->ReadQuality()) {
      const int verdict = static_cast<int>(mosaic::VerdictOf(c, thresholds));
      cells.push_back({c.col, c.row, std::round(c.mapped * 100.0) / 100.0, std::round(c.texture * 10.0) / 10.0,
                       std::round(c.ambiguity * 1000.0) / 1000.0, verdict});
    }
    const mosaic::MapGrid& grid = store_->grid();
    return nlohmann::json{{"available", true},
                          {"level", info->level},
                          {"cell_mm", grid.LevelMmPerPx(info->level) * grid.tile_size_px},
                          {"thresholds", {{"min_texture", thresholds.min_texture},
                                          {"max_ambiguity", thresholds.max_ambiguity},
                                          {"min_mapped", thresholds.min_mapped}}},
                          {"columns", {"col", "row", "mapped", "texture", "ambiguity", "verdict"}},
                          {"cells", cells}}
        .dump();
  }

  // The map's recorded updates (automatic mapping, map updates, reverts; design.md section 4)
  // with the level-0 tiles each wrote, the newest kMaxHistory of them.
  std::string HistoryLayer() const {
    static constexpr std::size_t kMaxHistory = 2000;
    const std::vector<mosaic::MapUpdate> updates = store_->History();
    std::map<std::int64_t, nlohmann::json> tiles;
    for (const auto& [id, key] : store_->UpdatedTiles()) {
      if (key.level == 0) tiles[id].push_back({key.col, key.row});
    }
    nlohmann::json list = nlohmann::json::array();
    std::int64_t in_force = 0;
    for (std::size_t i = updates.size() > kMaxHistory ? updates.size() - kMaxHistory : 0; i < updates.size(); ++i) {
      const mosaic::MapUpdate& u = updates[i];
      in_force += u.reverted.empty() ? 1 : 0;
      const auto t = tiles.find(u.id);
      list.push_back({{"id", u.id},
                      {"time", u.time},
                      {"kind", u.reason.starts_with("automatic mapping") ? "mapping"
                               : u.reason.starts_with("map update")      ? "update"
                                                                         : "other"},
                      {"reason", u.reason},
                      {"tiles", u.tiles},
                      {"reverted", u.reverted.empty() ? nlohmann::json(nullptr) : nlohmann::json(u.reverted)},
                      {"cells", t == tiles.end() ? nlohmann::json::array() : t->second}});
    }
    const mosaic::MapGrid& grid = store_->grid();
    return nlohmann::json{{"map_version", map_version_},
                          {"tile_mm", grid.mm_per_px * grid.tile_size_px},
                          {"count", updates.size()},
                          {"in_force", in_force},
                          {"updates", list}}
        .dump();
  }

  // Called with map_mutex_ held (or before the server starts).
  void ReadMap() {
    map_state_.map_info = MapInfo();
    map_state_.quality = QualityLayer();
    map_state_.history = HistoryLayer();
  }

  // What the map holds now: checked at most every kCheckS against SQLite's data_version, and
  // read again (the tile cache emptied) when another connection wrote to the map, as a live
  // run's automatic mapping and map updates, `map revert` or another process do.
  void Refresh() {
    static constexpr double kCheckS = 0.5;
    const std::lock_guard lock(map_mutex_);
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - last_check_).count() >= kCheckS) {
      last_check_ = now;
      const std::int64_t version = store_->DataVersion();
      if (version != data_version_) {
        data_version_ = version;
        ++map_version_;
        cache_.Clear();
        ReadMap();
      }
    }
  }
  std::string Current(std::string MapState::*part) {
    Refresh();
    const std::lock_guard lock(map_mutex_);
    return map_state_.*part;
  }

  nlohmann::json LiveJson(bool with_path) {
    // Copied under the lock, made into JSON outside it: the frame loop's try-lock is kept
    // waiting (and its frame dropped from the console) for a copy's time only.
    LivePose p;
    bool has_live = false;
    std::int64_t serial = 0;
    std::vector<std::array<double, 2>> path;
    {
      const std::lock_guard lock(live_mutex_);
      p = live_;
      has_live = has_live_;
      serial = live_serial_;
      if (with_path) {
        path.reserve(path_count_);
        for (std::size_t i = 0; i < path_count_; ++i) {
          path.push_back(path_[(path_next_ + kPathPoints - path_count_ + i) % kPathPoints]);
        }
      }
    }
    nlohmann::json live = {{"live", false}};
    if (has_live) {
      live = {{"live", true},
              {"serial", serial},
              {"t_s", p.t_s},
              {"known", p.known},
              {"x_mm", p.x_mm},
              {"y_mm", p.y_mm},
              {"yaw_rad", p.yaw_rad},
              {"covariance_mm2", {p.cov_xx, p.cov_xy, p.cov_yy}},
              {"sigma_yaw_rad", p.sigma_yaw_rad},
              {"lock", p.lock},
              {"mode", p.mode},
              {"fixed", p.fixed},
              {"quality", p.quality},
              {"scale", p.scale},
              {"height_mm", p.height_mm},
              {"latency_ms", p.latency_ms},
              {"frames", p.frames},
              {"fixes", p.fixes}};
      if (with_path) {
        nlohmann::json points = nlohmann::json::array();
        for (const auto& point : path) {
          points.push_back({std::round(point[0] * 100.0) / 100.0, std::round(point[1] * 100.0) / 100.0});
        }
        live["path"] = std::move(points);
      }
    }
    Refresh();
    {
      const std::lock_guard lock(map_mutex_);
      live["map_version"] = map_version_;  // the page redraws the map when it changes
    }
    const std::lock_guard lock(status_mutex_);
    live["status"] = status_;
    return live;
  }

  // The token from a Bearer header, the query (?token=, how a browser's first request brings
  // it) or the cookie set in answer to that (so the page's own requests carry it).
  bool Authorized(const httplib::Request& request) const {
    if (options_.token.empty()) return true;
    const std::string header = request.get_header_value("Authorization");
    if (header.rfind("Bearer ", 0) == 0 && SameSecret(header.substr(7), options_.token)) return true;
    if (request.has_param("token") && SameSecret(request.get_param_value("token"), options_.token)) return true;
    const std::string cookies = request.get_header_value("Cookie");
    for (std::size_t at = cookies.find(kTokenCookie); at != std::string::npos; at = cookies.find(kTokenCookie, at + 1)) {
      if (at != 0 && cookies[at - 1] != ' ' && cookies[at - 1] != ';') continue;
      const std::size_t begin = at + kTokenCookie.size();
      const std::size_t end = cookies.find(';', begin);
      if (SameSecret(cookies.substr(begin, end == std::string::npos ? std::string::npos : end - begin), options_.token)) {
        return true;
      }
    }
    return false;
  }

  void Routes() {
    server_.new_task_queue = [threads = options_.threads] {
      return new httplib::ThreadPool(static_cast<std::size_t>(threads));
    };
    // SO_REUSEADDR only: httplib's default also sets SO_REUSEPORT, with which another process
    // could bind the same port and take a share of the console's connections.
    server_.set_socket_options([](socket_t socket) {
      const int yes = 1;
      setsockopt(socket, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
    });
    server_.set_payload_max_length(1024);
    server_.set_read_timeout(5, 0);
    server_.set_write_timeout(5, 0);
    server_.set_keep_alive_timeout(5);
    server_.set_keep_alive_max_count(1000);
    server_.set_default_headers({{"X-Content-Type-Options", "nosniff"},
                                 {"Referrer-Policy", "no-referrer"},
                                 {"Cache-Control", "no-store"}});
    server_.set_pre_routing_handler([this](const httplib::Request& request, httplib::Response& response) {
      ++requests_;
      // At most gzip: the library compresses every text and JSON answer on the fly in the best
      // encoding the client accepts, and its brotli took 0.6 s for Leaflet's 420 KiB script
      // (gzip 14 ms), which delayed a page's first view by as much. The request is the
      // library's own, not const; only the header that drives that choice is changed.
      auto& headers = const_cast<httplib::Headers&>(request.headers);
      if (const auto it = headers.find("Accept-Encoding"); it != headers.end()) {
        const bool gzip = it->second.find("gzip") != std::string::npos;
        headers.erase("Accept-Encoding");
        if (gzip) headers.emplace("Accept-Encoding", "gzip");
      }
      if (!limiter_.Allow(request.remote_addr)) {
        ++rate_limited_;
        SendError(response, 429, "too many requests");
        return httplib::Server::HandlerResponse::Handled;
      }
      if (request.method != "GET" && request.method != "HEAD") {
        SendError(response, 405, "the console is read-only");
        return httplib::Server::HandlerResponse::Handled;
      }
      if (!Authorized(request)) {
        ++unauthorized_;
        SendError(response, 401, "a token is required (?token= or Authorization: Bearer)");
        return httplib::Server::HandlerResponse::Handled;
      }
      return httplib::Server::HandlerResponse::Unhandled;
    });
    server_.set_logger([](const httplib::Request& request, const httplib::Response& response) {
      core::Log().debug("console: {} {} {} {} bytes", request.remote_addr, request.path, response.status,
                        response.body.size());
    });
    server_.set_exception_handler([](const httplib::Request&, httplib::Response& response, std::exception_ptr error) {
      std::string message = "internal error";
      try {
        if (error) std::rethrow_exception(error);
      } catch (const std::exception& e) {
        message = e.what();
      } catch (...) {
      }
      SendError(response, 500, message);
    });
    server_.set_error_handler([](const httplib::Request&, httplib::Response& response) {
      if (response.body.empty()) {
        response.set_content(nlohmann::json{{"error", "no such resource"}}.dump(), "application/json");
      }
    });

    server_.Get("/", [this](const httplib::Request&, httplib::Response& response) {
      if (!options_.token.empty()) {
        // Only a request that carried the token gets here; the page's own requests (scripts,
        // tiles, the stream) then carry it as this cookie, never sent to another site.
        response.set_header("Set-Cookie", std::string(kTokenCookie) + options_.token +
                                              "; Path=/; HttpOnly; SameSite=Strict");
      }
      response.set_content(std::string(internal::kIndexHtml), "text/html; charset=utf-8");
    });
    server_.Get("/console.js", [](const httplib::Request&, httplib::Response& response) {
      response.set_content(std::string(internal::kConsoleJs), "text/javascript");
    });
    server_.Get("/console.css", [](const httplib::Request&, httplib::Response& response) {
      response.set_content(std::string(internal::kConsoleCss), "text/css");
    });
    server_.Get(R"(/leaflet/[a-z0-9/.-]+)", [this](const httplib::Request& request, httplib::Response& response) {
      const auto it = viewer_files_.find(request.path);
      if (it == viewer_files_.end()) return SendError(response, 404, "no such file");
      CacheFor(response, "max-age=86400");
      response.set_content(it->second.body, it->second.content_type);
    });
    server_.Get("/api/map", [this](const httplib::Request&, httplib::Response& response) {
      SendJson(response, Current(&MapState::map_info));
    });
    server_.Get(R"(/api/tiles/(\d{1,2})/(-?\d{1,12})/(-?\d{1,12})\.png)",
                [this](const httplib::Request& request, httplib::Response& response) { Tile(request, response); });
    server_.Get("/api/quality", [this](const httplib::Request&, httplib::Response& response) {
      SendJson(response, Current(&MapState::quality));
    });
    server_.Get("/api/history", [this](const httplib::Request&, httplib::Response& response) {
      SendJson(response, Current(&MapState::history));
    });
    server_.Get("/api/reports", [this](const httplib::Request&, httplib::Response& response) { SendJson(response, reports_); });
    server_.Get(R"(/api/reports/(\d{1,4}))", [this](const httplib::Request& request, httplib::Response& response) {
      const std::size_t id = std::stoul(request.matches[1]);
      if (id >= report_layers_.size()) return SendError(response, 404, "no report " + std::to_string(id));
      SendJson(response, report_layers_[id]);
    });
    server_.Get("/api/live", [this](const httplib::Request&, httplib::Response& response) {
      SendJson(response, LiveJson(true).dump());
    });
    server_.Get("/api/live/stream", [this](const httplib::Request&, httplib::Response& response) { Stream(response); });
  }

  void Tile(const httplib::Request& request, httplib::Response& response) {
    Refresh();  // a map written since is read anew: the cache holds no tile it replaced
    const mosaic::MapGrid& grid = store_->grid();
    const int level = std::stoi(request.matches[1]);
    if (level >= grid.levels) return SendError(response, 404, "no level " + std::to_string(level));
    const mosaic::TileKey key{level, std::stoll(request.matches[2]), std::stoll(request.matches[3])};
    std::shared_ptr<const std::string> png = cache_.Find(key);
    if (!png) {
      mosaic::EncodedTileRead read = store_->ReadEncoded(key);
      if (read.status == mosaic::TileStatus::kAbsent) return SendError(response, 404, "unmapped");
      if (read.status == mosaic::TileStatus::kCorrupt) return SendError(response, 500, read.problem);
      png = std::make_shared<const std::string>(read.png.begin(), read.png.end());
      cache_.Put(key, png);
    }
    CacheFor(response, "max-age=60");
    response.set_content(*png, "image/png");
  }

  // Every answer carries the default "no-store"; one that may be cached says how long instead.
  static void CacheFor(httplib::Response& response, const char* cache_control) {
    response.headers.erase("Cache-Control");
    response.set_header("Cache-Control", cache_control);
  }

  void Stream(httplib::Response& response) {
    if (++streams_ > options_.max_streams) {
      --streams_;
      ++streams_refused_;
      return SendError(response, 503, "too many live streams open");
    }
    const auto period = std::chrono::duration<double>(1.0 / options_.stream_hz);
    response.set_chunked_content_provider(
        "text/event-stream",
        [this, period, last_serial = std::int64_t{-1}](std::size_t, httplib::DataSink& sink) mutable {
          if (stopping_) return false;
          std::this_thread::sleep_for(period);
          nlohmann::json live = LiveJson(false);
          const std::int64_t serial = live.value("serial", std::int64_t{-1});
          // A comment line keeps a quiet stream open and finds a closed one.
          const std::string event = serial != last_serial ? "data: " + live.dump() + "\n\n" : ": idle\n\n";
          last_serial = serial;
          return sink.write(event.data(), event.size());
        },
        [this](bool) { --streams_; });
  }

  ConsoleOptions options_;
  ListenAddress address_;
  std::unique_ptr<mosaic::TileStore> store_;
  std::mutex map_mutex_;
  MapState map_state_;
  std::int64_t data_version_ = 0;
  std::int64_t map_version_ = 1;
  std::chrono::steady_clock::time_point last_check_ = std::chrono::steady_clock::now();
  std::string reports_;
  std::vector<std::string> report_layers_;
  std::map<std::string, internal::StaticFile> viewer_files_;
  internal::RateLimiter limiter_;
  internal::EncodedTileCache cache_;
  internal::ConsoleServer server_;
  std::thread thread_;
  int port_ = -1;
  std::atomic<bool> stopping_{false};
  std::atomic<int> streams_{0};
  std::atomic<std::int64_t> requests_{0}, rate_limited_{0}, unauthorized_{0}, streams_refused_{0};

  std::mutex live_mutex_;
  LivePose live_;
  bool has_live_ = false;
  std::int64_t live_serial_ = 0;
  std::array<std::array<double, 2>, kPathPoints> path_{};
  std::size_t path_next_ = 0;
  std::size_t path_count_ = 0;
  std::mutex status_mutex_;
  nlohmann::json status_ = nullptr;
};

Console::Console(const ConsoleOptions& options, const fs::path& map) : impl_(std::make_unique<Impl>(options, map)) {}
Console::~Console() = default;
int Console::Start() { return impl_->Start(); }
void Console::Stop() { impl_->Stop(); }
std::string Console::Answer(std::string_view request) { return impl_->Answer(request); }
std::string Console::Url() const { return impl_->Url(); }
void Console::PublishPose(const LivePose& pose) noexcept { impl_->PublishPose(pose); }
void Console::PublishStatus(const nlohmann::json& status) { impl_->PublishStatus(status); }
Console::Counters Console::counters() const { return impl_->counters(); }

}  // namespace mosaicloc::console
