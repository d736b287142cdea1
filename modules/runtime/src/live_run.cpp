#include "mosaicloc/runtime/live_run.hpp"
#include "mosaicloc/runtime/map_keeping.hpp"

// The live run (mosaicloc run). Four threads share the work (design.md section 1):
//   camera    - takes frames from the source into a short queue (oldest dropped when full);
//   PLC link  - every cycle reads the encoder counters, heartbeat and fix request, and writes
//               the fix: on request (echoing its counter) and periodically. Reading and
//               writing share one thread because a libmodbus context is not thread safe, and
//               so a request seen in a cycle is answered in the same cycle;
//   tracking  - owns the localizer: feeds it the encoder samples, registers each frame once
//               the odometry has passed its time, and publishes the latest state;
//   main      - reports a status line every second, stops when asked, shuts down.
// With --record, a fifth thread writes what the run saw as a dataset.

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <exception>
#include <mutex>
#include <numbers>
#include <pthread.h>
#include <random>
#include <thread>
#include <variant>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/dataset/fixes.hpp"
#include "mosaicloc/io/registers.hpp"
#include "mosaicloc/localizer/localizer.hpp"
#include "mosaicloc/runtime/encoder_stamper.hpp"
#include "mosaicloc/runtime/live_sources.hpp"
#include "mosaicloc/runtime/output_pose.hpp"
#include "mosaicloc/runtime/map_session.hpp"
#include "mosaicloc/runtime/report.hpp"
#include "mosaicloc/runtime/settings.hpp"
#include "mosaicloc/sim/config.hpp"
#include "latency_histogram.hpp"
#include "process_memory.hpp"

