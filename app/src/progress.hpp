#pragma once

#include <chrono>
#include <functional>
#include <string>

namespace mosaicloc::app {

/// A progress bar on standard error for work that takes over a second. Redrawn in place on
/// a terminal; elsewhere (CI logs) a line at every 25 %. Silent when quiet.
class ProgressBar {
 public:
  ProgressBar(std::string label, bool quiet);
  ~ProgressBar();
  void Update(double fraction);
  /// Update as the progress callback a library job takes.
  std::function<void(double)> Callback() {
    return [this](double fraction) { Update(fraction); };
  }
  void Finish();

 private:
  std::string label_;
  bool quiet_;
  bool terminal_;
  bool finished_ = false;
  int last_quarter_ = -1;
  int last_percent_ = -1;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace mosaicloc::app
