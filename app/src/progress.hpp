#pragma once

#include <chrono>
#include <functional>
#include <string>

#include "mosaicloc/core/stop_signals.hpp"

namespace mosaicloc::app {

/// A progress bar on standard error for work that takes over a second. Redrawn in place on
/// a terminal; elsewhere (CI logs) a line at every 25 %. Silent when quiet.
///
/// While it lives, SIGINT and SIGTERM stop the work at its next update instead of killing the
/// process: Update throws core::Stopped, naming the job, how far it got and `on_stop` (what
/// the stopped job keeps and how to go on), and the job's destructors leave its files as its
/// contract says (nothing half-written).
class ProgressBar {
 public:
  ProgressBar(std::string label, bool quiet, std::string on_stop = "nothing was written");
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  /// Draws the fraction done; throws core::Stopped once a stop signal arrived.
  void Update(double fraction);
  /// Update as the progress callback a library job takes.
  std::function<void(double)> Callback() {
    return [this](double fraction) { Update(fraction); };
  }
  /// Draws only, for a job that is given core::StopSignals::Reason and ends itself early
  /// with what it has (a stop signal then does not throw out of it).
  std::function<void(double)> DrawCallback() {
    return [this](double fraction) { Draw(fraction); };
  }
  void Finish();

 private:
  void Draw(double fraction);

  std::string label_;
  bool quiet_;
  std::string on_stop_;
  bool terminal_;
  bool finished_ = false;
  int last_quarter_ = -1;
  int last_percent_ = -1;
  std::chrono::steady_clock::time_point start_;
  core::StopSignals signals_;
};

}  // namespace mosaicloc::app
