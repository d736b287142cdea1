#pragma once

#include <optional>
#include <string>

namespace mosaicloc::core {

/// While alive, SIGINT and SIGTERM ask a long-running job to stop instead of killing the
/// process; the default handlers come back when it goes, also when the job throws. One at
/// a time: the handlers are the process's.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
  /// Why to stop ("interrupted (SIGINT)", "terminated (SIGTERM)"), or nothing yet.
  static std::optional<std::string> Reason();
};

}  // namespace mosaicloc::core
