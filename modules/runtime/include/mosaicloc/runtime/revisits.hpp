#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/dataset/trajectory.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::runtime {

struct RevisitOptions {
  /// The places and visits: as the truth-based repeatability finds them (10 mm, every 100 mm),
  /// along the estimate instead of the truth.
  dataset::EvaluationOptions places;
  /// The uncertainty of the relative pose two estimates imply, which sizes the registration's
  /// search: far above a fix's (micrometres), far below what would let the matcher wander.
  double prior_sigma_mm = 1.0;
  double prior_sigma_deg = 0.2;
  /// At most this many revisited places are registered (spread evenly over them): the first
  /// visits' frames are held in memory until the drive has passed them again.
  std::int64_t max_places = 200;
  /// The registration cuts both frames into this many blocks and uses every pixel (the
  /// tracker's tiled templates): a revisit has time, and the yaw it measures moves the vehicle's
  /// origin by the camera's lever arm.
  int tile_cols = 4;
  int tile_rows = 3;
};

/// Repeatability from a recording alone (design.md section 4, revisit_*), at the camera's
/// centre: the point every fix measures, and the one whose view is the same floor when the
/// vehicle passes again (the vehicle's origin adds the heading error times the lever arm, and
/// a pass the other way shows the camera other floor). Along `fixed` (the estimate at the frames
/// that got a visual fix, time order), the places the camera passes more than once are found
/// as the truth-based repeatability finds them; every later visit's frame is registered
/// directly to the first visit's frame, and the camera's position the registration gives is
/// compared with the one the later estimate gives. The difference d (world frame, mm) is that
/// visit's camera error minus the first's, so the spread of d at a place (0 for the first
/// visit) is the spread of the camera's errors there: the truth-based definition
/// (repeatability_camera_mm), without the truth. The frames are read again from the dataset at
/// `dataset_dir`, and registered with the localizer's matcher (`tracker`) in tiled mode
/// (RevisitOptions). Visits whose registration fails are counted, not used.
struct RevisitFigures {
  std::optional<double> repeatability_mm;
  std::int64_t places = 0;    ///< places with at least two registered visits
  std::int64_t visits = 0;    ///< visits behind the figure (first visits included)
  std::int64_t failures = 0;  ///< later visits whose frame did not register to the first's
};
RevisitFigures MeasureRevisits(const std::filesystem::path& dataset_dir, const dataset::Trajectory& fixed,
                               const camera::IdealCamera& camera, const tracking::TrackerOptions& tracker,
                               const core::Pose2& vehicle_from_camera,
                               const RevisitOptions& options = {});

}  // namespace mosaicloc::runtime