namespace mosaicloc::runtime {

bool LiveRunOptions::Check(std::string* why) const {
  const auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  const auto in = [](double value, double low, double high) { return value >= low && value <= high; };
  if (camera_source != "v4l2" && camera_source != "dataset" && camera_source != "simulator") {
    return fail("camera_source must be v4l2, dataset or simulator, got '" + camera_source + "'");
  }
  if (camera.width_px < 16 || camera.width_px > 16384) return fail("width_px must be in [16, 16384]");
  if (camera.height_px < 16 || camera.height_px > 16384) return fail("height_px must be in [16, 16384]");
  if (!in(camera.mm_per_px, 1e-4, 100.0)) return fail("mm_per_px must be in [0.0001, 100]");
  if (!in(dataset_start_unix_s, 0.0, 1e11)) return fail("dataset_start_unix_s must be in [0, 1e11]");
  if (!in(plc_cycle_ms, 1.0, 10000.0)) return fail("plc_cycle_ms must be in [1, 10000]");
  if (!in(fix_period_ms, 0.0, 600000.0)) return fail("fix_period_ms must be in [0, 600000]");
  if (!in(heartbeat_timeout_ms, 0.0, 600000.0)) return fail("heartbeat_timeout_ms must be in [0, 600000]");
  if (!in(encoder_latency_ms, 0.0, 1000.0)) return fail("encoder_latency_ms must be in [0, 1000]");
  if (!in(encoder_timing_sigma_ms, 0.0, 1000.0)) return fail("encoder_timing_sigma_ms must be in [0, 1000]");
  if (!in(stationary_after_ms, 1.0, 60000.0)) return fail("stationary_after_ms must be in [1, 60000]");
  if (!in(counter_period_ms, 0.0, 10000.0)) return fail("counter_period_ms must be in [0, 10000]");
  if (!in(odometry_bridge_ms, 0.0, 2000.0)) return fail("odometry_bridge_ms must be in [0, 2000]");
  if (!in(lock_age_ms, 1.0, 60000.0)) return fail("lock_age_ms must be in [1, 60000]");
  if (plc_thread_priority < 0 || plc_thread_priority > 99) return fail("thread_priority must be in [0, 99]");
  if (!in(start_sigma_mm, 1e-3, 1e5)) return fail("start_sigma_mm must be in [0.001, 100000]");
  if (!in(start_sigma_deg, 1e-4, 180.0)) return fail("start_sigma_deg must be in [0.0001, 180]");
  if (!in(max_encoder_wait_ms, 0.0, 10000.0)) return fail("max_encoder_wait_ms must be in [0, 10000]");
  return true;
}

// The live run's parts, named rather than file-local: LiveRun::Impl holds them.
namespace live_run_detail {

using Clock = std::chrono::steady_clock;

double Ms(core::Duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

// Frame latencies kept for the status line's median: a second's worth at any camera rate.
constexpr std::size_t kRecentLatencies = 4096;

// Writes what the run saw as a dataset (design.md section 4), on a thread of its own so PNG
// encoding never delays tracking. Committed on a clean shutdown only: an interrupted
// recording leaves nothing behind.
class Recorder {
 public:
  Recorder(const std::filesystem::path& directory, const dataset::DatasetInfo& info)
      : writer_(directory, info, /*overwrite=*/false), thread_([this] { Work(); }) {}
  ~Recorder() { Close(); }
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  void Frame(core::Timestamp time, const cv::Mat& image) { Push(FrameItem{time, image}); }
  void Encoders(const dataset::EncoderSample& sample) { Push(sample); }
  /// What the localizer reported for a frame: a row of fixes/data.csv.
  void Report(const dataset::FrameReport& report) {
    const std::string row = dataset::FixesCsvRow(report);
    const std::lock_guard lock(mutex_);
    fixes_ += row;
  }
  /// Writes everything still queued and renames the dataset into place.
  void Commit() {
    Close();
    if (error_) std::rethrow_exception(error_);
    writer_.AddFile("fixes/data.csv", fixes_);
    writer_.Commit();
  }
  std::int64_t frames() const { return frames_; }

 private:
  struct FrameItem {
    core::Timestamp time;
    cv::Mat image;
  };
  using Item = std::variant<FrameItem, dataset::EncoderSample>;

  void Push(Item item) {
    {
      const std::lock_guard lock(mutex_);
      if (closed_) return;
      queue_.push_back(std::move(item));
    }
    wake_.notify_one();
  }

  void Close() {
    {
      const std::lock_guard lock(mutex_);
      closed_ = true;
    }
    wake_.notify_one();
    if (thread_.joinable()) thread_.join();
  }

  void Work() {
    std::unique_lock lock(mutex_);
    while (true) {
      wake_.wait(lock, [this] { return closed_ || !queue_.empty(); });
      if (queue_.empty()) return;
      Item item = std::move(queue_.front());
      queue_.pop_front();
      lock.unlock();
      try {
        if (error_ == nullptr) {
          if (auto* frame = std::get_if<FrameItem>(&item)) {
            writer_.AddEncodedFrame(frame->time, dataset::DatasetWriter::EncodeFrame(frame->image));
            ++frames_;
          } else {
            writer_.AddEncoderSample(std::get<dataset::EncoderSample>(item));
          }
        }
      } catch (...) {
        error_ = std::current_exception();
      }
      lock.lock();
    }
  }

  dataset::DatasetWriter writer_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Item> queue_;
  bool closed_ = false;
  std::string fixes_ = dataset::FixesCsvHeader();
  std::atomic<std::int64_t> frames_{0};
  std::exception_ptr error_;
  std::thread thread_;  // last: starts once everything above exists
};

// What the tracking thread publishes for the PLC thread and the status line.
struct Published {
  estimation::MotionState motion;
  estimation::LockState lock = estimation::LockState::kLost;
  bool fixed_once = false;
  double quality = 0.0;
  double scale = 1.0;  // the image scale the localizer holds (FrameOutcome::scale)
  int mode = 0;        // localizer::Mode of the latest frame; 0 before the first
  Eigen::Vector2d wheel_scale = Eigen::Vector2d::Zero();  // the filter's calibration errors
  std::optional<core::Timestamp> judged;  // capture time of the frame the lock was last judged on
};

// Counters for the status line and the summary; each written by one thread.
struct RunStats {
  std::atomic<std::int64_t> frames{0};
  std::atomic<std::int64_t> frames_dropped{0};
  std::atomic<std::int64_t> processed{0};
  std::atomic<std::int64_t> fixes{0};
  std::atomic<std::int64_t> encoder_samples{0};
  std::atomic<std::int64_t> encoder_rejected{0};
  std::atomic<std::int64_t> encoder_late{0};  // counter updates the PLC made visible late (EncoderStamper)
  std::atomic<std::int64_t> requests{0};
  std::atomic<std::int64_t> relocalize_requests{0};
  std::atomic<std::int64_t> answered{0};
  std::atomic<std::int64_t> fix_writes{0};
  std::atomic<std::int64_t> stale_lock_writes{0};  // tracking written as degraded: the lock's frame too old
  std::atomic<std::int64_t> odometry_outages{0};
  std::array<std::atomic<std::int64_t>, 5> frames_by_mode{};  // by localizer::Mode (0 unused)
  std::atomic<bool> odometry_valid{false};
  std::atomic<bool> heartbeat_stale{false};
  std::mutex mutex;                   // guards what follows
  LatencyHistogram frame_latency;      // capture to fix, every processed frame
  LatencyHistogram processing;         // the tracking thread's own time for each frame
  LatencyHistogram answers;            // request seen to answer written
  std::vector<double> recent_latency_ms;  // capture to fix since the last status line
  io::PlcLinkStats link;
};

}  // namespace live_run_detail

using live_run_detail::Clock;
using live_run_detail::Ms;
using live_run_detail::Published;
using live_run_detail::Recorder;
using live_run_detail::RunStats;

class LiveRun::Impl {
 public:
  Impl(const LiveRunOptions& config, std::unique_ptr<io::FrameSource> source, const dataset::CameraInfo& camera,
       const dataset::VehicleInfo& vehicle, const std::filesystem::path& record)
      : config_(config), source_(std::move(source)), camera_info_(camera), vehicle_kind_(vehicle.kind) {
    runtime::MapSessionOptions map_options;
    map_options.cache_budget_bytes = config.localizer.cache_budget_mib << 20;
    map_options.camera_mm_per_px = camera.mm_per_px;
    if (config.localizer.prefetch_horizon_s > 0.0) map_options.prefetch = runtime::PrefetchOptionsFor(config.localizer, camera);
    map_options.writable = config.mapping;
    map_ = std::make_unique<runtime::MapSession>(config.map, map_options);
    const camera::IdealCamera ideal(camera::IdealCameraOptions{camera.width_px, camera.height_px, camera.mm_per_px});
    const localizer::LocalizerOptions localizer_options =
        runtime::LocalizerOptionsFor(config.localizer.localizer, camera, vehicle, config.encoder_timing_sigma_ms);
    localizer_ = std::make_unique<localizer::Localizer>(ideal, localizer_options, map_->reference(), &map_->places());
    odometry_ = localizer_options.odometry;
    if (config.mapping) {
      if (map_->created()) core::Log().info("run: {} created empty, to be mapped as the vehicle drives", config.map.string());
      empty_map_ = map_->store().Count(0) == 0;
      keeper_ = std::make_unique<runtime::MapKeeper>(*map_, ideal, localizer_options.tracker, config.localizer,
                                                     camera.vehicle_from_camera, /*background=*/true);
    }
    if (config.start_unknown && !map_->places().usable()) {
      core::ThrowInvalidInput("run: start.unknown needs a map with a place index: " + map_->places().problem());
    }
    // The PLC provides the counters of the vehicle driven (a recording's or the configured).
    io::PlcLinkOptions plc = config.plc;
    plc.registers.kind = vehicle.kind;
    if (std::string why; !plc.registers.Check(&why)) {
      core::ThrowInvalidInput("run: plc.registers for a " + std::string(core::ToString(vehicle.kind)) + ": " + why);
    }
    link_ = io::OpenPlcLink(plc);
    if (config.console) {
      console::ConsoleOptions console_options = *config.console;
      console_options.live_run = true;
      console_ = std::make_unique<console::Console>(console_options, config.map);
    }
    if (!record.empty()) {
      dataset::DatasetInfo info;
      info.camera = camera;
      info.vehicle = vehicle;
      info.provenance["recorded_by"] = "mosaicloc run";
      info.provenance["source"] = source_->Describe();
      info.provenance["plc"] = config.plc.Describe();
      info.provenance["encoder_timing_sigma_ms"] = fmt::format("{}", config.encoder_timing_sigma_ms);
      info.provenance["start_pose"] = fmt::format("{:.3f},{:.3f},{:.5f}", config.start.x_mm(), config.start.y_mm(),
                                                  config.start.yaw_rad() * 180.0 / std::numbers::pi);
      recorder_ = std::make_unique<Recorder>(record, info);
    }
  }

