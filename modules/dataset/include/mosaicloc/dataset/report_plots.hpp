#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/core/wheel_geometry.hpp"
#include "mosaicloc/dataset/fixes.hpp"

namespace mosaicloc::dataset {

/// A picture of the floor under a drive: grey pixels, and the world rectangle (mm) its outer
/// edges cover (x to the right, y up; image rows go down).
struct FloorPicture {
  cv::Mat image;  ///< CV_8UC1; empty: no picture
  double x0_mm = 0.0, x1_mm = 1.0, y0_mm = 0.0, y1_mm = 1.0;
};

/// Writes the drive drawn over the floor into `directory` (created if missing), two 1000 x 900
/// PNGs (atomic), with the world frame's
/// axes at the origin (when in view), a scale bar and a legend with counts:
///  - map_state.png: every frame's position, coloured by its lock state; frames without a fix
///    marked by reason (crosses);
///  - map_quality.png: the fixes coloured by their quality (0..1, a colour bar), the rest grey;
///  - map_mode.png (when the reports carry the localizer's mode): every frame coloured by it.
/// `floor` may be empty (no map: a white background). Needs no ground truth.
void WriteMapPlots(const std::filesystem::path& directory, const std::vector<FrameReport>& reports,
                   const FloorPicture& floor, const std::string& title);

/// One frame of a replay for the timelines; NaN where a value is unknown.
struct TimelineSample {
  double seconds = 0.0;     ///< since the first frame
  double quality = 0.0;     ///< the fix's, NaN without one
  double sigma_mm = 0.0;    ///< the estimate's position standard deviation after the frame
  double nis = 0.0;         ///< NaN where the filter judged no fix
  double speed_mps = 0.0;   ///< the estimate's
  double latency_ms = 0.0;  ///< processing time of the frame
  /// What the filter has learnt of the vehicle's calibration, NaN when not learnt: a
  /// differential drive's wheel scale errors (left, right, %), a tricycle's drive wheel scale
  /// error (%) and steering offset error (degrees).
  double calibration_first = 0.0;
  double calibration_second = 0.0;
  double height_mm = 0.0;   ///< the camera's height over the floor held, NaN when not estimated
};

/// Writes timelines.png into `directory` (created if missing; about 1000 x 1450, atomic): fix quality, position standard deviation (log),
/// NIS with its 95 % bound (log), speed, latency, the learnt calibration (the vehicle kind's)
/// and, when any sample has one, the camera's height, against time.
void WriteTimelines(const std::filesystem::path& directory, const std::vector<TimelineSample>& samples,
                    const std::string& title, core::DriveKind kind = core::DriveKind::kDifferential);

}  // namespace mosaicloc::dataset
