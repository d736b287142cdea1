#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mosaicloc/runtime/settings.hpp"
#include "mosaicloc/sim/simulator.hpp"

namespace mosaicloc::runtime {

/// `mosaicloc bench soak` (design.md section 8): a long simulated drive fed to the localizer in
/// one process, frame by frame as the simulator renders it (no dataset on disk), against a map
/// painted at the true poses from one slow lap of the same route; every fix compared with the
/// truth, and the process's memory, file descriptors and threads sampled as it goes.
struct SoakOptions {
  /// The drive: floor, route, speed, conditions (height, tilt, floor changes, light, drops),
  /// and `frames`, how many frames to localize (laps is ignored).
  sim::SimulatorOptions drive;
  double map_speed_mps = 0.5;  ///< the mapping lap's speed
  /// Laps mapped. The network route's second lap takes lanes its first does not: with one lap
  /// mapped the drive leaves the map every other lap (visual odometry off it, the returns).
  int map_laps = 1;
  LocalizationSettings settings;
  std::filesystem::path work;  ///< the mapping lap and the map are made here
  /// Laps per simulated segment: each segment is a new drive of the route (its own lateral
  /// deviation), from where the last one stopped, so memory does not grow with the frames.
  int segment_laps = 4;
  double wrong_mm = 1.0;        ///< a fix farther from the truth is wrong
  double sample_every_s = 5.0;  ///< wall-clock seconds between resource samples
  bool Check(std::string* why) const;
};

/// The process at one moment of the soak.
struct SoakSample {
  double wall_s = 0.0;
  std::int64_t frames = 0;
  double rss_mib = 0.0;
  double heap_mib = 0.0;  ///< what the program holds of the heap (mallinfo2: in use, mapped chunks included)
  double cache_mib = 0.0;  ///< of which the map's decoded tiles: the tile cache's slabs (reused, never freed: at most its budget and one slab)
  std::int64_t fds = 0;
  std::int64_t threads = 0;
};

struct SoakSummary {
  std::int64_t frames = 0, fixes = 0, lock_losses = 0, wrong_fixes = 0, relocalizations = 0, reanchorings = 0;
  std::int64_t encoder_samples_rejected = 0;
  double fix_rate = 0.0;
  double error_rms_mm = 0.0, error_max_mm = 0.0;  ///< of the fixes against the truth
  double driven_s = 0.0, driven_km = 0.0;          ///< simulated
  double seconds = 0.0, frames_per_s = 0.0;        ///< wall clock (rendering included)
  /// Per-frame processing (the localizer alone), ms, to 10 us.
  double processing_p50_ms = 0.0, processing_p99_ms = 0.0, processing_p9999_ms = 0.0, processing_max_ms = 0.0;
  /// Resident memory's least-squares slope over the samples after the first 10 % of the frames
  /// (the caches fill first), MiB per hour of wall clock and per 10^5 frames.
  double rss_slope_mib_per_h = 0.0, rss_slope_mib_per_100k_frames = 0.0;
  double heap_slope_mib_per_100k_frames = 0.0;   ///< the heap in use, over the same samples
  double cache_slope_mib_per_100k_frames = 0.0;  ///< the map's decoded tiles, over the same samples
  std::vector<SoakSample> samples;
  std::string stopped;  ///< why the drive ended before its frames (a stop signal), empty when it did not
};

/// Throws core::Error (invalid input) for bad options or an unreadable floor image.
/// `progress` gets the share of frames done. `stop`, asked between batches of frames, ends the
/// drive early when it gives a reason: the summary then covers the frames localized so far
/// and says why (SoakSummary::stopped).
SoakSummary RunSoak(const SoakOptions& options, const std::function<void(double)>& progress = {},
                    const std::function<std::optional<std::string>()>& stop = {});

/// The summary as `bench soak --json` prints it (samples as rows of wall_s, frames, rss_mib, heap_mib, cache_mib,
/// fds, threads), and as lines of text; `work` is where the map was made.
nlohmann::json SoakJson(const SoakSummary& summary, const std::filesystem::path& work);
std::string SoakText(const SoakSummary& summary, const std::filesystem::path& work);

/// What `bench soak` is asked for: the drive's simulator configuration (empty: the defaults)
/// with its floor, route, speed, frames and seed replaced, the localizer's configuration
/// (empty: the defaults), and where the map is made (empty: a new folder under the system's
/// temporary directory).
struct SoakRequest {
  std::filesystem::path simulator_config, localizer_config, work;
  std::string floor = "procedural", route = "network";
  std::int64_t frames = 100000;
  double speed_mps = 1.5;
  std::uint64_t seed = 7;
  int threads = 2;  ///< rendering threads
  int map_laps = 1;
};
/// Throws core::Error (invalid input) for an unreadable configuration, naming file and key.
SoakOptions SoakOptionsFor(const SoakRequest& request);

/// The process's resident memory and heap in use (MiB), open file descriptors and threads, from
/// /proc/self and mallinfo2 (the tile cache's share is the caller's to fill in).
SoakSample SampleProcess();

}  // namespace mosaicloc::runtime