  // Runs until the source ends, a signal arrives, or the duration passes. Returns the
  // summary as JSON.
  nlohmann::json Run(double duration_s, const StatusCallback& status, const StopCallback& stop_requested) {
    started_ = io::MonotonicNow();
    if (config_.start_unknown) {
      localizer_->InitializeUnknown(started_);
      core::Log().info("run: the start is unknown: searching the whole map");
    } else if (empty_map_) {
      // A map with no floor yet is mapped from where the vehicle stands: the start is its
      // origin, exact by definition.
      localizer_->Initialize(started_, config_.start, runtime::StartCovariance(1e-3, 1e-4));
      core::Log().info("run: the map has no floor yet: the start is its origin");
    } else {
      localizer_->Initialize(started_, config_.start,
                             runtime::StartCovariance(config_.start_sigma_mm, config_.start_sigma_deg));
    }
    Publish(false, 0.0);
    core::Log().info("run: camera {}; PLC {}; map {}", source_->Describe(), config_.plc.Describe(), config_.map.string());
    if (console_) console_->Start();

    std::thread camera([this] { Guard("camera", [this] { CameraLoop(); }); });
    std::thread plc([this] { Guard("PLC link", [this] { PlcLoop(); }); });
    std::thread tracking([this] { Guard("tracking", [this] { TrackingLoop(); }); });

    const Clock::time_point begin = Clock::now();
    Clock::time_point next_status = begin + std::chrono::seconds(1);
    std::string why = "the camera source ended";
    while (true) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      if (stop_requested) {
        if (std::optional<std::string> reason = stop_requested()) {
          why = std::move(*reason);
          break;
        }
      }
      if (tracking_done_) break;
      if (failed_) {
        why = "a thread failed";
        break;
      }
      if (duration_s > 0.0 && Clock::now() - begin >= std::chrono::duration<double>(duration_s)) {
        why = fmt::format("ran for {:g} s", duration_s);
        break;
      }
      if (Clock::now() >= next_status) {
        if (status || console_) {
          const nlohmann::json line = Status();
          if (status) status(line);
          if (console_) console_->PublishStatus(line);
        }
        next_status += std::chrono::seconds(1);
      }
    }
    core::Log().info("run: stopping: {}", why);
    stop_ = true;
    source_->Stop();
    wake_.notify_all();
    camera.join();
    tracking.join();
    plc.join();
    if (console_) console_->Stop();
    if (error_) std::rethrow_exception(error_);
    if (recorder_) recorder_->Commit();
    nlohmann::json summary = Summary(why);
    if (keeper_) {
      // What waits is mapped and the open stretch committed before the run says it is done.
      const runtime::MapKeepingSummary kept = keeper_->Finish();
      summary["map_extension_segments"] = kept.extension.segments;
      summary["map_extension_closed"] = kept.extension.closed;
      summary["map_extension_keyframes"] = kept.extension.keyframes;
      summary["map_extension_tiles"] = kept.extension.tiles_written;
      summary["map_extension_unanchored"] = kept.extension.unanchored;
      summary["map_extension_bridged"] = kept.extension.bridged;
      summary["map_extension_overspeed_frames"] = kept.overspeed_frames;
      summary["map_extension_speed_max_mps"] = kept.mapping_speed_max_mps;
      summary["map_updates"] = kept.updates.updates;
      summary["map_update_cells"] = kept.updates.cells_updated;
      summary["map_update_pending_cells"] = kept.updates.cells_pending;
      summary["map_keeping_dropped"] = kept.dropped;
      summary["map_reindexed"] = kept.reindexed;
      if (!kept.failure.empty()) summary["map_keeping_failure"] = kept.failure;
    }
    return summary;
  }

