#include "mosaicloc/estimation/lock.hpp"

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::estimation {

const char* ToString(LockState state) {
  switch (state) {
    case LockState::kTracking: return "tracking";
    case LockState::kDegraded: return "degraded";
    case LockState::kLost: return "lost";
    case LockState::kOffMap: return "off-map";
    case LockState::kSearching: return "searching";
  }
  return "unknown";
}

bool LockOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (degraded_after_misses < 1) return fail("degraded_after_misses must be >= 1");
  if (lost_after_misses < degraded_after_misses) return fail("lost_after_misses must be >= degraded_after_misses");
  if (regain_after_fixes < 1) return fail("regain_after_fixes must be >= 1");
  if (!(lost_above_sigma_mm > 0.0)) return fail("lost_above_sigma_mm must be > 0");
  return true;
}

LockMonitor::LockMonitor(const LockOptions& options) : options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("lock options: " + why);
}

LockState LockMonitor::Update(FrameVerdict verdict, double position_sigma_mm, const std::string& reason) {
  if (verdict == FrameVerdict::kFixed) {
    misses_ = 0;
    ++fixes_in_a_row_;
    if (state_ == LockState::kOffMap || state_ == LockState::kSearching) state_ = LockState::kDegraded;
    if (state_ != LockState::kTracking && fixes_in_a_row_ >= options_.regain_after_fixes) {
      state_ = LockState::kTracking;
    }
    return state_;
  }
  last_reason_ = reason;
  fixes_in_a_row_ = 0;
  if (verdict == FrameVerdict::kOffMap || verdict == FrameVerdict::kSearching) {
    // Neither is a loss: off the map no fix was expected, and a search starts from no lock.
    state_ = verdict == FrameVerdict::kOffMap ? LockState::kOffMap : LockState::kSearching;
    return state_;
  }
  ++misses_;
  LockState next = state_;
  if (misses_ >= options_.lost_after_misses || position_sigma_mm > options_.lost_above_sigma_mm) {
    next = LockState::kLost;
  } else if (misses_ >= options_.degraded_after_misses && state_ == LockState::kTracking) {
    next = LockState::kDegraded;
  } else if (state_ == LockState::kOffMap || state_ == LockState::kSearching) {
    next = LockState::kDegraded;  // back on the map (or the search ended), not fixed yet
  }
  if (next == LockState::kLost && (state_ == LockState::kTracking || state_ == LockState::kDegraded)) ++losses_;
  state_ = next;
  return state_;
}

}  // namespace mosaicloc::estimation
