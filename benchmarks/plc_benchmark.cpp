// Modbus round trips on loopback: mosaicloc's PLC link (client role) reading the inputs and
// writing a fix against a register server, beside plain libmodbus requests of the same size
// (the floor any link has to pay).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <memory>

#include <benchmark/benchmark.h>
#include <modbus/modbus.h>

#include "mosaicloc/core/log.hpp"
#include "mosaicloc/io/plc_link.hpp"
#include "mosaicloc/io/register_server.hpp"

namespace {

using namespace mosaicloc;

int FreePort() {
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(s, reinterpret_cast<sockaddr*>(&address), sizeof(address));
  socklen_t length = sizeof(address);
  getsockname(s, reinterpret_cast<sockaddr*>(&address), &length);
  close(s);
  return ntohs(address.sin_port);
}

struct Plc {
  io::PlcLinkOptions options;
  std::unique_ptr<io::RegisterServer> server;
  Plc() {
    core::SetLogLevel(core::LogLevel::kWarning);
    options.port = FreePort();
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
