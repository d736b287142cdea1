#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/dataset/trajectory.hpp"

namespace mosaicloc::dataset {

/// What the localizer reported for one frame (design.md section 4): a row of a replay
/// report's fixes.csv and of a live recording's fixes/data.csv.
struct FrameReport {
  core::Timestamp time;
  core::Pose2 world_from_vehicle;  ///< the visual fix when `fixed`, else the filter's estimate
  int status = 0;                  ///< design.md section 6: 1 tracking, 2 degraded, 3 lost, 4 off-map, 5 searching
  double quality = 0.0;            ///< 0..1 (written as 0..1000); 0 without a fix
  bool fixed = false;              ///< a visual fix was accepted for this frame
  double sigma_mm = 0.0;           ///< the estimate's position standard deviation after the frame
  /// The image scale the localizer holds after the frame: the camera's height over the floor
  /// against the calibrated one (1.0025: 0.5 mm higher at 200 mm); 1 where it is not estimated.
  double scale = 1.0;
  /// The normalized innovation squared of a fix the filter judged (accepted or rejected at its
  /// gate); empty otherwise.
  std::optional<double> nis;
  std::string reason;              ///< why no fix, one word ("off-map", "no-match", ...); empty with one
  /// What the localizer did with the frame (design.md section 7c): "track",
  /// "visual-odometry", "dead-reckoning", "searching"; empty in files written before the column.
  std::string mode;
};

/// The highest lock state fixes.csv holds (5, searching).
inline constexpr int kMaxStatus = 5;

/// The header line of fixes.csv, newline included.
std::string FixesCsvHeader();
/// One row of fixes.csv, newline included. A reason holding a comma, quote or line break is
/// invalid input (reasons are single words).
std::string FixesCsvRow(const FrameReport& report);

/// Reads fixes.csv; every line is validated (field count, numbers, status 0-5, quality
/// 0-1000, fix 0 or 1, scale in (0, 2), nis empty or not negative, mode one of its words or
/// empty, times increasing). Rows of nine fields (written before the scale column) read with
/// scale 1, rows of ten (before the nis column) without a NIS, rows of eleven (before the mode
/// column) without a mode. Throws core::Error (invalid input) "file:line:
/// reason" on the first bad line.
std::vector<FrameReport> ReadFixesCsv(const std::filesystem::path& file);

/// The frames' reports against ground truth: the wrong fixes are the visual fixes more than
/// `wrong_above_mm` from the true position (an AGV must never get one, however the lock
/// looks); frames off the map carry the dead-reckoning error.
struct FixCheck {
  std::int64_t checked_fixes = 0;  ///< fixes with ground truth at their time
  std::int64_t wrong_fixes = 0;
  std::optional<double> max_wrong_fix_mm;  ///< the largest error of a wrong fix; empty without one
  std::optional<double> max_fix_error_mm;  ///< the largest error of any checked fix
  std::optional<double> fix_error_rms_mm;  ///< RMS error of the checked fixes
  std::int64_t off_map_frames = 0;         ///< frames reported off-map (status 4)
  std::optional<double> off_map_max_error_mm;  ///< largest estimate error while off-map
};
FixCheck CheckFixes(const std::vector<FrameReport>& reports, const Trajectory& groundtruth,
                    double wrong_above_mm = 1.0);

/// Returns onto the map. `view_mapped[i]` is the share of frame i's true view that the map
/// covers (from the truth and the map). A return is the first frame whose view is wholly on
/// the map (share >= on_share) after one mostly off it (share < off_share): the vehicle left
/// the map and came back, rather than grazed its edge. Its first fix is the first after the
/// last frame mostly off the map, which may come while the view is still partly off it.
/// For each return: the frames from it to that fix (1 when the fix came at it or before),
/// counted to the end of its stretch on the map when none came, and the fix's error.
struct ReentryCheck {
  std::int64_t reentries = 0;
  std::optional<std::int64_t> frames_to_fix_max;  ///< empty without a return
  std::optional<double> first_fix_error_max_mm;   ///< empty when no return was fixed
};
/// `reports` and `view_mapped` hold the same frames in the same order (invalid input otherwise).
ReentryCheck CheckReentries(const std::vector<FrameReport>& reports, const std::vector<double>& view_mapped,
                            const Trajectory& groundtruth, double on_share = 0.98, double off_share = 0.5);

}  // namespace mosaicloc::dataset
