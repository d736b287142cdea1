#pragma once

#include <filesystem>
#include <string>

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

}  // namespace mosaicloc::dataset
