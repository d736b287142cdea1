// Modbus round trips on loopback: mosaicloc's PLC link (client role) reading the inputs and
// writing a fix against a register server, beside plain libmodbus requests of the same size
// (the floor any link has to pay).
#include <memory>

#include <benchmark/benchmark.h>
#include <modbus/modbus.h>

#include "mosaicloc/core/log.hpp"
#include "mosaicloc/io/plc_link.hpp"
#include "mosaicloc/io/register_server.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace {

using namespace mosaicloc;

struct Plc {
  io::PlcLinkOptions options;
  std::unique_ptr<io::RegisterServer> server;
  Plc() {
    core::SetLogLevel(core::LogLevel::kWarning);
    options.port = test::FreeLoopbackPort();
    options.response_timeout_ms = 500.0;
    server = std::make_unique<io::RegisterServer>(options, 0, 110);
  }
};

void BM_LinkRead(benchmark::State& state) {
  Plc plc;
  const auto link = io::OpenPlcLink(plc.options);
  for (auto _ : state) {
    auto read = link->Read();
    if (!read.ok()) state.SkipWithError(read.error().c_str());
    benchmark::DoNotOptimize(read);
  }
}
BENCHMARK(BM_LinkRead)->UseRealTime();

void BM_LinkWriteFix(benchmark::State& state) {
  Plc plc;
  const auto link = io::OpenPlcLink(plc.options);
  io::PlcOutputs fix{1234.56, -789.01, 0.5, 1, 990, 1, 1};
  for (auto _ : state) {
    ++fix.heartbeat;
    if (!link->Write(fix).ok()) state.SkipWithError("write failed");
  }
}
BENCHMARK(BM_LinkWriteFix)->UseRealTime();

void BM_LibmodbusRead6(benchmark::State& state) {
  Plc plc;
  modbus_t* context = modbus_new_tcp("127.0.0.1", plc.options.port);
  modbus_connect(context);
  std::uint16_t words[6];
  for (auto _ : state) {
    if (modbus_read_registers(context, 0, 6, words) != 6) state.SkipWithError("read failed");
  }
  modbus_close(context);
  modbus_free(context);
}
BENCHMARK(BM_LibmodbusRead6)->UseRealTime();

void BM_LibmodbusWrite10(benchmark::State& state) {
  Plc plc;
  modbus_t* context = modbus_new_tcp("127.0.0.1", plc.options.port);
  modbus_connect(context);
  std::uint16_t words[10] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  for (auto _ : state) {
    if (modbus_write_registers(context, 100, 10, words) != 10) state.SkipWithError("write failed");
  }
  modbus_close(context);
  modbus_free(context);
}
BENCHMARK(BM_LibmodbusWrite10)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
