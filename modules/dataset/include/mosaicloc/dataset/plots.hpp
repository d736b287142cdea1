#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "mosaicloc/dataset/evaluation.hpp"

namespace mosaicloc::dataset {

/// Writes three 1000 x 800 PNG plots of an evaluation into `directory` (created if missing),
/// each written atomically (temporary file, then rename):
///  - trajectory.png: top view of the world frame (x right, y up, equal scales, metres), the
///    ground truth as a thin grey line and the estimates as dots coloured by position error,
///    with a colour bar in mm;
///  - position_error.png: position error [mm] against time since the first sample [s], with the
///    RMS and p99 as dashed lines;
///  - heading_error.png: signed heading error [deg] against time [s].
/// `title` heads every plot (ASCII; other characters are drawn as '?'). An evaluation without
/// samples gives plots that say so. Throws core::Error (runtime) if a file cannot be written.
void WritePlots(const std::filesystem::path& directory, const Evaluation& evaluation,
                const std::string& title);

/// The camera's height over the floor against time: what the localizer held at each frame
/// and the truth, mm, with the time in seconds since the first frame.
struct HeightSeries {
  std::vector<double> seconds;
  std::vector<double> estimate_mm;
  std::vector<double> truth_mm;
};
/// Writes height.png (1000 x 800) into `directory`: the truth as a grey line, the estimate in
/// blue, and `error_rms_mm` (estimate - truth at the fixes) in the subtitle. Atomic.
void WriteHeightPlot(const std::filesystem::path& directory, const HeightSeries& series, const std::string& title,
                     double error_rms_mm);

}  // namespace mosaicloc::dataset
