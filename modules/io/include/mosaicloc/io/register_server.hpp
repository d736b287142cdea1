#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/io/plc_link.hpp"

namespace mosaicloc::io {

/// A Modbus server of holding registers answering on a thread of its own, over TCP (any
/// number of peers) or RTU: what mosaicloc's server role is built on, and the PLC that
/// `mosaicloc plc-sim` plays. Requests outside the table get Modbus exceptions.
class RegisterServer {
 public:
  /// Called on the server's thread after a peer's write was applied and answered, still
  /// under the table's lock: the registers written, when the request arrived (monotonic
  /// clock) and the whole table (`table[i]` is register base + i). A reader that takes the
  /// table after the peer has its reply sees what the observer did; the observer must not
  /// call Get, Set or Update.
  using WriteObserver =
      std::function<void(int address, int count, core::Timestamp time, const std::uint16_t* table)>;

  /// Serves registers [base, base + count) with the connection settings of `options`
  /// (transport, host/port or device, unit id). Throws core::Error (runtime) naming the
  /// port or device when it cannot listen on it.
  RegisterServer(const PlcLinkOptions& options, int base, int count, WriteObserver on_write = {});
  ~RegisterServer();
  RegisterServer(const RegisterServer&) = delete;
  RegisterServer& operator=(const RegisterServer&) = delete;

  /// Copies registers out of or into the table, under its lock (a peer never sees half).
  void Get(int address, int count, std::uint16_t* words) const;
  void Set(int address, int count, const std::uint16_t* words);
  /// Runs `change` on the table's words (indexed from `base`) under the lock.
  void Update(const std::function<void(std::uint16_t* table)>& change);
  int base() const { return base_; }
  int clients() const { return clients_connected_; }
  /// Connections accepted since the start (TCP), for the link's statistics.
  std::int64_t connections() const { return connections_; }
  std::int64_t requests() const { return requests_; }

 private:
  struct State;
  void Serve();
  void Answer(int length);

  PlcLinkOptions options_;
  int base_;
  int count_;
  WriteObserver on_write_;
  std::unique_ptr<State> state_;
  mutable std::mutex mutex_;
  std::atomic<int> clients_connected_{0};
  std::atomic<std::int64_t> requests_{0};
  std::atomic<std::int64_t> connections_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace mosaicloc::io
