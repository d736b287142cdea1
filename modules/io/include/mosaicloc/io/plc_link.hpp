#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/io/registers.hpp"

namespace mosaicloc::io {

/// How mosaicloc talks to the PLC (design.md section 6).
struct PlcLinkOptions {
  /// "client": mosaicloc polls the PLC (the default). "server": mosaicloc serves the
  /// registers and the PLC writes its inputs and reads the fixes.
  std::string role = "client";
  std::string transport = "tcp";  ///< "tcp" or "rtu"
  /// TCP: the PLC's address (client), or the interface to listen on (server; "0.0.0.0" = all).
  std::string host = "127.0.0.1";
  int port = 502;
  /// RTU: serial device and line settings.
  std::string device = "/dev/ttyUSB0";
  int baud = 115200;
  std::string parity = "N";  ///< N, E or O
  int data_bits = 8;
  int stop_bits = 1;
  int unit_id = 1;  ///< Modbus unit (slave) id
  /// A request not answered within this is a timeout (the cycle goes on without it).
  double response_timeout_ms = 50.0;
  /// After a failed connection attempt the next waits this long, doubling up to the maximum.
  double reconnect_min_ms = 100.0;
  double reconnect_max_ms = 2000.0;
  RegisterMap registers;
  bool Check(std::string* why) const;
  /// "tcp client of 127.0.0.1:502, unit 1".
  std::string Describe() const;
};

/// What the PLC provides, decoded.
struct PlcInputs {
  /// When the values were valid on the monotonic clock: the middle of the read request's
  /// round trip (client), or the PLC's write of the tick registers (server).
  core::Timestamp time;
  /// False when nothing changed since the previous read (server role: the PLC has not
  /// written again); such inputs carry no new encoder sample.
  bool fresh = true;
  /// Raw counters as odometry takes them: modulo 2^32 (the register map's kind's two; the
  /// tricycle's steering count as the encoder reads it).
  /// A mecanum vehicle's front wheels are left_ticks and right_ticks.
  core::EncoderCounts counts;
  std::uint32_t plc_heartbeat = 0;
  std::uint32_t fix_request = 0;
  std::uint32_t relocalize_request = 0;
  core::Duration round_trip{};   ///< client role: the read request's round trip
};

/// What mosaicloc writes back.
struct PlcOutputs {
  double x_mm = 0.0;
  double y_mm = 0.0;
  double yaw_rad = 0.0;
  int status = 0;            ///< 0 none, 1 tracking, 2 degraded, 3 lost, 4 off-map
  int quality = 0;           ///< 0-1000
  std::uint32_t request_echo = 0;
  std::uint32_t heartbeat = 0;
  int mode = 0;              ///< 0 none, 1 track, 2 visual odometry, 3 dead reckoning, 4 searching
};

/// Health of the link, for the status line and the logs. Every Modbus error is counted.
struct PlcLinkStats {
  bool connected = false;
  std::int64_t reads = 0;
  std::int64_t writes = 0;
  std::int64_t read_errors = 0;
  std::int64_t write_errors = 0;
  std::int64_t timeouts = 0;
  std::int64_t connects = 0;          ///< successful (re)connections
  std::int64_t connect_failures = 0;
  std::int64_t out_of_range = 0;      ///< outputs clamped to their field's range
  double last_round_trip_ms = 0.0;
  std::string last_error;             ///< names the registers it concerned
};

/// A link to the PLC. Never throws once constructed and never crashes on what the PLC or
/// the network does: a failed read or write is counted, logged (on the first failure and
/// on recovery, so an unplugged cable does not flood the log) and returned as a failure.
/// Not thread safe: one link per thread, as libmodbus contexts are.
class PlcLink {
 public:
  virtual ~PlcLink() = default;
  /// Reads the PLC's inputs (a client polls; a server returns what the PLC last wrote).
  virtual core::Result<PlcInputs> Read() = 0;
  /// Writes the outputs; on success, the time the request took.
  virtual core::Result<core::Duration> Write(const PlcOutputs& outputs) = 0;
  virtual PlcLinkStats stats() const = 0;
};

/// Opens the link of options.role. Throws core::Error (invalid input) on bad options, and
/// (runtime) when a server cannot listen on its port or device. A client that cannot reach
/// the PLC yet does not throw: it keeps trying with backoff.
std::unique_ptr<PlcLink> OpenPlcLink(const PlcLinkOptions& options);

/// Converts fix outputs to register words and back: what a link writes and what a PLC
/// reads. `words` covers the holding registers from `base_address`. Returns false when a
/// value was clamped to its field's range.
bool EncodeOutputs(const RegisterMap& map, const PlcOutputs& outputs, int base_address, std::uint16_t* words);

/// The monotonic clock as a Timestamp (the epoch of every live timestamp).
core::Timestamp MonotonicNow();

/// Watches the PLC's heartbeat counter: stale when it has not changed for longer than the
/// timeout (the PLC program stopped though its network card still answers). A timeout of
/// zero disables the watch.
class HeartbeatMonitor {
 public:
  explicit HeartbeatMonitor(core::Duration timeout) : timeout_(timeout) {}
  /// One reading; returns whether the heartbeat is stale now.
  bool Update(core::Timestamp time, std::uint32_t value);
  bool stale(core::Timestamp now) const;
  void Reset() { last_change_.reset(); }

 private:
  core::Duration timeout_;
  std::optional<core::Timestamp> last_change_;
  std::uint32_t last_value_ = 0;
};

/// When polled counters that changed between two reads took their new values: after the
/// previous read and, the PLC updating them every `counter_period` (0: unknown), within the
/// last period before this read; the middle of that interval. A poll that came late (the
/// machine busy) does not date them to long before the read.
core::Timestamp CountersChangedAt(core::Timestamp previous_read, core::Timestamp read, core::Duration counter_period);

}  // namespace mosaicloc::io
