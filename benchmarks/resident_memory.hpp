#pragma once
// The benchmarks' peak resident memory, from /proc/self/status.
#include <fstream>
#include <string>

namespace mosaicloc::bench {

/// Peak resident set size of this process so far (VmHWM), MiB; 0 where /proc has none.
inline double PeakResidentMib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return 0.0;
}

}  // namespace mosaicloc::bench
