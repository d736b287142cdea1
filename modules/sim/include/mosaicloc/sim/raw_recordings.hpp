#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "mosaicloc/camera/board.hpp"
#include "mosaicloc/sim/simulator.hpp"

namespace mosaicloc::sim {

/// Photographs for trying the calibration steps with a known truth (`calibrate simulate`):
/// a hand-held board for the intrinsics and a board on the floor for the ground plane, made
/// through CalibrationTruthCamera.
struct CalibrationPhotographsOptions {
  camera::BoardSpec board = {camera::BoardSpec::Kind::kChessboard, 9, 6, 20.0, 0.5};
  camera::BoardSpec floor_board = {camera::BoardSpec::Kind::kChessboard, 9, 6, 10.0, 0.5};
  int shots = 12;  ///< photographs of the hand-held board, 3 to 100
  std::uint64_t seed = 1;
  bool Check(std::string* why) const;
};

struct CalibrationPhotographs {
  int board_images = 0;  ///< OUT/intrinsics/board-NN.png
  int floor_images = 0;  ///< OUT/ground/floor-NN.png
};

/// Writes OUT/intrinsics/, OUT/ground/ and OUT/truth.yaml (the camera they were made with).
/// Throws core::Error on bad options or when a file cannot be written.
CalibrationPhotographs WriteCalibrationPhotographs(const CalibrationPhotographsOptions& options,
                                                   const std::filesystem::path& out);

/// The same drive seen through the simulated real camera: every frame of the dataset at
/// `drive` rendered raw (distorted, tilted: CalibrationTruthCamera) at its true camera pose,
/// over the floor of `simulator` (the configuration the drive was made with), with its
/// sensor noise; encoders and ground truth copied. The camera sits at the true mounting a
/// simulated calibration drive records in its provenance, else at the dataset's. Throws
/// core::Error (invalid input) naming the dataset when it has no ground truth; nothing is
/// left at `out` on failure. Returns the number of frames.
std::int64_t WriteRawDrive(const std::filesystem::path& drive, const SimulatorOptions& simulator,
                           const std::filesystem::path& out, bool overwrite,
                           const std::function<void(double)>& progress = {});

}  // namespace mosaicloc::sim
