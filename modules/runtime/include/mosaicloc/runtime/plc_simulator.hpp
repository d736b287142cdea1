#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mosaicloc/io/registers.hpp"

namespace mosaicloc::runtime {

/// `mosaicloc plc-sim`: a Modbus TCP server standing in for the PLC. It plays a dataset's
/// encoder counters in real time (or a simulated drive's, each sample computed when it is due,
/// sim::PlannedDrive), beats its heartbeat, asks for a fix every request period, and records
/// the fixes a `mosaicloc run` writes back against the drive's ground truth.
struct PlcSimulatorOptions {
  std::filesystem::path dataset;                  ///< the drive to play, or
  std::optional<std::filesystem::path> simulate;  ///< a simulator configuration (empty path: the defaults)
  std::string host = "127.0.0.1";
  int port = 0;
  int unit = 1;
  io::RegisterMap registers;
  double start_unix_s = 0.0;  ///< wall-clock start of playback (0: now)
  double request_period_ms = 500.0;  ///< 0: never
  double heartbeat_period_ms = 10.0;
  double linger_s = 1.0;  ///< serving on after the last sample
  std::filesystem::path fixes_out;  ///< every fix received and its error, CSV (empty: none)
};

/// Once a second while serving.
struct PlcSimulatorStatus {
  double seconds = 0.0;  ///< since playback started
  int clients = 0;
  std::vector<std::int32_t> counters;  ///< the vehicle kind's counters as played
  std::uint32_t heartbeat = 0;
  std::int64_t requests = 0, answered = 0, fixes = 0;
  std::optional<double> last_error_mm;
};

struct PlcSimulatorCallbacks {
  std::function<void(const std::string& played)> serving;  ///< once, when the server listens: what it plays
  std::function<void(const PlcSimulatorStatus&)> every_second;
  std::function<bool()> stop;  ///< polled every millisecond; true ends the run early
};

struct PlcSimulatorSummary {
  std::int64_t fixes_received = 0;
  std::vector<std::int64_t> status_counts;  ///< by PLC status: none, tracking, degraded, lost, off-map, searching
  std::vector<std::int64_t> mode_counts;    ///< by PLC mode: none, track, visual odometry, dead reckoning, searching
  std::int64_t requests = 0, answered = 0;
  std::optional<double> answer_p50_ms, answer_p99_ms, answer_max_ms;
  /// Against the ground truth, over fixes with a status other than none (when the drive has one).
  std::optional<double> position_rms_mm, position_p50_mm, position_max_mm, heading_max_deg;

  /// `plc-sim --json`: the counts, and each figure (null where there was none).
  nlohmann::json ToJson() const;
  /// The line `plc-sim` prints at its end.
  std::string Text() const;
};

/// Serves until the drive has been played and `linger_s` has passed, or `stop` says so.
/// Throws core::Error naming the dataset when it has no encoder samples.
PlcSimulatorSummary RunPlcSimulator(const PlcSimulatorOptions& options, const PlcSimulatorCallbacks& callbacks);

}  // namespace mosaicloc::runtime
