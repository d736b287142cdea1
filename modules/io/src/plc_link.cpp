#include "mosaicloc/io/plc_link.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>

#include "modbus_common.hpp"
#include "mosaicloc/core/error.hpp"

namespace mosaicloc::io {

std::unique_ptr<PlcLink> OpenModbusClient(const PlcLinkOptions& options);  // modbus_client.cpp
std::unique_ptr<PlcLink> OpenModbusServer(const PlcLinkOptions& options);  // modbus_server.cpp

bool PlcLinkOptions::Check(std::string* why) const {
  auto fail = [why](std::string message) {
    if (why != nullptr) *why = std::move(message);
    return false;
  };
  if (role != "client" && role != "server") return fail("role must be client or server, not '" + role + "'");
  if (transport != "tcp" && transport != "rtu") return fail("transport must be tcp or rtu, not '" + transport + "'");
  if (transport == "tcp" && (port < 1 || port > 65535)) return fail("port must be in 1-65535");
  if (transport == "tcp" && host.empty()) return fail("host must not be empty");
  if (transport == "rtu") {
    if (device.empty()) return fail("device must not be empty");
    if (baud < 300 || baud > 4000000) return fail("baud must be in 300-4000000");
    if (parity != "N" && parity != "E" && parity != "O") return fail("parity must be N, E or O");
    if (data_bits < 5 || data_bits > 8) return fail("data_bits must be in 5-8");
    if (stop_bits != 1 && stop_bits != 2) return fail("stop_bits must be 1 or 2");
  }
  if (unit_id < 0 || unit_id > 247) return fail("unit_id must be in 0-247");
  if (!(response_timeout_ms >= 1.0 && response_timeout_ms <= 10000.0)) {
    return fail("response_timeout_ms must be in 1-10000");
  }
  if (!(reconnect_min_ms >= 1.0 && reconnect_min_ms <= 600000.0)) return fail("reconnect_min_ms must be in 1-600000");
  if (!(reconnect_max_ms >= reconnect_min_ms && reconnect_max_ms <= 600000.0)) {
    return fail("reconnect_max_ms must be at least reconnect_min_ms and at most 600000");
  }
  std::string registers_why;
  if (!registers.Check(&registers_why)) return fail("registers: " + registers_why);
  return true;
}

std::string PlcLinkOptions::Describe() const {
  const std::string where =
      transport == "tcp" ? fmt::format("{}:{}", host, port) : fmt::format("{} {} {}{}{}", device, baud, data_bits, parity, stop_bits);
  return fmt::format("Modbus {} {} of {}, unit {}", transport == "tcp" ? "TCP" : "RTU", role, where, unit_id);
}

std::unique_ptr<PlcLink> OpenPlcLink(const PlcLinkOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("PLC link: " + why);
  return options.role == "client" ? OpenModbusClient(options) : OpenModbusServer(options);
}

bool EncodeOutputs(const RegisterMap& map, const PlcOutputs& outputs, int base_address, std::uint16_t* words) {
  bool in_range = true;
  const auto put = [&](const RegisterField& field, std::int64_t count) {
    in_range = EncodeCount(field, count, words + (field.address - base_address)) && in_range;
  };
  // llround of a non-finite value is undefined: such a value is out of every range.
  const auto counts = [&](double value, const RegisterField& field) -> std::int64_t {
    const double c = value / field.scale;
    if (!std::isfinite(c)) {
      in_range = false;
      return 0;
    }
    return static_cast<std::int64_t>(std::llround(std::clamp(c, -9.0e18, 9.0e18)));
  };
  put(map.fix_x, counts(outputs.x_mm, map.fix_x));
  put(map.fix_y, counts(outputs.y_mm, map.fix_y));
  put(map.fix_yaw, counts(outputs.yaw_rad, map.fix_yaw));
  put(map.fix_status, outputs.status);
  put(map.fix_quality, outputs.quality);
  put(map.fix_mode, outputs.mode);
  // The counters wrap like the PLC's own: only their low bits are written.
  const auto wrapped = [](std::uint32_t value, const RegisterField& field) -> std::int64_t {
    const std::uint64_t modulus = std::uint64_t{1} << field.width_bits;
    const auto v = static_cast<std::int64_t>(value % modulus);
    return field.is_signed && v > field.MaxCount() ? v - static_cast<std::int64_t>(modulus) : v;
  };
  put(map.fix_request_echo, wrapped(outputs.request_echo, map.fix_request_echo));
  put(map.heartbeat, wrapped(outputs.heartbeat, map.heartbeat));
  return in_range;
}

core::Timestamp MonotonicNow() {
  return core::Timestamp::FromNanoseconds(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
          .count());
}

bool HeartbeatMonitor::Update(core::Timestamp time, std::uint32_t value) {
  if (!last_change_ || value != last_value_) {
    last_change_ = time;
    last_value_ = value;
  }
  return stale(time);
}

bool HeartbeatMonitor::stale(core::Timestamp now) const {
  if (timeout_ <= core::Duration::zero()) return false;
  return !last_change_ || now - *last_change_ > timeout_;
}

core::Timestamp CountersChangedAt(core::Timestamp previous_read, core::Timestamp read, core::Duration counter_period) {
  const core::Timestamp since =
      counter_period > core::Duration::zero() ? std::max(previous_read, read - counter_period) : previous_read;
  return since + (read - since) / 2;
}

namespace detail {

ModbusContext NewContext(const PlcLinkOptions& options, bool server) {
  modbus_t* context = nullptr;
  if (options.transport == "tcp") {
    const bool any = server && (options.host == "0.0.0.0" || options.host.empty());
    context = modbus_new_tcp(any ? nullptr : options.host.c_str(), options.port);
  } else {
    context = modbus_new_rtu(options.device.c_str(), options.baud, options.parity[0], options.data_bits,
                             options.stop_bits);
  }
  if (context == nullptr) {
    core::ThrowInvalidInput(fmt::format("PLC link: libmodbus refused {}: {}", options.Describe(), modbus_strerror(errno)));
  }
  ModbusContext owned(context);
  if (modbus_set_slave(context, options.unit_id) != 0) {
    core::ThrowInvalidInput(fmt::format("PLC link: unit_id {}: {}", options.unit_id, modbus_strerror(errno)));
  }
  const auto timeout_us = static_cast<std::uint32_t>(std::lround(options.response_timeout_ms * 1000.0));
  modbus_set_response_timeout(context, timeout_us / 1000000U, timeout_us % 1000000U);
  // Between the bytes of one answer, too: libmodbus' default of 0.5 s let a PLC that sent half
  // an answer hold the cycle that long.
  modbus_set_byte_timeout(context, timeout_us / 1000000U, timeout_us % 1000000U);
  return owned;
}

RegisterRange RangeOf(const std::vector<const RegisterField*>& fields) {
  int low = 65536;
  int high = 0;
  for (const RegisterField* field : fields) {
    low = std::min(low, field->address);
    high = std::max(high, field->address + field->words());
  }
  return {low, high - low};
}

InputDecoder::InputDecoder(const RegisterMap& map)
    : map_(map) {
  for (const RegisterField* field : map.Counters()) unwrappers_.emplace_back(field->width_bits);
}

std::int32_t InputDecoder::Ticks(const RegisterField& field, CounterUnwrapper* unwrapper, std::int64_t count) {
  const std::int64_t extended = unwrapper->Update(count);
  const auto ticks = field.scale == 1.0 ? extended : static_cast<std::int64_t>(std::llround(extended * field.scale));
  // Odometry takes counters modulo 2^32.
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(static_cast<std::uint64_t>(ticks) & 0xFFFFFFFFU));
}

PlcInputs InputDecoder::Decode(const std::uint16_t* words, int base) {
  const auto at = [&](const RegisterField& field) { return DecodeCount(field, words + (field.address - base)); };
  PlcInputs inputs;
  if (map_.kind == core::DriveKind::kTricycle) {
    inputs.counts.drive_ticks = Ticks(map_.drive_ticks, &unwrappers_[0], at(map_.drive_ticks));
    // An absolute angle: its count as read (scaled), never unwrapped.
    const std::int64_t steering = at(map_.steering_ticks);
    inputs.counts.steering_ticks = static_cast<std::int32_t>(
        map_.steering_ticks.scale == 1.0 ? steering : std::llround(static_cast<double>(steering) * map_.steering_ticks.scale));
  } else if (map_.kind == core::DriveKind::kMecanum) {
    inputs.counts.left_ticks = Ticks(map_.front_left_ticks, &unwrappers_[0], at(map_.front_left_ticks));
    inputs.counts.right_ticks = Ticks(map_.front_right_ticks, &unwrappers_[1], at(map_.front_right_ticks));
    inputs.counts.rear_left_ticks = Ticks(map_.rear_left_ticks, &unwrappers_[2], at(map_.rear_left_ticks));
    inputs.counts.rear_right_ticks = Ticks(map_.rear_right_ticks, &unwrappers_[3], at(map_.rear_right_ticks));
  } else {
    inputs.counts.left_ticks = Ticks(map_.left_ticks, &unwrappers_[0], at(map_.left_ticks));
    inputs.counts.right_ticks = Ticks(map_.right_ticks, &unwrappers_[1], at(map_.right_ticks));
  }
  inputs.plc_heartbeat = static_cast<std::uint32_t>(at(map_.plc_heartbeat));
  inputs.fix_request = static_cast<std::uint32_t>(at(map_.fix_request));
  inputs.relocalize_request = static_cast<std::uint32_t>(at(map_.relocalize_request));
  return inputs;
}

}  // namespace detail
}  // namespace mosaicloc::io
