#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/core/timestamp.hpp"

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

}  // namespace mosaicloc::dataset
