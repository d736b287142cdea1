#pragma once

#include <optional>
#include <stdexcept>
#include <string>

namespace mosaicloc::core {

/// While alive, SIGINT and SIGTERM ask a long-running job to stop instead of killing the
/// process; the default handlers come back when it goes, also when the job throws. A second
/// signal while the job is still stopping kills the process as the default handler would
/// (Ctrl-C twice). One at a time: the handlers are the process's.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
  /// Why to stop ("interrupted (SIGINT)", "terminated (SIGTERM)"), or nothing yet.
  static std::optional<std::string> Reason();
  /// The signal that asked to stop, or 0.
  static int Signal();
};

/// Thrown out of a long job a stop signal ended early. The message says where it stopped and
/// what is kept; the process exits with 128 + signal(), as a shell reports a killed program.
class Stopped : public std::runtime_error {
 public:
  Stopped(int signal, const std::string& message) : std::runtime_error(message), signal_(signal) {}
  int signal() const { return signal_; }

 private:
  int signal_;
};

}  // namespace mosaicloc::core