 private:
  template <typename Body>
  void Guard(const char* name, Body body) {
    try {
      body();
    } catch (...) {
      const std::lock_guard lock(mutex_);
      if (!error_) error_ = std::current_exception();
      core::Log().error("run: the {} thread stopped on an error", name);
      failed_ = true;
    }
  }

  void CameraLoop() {
    while (!stop_) {
      std::optional<io::CapturedFrame> frame = source_->Next();
      if (!frame) break;
      ++stats_.frames;
      {
        const std::lock_guard lock(mutex_);
        if (frames_.size() >= kFrameQueue) {
          frames_.pop_front();
          ++stats_.frames_dropped;
        }
        frames_.push_back(std::move(*frame));
      }
      wake_.notify_one();
    }
    {
      const std::lock_guard lock(mutex_);
      camera_done_ = true;
    }
    wake_.notify_one();
  }

  // The fix the PLC receives now: the latest state carried on to this instant by the encoder
  // samples the PLC thread read since (runtime::OutputPose). Status 0 until the first visual
  // fix (5 while the pose is unknown and searched for); tracking is degraded while odometry is
  // invalid, and while the lock was last judged on a frame older than plc.lock_age_ms (the
  // tracking thread or the camera has fallen behind: the pose is the encoders' alone since).
  // The fix registers' values for a write now.
  io::PlcOutputs Outputs(const runtime::OutputPose& output_pose) {
    Published state;
    {
      const std::lock_guard lock(published_mutex_);
      state = published_;
    }
    // The clock read once the state is in hand: the pose is for the instant after any wait.
    const core::Timestamp now = io::MonotonicNow();
    io::PlcOutputs outputs;
    const core::Pose2 pose = output_pose.At(state.motion, state.wheel_scale, now).world_from_vehicle;
    outputs.x_mm = pose.x_mm();
    outputs.y_mm = pose.y_mm();
    outputs.yaw_rad = pose.yaw_rad();
    // Searching the whole map says so from the start: the PLC sees the relocalization under way.
    int status = state.fixed_once || state.lock == estimation::LockState::kSearching ? static_cast<int>(state.lock) : 0;
    if (status == 1 && !stats_.odometry_valid) status = 2;
    if (status == 1 && (!state.judged || now - *state.judged > core::FromSeconds(config_.lock_age_ms * 1e-3))) {
      status = 2;
      ++stats_.stale_lock_writes;
    }
    outputs.status = status;
    // Lost or off the map, the pose is dead reckoning: no visual quality to report.
    const bool visual = status == 1 || status == 2;
    outputs.quality = visual ? static_cast<int>(std::lround(1000.0 * state.quality)) : 0;
    outputs.mode = state.mode;
    return outputs;
  }

