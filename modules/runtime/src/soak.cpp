#include "mosaicloc/runtime/soak.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <random>
#include <string>
#include <malloc.h>
#include <unistd.h>

#include <fmt/format.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/core/worker_pool.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/localizer/localizer.hpp"
#include "latency_histogram.hpp"
#include "process_memory.hpp"
#include "mosaicloc/runtime/map_jobs.hpp"
#include "mosaicloc/runtime/localization_config.hpp"
#include "mosaicloc/runtime/map_session.hpp"
#include "mosaicloc/sim/config.hpp"
#include "mosaicloc/sim/encoders.hpp"
#include "mosaicloc/sim/route.hpp"

namespace mosaicloc::runtime {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Least-squares slope of y over x (0 with fewer than two distinct x).
double Slope(const std::vector<double>& x, const std::vector<double>& y) {
  const auto n = static_cast<double>(x.size());
  if (x.size() < 2) return 0.0;
  double mx = 0.0, my = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    mx += x[i] / n;
    my += y[i] / n;
  }
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
  }
  return sxx > 0.0 ? sxy / sxx : 0.0;
}

// The map the soak drives on: one slow lap of the route, painted at the true poses (the soak
// measures the localizer over time, not the mapping).
fs::path MakeSoakMap(const SoakOptions& options) {
  sim::SimulatorOptions lap = options.drive;
  lap.laps = options.map_laps;
  lap.route.speed_mps = options.map_speed_mps;
  lap.seed = options.drive.seed + 1000;
  lap.drop_probability = 0.0;
  lap.changes = sim::FloorChangeOptions{};  // the floor as it was mapped; the drive sees its changes
  fs::create_directories(options.work);
  const fs::path dataset = options.work / "mapping-lap";
  sim::Simulate(lap, dataset, /*overwrite=*/true);
  MapBuildOptions build;
  build.dataset = dataset;
  build.out = options.work / "soak.mosaic";
  build.poses = "groundtruth";
  build.overwrite = true;
  BuildMap(build);
  return build.out;
}

}  // namespace

bool SoakOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!drive.Check(why)) return false;
  if (drive.frames < 1) return fail("soak: frames must be >= 1");
  if (!(map_speed_mps > 0.0)) return fail("soak: map_speed_mps must be > 0");
  if (map_laps < 1) return fail("soak: map_laps must be >= 1");
  if (segment_laps < 1) return fail("soak: segment_laps must be >= 1");
  if (!(wrong_mm > 0.0)) return fail("soak: wrong_mm must be > 0");
  if (!(sample_every_s > 0.0)) return fail("soak: sample_every_s must be > 0");
  if (work.empty()) return fail("soak: no work directory");
  return true;
}

SoakSample SampleProcess() {
  SoakSample sample;
  const ProcessMemory memory = ReadProcessMemory();
  sample.rss_mib = memory.rss_mib;
  sample.heap_mib = memory.heap_mib;
  std::error_code ec;
  for (auto it = fs::directory_iterator("/proc/self/fd", ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    ++sample.fds;
  }
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("Threads:", 0) == 0) sample.threads = std::stoll(line.substr(8));
  }
  return sample;
}

SoakOptions SoakOptionsFor(const SoakRequest& request) {
  sim::SimulatorOverrides drive;
  drive.floor = request.floor;
  drive.route = request.route;
  drive.speed_mps = request.speed_mps;
  drive.frames = request.frames;
  drive.seed = request.seed;
  drive.threads = request.threads;
  SoakOptions options;
  options.drive = sim::SimulatorOptionsFor(request.simulator_config, drive);
  options.map_laps = request.map_laps;
  if (!request.localizer_config.empty()) options.settings = LoadLocalizerConfig(request.localizer_config);
  options.work = request.work.empty()
                     ? std::filesystem::temp_directory_path() / ("mosaicloc-soak-" + std::to_string(::getpid()))
                     : request.work;
  return options;
}

