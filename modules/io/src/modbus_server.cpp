// mosaicloc as the Modbus server, for PLCs that prefer to write: the PLC writes the encoder
// counters, heartbeat and fix requests into mosaicloc's holding registers and reads the
// fixes from them. A thread of its own answers requests; Read and Write only touch the
// register table, under a lock.

#include <sys/select.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <mutex>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "modbus_common.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/io/plc_link.hpp"

namespace mosaicloc::io {
namespace {

struct MappingDeleter {
  void operator()(modbus_mapping_t* mapping) const { modbus_mapping_free(mapping); }
};

class ModbusServer final : public PlcLink {
 public:
  explicit ModbusServer(const PlcLinkOptions& options)
      : options_(options), context_(detail::NewContext(options, /*server=*/true)), decoder_(options.registers) {
    std::vector<const RegisterField*> all = options.registers.Inputs();
    const std::vector<const RegisterField*> outputs = options.registers.Outputs();
    all.insert(all.end(), outputs.begin(), outputs.end());
    table_range_ = detail::RangeOf(all);
    mapping_.reset(modbus_mapping_new_start_address(0, 0, 0, 0, static_cast<unsigned>(table_range_.base),
                                                    static_cast<unsigned>(table_range_.count), 0, 0));
    if (!mapping_) core::ThrowRuntime("PLC link: cannot allocate the register table");
    for (const RegisterField* field : {&options.registers.left_ticks, &options.registers.right_ticks}) {
      tick_registers_.push_back({field->address, field->words()});
    }
    if (options.transport == "tcp") {
      listen_socket_ = modbus_tcp_listen(context_.get(), 4);
      if (listen_socket_ < 0) {
        core::ThrowRuntime(fmt::format("PLC link: cannot listen as {}: {}", options.Describe(), modbus_strerror(errno)));
      }
    } else {
      if (modbus_connect(context_.get()) != 0) {
        core::ThrowRuntime(fmt::format("PLC link: cannot open {}: {}", options.Describe(), modbus_strerror(errno)));
      }
      modbus_set_indication_timeout(context_.get(), 0, 100000);
    }
    core::Log().info("PLC: serving {}", options.Describe());
    thread_ = std::thread([this] { Serve(); });
  }

  ~ModbusServer() override {
    stop_ = true;
    thread_.join();
    for (const int socket : clients_) close(socket);
    if (listen_socket_ >= 0) close(listen_socket_);
    if (options_.transport == "tcp") modbus_set_socket(context_.get(), -1);  // closed above
  }

  ModbusServer(const ModbusServer&) = delete;
  ModbusServer& operator=(const ModbusServer&) = delete;

  core::Result<PlcInputs> Read() override {
    const std::lock_guard lock(mutex_);
    if (tick_writes_ == 0) {
      stats_.last_error = "the PLC has not written the encoder registers yet";
      return core::Fail(stats_.last_error);
    }
    PlcInputs inputs = decoder_.Decode(mapping_->tab_registers, table_range_.base);
    inputs.time = last_tick_write_;
    inputs.fresh = tick_writes_ != tick_writes_read_;
    tick_writes_read_ = tick_writes_;
    ++stats_.reads;
    return inputs;
  }

  core::Result<core::Duration> Write(const PlcOutputs& outputs) override {
    const std::lock_guard lock(mutex_);
    if (!EncodeOutputs(options_.registers, outputs, table_range_.base, mapping_->tab_registers)) {
      ++stats_.out_of_range;
    }
    ++stats_.writes;
    return core::Duration::zero();
  }

  PlcLinkStats stats() const override {
    const std::lock_guard lock(mutex_);
    return stats_;
  }

 private:
  // Whether a request writes any of the tick registers (function codes 6, 16 and 23).
  bool WritesTicks(const std::uint8_t* request, int length) const {
    const int h = modbus_get_header_length(context_.get());
    if (length < h + 5) return false;
    const auto word = [&](int offset) { return (request[h + offset] << 8) | request[h + offset + 1]; };
    int address = 0;
    int count = 0;
    switch (request[h]) {
      case 0x06: address = word(1); count = 1; break;
      case 0x10: address = word(1); count = word(3); break;
      case 0x17:
        if (length < h + 9) return false;
        address = word(5);
        count = word(7);
        break;
      default: return false;
    }
    return std::any_of(tick_registers_.begin(), tick_registers_.end(), [&](const auto& r) {
      return address < r.first + r.second && r.first < address + count;
    });
  }

  void Answer(int length) {
    const std::lock_guard lock(mutex_);
    const bool ticks = WritesTicks(query_, length);
    if (modbus_reply(context_.get(), query_, length, mapping_.get()) < 0) {
      ++stats_.write_errors;
      stats_.last_error = fmt::format("reply to the PLC failed: {}", modbus_strerror(errno));
      return;
    }
    // A write outside the table is answered with an exception by libmodbus and changes nothing.
    if (ticks) {
      last_tick_write_ = MonotonicNow();
      ++tick_writes_;
    }
  }

  void Serve() {
    if (options_.transport == "rtu") {
      while (!stop_) {
        const int length = modbus_receive(context_.get(), query_);
        if (length > 0) Answer(length);
      }
      return;
    }
    while (!stop_) {
      fd_set readable;
      FD_ZERO(&readable);
      FD_SET(listen_socket_, &readable);
      int highest = listen_socket_;
      for (const int socket : clients_) {
        FD_SET(socket, &readable);
        highest = std::max(highest, socket);
      }
      timeval timeout{0, 50000};
      if (select(highest + 1, &readable, nullptr, nullptr, &timeout) <= 0) continue;
      if (FD_ISSET(listen_socket_, &readable)) {
        int listening = listen_socket_;
        const int socket = modbus_tcp_accept(context_.get(), &listening);
        if (socket >= 0) {
          clients_.push_back(socket);
          const std::lock_guard lock(mutex_);
          stats_.connected = true;
          ++stats_.connects;
        }
      }
      for (auto it = clients_.begin(); it != clients_.end();) {
        if (!FD_ISSET(*it, &readable)) {
          ++it;
          continue;
        }
        modbus_set_socket(context_.get(), *it);
        const int length = modbus_receive(context_.get(), query_);
        if (length > 0) Answer(length);
        if (length < 0) {  // the PLC closed the connection, or sent garbage
          close(*it);
          modbus_set_socket(context_.get(), -1);
          it = clients_.erase(it);
          const std::lock_guard lock(mutex_);
          stats_.connected = !clients_.empty();
        } else {
          ++it;
        }
      }
    }
  }

  PlcLinkOptions options_;
  detail::ModbusContext context_;
  std::unique_ptr<modbus_mapping_t, MappingDeleter> mapping_;
  detail::RegisterRange table_range_;
  std::vector<std::pair<int, int>> tick_registers_;  // address, words
  detail::InputDecoder decoder_;
  int listen_socket_ = -1;
  std::vector<int> clients_;
  std::uint8_t query_[MODBUS_TCP_MAX_ADU_LENGTH > MODBUS_RTU_MAX_ADU_LENGTH ? MODBUS_TCP_MAX_ADU_LENGTH
                                                                             : MODBUS_RTU_MAX_ADU_LENGTH] = {};
  mutable std::mutex mutex_;
  core::Timestamp last_tick_write_;
  std::int64_t tick_writes_ = 0;
  std::int64_t tick_writes_read_ = 0;
  PlcLinkStats stats_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace

std::unique_ptr<PlcLink> OpenModbusServer(const PlcLinkOptions& options) {
  return std::make_unique<ModbusServer>(options);
}

}  // namespace mosaicloc::io
