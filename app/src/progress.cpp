#include "progress.hpp"

#include <unistd.h>

#include <cstdio>

namespace mosaicloc::app {

ProgressBar::ProgressBar(std::string label, bool quiet, std::string on_stop)
    : label_(std::move(label)), quiet_(quiet), on_stop_(std::move(on_stop)), terminal_(::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()) {}

ProgressBar::~ProgressBar() { Finish(); }

void ProgressBar::Update(double fraction) {
  if (const auto reason = core::StopSignals::Reason(); reason && !finished_) {
    finished_ = true;
    if (terminal_ && !quiet_ && last_percent_ >= 0) std::fprintf(stderr, "\n");
    throw core::Stopped(core::StopSignals::Signal(), label_ + ": " + *reason + " at " +
                                                         std::to_string(static_cast<int>(fraction * 100.0)) +
                                                         " %: " + on_stop_);
  }
  Draw(fraction);
}

void ProgressBar::Draw(double fraction) {
  if (quiet_ || finished_) return;
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const int percent = static_cast<int>(fraction * 100.0);
  if (terminal_) {
    if (percent == last_percent_) return;
    last_percent_ = percent;
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(fraction * kWidth);
    std::fprintf(stderr, "\r%s [%.*s%*s] %3d%% %5.1f s", label_.c_str(), filled,
                 "==============================", kWidth - filled, "", percent, elapsed_s);
    std::fflush(stderr);
  } else {
    const int quarter = static_cast<int>(fraction * 4.0);
    if (quarter == last_quarter_ || quarter == 0) return;
    last_quarter_ = quarter;
    std::fprintf(stderr, "%s: %d%% (%.1f s)\n", label_.c_str(), quarter * 25, elapsed_s);
  }
}

void ProgressBar::Finish() {
  if (quiet_ || finished_) return;
  Draw(1.0);  // the work may end between two updates: always show completion
  finished_ = true;
  if (terminal_ && last_percent_ >= 0) std::fprintf(stderr, "\n");
}

}  // namespace mosaicloc::app
