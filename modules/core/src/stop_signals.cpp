#include "mosaicloc/core/stop_signals.hpp"

#include <atomic>
#include <csignal>

namespace mosaicloc::core {
namespace {

std::atomic<int> g_signal{0};
extern "C" void OnStopSignal(int signal) { g_signal = signal; }

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

}  // namespace mosaicloc::core