  void PlcLoop() {
    if (config_.plc_thread_priority > 0) {
      sched_param priority{};
      priority.sched_priority = config_.plc_thread_priority;
      if (const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &priority); error != 0) {
        core::Log().warn("run: the PLC thread keeps normal scheduling: SCHED_FIFO priority {} refused ({}; it needs "
                         "CAP_SYS_NICE)", config_.plc_thread_priority, std::strerror(error));
      } else {
        core::Log().info("run: the PLC thread runs at SCHED_FIFO priority {}", config_.plc_thread_priority);
      }
    }
    const auto cycle = core::FromSeconds(config_.plc_cycle_ms * 1e-3);
    const auto fix_period = core::FromSeconds(config_.fix_period_ms * 1e-3);
    const auto latency = core::FromSeconds(config_.encoder_latency_ms * 1e-3);
    io::HeartbeatMonitor heartbeat(core::FromSeconds(config_.heartbeat_timeout_ms * 1e-3));
    std::optional<std::uint32_t> request;
    std::optional<std::uint32_t> relocalize_seen;
    std::int64_t connects_seen = 0;
    std::uint32_t own_heartbeat = 0;
    core::Timestamp next_cycle = io::MonotonicNow();
    core::Timestamp next_fix = next_cycle;
    std::string invalid_reason = "no reading yet";
    const auto bridge = core::FromSeconds(config_.odometry_bridge_ms * 1e-3);
    core::Timestamp outage_start = next_cycle;
    runtime::EncoderStamperOptions stamping;
    stamping.polling = config_.plc.role == "client";
    stamping.counter_period = core::FromSeconds(config_.counter_period_ms * 1e-3);
    stamping.stationary_after = core::FromSeconds(config_.stationary_after_ms * 1e-3);
    stamping.latency = latency;
    runtime::EncoderStamper stamper(stamping);
    // The pose written, carried by this thread's samples.
    runtime::OutputPose output_pose(odometry_, std::chrono::milliseconds(40), std::chrono::seconds(2),
                                    stamping.counter_period);
    std::minstd_rand spread_random(1);
    std::uniform_real_distribution<double> spread_of(0.75, 1.25);
    while (runtime::SleepUntil(next_cycle, stop_)) {
      const core::Timestamp now = io::MonotonicNow();
      // Polling, each period is 0.75 to 1.25 cycles at random (the mean the cycle): reads at
      // every phase of the PLC's own counter cycle, uncorrelated, let the stamper learn when in
      // it the counters change (EncoderStamperOptions::phase_lock).
      const double spread = stamping.polling ? spread_of(spread_random) : 1.0;
      const auto this_cycle = core::FromSeconds(spread * core::ToSeconds(cycle));
      next_cycle = next_cycle + this_cycle;
      if (next_cycle < now) next_cycle = now + this_cycle;  // fell behind: do not burst

      const core::Result<io::PlcInputs> read = link_->Read();
      bool valid = read.ok();
      if (!valid) {
        invalid_reason = read.error();
      } else if (heartbeat.Update(now, read.value().plc_heartbeat)) {
        valid = false;
        invalid_reason = fmt::format("the PLC heartbeat ({}) has not changed for {:g} ms",
                                     config_.plc.registers.plc_heartbeat.Describe(), config_.heartbeat_timeout_ms);
      }
      stats_.heartbeat_stale = read.ok() && !valid;
      if (!valid && stats_.odometry_valid) {
        core::Log().warn("PLC: odometry invalid: {}", invalid_reason);
        stats_.odometry_valid = false;
        ++stats_.odometry_outages;
        outage_start = now;
      }
      // Odometry forgets the counters once the outage is too long to bridge (or the PLC is
      // alive but its heartbeat stale: it stalled long ago).
      if (!valid && !odometry_suspended_ && (stats_.heartbeat_stale || now - outage_start > bridge)) {
        odometry_suspended_ = true;
        PushEncoders(Encoder{true, {}});
      }
      if (valid && !stats_.odometry_valid) {
        if (!odometry_suspended_ && stats_.odometry_outages > 0) {
          core::Log().info("PLC: odometry valid again after {:.0f} ms: the counters bridge the gap",
                           core::ToSeconds(now - outage_start) * 1e3);
        } else if (odometry_suspended_ && stats_.odometry_outages > 0) {
          core::Log().info("PLC: odometry valid again");
        }
        stats_.odometry_valid = true;
        odometry_suspended_ = false;
      }
      if (valid) {
        // When the counters took these values (runtime::EncoderStamper).
        const std::optional<dataset::EncoderSample> sample = stamper.Take(read.value());
        stats_.encoder_late = stamper.late_changes();
        if (sample) output_pose.Add(*sample);
        output_pose.Read(read.value().time, read.value().counts);
        if (sample) {
          PushEncoders(Encoder{false, *sample});
          if (recorder_) recorder_->Encoders(*sample);
          ++stats_.encoder_samples;
        }
      } else {
        stamper.Forget();
        output_pose.Forget();
      }

      bool answer = false;
      core::Timestamp seen;
      if (read.ok()) {
        // The PLC says the pose is unknown (the vehicle was moved): the tracking thread
        // relocalizes without trusting the estimate. A reconnected PLC may have restarted
        // with its counter at 0: its first value is taken as it is, not as a request.
        const std::int64_t connects = link_->stats().connects;
        if (connects != connects_seen) relocalize_seen.reset();
        connects_seen = connects;
        const std::uint32_t relocalize = read.value().relocalize_request;
        if (relocalize_seen && relocalize != *relocalize_seen) {
          relocalize_pending_ = true;
          ++stats_.relocalize_requests;
          core::Log().info("run: the PLC asks for a relocalization (request {})", relocalize);
        }
        relocalize_seen = relocalize;
        const std::uint32_t counter = read.value().fix_request;
        if (request && counter != *request) {
          answer = true;
          seen = now;
          ++stats_.requests;
        }
        request = counter;
      }
      const bool due = config_.fix_period_ms > 0.0 && now >= next_fix;
      if ((answer || due) && request) {
        io::PlcOutputs outputs = Outputs(output_pose);
        outputs.request_echo = *request;
        outputs.heartbeat = ++own_heartbeat;
        if (link_->Write(outputs).ok()) {
          ++stats_.fix_writes;
          if (answer) {
            ++stats_.answered;
            const std::lock_guard lock(stats_.mutex);
            stats_.answers.Add(Ms(io::MonotonicNow() - seen));
          }
        }
        if (due) next_fix = now + fix_period;
      }
      const std::lock_guard lock(stats_.mutex);
      stats_.link = link_->stats();
    }
  }

  struct Encoder {
    bool suspend = false;  // odometry became invalid here
    dataset::EncoderSample sample;
  };

  void PushEncoders(Encoder encoder) {
    {
      const std::lock_guard lock(mutex_);
      encoders_.push_back(encoder);
    }
    wake_.notify_one();
  }

  // `judged`: the capture time of the frame just processed (the lock was judged on it).
  void Publish(bool fixed, double quality, std::optional<double> scale = std::nullopt,
               std::optional<core::Timestamp> judged = std::nullopt) {
    const estimation::MotionState motion = localizer_->Latest();
    // Each prediction replans the prefetch. Encoder batches come several times a frame, and
    // a prediction every 30 ms is all the loaders need: from frames, or from odometry alone
    // when frames stop.
    const Clock::time_point now = Clock::now();
    if (map_->prefetcher() && localizer_->initialized() && now - last_prediction_ >= std::chrono::milliseconds(30)) {
      last_prediction_ = now;
      runtime::PredictTiles(*map_->prefetcher(), motion, camera_info_.vehicle_from_camera);
    }
    const std::lock_guard lock(published_mutex_);
    published_.motion = motion;
    published_.lock = localizer_->lock().state();
    if (fixed) {
      published_.fixed_once = true;
      published_.quality = quality;
    }
    if (scale) published_.scale = *scale;
    if (judged) published_.judged = judged;
    if (localizer_->initialized()) published_.wheel_scale = localizer_->wheel_scale_error();
    if (stats_.processed > 0) published_.mode = static_cast<int>(localizer_->mode());
  }