SoakSummary RunSoak(const SoakOptions& options, const std::function<void(double)>& progress,
                    const std::function<std::optional<std::string>()>& stop) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  const fs::path map_file = MakeSoakMap(options);
  // What building the map allocated goes back to the system: the samples start from the soak's own.
  malloc_trim(0);
  const dataset::DatasetInfo info = dataset::DatasetReader(options.work / "mapping-lap").info();

  const LocalizationSettings& settings = options.settings;
  MapSessionOptions map_options;
  map_options.cache_budget_bytes = settings.cache_budget_mib << 20;
  map_options.camera_mm_per_px = info.camera.mm_per_px;
  MapSession map(map_file, map_options);
  const camera::IdealCamera camera(options.drive.camera);
  const localizer::LocalizerOptions localizer_options = LocalizerOptionsFor(
      settings.localizer, info.camera, info.vehicle, settings.localizer.odometry_timing_sigma_ms);
  localizer::Localizer localizer(camera, localizer_options, map.reference(), &map.places());

  const sim::SimulatorOptions& drive_options = options.drive;
  sim::EncoderModel encoders(drive_options.encoders, drive_options.seed);
  const double period_s = 1.0 / drive_options.frame_rate_hz;
  const double encoder_period_s = 1.0 / drive_options.encoders.rate_hz;
  std::mt19937_64 rng(drive_options.seed ^ 0x50a4ULL);
  std::normal_distribution<double> jitter(0.0, drive_options.timestamp_jitter_ms * 1e-3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int threads = std::max(1, drive_options.threads);
  core::WorkerPool workers(threads);  // the same rendering threads for the whole drive

  SoakSummary summary;
  LatencyHistogram processing;
  double error_sum_sq = 0.0;
  const auto start = Clock::now();
  auto next_sample = start;
  const auto sample = [&] {
    SoakSample s = SampleProcess();
    s.wall_s = std::chrono::duration<double>(Clock::now() - start).count();
    s.frames = summary.frames;
    s.cache_mib = map.cache_mib();
    summary.samples.push_back(s);
  };
  sample();

  double segment_start_s = 0.0;  // drive time at which the segment starts
  std::int64_t encoder_index = 0;
  std::int64_t frame_index = 0;  // capture slots, dropped ones included
  bool initialized = false;
  double last_frame_s = 0.0;  // drive time of the last frame localized
  for (std::uint64_t segment = 0; summary.frames < drive_options.frames && summary.stopped.empty(); ++segment) {
    const sim::Drive drive(drive_options.route, options.segment_laps, drive_options.seed + segment);
    const sim::FrameRenderer renderer(drive_options, drive);
    const double segment_end_s = segment_start_s + drive.duration_s();
    // The encoder samples up to drive time t (the segment's drive, from where it started).
    std::optional<dataset::EncoderSample> pending;
    const auto next_encoder = [&]() -> std::optional<dataset::EncoderSample> {
      const double t = static_cast<double>(encoder_index) * encoder_period_s;
      if (t > segment_end_s) return std::nullopt;
      ++encoder_index;
      return encoders.Step(core::Timestamp::FromSeconds(t), drive.At(t - segment_start_s).world_from_vehicle,
                           drive.At(t - segment_start_s + sim::kSteeringInstantS).world_from_vehicle);
    };
    pending = next_encoder();
    if (!initialized && pending) {
      localizer.Initialize(pending->time, drive.At(0.0).world_from_vehicle,
                           StartCovariance(settings.start_sigma_mm, settings.start_sigma_deg));
      initialized = true;
    }
    const auto feed = [&] {
      if (!localizer.AddEncoders(pending->time, pending->counts)) {
        ++summary.encoder_samples_rejected;
      }
      pending = next_encoder();
    };
    // Capture instants of this segment, then its frames rendered in batches on `threads`.
    std::vector<double> capture_s;
    std::vector<std::uint64_t> slot;  // each capture's index among the drive's capture instants (its noise seed)
    for (; summary.frames + static_cast<std::int64_t>(capture_s.size()) < drive_options.frames; ++frame_index) {
      const double t = static_cast<double>(frame_index) * period_s;
      if (t + period_s > segment_end_s) break;
      const double j = std::clamp(jitter(rng), -0.25 * period_s, 0.25 * period_s);
      if (unit(rng) < drive_options.drop_probability) continue;
      capture_s.push_back(std::max(segment_start_s, t + j));
      slot.push_back(static_cast<std::uint64_t>(frame_index));
    }
    const std::size_t batch = 8 * static_cast<std::size_t>(threads);
    std::vector<cv::Mat> images(batch);
    for (std::size_t first = 0; first < capture_s.size(); first += batch) {
      if (stop) {
        if (const std::optional<std::string> reason = stop()) {
          summary.stopped = *reason;
          break;
        }
      }
      const std::size_t count = std::min(batch, capture_s.size() - first);
      workers.Run(count, [&](std::size_t i) {
        const double t = capture_s[first + i];
        images[i] = renderer.Render(t - segment_start_s, sim::FrameSeed(drive_options.seed, slot[first + i]));
      });
      for (std::size_t i = 0; i < count; ++i) {
        const double t = capture_s[first + i];
        const core::Timestamp time = core::Timestamp::FromSeconds(t);
        while (pending && pending->time <= time) feed();
        if (pending) feed();  // one sample past the frame: the fix arrives late, as on a vehicle
        const auto began = Clock::now();
        const localizer::FrameOutcome outcome = localizer.ProcessFrame(time, images[i]);
        processing.Add(std::chrono::duration<double, std::milli>(Clock::now() - began).count());
        ++summary.frames;
        last_frame_s = t;
        if (outcome.fixed) {
          ++summary.fixes;
          const core::Pose2 truth = drive.At(t - segment_start_s).world_from_vehicle;
          const double error = core::Distance(outcome.world_from_vehicle, truth);
          error_sum_sq += error * error;
          summary.error_max_mm = std::max(summary.error_max_mm, error);
          if (error > options.wrong_mm) {
            if (++summary.wrong_fixes <= 5) {
              core::Log().warn("soak: a wrong fix at {:.3f} s: {:.3f} mm from the truth", t, error);
            }
          }
        }
        if (Clock::now() >= next_sample) {
          sample();
          next_sample = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(options.sample_every_s));
        }
      }
      if (progress) progress(static_cast<double>(summary.frames) / static_cast<double>(drive_options.frames));
    }
    // The last sample while the drive is still under way: the segment's renderer, freed below,
    // would otherwise show as a drop of the heap at the very end.
    if (summary.frames >= drive_options.frames || !summary.stopped.empty()) sample();
    if (!summary.stopped.empty()) {  // the segment driven up to its last frame
      summary.driven_km += 1e-3 * drive.At(last_frame_s - segment_start_s).path_distance_m;
      segment_start_s = last_frame_s;
      break;
    }
    summary.driven_km += 1e-3 * drive.length_m();
    segment_start_s = segment_end_s;
    frame_index = static_cast<std::int64_t>(std::ceil(segment_start_s / period_s));
  }
  summary.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  summary.frames_per_s = static_cast<double>(summary.frames) / std::max(summary.seconds, 1e-9);
  summary.driven_s = segment_start_s;
  summary.lock_losses = localizer.lock().losses();
  summary.relocalizations = localizer.relocalizations();
  summary.reanchorings = localizer.reanchorings();
  summary.fix_rate = static_cast<double>(summary.fixes) / static_cast<double>(std::max<std::int64_t>(summary.frames, 1));
  summary.error_rms_mm = summary.fixes > 0 ? std::sqrt(error_sum_sq / static_cast<double>(summary.fixes)) : 0.0;
  summary.processing_p50_ms = processing.Percentile(50.0);
  summary.processing_p99_ms = processing.Percentile(99.0);
  summary.processing_p9999_ms = processing.Percentile(99.99);
  summary.processing_max_ms = processing.max_ms();
  // Memory after the caches filled: the samples past the first 10 % of the frames.
  std::vector<double> hours, per_100k, rss, heap, cache;
  for (const SoakSample& s : summary.samples) {
    if (s.frames < summary.frames / 10) continue;
    hours.push_back(s.wall_s / 3600.0);
    per_100k.push_back(static_cast<double>(s.frames) / 1e5);
    rss.push_back(s.rss_mib);
    heap.push_back(s.heap_mib);
    cache.push_back(s.cache_mib);
  }
  summary.rss_slope_mib_per_h = Slope(hours, rss);
  summary.rss_slope_mib_per_100k_frames = Slope(per_100k, rss);
  summary.heap_slope_mib_per_100k_frames = Slope(per_100k, heap);
  summary.cache_slope_mib_per_100k_frames = Slope(per_100k, cache);
  return summary;
}

