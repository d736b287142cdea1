#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/dataset/trajectory.hpp"

namespace mosaicloc::dataset {

/// Where a simulated dataset keeps the truth of its camera's geometry, frame by frame
/// (design.md section 4). Absent from recordings.
inline constexpr char kCameraTruthFile[] = "groundtruth/camera.csv";

/// The camera relative to the floor under the image centre: the lens's height over the
/// floor's tangent plane there (along its normal, mm), the camera's tilt against that normal
/// (rotations about the camera's x and y axes, rad), and where the image centre falls
/// relative to the nominal mounting point, in the vehicle frame (mm).
struct CameraTruth {
  double height_mm = 0.0;
  double tilt_x_rad = 0.0;
  double tilt_y_rad = 0.0;
  Eigen::Vector2d centre_offset_mm = Eigen::Vector2d::Zero();
};

struct CameraTruthSample {
  core::Timestamp time;
  CameraTruth truth;
};

/// The header line of camera.csv, newline included.
std::string CameraTruthHeader();
/// One row, newline included.
std::string CameraTruthRow(core::Timestamp time, const CameraTruth& truth);
/// Reads camera.csv; every line is validated (six fields, numbers, height > 0, |tilt| < 0.5
/// rad, times increasing). Throws core::Error (invalid input) "file:line: reason".
std::vector<CameraTruthSample> ReadCameraTruth(const std::filesystem::path& file);

/// A drive's ground truth where its camera's view lay: each pose of `world_from_vehicle` at a
/// time `views` records (to the nanosecond) moved by that view's centre offset, the others
/// kept. A body that pitches, rolls or stands on an uneven floor tilts the camera, which then
/// looks at floor beside its mounting point (a millimetre for 0.3 degrees at 200 mm): a map
/// painted at these poses holds the floor where it is, and they are what a mapping drive's
/// registrations measure.
Trajectory ViewPoses(const Trajectory& world_from_vehicle, const std::vector<CameraTruthSample>& views);

}  // namespace mosaicloc::dataset
