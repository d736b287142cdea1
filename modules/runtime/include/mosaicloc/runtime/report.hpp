#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/dataset/fixes.hpp"
#include "mosaicloc/dataset/report_plots.hpp"
#include "mosaicloc/dataset/trajectory.hpp"
#include "mosaicloc/localizer/localizer.hpp"
#include "mosaicloc/runtime/map_session.hpp"

namespace mosaicloc::runtime {

/// Writes a report directory (design.md section 4): estimate.tum, and when ground truth is
/// given metrics.json and the PNG plots. `metrics` carries what the caller knows (frames,
/// fixes, timing, wrong fixes); the evaluation fills the accuracy figures. Returns the final
/// metrics.
dataset::Metrics WriteReport(const std::filesystem::path& directory, const dataset::Trajectory& estimate,
                             const std::optional<dataset::Trajectory>& groundtruth, dataset::Metrics metrics,
                             const std::string& title);

/// `mosaicloc evaluate`: an estimated trajectory (TUM) against a reference (TUM), the report
/// written into `directory` titled by the estimate's file name. Throws core::Error (invalid
/// input) naming the file and line of a malformed TUM file.
dataset::Metrics EvaluateTrajectoryFiles(const std::filesystem::path& estimate,
                                         const std::filesystem::path& groundtruth,
                                         const std::filesystem::path& directory);

/// The map's mosaic under a drive (the reports' positions, with a margin), at the finest
/// pyramid level that keeps it within about 1600 pixels; unmapped floor white. Empty when
/// even the coarsest level would be too large, or there are no reports.
dataset::FloorPicture FloorPictureOf(const MapSession& map, const std::vector<dataset::FrameReport>& reports);

/// The row of fixes.csv for a localized frame: the visual fix when one was accepted, else
/// the filter's estimate, with the lock state as the PLC receives it.
dataset::FrameReport FrameReportOf(core::Timestamp time, const localizer::FrameOutcome& outcome);

}  // namespace mosaicloc::runtime