nlohmann::json SoakJson(const SoakSummary& r, const std::filesystem::path& work) {
  nlohmann::json samples = nlohmann::json::array();
  for (const SoakSample& s : r.samples) samples.push_back({s.wall_s, s.frames, s.rss_mib, s.heap_mib, s.cache_mib, s.fds, s.threads});
  return {{"frames", r.frames},
          {"fixes", r.fixes},
          {"fix_rate", r.fix_rate},
          {"lock_losses", r.lock_losses},
          {"wrong_fixes", r.wrong_fixes},
          {"relocalizations", r.relocalizations},
          {"reanchorings", r.reanchorings},
          {"encoder_samples_rejected", r.encoder_samples_rejected},
          {"error_rms_mm", r.error_rms_mm},
          {"error_max_mm", r.error_max_mm},
          {"driven_s", r.driven_s},
          {"driven_km", r.driven_km},
          {"seconds", r.seconds},
          {"frames_per_s", r.frames_per_s},
          {"processing_p50_ms", r.processing_p50_ms},
          {"processing_p99_ms", r.processing_p99_ms},
          {"processing_p9999_ms", r.processing_p9999_ms},
          {"processing_max_ms", r.processing_max_ms},
          {"rss_slope_mib_per_h", r.rss_slope_mib_per_h},
          {"rss_slope_mib_per_100k_frames", r.rss_slope_mib_per_100k_frames},
          {"heap_slope_mib_per_100k_frames", r.heap_slope_mib_per_100k_frames},
          {"cache_slope_mib_per_100k_frames", r.cache_slope_mib_per_100k_frames},
          {"samples_columns", {"wall_s", "frames", "rss_mib", "heap_mib", "cache_mib", "fds", "threads"}},
          {"samples", samples},
          {"stopped", r.stopped.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.stopped)},
          {"work", work.string()}};
}