  void TrackingLoop() {
    const auto max_wait = core::FromSeconds(config_.max_encoder_wait_ms * 1e-3);
    std::optional<core::Timestamp> latest_encoder;
    std::vector<Encoder> encoders;
    while (true) {
      std::optional<io::CapturedFrame> frame;
      {
        std::unique_lock lock(mutex_);
        wake_.wait_for(lock, std::chrono::milliseconds(10), [this] {
          return stop_ || camera_done_ || !encoders_.empty() || !frames_.empty();
        });
        encoders.assign(encoders_.begin(), encoders_.end());
        encoders_.clear();
        if (!encoders.empty() && !encoders.back().suspend) latest_encoder = encoders.back().sample.time;
        if (!frames_.empty()) {
          const io::CapturedFrame& next = frames_.front();
          // The frame's fix goes in at its own time once the odometry has passed it; without
          // odometry it waits at most max_wait (then the filter coasts to it), also through an
          // outage the counters will bridge; it does not wait once odometry is suspended.
          const bool odometry_past = latest_encoder && *latest_encoder >= next.time;
          if (odometry_past || io::MonotonicNow() - next.time >= max_wait || odometry_suspended_ || stop_) {
            frame = std::move(frames_.front());
            frames_.pop_front();
          }
        }
        if (!frame && encoders.empty() && (stop_ || (camera_done_ && frames_.empty()))) break;
      }
      for (const Encoder& e : encoders) {
        if (e.suspend) {
          localizer_->SuspendOdometry();
        } else if (!localizer_->AddEncoders(e.sample.time, e.sample.counts)) {
          ++stats_.encoder_rejected;
          const auto why = localizer_->last_encoder_failure();
          core::Log().warn("run: encoder sample rejected: {} (stamped {:.4f} s, counters {})",
                           why ? estimation::ToString(*why) : std::string("?"),
                           core::ToSeconds(e.sample.time - core::Timestamp()),
                           fmt::join(core::CountersOf(vehicle_kind_, e.sample.counts), ", "));
        }
      }
      if (!frame) {
        if (!encoders.empty()) Publish(false, 0.0);
        continue;
      }
      if (recorder_) recorder_->Frame(frame->time, frame->image);
      // The PLC says the vehicle was moved: a known kidnap (design.md sections 7 and 7b).
      if (relocalize_pending_.exchange(false)) localizer_->RequestRelocalization();
      const auto processing_start = io::MonotonicNow();
      const localizer::FrameOutcome outcome = localizer_->ProcessFrame(frame->time, frame->image);
      if (keeper_) keeper_->Frame(frame->time, frame->image, outcome, !localizer_->pose_unknown());
      ++stats_.processed;
      ++stats_.frames_by_mode[static_cast<std::size_t>(outcome.mode)];
      if (recorder_) recorder_->Report(runtime::FrameReportOf(frame->time, outcome));
      if (outcome.fixed) {
        ++stats_.fixes;
      } else {
        core::Log().debug("run: frame {} not fixed: {}", frame->sequence, outcome.reason);
      }
      Publish(outcome.fixed, outcome.fix_quality, outcome.scale, frame->time);
      if (console_) console_->PublishPose(LivePoseOf(frame->time, outcome));
      const std::lock_guard lock(stats_.mutex);
      const auto done = io::MonotonicNow();
      stats_.frame_latency.Add(Ms(done - frame->time));
      stats_.processing.Add(Ms(done - processing_start));
      // The status line's window; without status lines, only the newest are kept.
      if (stats_.recent_latency_ms.size() >= live_run_detail::kRecentLatencies) stats_.recent_latency_ms.clear();
      stats_.recent_latency_ms.push_back(Ms(done - frame->time));
    }
    tracking_done_ = true;
  }

  // What the console shows of a frame's outcome (copied, never waited for).
  console::LivePose LivePoseOf(core::Timestamp time, const localizer::FrameOutcome& outcome) const {
    console::LivePose pose;
    pose.t_s = core::ToSeconds(time - started_);
    pose.known = localizer_->initialized() && !localizer_->pose_unknown();
    pose.x_mm = outcome.world_from_vehicle.x_mm();
    pose.y_mm = outcome.world_from_vehicle.y_mm();
    pose.yaw_rad = outcome.world_from_vehicle.yaw_rad();
    pose.cov_xx = outcome.covariance(0, 0);
    pose.cov_xy = outcome.covariance(0, 1);
    pose.cov_yy = outcome.covariance(1, 1);
    pose.sigma_yaw_rad = std::sqrt(std::max(0.0, outcome.covariance(2, 2)));
    pose.lock = static_cast<int>(outcome.lock);  // design.md section 6, as fixes.csv writes it
    pose.mode = localizer::ToString(outcome.mode);
    pose.fixed = outcome.fixed;
    pose.quality = outcome.fix_quality;
    pose.scale = outcome.scale;
    pose.latency_ms = Ms(io::MonotonicNow() - time);
    pose.frames = stats_.processed;
    pose.fixes = stats_.fixes;
    return pose;
  }

