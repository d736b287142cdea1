// mosaicloc plc-sim: a Modbus TCP PLC on this machine that plays a drive's encoder counters
// and shows the fixes it gets back (runtime::RunPlcSimulator), for trying a run without a PLC.
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "commands.hpp"
#include "mosaicloc/core/stop_signals.hpp"
#include "report.hpp"
#include "mosaicloc/core/yaml.hpp"
#include "mosaicloc/runtime/plc_simulator.hpp"
#include "mosaicloc/runtime/run_config.hpp"

namespace mosaicloc::app {
namespace {

struct PlcSimArgs {
  runtime::PlcSimulatorOptions options;
  std::filesystem::path config;
};

void RunPlcSim(PlcSimArgs args, const GlobalOptions& global) {
  if (!args.config.empty()) {
    runtime::ReadRegisterMap(core::LoadYamlFile(args.config), args.config.string(), &args.options.registers);
  }
  const runtime::PlcSimulatorOptions& o = args.options;
  runtime::PlcSimulatorCallbacks callbacks;
  callbacks.serving = [&](const std::string& played) {
    if (!global.quiet) {
      std::fprintf(stderr, "plc-sim: serving holding registers on %s:%d (unit %d), playing %s\n", o.host.c_str(),
                   o.port, o.unit, played.c_str());
    }
  };
  callbacks.every_second = [&](const runtime::PlcSimulatorStatus& s) {
    if (global.quiet || global.json) return;
    std::printf("%7.1f s  clients %d  ticks %s  heartbeat %u  requests %lld answered %lld  fixes %lld  "
                "last error %s\n",
                s.seconds, s.clients, fmt::format("{}", fmt::join(s.counters, " ")).c_str(), s.heartbeat,
                static_cast<long long>(s.requests),
                static_cast<long long>(s.answered), static_cast<long long>(s.fixes),
                s.last_error_mm ? fmt::format("{:.3f} mm", *s.last_error_mm).c_str() : "-");
    std::fflush(stdout);
  };
  callbacks.stop = [] { return core::StopSignals::Reason().has_value(); };
  const core::StopSignals signals;
  const runtime::PlcSimulatorSummary r = runtime::RunPlcSimulator(o, callbacks);
  if (global.json) {
    PrintJson(r.ToJson());
  } else {
    std::fputs(r.Text().c_str(), stdout);
  }
}

}  // namespace

Action AddPlcSimCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<PlcSimArgs>();
  CLI::App* command =
      app.add_subcommand("plc-sim", "A Modbus TCP PLC that plays a dataset's encoder ticks and shows the fixes it gets");
  auto* dataset = command->add_option("--dataset", args->options.dataset, "Dataset whose encoder ticks to play");
  command->add_option("--simulate", args->options.simulate,
                      "Play a drive of the simulator instead (its configuration file, or nothing for the defaults): "
                      "the same drive a run with camera source simulator sees")
      ->expected(0, 1)
      ->excludes(dataset);
  command->add_option("--port", args->options.port, "TCP port to serve on")->required()->check(CLI::Range(1, 65535));
  command->add_option("--host", args->options.host, "Address to listen on (default 127.0.0.1; 0.0.0.0 for all)");
  command->add_option("--unit", args->options.unit, "Modbus unit id")->check(CLI::Range(0, 247));
  command->add_option("--config", args->config, "Take the register map from this run configuration")
      ->check(CLI::ExistingFile);
  command->add_option("--start-unix", args->options.start_unix_s,
                      "Start playing at this wall-clock time (seconds since the Unix epoch), in step with a "
                      "`mosaicloc run` given the same time; default now");
  command->add_option("--request-period-ms", args->options.request_period_ms, "Ask for a fix this often (0: never)")
      ->check(CLI::Range(0.0, 3600000.0));
  command->add_option("--heartbeat-period-ms", args->options.heartbeat_period_ms, "PLC heartbeat period")
      ->check(CLI::Range(1.0, 60000.0));
  command->add_option("--linger", args->options.linger_s, "Keep serving this many seconds after the last sample")
      ->check(CLI::Range(0.0, 3600.0));
  command->add_option("--fixes-out", args->options.fixes_out, "Write every fix received (and its error) to this CSV");
  return [args, &global] { RunPlcSim(*args, global); };
}

}  // namespace mosaicloc::app
