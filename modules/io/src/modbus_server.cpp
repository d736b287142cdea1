// The Modbus register server, and mosaicloc's server role on top of it (for PLCs that prefer
// to write): the PLC writes the encoder counters, heartbeat and fix requests into
// mosaicloc's holding registers and reads the fixes from them.

#include <sys/select.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <vector>

#include <fmt/format.h>

#include "modbus_common.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/io/plc_link.hpp"
#include "mosaicloc/io/register_server.hpp"

namespace mosaicloc::io {

struct RegisterServer::State {
  detail::ModbusContext context;
  modbus_mapping_t* mapping = nullptr;
  int listen_socket = -1;
  std::vector<int> clients;
  std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH > MODBUS_RTU_MAX_ADU_LENGTH ? MODBUS_TCP_MAX_ADU_LENGTH
                                                                            : MODBUS_RTU_MAX_ADU_LENGTH] = {};
  ~State() {
    for (const int socket : clients) close(socket);
    if (listen_socket >= 0) close(listen_socket);
    if (context) modbus_set_socket(context.get(), -1);  // closed above
    if (mapping != nullptr) modbus_mapping_free(mapping);
  }
};

RegisterServer::RegisterServer(const PlcLinkOptions& options, int base, int count, WriteObserver on_write)
    : options_(options), base_(base), count_(count), on_write_(std::move(on_write)), state_(std::make_unique<State>()) {
  if (base < 0 || count < 1 || base + count > 65536) core::ThrowInvalidInput("register server: bad register range");
  state_->context = detail::NewContext(options, /*server=*/true);
  state_->mapping =
      modbus_mapping_new_start_address(0, 0, 0, 0, static_cast<unsigned>(base), static_cast<unsigned>(count), 0, 0);
  if (state_->mapping == nullptr) core::ThrowRuntime("register server: cannot allocate the register table");
  const std::string where = options.transport == "tcp" ? fmt::format("{}:{}", options.host, options.port) : options.device;
  if (options.transport == "tcp") {
    state_->listen_socket = modbus_tcp_listen(state_->context.get(), 8);
    if (state_->listen_socket < 0) {
      core::ThrowRuntime(fmt::format("Modbus server: cannot listen on {}: {}", where, modbus_strerror(errno)));
    }
  } else {
    if (modbus_connect(state_->context.get()) != 0) {
      core::ThrowRuntime(fmt::format("Modbus server: cannot open {}: {}", where, modbus_strerror(errno)));
    }
    modbus_set_indication_timeout(state_->context.get(), 0, 100000);
  }
  // A request's bytes arrive together: a peer that sends part of one and waits holds the one
  // serving thread (and every other client) for at most this, not libmodbus' default 0.5 s.
  modbus_set_byte_timeout(state_->context.get(), 0, 50000);
  thread_ = std::thread([this] { Serve(); });
}

RegisterServer::~RegisterServer() {
  stop_ = true;
  thread_.join();
}

void RegisterServer::Get(int address, int count, std::uint16_t* words) const {
  const std::lock_guard lock(mutex_);
  std::memcpy(words, state_->mapping->tab_registers + (address - base_), sizeof(std::uint16_t) * static_cast<std::size_t>(count));
}

void RegisterServer::Set(int address, int count, const std::uint16_t* words) {
  const std::lock_guard lock(mutex_);
  std::memcpy(state_->mapping->tab_registers + (address - base_), words, sizeof(std::uint16_t) * static_cast<std::size_t>(count));
}

void RegisterServer::Update(const std::function<void(std::uint16_t* table)>& change) {
  const std::lock_guard lock(mutex_);
  change(state_->mapping->tab_registers);
}

void RegisterServer::Answer(int length) {
  const std::uint8_t* request = state_->query;
  // The registers a write request changes (function codes 6, 16 and 23), if any.
  const int h = modbus_get_header_length(state_->context.get());
  const auto word = [&](int offset) { return length > h + offset + 1 ? (request[h + offset] << 8) | request[h + offset + 1] : 0; };
  int address = 0;
  int count = 0;
  switch (request[h]) {
    case 0x06: address = word(1); count = 1; break;
    case 0x10: address = word(1); count = word(3); break;
    case 0x17: address = word(5); count = word(7); break;
    default: break;
  }
  // libmodbus answers a write outside the table with an exception and changes nothing.
  const bool applied = count > 0 && address >= base_ && address + count <= base_ + count_;
  const core::Timestamp arrived = MonotonicNow();
  {
    const std::lock_guard lock(mutex_);
    const int rc = modbus_reply(state_->context.get(), request, length, state_->mapping);
    if (rc >= 0 && applied && on_write_) on_write_(address, count, arrived, state_->mapping->tab_registers);
  }
  ++requests_;
}