  // Frames per mode so far, by the modes' names.
  nlohmann::json FramesByMode() const {
    nlohmann::json counts = nlohmann::json::object();
    for (const localizer::Mode mode : {localizer::Mode::kTrack, localizer::Mode::kVisualOdometry,
                                       localizer::Mode::kDeadReckoning, localizer::Mode::kSearching}) {
      counts[localizer::ToString(mode)] = stats_.frames_by_mode[static_cast<std::size_t>(mode)].load();
    }
    return counts;
  }

  // The status line of the last second (LiveRun::Run).
  nlohmann::json Status() {
    Published state;
    {
      const std::lock_guard lock(published_mutex_);
      state = published_;
    }
    const std::int64_t frames = stats_.processed, fixes = stats_.fixes;
    const std::int64_t new_frames = frames - status_frames_, new_fixes = fixes - status_fixes_;
    status_frames_ = frames;
    status_fixes_ = fixes;
    std::vector<double> latencies;
    io::PlcLinkStats link;
    {
      const std::lock_guard lock(stats_.mutex);
      latencies.swap(stats_.recent_latency_ms);
      link = stats_.link;
    }
    std::sort(latencies.begin(), latencies.end());
    const double latency = latencies.empty() ? 0.0 : dataset::Percentile(latencies, 50.0);
    const std::string plc = !link.connected                ? "down"
                            : stats_.heartbeat_stale       ? "stale"
                            : stats_.odometry_valid        ? "ok"
                                                           : "waiting";
    const core::Pose2 pose = state.motion.PoseAt(io::MonotonicNow());
    const double elapsed = core::ToSeconds(io::MonotonicNow() - started_);
    const std::int64_t errors = link.read_errors + link.write_errors + link.connect_failures;
    // Memory, so that a long run shows what grows: the map's decoded tiles (the cache's slabs),
    // the rest of the heap, and what the allocator holds beyond them. Read every 10 s: reading
    // the heap takes each allocator arena's lock.
    const auto now = io::MonotonicNow();
    if (!memory_read_ || now - *memory_read_ >= core::FromSeconds(10.0)) {
      memory_ = ReadProcessMemory();
      map_cache_mib_ = map_ ? map_->cache_mib() : 0.0;
      memory_read_ = now;
    }
    return {{"t_s", elapsed},
            {"lock", state.fixed_once ? estimation::ToString(state.lock) : "none"},
            {"mode", state.mode > 0 ? localizer::ToString(static_cast<localizer::Mode>(state.mode)) : "none"},
            {"fixes_per_s", new_fixes},
            {"frames_per_s", new_frames},
            {"latency_p50_ms", latency},
            {"plc", plc},
            {"plc_round_trip_ms", link.last_round_trip_ms},
            {"plc_errors", errors},
            {"requests", stats_.requests.load()},
            {"answered", stats_.answered.load()},
            {"x_mm", pose.x_mm()},
            {"y_mm", pose.y_mm()},
            {"yaw_deg", pose.yaw_rad() * 180.0 / std::numbers::pi},
            {"scale", state.scale},
            {"rss_mib", memory_.rss_mib},
            {"heap_mib", memory_.heap_mib},
            {"map_cache_mib", map_cache_mib_}};
  }

  nlohmann::json Summary(const std::string& why) {
    const std::lock_guard lock(stats_.mutex);
    const auto percentile = [](const LatencyHistogram& h, double p) -> nlohmann::json {
      if (h.count() == 0) return nullptr;
      return h.Percentile(p);
    };
    const LatencyHistogram& latency = stats_.frame_latency;
    const LatencyHistogram& processing = stats_.processing;
    const LatencyHistogram& answers = stats_.answers;
    const io::PlcLinkStats& link = stats_.link;
    const std::int64_t processed = stats_.processed;
    double scale = 1.0;
    {
      const std::lock_guard published(published_mutex_);
      scale = published_.scale;
    }
    nlohmann::json summary = {{"stopped", why},
            {"frames", stats_.frames.load()},
            {"frames_dropped", stats_.frames_dropped.load() + source_->dropped()},
            {"frames_processed", processed},
            {"fixes", stats_.fixes.load()},
            {"fix_rate", processed > 0 ? static_cast<double>(stats_.fixes) / static_cast<double>(processed) : 0.0},
            {"lock_losses", localizer_->lock().losses()},
            {"relocalizations", localizer_->relocalizations()},
            {"reanchorings", localizer_->reanchorings()},
            {"mode_switches", localizer_->mode_switches()},
            {"frames_by_mode", FramesByMode()},
            {"relocalize_requests", stats_.relocalize_requests.load()},
            {"scale", scale},
            {"latency_p50_ms", percentile(latency, 50.0)},
            {"latency_p99_ms", percentile(latency, 99.0)},
            {"processing_p50_ms", percentile(processing, 50.0)},
            {"processing_p99_ms", percentile(processing, 99.0)},
            {"encoder_samples", stats_.encoder_samples.load()},
            {"encoder_rejected", stats_.encoder_rejected.load()},
            {"encoder_late_updates", stats_.encoder_late.load()},
            {"odometry_outages", stats_.odometry_outages.load()},
            {"fix_writes", stats_.fix_writes.load()},
            {"stale_lock_writes", stats_.stale_lock_writes.load()},
            {"requests", stats_.requests.load()},
            {"answered", stats_.answered.load()},
            {"answer_p50_ms", percentile(answers, 50.0)},
            {"answer_max_ms", answers.count() == 0 ? nlohmann::json(nullptr) : nlohmann::json(answers.max_ms())},
            {"plc_reads", link.reads},
            {"plc_read_errors", link.read_errors},
            {"plc_writes", link.writes},
            {"plc_write_errors", link.write_errors},
            {"plc_timeouts", link.timeouts},
            {"plc_connects", link.connects},
            {"plc_connect_failures", link.connect_failures},
            {"recorded_frames", recorder_ ? nlohmann::json(recorder_->frames()) : nlohmann::json(nullptr)}};
    // The calibration errors the filter learnt, as a replay's metrics name them (null before
    // its first frame).
    const runtime::CalibrationErrors learnt =
        runtime::CalibrationErrorsShown(localizer_->initialized() ? localizer_->wheel_scale_error() : Eigen::Vector2d::Zero(),
                                        vehicle_kind_);
    for (int i = 0; i < 2; ++i) {
      summary[learnt.names[i]] = localizer_->initialized() ? nlohmann::json(learnt.values[i]) : nlohmann::json(nullptr);
    }
    return summary;
  }

