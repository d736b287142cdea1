#pragma once

#include <cstdint>
#include <optional>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/trajectory.hpp"

namespace mosaicloc::runtime {

/// What the pipelines read of a recorded or simulated drive besides its frames.

/// The dataset's ideal camera.
camera::IdealCamera CameraOf(const dataset::DatasetInfo& info);

/// The dataset's ground truth, when it has one.
std::optional<dataset::Trajectory> GroundTruthOf(const dataset::DatasetReader& reader);

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
