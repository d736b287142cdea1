// mosaicloc as the Modbus client: it polls the PLC's input registers and writes the fixes.

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "modbus_common.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/io/plc_link.hpp"

namespace mosaicloc::io {
namespace {

using detail::ModbusContext;

class ModbusClient final : public PlcLink {
 public:
  explicit ModbusClient(const PlcLinkOptions& options)
      : options_(options),
        context_(detail::NewContext(options, /*server=*/false)),
        read_spans_(GroupIntoSpans(options_.registers.Inputs(), /*max_gap=*/8)),
        write_spans_(GroupIntoSpans(options_.registers.Outputs(), /*max_gap=*/0)),
        input_range_(detail::RangeOf(options_.registers.Inputs())),
        output_range_(detail::RangeOf(options_.registers.Outputs())),
        decoder_(options_.registers),
        backoff_(Milliseconds(options.reconnect_min_ms)) {}

  core::Result<PlcInputs> Read() override {
    if (!EnsureConnected()) return core::Fail(stats_.last_error);
    std::vector<std::uint16_t> words(static_cast<std::size_t>(input_range_.count), 0);
    const auto started = std::chrono::steady_clock::now();
    for (const RegisterSpan& span : read_spans_) {
      const int rc = modbus_read_registers(context_.get(), span.address, span.count,
                                           words.data() + (span.address - input_range_.base));
      if (rc != span.count) {
        ++stats_.read_errors;
        return core::Fail(Failed("read of " + span.Describe(), rc));
      }
    }
    const auto finished = std::chrono::steady_clock::now();
    ++stats_.reads;
    Recovered();
    PlcInputs inputs = decoder_.Decode(words.data(), input_range_.base);
    inputs.round_trip = finished - started;
    inputs.time = MonotonicNow() - (finished - started) / 2;
    stats_.last_round_trip_ms = std::chrono::duration<double, std::milli>(inputs.round_trip).count();
    return inputs;
  }

  core::Result<core::Duration> Write(const PlcOutputs& outputs) override {
    if (!EnsureConnected()) return core::Fail(stats_.last_error);
    std::vector<std::uint16_t> words(static_cast<std::size_t>(output_range_.count), 0);
    if (!EncodeOutputs(options_.registers, outputs, output_range_.base, words.data())) {
      ++stats_.out_of_range;
      core::Log().warn("PLC: a fix value did not fit its register and was clamped ({:.2f} mm, {:.2f} mm, {:.6f} rad)",
                       outputs.x_mm, outputs.y_mm, outputs.yaw_rad);
    }
    const auto started = std::chrono::steady_clock::now();
    for (const RegisterSpan& span : write_spans_) {
      const int rc = modbus_write_registers(context_.get(), span.address, span.count,
                                            words.data() + (span.address - output_range_.base));
      if (rc != span.count) {
        ++stats_.write_errors;
        return core::Fail(Failed("write of " + span.Describe(), rc));
      }
    }
    ++stats_.writes;
    Recovered();
    return core::Duration(std::chrono::steady_clock::now() - started);
  }

  PlcLinkStats stats() const override { return stats_; }

 private:
  static std::chrono::steady_clock::duration Milliseconds(double ms) {
    return std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double, std::milli>(ms));
  }

  // Connects when needed, no more often than the backoff allows.
  bool EnsureConnected() {
    if (connected_) return true;
    const auto now = std::chrono::steady_clock::now();
    if (now < next_attempt_) {
      stats_.last_error = fmt::format("not connected to {} (next attempt in {:.0f} ms)", options_.Describe(),
                                      std::chrono::duration<double, std::milli>(next_attempt_ - now).count());
      return false;
    }
    if (modbus_connect(context_.get()) != 0) {
      ++stats_.connect_failures;
      const std::string reason = modbus_strerror(errno);
      stats_.last_error = fmt::format("cannot connect to {}: {}", options_.Describe(), reason);
      if (!failing_) core::Log().warn("PLC: {}; retrying with backoff", stats_.last_error);
      failing_ = true;
      modbus_close(context_.get());
      next_attempt_ = now + backoff_;
      backoff_ = std::min(backoff_ * 2, Milliseconds(options_.reconnect_max_ms));
      return false;
    }
    connected_ = true;
    stats_.connected = true;
    ++stats_.connects;
    backoff_ = Milliseconds(options_.reconnect_min_ms);
    core::Log().info("PLC: connected to {}", options_.Describe());
    return true;
  }

  // Counts and logs a failed request, and makes sure a late reply cannot poison the next one.
  std::string Failed(const std::string& what, int rc) {
    const int error = errno;
    std::string message = fmt::format("PLC {} on {} failed: {}", what, options_.Describe(),
                                      rc < 0 ? modbus_strerror(error) : fmt::format("short answer ({} registers)", rc));
    const bool timeout = rc < 0 && error == ETIMEDOUT;
    if (timeout) ++stats_.timeouts;
    if (!failing_) core::Log().warn("{}", message);
    failing_ = true;
    stats_.last_error = message;
    // A reply that arrives after the timeout would be taken as the answer to the next
    // request. TCP: drop the connection, so it lands on a closed socket; the next cycle
    // reconnects at once. RTU: wait for it to arrive and discard it.
    const bool connection_broken = rc < 0 && (error == ECONNRESET || error == EPIPE || error == EBADF ||
                                              error == ECONNREFUSED || error == ENOTCONN);
    if (options_.transport == "tcp" && (timeout || connection_broken || rc >= 0 || error == EMBBADDATA ||
                                        error == EMBBADCRC || error == EMBBADSLAVE)) {
      modbus_close(context_.get());
      connected_ = false;
      stats_.connected = false;
      next_attempt_ = std::chrono::steady_clock::now();
    } else if (timeout || error == EMBBADCRC || error == EMBBADDATA) {
      std::this_thread::sleep_for(Milliseconds(options_.response_timeout_ms));
      modbus_flush(context_.get());
    }
    return message;
  }

  void Recovered() {
    if (failing_) core::Log().info("PLC: {} answers again", options_.Describe());
    failing_ = false;
  }

  PlcLinkOptions options_;
  ModbusContext context_;
  std::vector<RegisterSpan> read_spans_;
  std::vector<RegisterSpan> write_spans_;
  detail::RegisterRange input_range_;
  detail::RegisterRange output_range_;
  detail::InputDecoder decoder_;
  bool connected_ = false;
  bool failing_ = false;
  std::chrono::steady_clock::duration backoff_;
  std::chrono::steady_clock::time_point next_attempt_{};
  PlcLinkStats stats_;
};

}  // namespace

std::unique_ptr<PlcLink> OpenModbusClient(const PlcLinkOptions& options) {
  return std::make_unique<ModbusClient>(options);
}

}  // namespace mosaicloc::io
