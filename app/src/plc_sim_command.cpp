// mosaicloc plc-sim: a Modbus TCP server that behaves as the vehicle's PLC. It plays a
// dataset's encoder counters in real time, beats its heartbeat, asks for fixes, and shows the
// fixes it receives, compared with the dataset's ground truth when it has one. For
// integration tests, and for integrators to try the setup on a bench.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <deque>
#include <mutex>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "mosaicloc/runtime/live_sources.hpp"
#include "mosaicloc/sim/config.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/core/yaml.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/io/register_server.hpp"
#include "mosaicloc/runtime/run_config.hpp"

namespace mosaicloc::app {
namespace {

std::atomic<int> g_plc_signal{0};
extern "C" void OnPlcSignal(int signal) { g_plc_signal = signal; }

struct PlcSimArgs {
  std::filesystem::path dataset;
  std::optional<std::filesystem::path> simulate;
  std::string host = "127.0.0.1";
  int port = 0;
  int unit = 1;
  std::filesystem::path config;
  double start_unix_s = 0.0;
  double request_period_ms = 500.0;
  double heartbeat_period_ms = 10.0;
  double linger_s = 1.0;
  std::filesystem::path fixes_out;
};

// One write of the fix registers, as the PLC saw it.
struct ReceivedFix {
  core::Timestamp time;  // monotonic
  io::PlcOutputs fix;
};

std::uint32_t Masked(std::uint32_t value, const io::RegisterField& field) {
  return field.width_bits == 32 ? value : value & 0xFFFFU;
}

void RunPlcSim(const PlcSimArgs& args, const GlobalOptions& global) {
  io::RegisterMap map;
  if (!args.config.empty()) runtime::ReadRegisterMap(core::LoadYamlFile(args.config), args.config.string(), &map);
  std::unique_ptr<runtime::SimulatedDrive> drive;
  if (args.simulate) drive = std::make_unique<runtime::SimulatedDrive>(sim::SimulatorConfigOrDefaults(*args.simulate));
  const std::filesystem::path played = drive ? drive->directory() : args.dataset;
  if (played.empty()) core::ThrowInvalidInput("plc-sim: give --dataset DIR or --simulate [YAML]");
  const dataset::DatasetReader reader(played);
  const std::optional<dataset::Trajectory> groundtruth =
      reader.HasGroundTruth() ? std::optional<dataset::Trajectory>(reader.GroundTruth()) : std::nullopt;
  const runtime::Playback playback = runtime::Playback::Of(reader, args.start_unix_s);

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
  std::atomic<io::RegisterServer*> server_ptr{nullptr};  // set once the server exists
  std::vector<std::uint16_t> scratch(static_cast<std::size_t>(high - low));
  auto server_owner = std::make_unique<io::RegisterServer>(server_options, low, high - low, [&](int address, int count,
                                                                                              core::Timestamp time) {
    const io::RegisterField& x = map.fix_x;
    io::RegisterServer* const serving = server_ptr.load();
    if (!(address < x.address + x.words() && x.address < address + count) || serving == nullptr) return;
    serving->Get(low, high - low, scratch.data());
    const auto at = [&](const io::RegisterField& f) { return io::DecodeCount(f, scratch.data() + (f.address - low)); };
    ReceivedFix r;
    r.time = time;
    r.fix.x_mm = static_cast<double>(at(map.fix_x)) * map.fix_x.scale;
    r.fix.y_mm = static_cast<double>(at(map.fix_y)) * map.fix_y.scale;
    r.fix.yaw_rad = static_cast<double>(at(map.fix_yaw)) * map.fix_yaw.scale;
    r.fix.status = static_cast<int>(at(map.fix_status));
    r.fix.quality = static_cast<int>(at(map.fix_quality));
    r.fix.request_echo = static_cast<std::uint32_t>(at(map.fix_request_echo));
    r.fix.heartbeat = static_cast<std::uint32_t>(at(map.heartbeat));
    const std::lock_guard lock(received_mutex);
    received.push_back(r);
  });
  io::RegisterServer& server = *server_owner;
  server_ptr = &server;
  if (!global.quiet) {
    std::fprintf(stderr, "plc-sim: serving %s on %s:%d (unit %d), playing %s\n", "holding registers", args.host.c_str(),
                 args.port, args.unit, played.string().c_str());
  }

  auto encoders = reader.Encoders();
  std::optional<dataset::EncoderSample> pending = encoders.Next();
  if (!pending) core::ThrowInvalidInput(played.string() + ": no encoder samples");
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
  std::vector<std::int64_t> status_counts(5, 0);  // none, tracking, degraded, lost, off-map
  std::string csv = "#time_s,x_mm,y_mm,yaw_rad,status,quality,request_echo,heartbeat,gt_x_mm,gt_y_mm,error_mm\n";
  core::Timestamp next_print = io::MonotonicNow() + std::chrono::seconds(1);

  const auto process_received = [&] {
      std::deque<ReceivedFix> batch;
      {
        const std::lock_guard lock(received_mutex);
        batch.swap(received);
      }
      for (const ReceivedFix& r : batch) {
        ++fixes;
        ++status_counts[static_cast<std::size_t>(std::clamp(r.fix.status, 0, 4))];
        if (!request_answered && request_time && r.fix.request_echo == Masked(request, map.fix_request_echo)) {
          request_answered = true;
          ++answered;
          answer_ms.push_back(std::chrono::duration<double, std::milli>(r.time - *request_time).count());
        }
        const core::Timestamp dataset_time = playback.ToDataset(r.time);
        std::optional<core::Pose2> truth;
        if (groundtruth) truth = dataset::PoseAt(*groundtruth, dataset_time, std::chrono::milliseconds(200));
        double error = std::nan("");
        if (truth && r.fix.status != 0) {
          error = std::hypot(r.fix.x_mm - truth->x_mm(), r.fix.y_mm - truth->y_mm());
          errors_mm.push_back(error);
          heading_errors_deg.push_back(std::abs(core::WrapAngle(r.fix.yaw_rad - truth->yaw_rad())) * 180.0 /
                                       std::numbers::pi);
        }
        csv += fmt::format("{:.6f},{:.2f},{:.2f},{:.6f},{},{},{},{},{},{},{}\n", dataset_time.seconds(), r.fix.x_mm,
                           r.fix.y_mm, r.fix.yaw_rad, r.fix.status, r.fix.quality, r.fix.request_echo, r.fix.heartbeat,
                           truth ? fmt::format("{:.2f}", truth->x_mm()) : "", truth ? fmt::format("{:.2f}", truth->y_mm()) : "",
                           std::isnan(error) ? "" : fmt::format("{:.3f}", error));
      }
  };
  g_plc_signal = 0;
  std::signal(SIGINT, OnPlcSignal);
  std::signal(SIGTERM, OnPlcSignal);
  while (g_plc_signal == 0) {
    const core::Timestamp now = io::MonotonicNow();
    while (pending && playback.ToMonotonic(pending->time) <= now) {
      current = *pending;
      last_sample_time = pending->time;
      pending = encoders.Next();
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
      put(map.left_ticks, wrap(std::llround(current.left_ticks / map.left_ticks.scale), map.left_ticks));
      put(map.right_ticks, wrap(std::llround(current.right_ticks / map.right_ticks.scale), map.right_ticks));
      put(map.plc_heartbeat, wrap(heartbeat, map.plc_heartbeat));
      put(map.fix_request, wrap(request, map.fix_request));
    });

    process_received();
    if (now >= next_print) {
      next_print = next_print + std::chrono::seconds(1);
      if (!global.quiet && !global.json) {
        std::printf("%7.1f s  clients %d  ticks %d %d  heartbeat %u  requests %lld answered %lld  fixes %lld  "
                    "last error %s\n",
                    core::ToSeconds(now - playback.start), server.clients(), current.left_ticks, current.right_ticks,
                    heartbeat, static_cast<long long>(requests), static_cast<long long>(answered),
                    static_cast<long long>(fixes),
                    errors_mm.empty() ? "-" : fmt::format("{:.3f} mm", errors_mm.back()).c_str());
        std::fflush(stdout);
      }
    }
    if (ended && now - *ended > core::FromSeconds(args.linger_s)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  (void)last_sample_time;
  // Stop serving, then take in what the last requests wrote.
  server_owner.reset();
  process_received();

  if (!args.fixes_out.empty()) core::WriteFileAtomically(args.fixes_out, csv);
  std::sort(answer_ms.begin(), answer_ms.end());
  std::vector<double> sorted_errors = errors_mm;
  std::sort(sorted_errors.begin(), sorted_errors.end());
  const auto percentile = [](const std::vector<double>& v, double p) -> nlohmann::json {
    if (v.empty()) return nullptr;
    return dataset::Percentile(v, p);
  };
  double sum2 = 0.0;
  for (const double e : errors_mm) sum2 += e * e;
  const nlohmann::json summary = {
      {"fixes_received", fixes},
      {"status_counts", status_counts},
      {"requests", requests},
      {"answered", answered},
      {"answer_p50_ms", percentile(answer_ms, 50.0)},
      {"answer_p99_ms", percentile(answer_ms, 99.0)},
      {"answer_max_ms", answer_ms.empty() ? nlohmann::json(nullptr) : nlohmann::json(answer_ms.back())},
      {"position_rms_mm", errors_mm.empty() ? nlohmann::json(nullptr)
                                            : nlohmann::json(std::sqrt(sum2 / static_cast<double>(errors_mm.size())))},
      {"position_p50_mm", percentile(sorted_errors, 50.0)},
      {"position_max_mm", sorted_errors.empty() ? nlohmann::json(nullptr) : nlohmann::json(sorted_errors.back())},
      {"heading_max_deg", heading_errors_deg.empty()
                              ? nlohmann::json(nullptr)
                              : nlohmann::json(*std::max_element(heading_errors_deg.begin(), heading_errors_deg.end()))}};
  if (global.json) {
    std::printf("%s\n", summary.dump(2).c_str());
  } else {
    std::printf("fixes received %lld, requests %lld, answered %lld (p50 %s ms), position error rms %s mm, max %s mm\n",
                static_cast<long long>(fixes), static_cast<long long>(requests), static_cast<long long>(answered),
                summary["answer_p50_ms"].dump().c_str(), summary["position_rms_mm"].dump().c_str(),
                summary["position_max_mm"].dump().c_str());
  }
}

}  // namespace

Action AddPlcSimCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<PlcSimArgs>();
  CLI::App* command =
      app.add_subcommand("plc-sim", "A Modbus TCP PLC that plays a dataset's encoder ticks and shows the fixes it gets");
  auto* dataset = command->add_option("--dataset", args->dataset, "Dataset whose encoder ticks to play");
  command->add_option("--simulate", args->simulate,
                      "Play a drive of the simulator instead (its configuration file, or nothing for the defaults): "
                      "the same drive a run with camera source simulator sees")
      ->expected(0, 1)
      ->excludes(dataset);
  command->add_option("--port", args->port, "TCP port to serve on")->required()->check(CLI::Range(1, 65535));
  command->add_option("--host", args->host, "Address to listen on (default 127.0.0.1; 0.0.0.0 for all)");
  command->add_option("--unit", args->unit, "Modbus unit id")->check(CLI::Range(0, 247));
  command->add_option("--config", args->config, "Take the register map from this run configuration")
      ->check(CLI::ExistingFile);
  command->add_option("--start-unix", args->start_unix_s,
                      "Start playing at this wall-clock time (seconds since the Unix epoch), in step with a "
                      "`mosaicloc run` given the same time; default now");
  command->add_option("--request-period-ms", args->request_period_ms, "Ask for a fix this often (0: never)")
      ->check(CLI::Range(0.0, 3600000.0));
  command->add_option("--heartbeat-period-ms", args->heartbeat_period_ms, "PLC heartbeat period")
      ->check(CLI::Range(1.0, 60000.0));
  command->add_option("--linger", args->linger_s, "Keep serving this many seconds after the last sample")
      ->check(CLI::Range(0.0, 3600.0));
  command->add_option("--fixes-out", args->fixes_out, "Write every fix received (and its error) to this CSV");
  return [args, &global] { RunPlcSim(*args, global); };
}

}  // namespace mosaicloc::app
