#include "mosaicloc/core/stop_signals.hpp"

#include <atomic>
#include <csignal>

namespace mosaicloc::core {
namespace {

std::atomic<int> g_signal{0};
// Only async-signal-safe calls here: a second signal restores the default and raises again.
extern "C" void OnStopSignal(int signal) {
  if (g_signal.exchange(signal) != 0) {
    std::signal(signal, SIG_DFL);
    std::raise(signal);
  }
}

}  // namespace

StopSignals::StopSignals() {
  g_signal = 0;
  std::signal(SIGINT, OnStopSignal);
  std::signal(SIGTERM, OnStopSignal);
}

StopSignals::~StopSignals() {
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
}

std::optional<std::string> StopSignals::Reason() {
  const int signal = g_signal;
  if (signal == 0) return std::nullopt;
  return signal == SIGINT ? "interrupted (SIGINT)" : "terminated (SIGTERM)";
}

int StopSignals::Signal() { return g_signal; }

}  // namespace mosaicloc::core
