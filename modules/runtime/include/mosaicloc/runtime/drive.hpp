#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <unordered_map>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/dataset/camera_truth.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/trajectory.hpp"

namespace mosaicloc::runtime {

/// What the pipelines read of a recorded or simulated drive besides its frames.

/// The dataset's ideal camera.
camera::IdealCamera CameraOf(const dataset::DatasetInfo& info);

/// The dataset's ground truth, when it has one.
std::optional<dataset::Trajectory> GroundTruthOf(const dataset::DatasetReader& reader);

/// The camera's calibrated height over the floor the dataset notes (provenance
/// camera_height_mm), if it does. Throws core::Error (invalid input, naming `dataset`) for a
/// note that is not a positive number.
std::optional<double> CalibratedHeightMm(const std::filesystem::path& dataset, const dataset::DatasetInfo& info);

/// How a frame's camera looked at the floor beyond its pose: its height over the floor against
/// the calibrated height (the floor a pixel shows, relative to mm_per_px) and its tilt against
/// the floor (dataset::CameraTruth's axes). What a map is painted with (MapBuilder::AddFrame).
struct FrameView {
  double scale = 1.0;
  double tilt_x_rad = 0.0;
  double tilt_y_rad = 0.0;
};
/// Each frame's view by its time in ns, from rows of camera.csv's format.
std::unordered_map<std::int64_t, FrameView> FrameViews(const std::vector<dataset::CameraTruthSample>& views,
                                                       double calibrated_height_mm);

/// The ground truth of where the camera looked, from a simulated drive that records its
/// camera's geometry (dataset::kCameraTruthFile): its poses moved by each view's centre offset
/// (dataset::ViewPoses), and each frame's view. Without that file, or without a calibrated
/// height, the ground truth as it is and no views. Throws core::Error (invalid input) where the
/// dataset has no ground truth or either file is malformed (naming file and line).
struct ViewTruth {
  dataset::Trajectory world_from_vehicle;
  std::unordered_map<std::int64_t, FrameView> views;
  double focal_px = 0.0;  ///< the calibrated height over mm_per_px, where there are views
};
ViewTruth ViewTruthOf(const std::filesystem::path& dataset, const dataset::DatasetReader& reader);

/// Where the drive starts (as a localizer is told at installation, or the map's frame is
/// chosen): the ground truth at `time`, else its first pose; without ground truth, the start
/// pose a live recording noted in its provenance ("x_mm,y_mm,yaw_deg"), else the origin.
core::Pose2 StartPose(const std::optional<dataset::Trajectory>& groundtruth, const dataset::DatasetInfo& info,
                      core::Timestamp time);

/// The wheel encoders integrated from `start` (dead reckoning), one pose per accepted sample.
/// Rejected samples are logged and skipped, and counted in `rejected`. Throws core::Error
/// (invalid input) when no sample is accepted.
dataset::Trajectory WheelTrajectory(const dataset::DatasetReader& reader, const core::Pose2& start,
                                    std::int64_t* rejected);

}  // namespace mosaicloc::runtime
