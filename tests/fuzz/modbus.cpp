// Modbus from a hostile or broken peer, both ways. The first byte picks the side:
// - 's': mosaicloc serves the registers (role server) and the rest of the input arrives as a
//   TCP client's bytes; the link then decodes whatever the registers hold.
// - otherwise: mosaicloc polls a PLC (role client) that answers every request with the rest of
//   the input (its transaction id made the request's, so that the reply gets past the first
//   check); the link reads and writes once.
// Neither may crash, hang or throw: every failure is a counted, returned failure.
#include <atomic>
#include <cstring>
#include <mutex>
#include <thread>
#include <vector>

#include "fuzz_input.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/io/plc_link.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace {

using mosaicloc::io::PlcLinkOptions;

// The served registers, started once per process.
struct Served {
  int port = mosaicloc::test::FreeLoopbackPort();
  std::unique_ptr<mosaicloc::io::PlcLink> link;
  Served() {
    PlcLinkOptions options;
    options.role = "server";
    options.port = port;
    link = mosaicloc::io::OpenPlcLink(options);
  }
};

// A PLC that answers each request with the current reply, on a thread of its own.
class ScriptedPlc {
 public:
  ScriptedPlc() {
    listener_ = socket(AF_INET, SOCK_STREAM, 0);
    const int yes = 1;
    setsockopt(listener_, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(listener_, reinterpret_cast<sockaddr*>(&address), sizeof(address));
    socklen_t length = sizeof(address);
    getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &length);
    port_ = ntohs(address.sin_port);
    listen(listener_, 4);
    thread_ = std::thread([this] { Serve(); });
  }
  int port() const { return port_; }
  void SetReply(const std::uint8_t* data, std::size_t size) {
    const std::lock_guard lock(mutex_);
    reply_.assign(data, data + size);
  }

 private:
  void Serve() {
    for (;;) {
      const int client = accept(listener_, nullptr, nullptr);
      if (client < 0) continue;
      std::uint8_t request[260];
      for (;;) {
        pollfd readable{client, POLLIN, 0};
        if (poll(&readable, 1, 1000) <= 0) break;
        const ssize_t n = recv(client, request, sizeof(request), 0);
        if (n <= 0) break;
        std::vector<std::uint8_t> reply;
        {
          const std::lock_guard lock(mutex_);
          reply = reply_;
        }
        if (reply.size() >= 2 && n >= 2) std::memcpy(reply.data(), request, 2);  // the transaction id
        if (!reply.empty()) send(client, reply.data(), reply.size(), MSG_NOSIGNAL);
      }
      close(client);
    }
  }
  int listener_ = -1;
  int port_ = 0;
  std::mutex mutex_;
  std::vector<std::uint8_t> reply_;
  std::thread thread_;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const bool quiet = [] {
    mosaicloc::core::Log().set_level(spdlog::level::off);
    return true;
  }();
  (void)quiet;
  if (data[0] == 's') {
    static Served served;
    mosaicloc::fuzz::Exchange(served.port, data + 1, size - 1, 150);
    (void)served.link->Read();
    (void)served.link->Write(mosaicloc::io::PlcOutputs{});
    return 0;
  }
  static ScriptedPlc* const plc = new ScriptedPlc();  // its thread serves until the process ends
  plc->SetReply(data + 1, size - 1);
  PlcLinkOptions options;
  options.port = plc->port();
  // Loopback answers in microseconds; the time-out (also between a reply's bytes) is waited out
  // on every garbled reply, and is kept well above a busy machine's scheduling delays.
  options.response_timeout_ms = 5.0;
  mosaicloc::fuzz::ExpectOnlyCoreErrors([&] {
    const auto link = mosaicloc::io::OpenPlcLink(options);
    (void)link->Read();
    (void)link->Write(mosaicloc::io::PlcOutputs{});
  });
  return 0;
}