std::string SoakText(const SoakSummary& r, const std::filesystem::path& work) {
  const SoakSample& first = r.samples.front();
  const SoakSample& last = r.samples.back();
  const std::string stopped = r.stopped.empty() ? std::string() : "  stopped early: " + r.stopped + "\n";
  return stopped + fmt::format(
      "soak: {} frames ({:.2f} h driven, {:.2f} km) in {:.0f} s ({:.0f} frames/s, rendering included)\n"
      "  fixes {:.3f} %, lock losses {}, wrong fixes (> 1 mm) {}, relocalizations {}, re-anchorings {}; fix error RMS {:.4f} mm, max "
      "{:.4f} mm\n"
      "  processing per frame: p50 {:.3f} ms, p99 {:.3f} ms, p99.99 {:.3f} ms, max {:.3f} ms\n"
      "  resident memory {:.1f} -> {:.1f} MiB, slope after warm-up {:+.2f} MiB/h ({:+.3f} MiB per 10^5 frames); heap in use "
      "{:.1f} -> {:.1f} MiB ({:+.3f} MiB per 10^5 frames), of which map tiles "
      "{:.1f} -> {:.1f} MiB ({:+.3f} MiB per 10^5 frames); file descriptors {} -> {}; threads {} -> {}\n"
      "  map and mapping lap in {}\n",
      r.frames, r.driven_s / 3600.0, r.driven_km, r.seconds, r.frames_per_s, 100.0 * r.fix_rate, r.lock_losses,
      r.wrong_fixes, r.relocalizations, r.reanchorings, r.error_rms_mm, r.error_max_mm, r.processing_p50_ms, r.processing_p99_ms,
      r.processing_p9999_ms, r.processing_max_ms, first.rss_mib, last.rss_mib, r.rss_slope_mib_per_h,
      r.rss_slope_mib_per_100k_frames, first.heap_mib, last.heap_mib, r.heap_slope_mib_per_100k_frames,
      first.cache_mib, last.cache_mib, r.cache_slope_mib_per_100k_frames, first.fds, last.fds, first.threads, last.threads, work.string());
}

}  // namespace mosaicloc::runtime
