#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/board.hpp"
#include "mosaicloc/camera/real_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/sim/floor.hpp"

namespace mosaicloc::sim {

/// How raw (distorted, tilted) images are formed through camera::RealCamera, for
/// calibration: no motion blur, no vignetting, evenly lit.
struct RawImagingOptions {
  /// Samples per pixel along each axis; each pixel is the mean over its square footprint.
  int supersampling = 4;
  double noise_std_dn = 1.0;  ///< additive Gaussian sensor noise, 8-bit digital numbers
  double black_dn = 25.0;     ///< what black print (or texel value 0) looks like
  double white_dn = 225.0;    ///< what white print (or texel value 255) looks like
  bool Check(std::string* why) const;
};

/// The raw image of `board` lying on the floor, its board frame B at `camera_from_board`
/// in the camera floor frame C (board z up, out of the floor). Floor outside the board is
/// white paper too (the board's margin extends to infinity). CV_8UC1, camera's size.
/// Deterministic for a seed. Throws core::Error (invalid input) on bad options.
cv::Mat RenderBoardRaw(const camera::RealCamera& camera, const camera::BoardSpec& board,
                       const core::Pose2& camera_from_board, const RawImagingOptions& options, std::uint64_t seed);

/// The raw image of a floor texture with the camera floor frame C at `world_from_camera`:
/// what the real camera sees where the ideal camera (same C) would see its ideal image.
cv::Mat RenderFloorRaw(const camera::RealCamera& camera, const Floor& floor, const core::Pose2& world_from_camera,
                       const RawImagingOptions& options, std::uint64_t seed);

/// One simulated photograph of a board: the camera's pose over the board (height and tilt
/// in `camera`, the board's place in the floor frame C in `camera_from_board`) and the image.
struct BoardShot {
  camera::RealCameraOptions camera;
  core::Pose2 camera_from_board;
  cv::Mat image;
};

/// The real camera the simulated calibration photographs and raw drives are made with (the
/// truth `calibrate simulate` writes beside them, and the calibration tests hold their
/// results to): a 640x480 floor camera with fx 812, fy 806, principal point (326.4, 233.7)
/// px, barrel distortion k1 = -0.14, 200 mm above the floor, tilted by 0.035 rad about the
/// image x axis and -0.02 rad about the image y axis.
camera::RealCameraOptions CalibrationTruthCamera();

/// `count` photographs of `board` for intrinsic calibration, as an integrator takes them:
/// the intrinsics of `camera`, the camera tilted by up to `max_tilt_rad` about both axes,
/// at 0.8-1.4 times the height where the board spans 70 % of the image width, the board
/// turned and shifted, every feature at least one pitch inside the image. Deterministic.
std::vector<BoardShot> RenderIntrinsicsShots(const camera::RealCameraOptions& camera, const camera::BoardSpec& board,
                                             int count, double max_tilt_rad, const RawImagingOptions& options,
                                             std::uint64_t seed);

}  // namespace mosaicloc::sim
