#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace mosaicloc::console {

/// Where the console listens and what it may serve (design.md section 5b). Read-only always;
/// bound to the loopback interface unless allow_remote, which also needs a token.
struct ConsoleOptions {
  /// "HOST:PORT" with HOST an IP address or "localhost"; port 0 takes any free port.
  std::string listen = "127.0.0.1:8080";
  /// Listening on an address other than loopback: must be asked for, and then every request
  /// must carry `token` (Authorization: Bearer TOKEN, or ?token=TOKEN for a browser's page).
  bool allow_remote = false;
  /// Required with allow_remote (at least 16 characters); on loopback optional, and enforced
  /// when given.
  std::string token;
  /// Report folders served as layers: a replay's report (fixes.csv, metrics.json) or a map
  /// build's mapping report (consistency.json, poses.tum, loops.csv). Read once at start.
  std::vector<std::filesystem::path> reports;
  /// Where Debian's libjs-leaflet puts the map viewer the page loads.
  std::filesystem::path leaflet_dir = "/usr/share/javascript/leaflet";
  /// Threads answering requests (each live stream holds one while it is open).
  int threads = 8;
  /// Live streams open at once (server-sent events); more are refused with 503.
  int max_streams = 4;
  /// Requests a second each client address may make on average, and in a burst; more are
  /// refused with 429.
  double requests_per_s = 200.0;
  double burst = 400.0;
  /// Live state pushed to each stream this often, Hz.
  double stream_hz = 20.0;
  /// A live run publishes to this console: the page opens the live stream (a console over a
  /// map and reports alone has nothing to stream).
  bool live_run = false;
  /// Bytes of encoded tiles kept in memory for repeated requests.
  std::int64_t tile_cache_bytes = 64LL << 20;
  /// Ranges and the remote rule; each complaint starts with the field's name.
  bool Check(std::string* why) const;
};

/// The host and the port of "HOST:PORT"; throws core::Error (invalid input) naming the text.
struct ListenAddress {
  std::string host;
  int port = 0;
  bool loopback = false;
};
ListenAddress ParseListen(const std::string& text);

/// The token in a file's first line (surrounding white space dropped), so it stays out of
/// command lines and configuration files; throws core::Error naming the file when it cannot be
/// read or is empty.
std::string ReadTokenFile(const std::filesystem::path& file);

/// One frame's result as the live run publishes it (cheap to copy; no allocation).
struct LivePose {
  double t_s = 0.0;            ///< since the run started
  bool known = false;          ///< there is an estimate (not while searching from an unknown start)
  double x_mm = 0.0, y_mm = 0.0, yaw_rad = 0.0;  ///< world_from_vehicle
  double cov_xx = 0.0, cov_xy = 0.0, cov_yy = 0.0;  ///< position covariance, mm^2
  double sigma_yaw_rad = 0.0;
  int lock = 0;                ///< design.md section 6: 1 tracking ... 5 searching
  std::string mode;            ///< what the localizer did (design.md section 7c): "track", ...
  bool fixed = false;          ///< this frame had an accepted visual fix
  double quality = 0.0;        ///< 0..1
  double scale = 1.0;          ///< the image scale held (height over the calibrated height)
  double height_mm = 0.0;      ///< the camera's height over the floor that scale means; 0: unknown
  double latency_ms = 0.0;     ///< frame time to result
  std::int64_t frames = 0;     ///< processed so far
  std::int64_t fixes = 0;
};

/// The integrator's console (design.md section 5b): an HTTP server serving the map's tiles
/// straight from its file, the report layers, the live state and a page that shows them
/// (Leaflet, from the Debian package, served locally). Nothing is served from a path a request
/// names: tiles are addressed by level and index, reports by their number, the viewer's files
/// by a fixed list. Requests run on the server's own threads; the live run's frame loop only
/// ever tries a lock (PublishPose), so no client can slow it.
class Console {
 public:
  /// Opens the map (read-only) and reads the reports and the viewer's files; throws
  /// core::Error naming the file, folder or option at fault. Does not listen yet.
  Console(const ConsoleOptions& options, const std::filesystem::path& map);
  ~Console();
  Console(const Console&) = delete;
  Console& operator=(const Console&) = delete;

  /// Binds and starts answering on a thread of its own; throws core::Error naming the address
  /// when it cannot listen. Returns the port (the one taken, for port 0).
  int Start();
  /// Stops listening, ends the live streams and joins the threads (also on destruction).
  void Stop();
  /// http://HOST:PORT/ (with the token, if any), once started.
  std::string Url() const;
  /// The bytes one client connection sends, answered as the server answers them (the same
  /// request parsing, token check, rate limit and routes, the client at 127.0.0.1), without a
  /// socket; returns what it would send back. Started or not. For fuzzing the console.
  std::string Answer(std::string_view request);

  /// The live run's newest frame: never waits (dropped when a reader holds the state), so the
  /// frame loop is never slowed.
  void PublishPose(const LivePose& pose) noexcept;
  /// The live run's once-a-second status (fix rate, latencies, the PLC link's counters and
  /// heartbeat), shown beside the pose.
  void PublishStatus(const nlohmann::json& status);

  /// Requests answered, refused by the rate limit, refused for want of the token.
  struct Counters {
    std::int64_t requests = 0, rate_limited = 0, unauthorized = 0, streams_refused = 0;
  };
  Counters counters() const;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mosaicloc::console