  static constexpr std::size_t kFrameQueue = 4;

  LiveRunOptions config_;
  std::unique_ptr<io::FrameSource> source_;
  dataset::CameraInfo camera_info_;
  core::DriveKind vehicle_kind_;
  std::unique_ptr<runtime::MapSession> map_;  // before the localizer, which renders from it
  bool empty_map_ = false;  ///< mapping from a map with no floor yet
  Clock::time_point last_prediction_{};  // of the prefetcher; Publish runs on the tracking thread
  std::unique_ptr<localizer::Localizer> localizer_;
  estimation::OdometryOptions odometry_;  ///< the localizer's, for the PLC thread's OutputPose
  std::unique_ptr<runtime::MapKeeper> keeper_;  ///< with mapping; after the map, which it writes
  std::unique_ptr<io::PlcLink> link_;
  std::unique_ptr<Recorder> recorder_;
  std::unique_ptr<console::Console> console_;
  core::Timestamp started_;

  std::mutex mutex_;  // guards the queues and camera_done_
  std::condition_variable wake_;
  std::deque<io::CapturedFrame> frames_;
  std::deque<Encoder> encoders_;
  bool camera_done_ = false;
  std::atomic<bool> stop_{false};
  std::atomic<bool> tracking_done_{false};
  std::atomic<bool> relocalize_pending_{false};  // set by the PLC thread, taken by the tracking thread
  // No counters to wait for: none read yet, or an outage too long to bridge (the PLC thread's).
  std::atomic<bool> odometry_suspended_{true};
  std::atomic<bool> failed_{false};
  std::exception_ptr error_;

  std::mutex published_mutex_;
  Published published_;
  RunStats stats_;
  std::int64_t status_frames_ = 0;
  std::int64_t status_fixes_ = 0;
  // The status line's memory figures and when they were read (the main thread's only).
  std::optional<core::Timestamp> memory_read_;
  ProcessMemory memory_;
  double map_cache_mib_ = 0.0;
};

LiveRun::LiveRun(const LiveRunOptions& options, std::unique_ptr<io::FrameSource> source,
                 const dataset::CameraInfo& camera, const dataset::VehicleInfo& vehicle,
                 const std::filesystem::path& record)
    : impl_(std::make_unique<Impl>(options, std::move(source), camera, vehicle, record)) {}

LiveRun::~LiveRun() = default;

nlohmann::json LiveRun::Run(double duration_s, const StatusCallback& status, const StopCallback& stop_requested) {
  return impl_->Run(duration_s, status, stop_requested);
}

LiveSource::LiveSource() = default;
LiveSource::LiveSource(LiveSource&&) noexcept = default;
LiveSource::~LiveSource() = default;

LiveSource OpenLiveSource(const LiveRunOptions& config) {
  LiveSource source;
  source.camera = config.camera;
  source.vehicle = config.vehicle;
  if (config.camera_source == "simulator") {
    // The simulated drive carries its own camera and vehicle calibration.
    source.drive = std::make_shared<const sim::PlannedDrive>(sim::SimulatorConfigOrDefaults(config.simulator_config));
    source.camera = source.drive->info().camera;
    source.vehicle = source.drive->info().vehicle;
    source.frames = std::make_unique<SimulatedFrameSource>(source.drive, config.dataset_start_unix_s);
  } else if (config.camera_source == "dataset") {
    // A recording carries its own camera and vehicle calibration.
    auto played = std::make_unique<DatasetFrameSource>(config.dataset, config.dataset_start_unix_s);
    source.camera = played->info().camera;
    source.vehicle = played->info().vehicle;
    source.frames = std::move(played);
  } else {
    source.frames = std::make_unique<io::V4l2Camera>(config.v4l2);
  }
  if (config.ground_calibration) {
    // A real camera: its raw frames are made ideal, and the ideal image is the camera.
    const camera::IdealCameraOptions& ideal = config.ground_calibration->ideal;
    source.camera.width_px = ideal.width_px;
    source.camera.height_px = ideal.height_px;
    source.camera.mm_per_px = ideal.mm_per_px;
    source.frames = std::make_unique<RectifyingFrameSource>(std::move(source.frames), *config.ground_calibration);
  }
  return source;
}

}  // namespace mosaicloc::runtime
