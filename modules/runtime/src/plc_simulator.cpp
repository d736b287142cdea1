#include "mosaicloc/runtime/plc_simulator.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <deque>
#include <mutex>
#include <numbers>
#include <thread>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/io/register_server.hpp"
#include "mosaicloc/runtime/live_sources.hpp"
#include "mosaicloc/sim/config.hpp"
#include "mosaicloc/sim/simulator.hpp"

namespace mosaicloc::runtime {
namespace {

// One write of the fix registers, as the PLC saw it.
struct ReceivedFix {
  core::Timestamp time;  // monotonic
  io::PlcOutputs fix;
};

std::uint32_t Masked(std::uint32_t value, const io::RegisterField& field) {
  return field.width_bits == 32 ? value : value & 0xFFFFU;
}

}  // namespace

PlcSimulatorSummary RunPlcSimulator(const PlcSimulatorOptions& args, const PlcSimulatorCallbacks& callbacks) {
  // The drive played: a recording's encoder samples and truth, or the simulator's, each
  // computed when it is due (no recording: a drive of hours starts at once).
  std::unique_ptr<sim::PlannedDrive> plan;
  std::unique_ptr<dataset::DatasetReader> reader;
  std::optional<dataset::Trajectory> groundtruth;
  std::optional<sim::PlannedDrive::EncoderStream> simulated_samples;
  std::optional<dataset::DatasetReader::EncoderStream> recorded_samples;
  std::string played;
  core::DriveKind kind = core::DriveKind::kDifferential;
  Playback playback;
  if (args.simulate) {
    plan = std::make_unique<sim::PlannedDrive>(sim::SimulatorConfigOrDefaults(*args.simulate));
    played = fmt::format("a simulated drive ({}, {:.0f} s)",
                         args.simulate->empty() ? std::string("the built-in defaults") : args.simulate->string(),
                         plan->capture_s().back());
    kind = plan->info().vehicle.kind;
    simulated_samples.emplace(plan->Encoders());
    playback = Playback::Starting(core::Timestamp(), args.start_unix_s);  // the drive's clock starts at 0
  } else {
    if (args.dataset.empty()) core::ThrowInvalidInput("plc-sim: give --dataset DIR or --simulate [YAML]");
    reader = std::make_unique<dataset::DatasetReader>(args.dataset);
    played = args.dataset.string();
    kind = reader->info().vehicle.kind;
    if (reader->HasGroundTruth()) groundtruth = reader->GroundTruth();
    recorded_samples.emplace(reader->Encoders());
    playback = Playback::Of(*reader, args.start_unix_s);
  }
  const auto next_sample = [&]() -> std::optional<dataset::EncoderSample> {
    return simulated_samples ? simulated_samples->Next() : recorded_samples->Next();
  };
  const auto truth_at = [&](core::Timestamp time) -> std::optional<core::Pose2> {
    if (plan) return plan->TruthAt(core::ToSeconds(time - core::Timestamp()));
    if (groundtruth) return dataset::PoseAt(*groundtruth, time, std::chrono::milliseconds(200));
    return std::nullopt;
  };
  // The counters of the vehicle the drive was recorded on.
  io::RegisterMap map = args.registers;
  map.kind = kind;
  if (std::string why; !map.Check(&why)) {
    core::ThrowInvalidInput("plc-sim: the register map for a " + std::string(core::ToString(map.kind)) + ": " + why);
  }
  std::vector<std::string> served;
  for (const io::RegisterField* field : map.Counters()) served.push_back(field->Describe());
  played += fmt::format(", serving the {}'s {}", core::ToString(kind), fmt::join(served, ", "));

  std::vector<const io::RegisterField*> fields = map.Inputs();
  const std::vector<const io::RegisterField*> outputs = map.Outputs();
  fields.insert(fields.end(), outputs.begin(), outputs.end());
  int low = 65536, high = 0;
  for (const io::RegisterField* f : fields) {
    low = std::min(low, f->address);
    high = std::max(high, f->address + f->words());
  }
  io::PlcLinkOptions server_options;
  server_options.role = "server";
  server_options.host = args.host;
  server_options.port = args.port;
  server_options.unit_id = args.unit;
  server_options.registers = map;

  std::mutex received_mutex;
  std::deque<ReceivedFix> received;
  auto server_owner = std::make_unique<io::RegisterServer>(server_options, low, high - low, [&](int address, int count,
                                                                                              core::Timestamp time,
                                                                                              const std::uint16_t* table) {
    const io::RegisterField& x = map.fix_x;
    if (!(address < x.address + x.words() && x.address < address + count)) return;
    const auto at = [&](const io::RegisterField& f) { return io::DecodeCount(f, table + (f.address - low)); };
    ReceivedFix r;
    r.time = time;
    r.fix.x_mm = static_cast<double>(at(map.fix_x)) * map.fix_x.scale;
    r.fix.y_mm = static_cast<double>(at(map.fix_y)) * map.fix_y.scale;
    r.fix.yaw_rad = static_cast<double>(at(map.fix_yaw)) * map.fix_yaw.scale;
    r.fix.status = static_cast<int>(at(map.fix_status));
    r.fix.quality = static_cast<int>(at(map.fix_quality));
    r.fix.mode = static_cast<int>(at(map.fix_mode));
    r.fix.request_echo = static_cast<std::uint32_t>(at(map.fix_request_echo));
    r.fix.heartbeat = static_cast<std::uint32_t>(at(map.heartbeat));
    const std::lock_guard lock(received_mutex);
    received.push_back(r);
  });
  io::RegisterServer& server = *server_owner;
  if (callbacks.serving) callbacks.serving(played);

  std::optional<dataset::EncoderSample> pending = next_sample();
  if (!pending) core::ThrowInvalidInput(played + ": no encoder samples");
  dataset::EncoderSample current = *pending;  // the counters hold the first sample until playback starts
  core::Timestamp last_sample_time = current.time;
  std::uint32_t heartbeat = 0, request = 0;
  std::optional<core::Timestamp> request_time;
  bool request_answered = true;
  const auto heartbeat_period = core::FromSeconds(args.heartbeat_period_ms * 1e-3);
  const auto request_period = core::FromSeconds(args.request_period_ms * 1e-3);
  core::Timestamp next_heartbeat = io::MonotonicNow();
  core::Timestamp next_request = playback.start + request_period;
  std::optional<core::Timestamp> ended;

  std::int64_t fixes = 0, requests = 0, answered = 0;
  std::vector<double> answer_ms, errors_mm, heading_errors_deg;
  std::vector<std::int64_t> status_counts(6, 0);  // none, tracking, degraded, lost, off-map, searching
  std::vector<std::int64_t> mode_counts(5, 0);    // none, track, visual odometry, dead reckoning, searching
  std::string csv = "#time_s,x_mm,y_mm,yaw_rad,status,quality,request_echo,heartbeat,gt_x_mm,gt_y_mm,error_mm,mode\n";
  core::Timestamp next_print = io::MonotonicNow() + std::chrono::seconds(1);

  const auto process_received = [&] {
      std::deque<ReceivedFix> batch;
      {
        const std::lock_guard lock(received_mutex);
        batch.swap(received);
      }
      for (const ReceivedFix& r : batch) {
        ++fixes;
        ++status_counts[static_cast<std::size_t>(std::clamp(r.fix.status, 0, 5))];
        ++mode_counts[static_cast<std::size_t>(std::clamp(r.fix.mode, 0, 4))];
        if (!request_answered && request_time && r.fix.request_echo == Masked(request, map.fix_request_echo)) {
          request_answered = true;
          ++answered;
          answer_ms.push_back(std::chrono::duration<double, std::milli>(r.time - *request_time).count());
        }
        const core::Timestamp dataset_time = playback.ToDataset(r.time);
        const std::optional<core::Pose2> truth = truth_at(dataset_time);
        double error = std::nan("");
        if (truth && r.fix.status != 0) {
          error = std::hypot(r.fix.x_mm - truth->x_mm(), r.fix.y_mm - truth->y_mm());
          errors_mm.push_back(error);
          heading_errors_deg.push_back(std::abs(core::WrapAngle(r.fix.yaw_rad - truth->yaw_rad())) * 180.0 /
                                       std::numbers::pi);
        }
        csv += fmt::format("{:.6f},{:.2f},{:.2f},{:.6f},{},{},{},{},{},{},{},{}\n", dataset_time.seconds(), r.fix.x_mm,
                           r.fix.y_mm, r.fix.yaw_rad, r.fix.status, r.fix.quality, r.fix.request_echo, r.fix.heartbeat,
                           truth ? fmt::format("{:.2f}", truth->x_mm()) : "", truth ? fmt::format("{:.2f}", truth->y_mm()) : "",
                           std::isnan(error) ? "" : fmt::format("{:.3f}", error), r.fix.mode);
      }
  };
  while (!(callbacks.stop && callbacks.stop())) {
    const core::Timestamp now = io::MonotonicNow();
    while (pending && playback.ToMonotonic(pending->time) <= now) {
      current = *pending;
      last_sample_time = pending->time;
      pending = next_sample();
    }
    if (!pending && !ended) ended = now;
    if (now >= next_heartbeat) {
      ++heartbeat;
      next_heartbeat = next_heartbeat + heartbeat_period;
    }
    if (args.request_period_ms > 0.0 && now >= next_request) {
      ++request;
      ++requests;
      request_time = now;
      request_answered = false;
      next_request = next_request + request_period;
    }
    server.Update([&](std::uint16_t* table) {
      const auto put = [&](const io::RegisterField& f, std::int64_t count) {
        io::EncodeCount(f, count, table + (f.address - low));
      };
      // The counters as a PLC holds them: raw, wrapping at the field's width.
      const auto wrap = [](std::int64_t v, const io::RegisterField& f) {
        const std::int64_t modulus = std::int64_t{1} << f.width_bits;
        std::int64_t w = ((v % modulus) + modulus) % modulus;
        return f.is_signed && w > f.MaxCount() ? w - modulus : w;
      };
      const auto counters = map.Counters();
      const auto values = map.CounterValues(current.counts);
      for (std::size_t i = 0; i < counters.size(); ++i) {
        put(*counters[i], wrap(std::llround(values[i] / counters[i]->scale), *counters[i]));
      }
      put(map.plc_heartbeat, wrap(heartbeat, map.plc_heartbeat));
      put(map.fix_request, wrap(request, map.fix_request));
    });

    process_received();
    if (now >= next_print) {
      next_print = next_print + std::chrono::seconds(1);
      if (callbacks.every_second) {
        PlcSimulatorStatus status;
        status.seconds = core::ToSeconds(now - playback.start);
        status.clients = server.clients();
        status.counters = map.CounterValues(current.counts);
        status.heartbeat = heartbeat;
        status.requests = requests;
        status.answered = answered;
        status.fixes = fixes;
        if (!errors_mm.empty()) status.last_error_mm = errors_mm.back();
        callbacks.every_second(status);
      }
    }
    if (ended && now - *ended > core::FromSeconds(args.linger_s)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  (void)last_sample_time;
  // Stop serving, then take in what the last requests wrote.
  server_owner.reset();
  process_received();

  if (!args.fixes_out.empty()) core::WriteFileAtomically(args.fixes_out, csv);
  PlcSimulatorSummary summary;
  summary.fixes_received = fixes;
  summary.status_counts = status_counts;
  summary.mode_counts = mode_counts;
  summary.requests = requests;
  summary.answered = answered;
  std::sort(answer_ms.begin(), answer_ms.end());
  if (!answer_ms.empty()) {
    summary.answer_p50_ms = dataset::Percentile(answer_ms, 50.0);
    summary.answer_p99_ms = dataset::Percentile(answer_ms, 99.0);
    summary.answer_max_ms = answer_ms.back();
  }
  if (!errors_mm.empty()) {
    double sum2 = 0.0;
    for (const double e : errors_mm) sum2 += e * e;
    summary.position_rms_mm = std::sqrt(sum2 / static_cast<double>(errors_mm.size()));
    std::sort(errors_mm.begin(), errors_mm.end());
    summary.position_p50_mm = dataset::Percentile(errors_mm, 50.0);
    summary.position_max_mm = errors_mm.back();
    summary.heading_max_deg = *std::max_element(heading_errors_deg.begin(), heading_errors_deg.end());
  }
  return summary;
}

nlohmann::json PlcSimulatorSummary::ToJson() const {
  const auto figure = [](const std::optional<double>& value) { return value ? nlohmann::json(*value) : nlohmann::json(); };
  return {{"fixes_received", fixes_received},
          {"status_counts", status_counts},
          {"mode_counts", mode_counts},
          {"requests", requests},
          {"answered", answered},
          {"answer_p50_ms", figure(answer_p50_ms)},
          {"answer_p99_ms", figure(answer_p99_ms)},
          {"answer_max_ms", figure(answer_max_ms)},
          {"position_rms_mm", figure(position_rms_mm)},
          {"position_p50_mm", figure(position_p50_mm)},
          {"position_max_mm", figure(position_max_mm)},
          {"heading_max_deg", figure(heading_max_deg)}};
}

std::string PlcSimulatorSummary::Text() const {
  const nlohmann::json json = ToJson();
  return fmt::format("fixes received {}, requests {}, answered {} (p50 {} ms), position error rms {} mm, max {} mm\n",
                     fixes_received, requests, answered, json["answer_p50_ms"].dump(), json["position_rms_mm"].dump(),
                     json["position_max_mm"].dump());
}

}  // namespace mosaicloc::runtime