void RegisterServer::Serve() {
  modbus_t* context = state_->context.get();
  if (options_.transport == "rtu") {
    clients_connected_ = 1;
    while (!stop_) {
      const int length = modbus_receive(context, state_->query);
      if (length > 0) Answer(length);
    }
    return;
  }
  std::vector<int>& clients = state_->clients;
  while (!stop_) {
    fd_set readable;
    FD_ZERO(&readable);
    FD_SET(state_->listen_socket, &readable);
    int highest = state_->listen_socket;
    for (const int socket : clients) {
      FD_SET(socket, &readable);
      highest = std::max(highest, socket);
    }
    timeval timeout{0, 50000};
    if (select(highest + 1, &readable, nullptr, nullptr, &timeout) <= 0) continue;
    if (FD_ISSET(state_->listen_socket, &readable)) {
      int listening = state_->listen_socket;
      const int socket = modbus_tcp_accept(context, &listening);
      if (socket >= 0) {
        clients.push_back(socket);
        ++connections_;
      }
    }
    for (auto it = clients.begin(); it != clients.end();) {
      if (!FD_ISSET(*it, &readable)) {
        ++it;
        continue;
      }
      modbus_set_socket(context, *it);
      const int length = modbus_receive(context, state_->query);
      if (length > 0) Answer(length);
      if (length < 0) {  // the peer closed the connection, or sent garbage
        close(*it);
        modbus_set_socket(context, -1);
        it = clients.erase(it);
      } else {
        ++it;
      }
    }
    clients_connected_ = static_cast<int>(clients.size());
  }
}

namespace {

class ModbusServerLink final : public PlcLink {
 public:
  explicit ModbusServerLink(const PlcLinkOptions& options) : options_(options), decoder_(options.registers) {
    std::vector<const RegisterField*> all = options.registers.Inputs();
    const std::vector<const RegisterField*> outputs = options.registers.Outputs();
    all.insert(all.end(), outputs.begin(), outputs.end());
    range_ = detail::RangeOf(all);
    for (const RegisterField* field : options.registers.Counters()) {
      tick_registers_.push_back({field->address, field->words()});
    }
    try {
      server_ = std::make_unique<RegisterServer>(options, range_.base, range_.count,
                                                 [this](int address, int count, core::Timestamp time, const std::uint16_t*) {
                                                   OnWrite(address, count, time);
                                                 });
    } catch (const core::Error& e) {
      core::ThrowRuntime(fmt::format("PLC link: cannot serve as {}: {}", options.Describe(), e.what()));
    }
    core::Log().info("PLC: serving {}", options.Describe());
  }

  core::Result<PlcInputs> Read() override {
    std::vector<std::uint16_t> words(static_cast<std::size_t>(range_.count));
    server_->Get(range_.base, range_.count, words.data());
    const std::lock_guard lock(mutex_);
    stats_.connected = server_->clients() > 0;
    if (tick_writes_ == 0) {
      stats_.last_error = "the PLC has not written the encoder registers yet";
      return core::Fail(stats_.last_error);
    }
    PlcInputs inputs = decoder_.Decode(words.data(), range_.base);
    inputs.time = last_tick_write_;
    inputs.fresh = tick_writes_ != tick_writes_read_;
    tick_writes_read_ = tick_writes_;
    ++stats_.reads;
    return inputs;
  }

  core::Result<core::Duration> Write(const PlcOutputs& outputs) override {
    bool in_range = true;
    server_->Update([&](std::uint16_t* table) {
      in_range = EncodeOutputs(options_.registers, outputs, range_.base, table);
    });
    const std::lock_guard lock(mutex_);
    if (!in_range) ++stats_.out_of_range;
    ++stats_.writes;
    return core::Duration::zero();
  }

  PlcLinkStats stats() const override {
    const std::lock_guard lock(mutex_);
    PlcLinkStats stats = stats_;
    stats.connected = server_->clients() > 0;
    stats.connects = server_->connections();
    return stats;
  }

 private:
  void OnWrite(int address, int count, core::Timestamp time) {
    const bool ticks = std::any_of(tick_registers_.begin(), tick_registers_.end(), [&](const auto& r) {
      return address < r.first + r.second && r.first < address + count;
    });
    if (!ticks) return;
    const std::lock_guard lock(mutex_);
    last_tick_write_ = time;
    ++tick_writes_;
  }

  PlcLinkOptions options_;
  detail::RegisterRange range_;
  std::vector<std::pair<int, int>> tick_registers_;  // address, words
  detail::InputDecoder decoder_;
  mutable std::mutex mutex_;
  core::Timestamp last_tick_write_;
  std::int64_t tick_writes_ = 0;
  std::int64_t tick_writes_read_ = 0;
  PlcLinkStats stats_;
  std::unique_ptr<RegisterServer> server_;  // last: its thread calls OnWrite until destroyed
};

}  // namespace

std::unique_ptr<PlcLink> OpenModbusServer(const PlcLinkOptions& options) {
  return std::make_unique<ModbusServerLink>(options);
}

}  // namespace mosaicloc::io
