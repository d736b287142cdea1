#pragma once

#include <cstdint>
#include <string>

namespace mosaicloc::estimation {

/// Visual lock, as reported to the PLC (design.md section 6: 1 tracking, 2 degraded, 3 lost,
/// 4 off-map, 5 searching). Off-map: the prediction puts the camera's view (partly) off the
/// mapped floor, so no fix is expected and the estimate is dead reckoning; that is not a loss
/// of the lock. Searching: the pose is unknown (a start without one, a relocalization the PLC
/// asked for) and every frame is looked for on the whole map; there is no estimate.
enum class LockState { kTracking = 1, kDegraded = 2, kLost = 3, kOffMap = 4, kSearching = 5 };
const char* ToString(LockState state);

/// What one frame gave the lock.
enum class FrameVerdict {
  kFixed,   ///< a visual fix was accepted
  kMissed,  ///< no fix where the map says there should be one
  kOffMap,  ///< no fix, and the predicted view is (partly) off the map: none was expected
  kSearching,  ///< no fix, and the pose is unknown: the whole map was searched
};

struct LockOptions {
  int degraded_after_misses = 2;   ///< consecutive frames without a fix before "degraded"
  int lost_after_misses = 15;      ///< ... before "lost" (half a second at 30 Hz)
  int regain_after_fixes = 3;      ///< consecutive fixes to return to "tracking"
  /// Position standard deviation beyond which the lock is lost whatever the misses, mm.
  double lost_above_sigma_mm = 20.0;
  bool Check(std::string* why) const;
};

/// Lock state with hysteresis: it degrades after a few frames without a fix, is lost after
/// more (or when the position uncertainty grows too large), and needs several fixes in a row
/// to return to tracking. Frames predicted off the map put it in kOffMap, whatever the
/// uncertainty, without counting towards a loss; the first fix back on the map makes it
/// degraded. Counts every loss: a change to kLost from tracking or degraded (off-map to lost
/// is not one: the lock ended when the view left the map).
class LockMonitor {
 public:
  explicit LockMonitor(const LockOptions& options);
  /// One frame's outcome; `reason` (why there was no fix) is kept for reporting.
  LockState Update(FrameVerdict verdict, double position_sigma_mm, const std::string& reason = {});
  LockState state() const { return state_; }
  std::int64_t losses() const { return losses_; }
  const std::string& last_reason() const { return last_reason_; }

 private:
  LockOptions options_;
  LockState state_ = LockState::kTracking;
  int misses_ = 0;
  int fixes_in_a_row_ = 0;
  std::int64_t losses_ = 0;
  std::string last_reason_;
};

}  // namespace mosaicloc::estimation
