#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/calibration/ground.hpp"
#include "mosaicloc/calibration/intrinsics.hpp"
#include "mosaicloc/camera/board.hpp"

namespace mosaicloc::calibration {

/// The files a shell pattern (e.g. 'cal/*.png') matches, sorted. Throws core::Error
/// (invalid input) quoting the pattern when none does.
std::vector<std::filesystem::path> MatchImages(const std::string& pattern);

/// An image file as 8-bit grey. Throws core::Error (invalid input) naming the file when it
/// cannot be read as an image.
cv::Mat ReadGreyImage(const std::filesystem::path& file);

/// The board detected in every image (a view without points where it is not found); all
/// images must have the size of the first, which goes to *width and *height. Throws
/// core::Error (invalid input) naming an image of another size.
std::vector<BoardView> DetectBoardInImages(const std::vector<std::filesystem::path>& files,
                                           const camera::BoardSpec& board, int* width, int* height);

/// `calibrate intrinsics`: the board found in the photographs a pattern matches, the
/// intrinsics calibrated with ViSP and OpenCV, ViSP's written to `camera_xml` as `camera_name`.
/// Throws core::Error (invalid input) when the board is in none of them.
struct ImagesIntrinsics {
  IntrinsicsResult result;
  int width_px = 0, height_px = 0;
};
ImagesIntrinsics CalibrateIntrinsicsFromImages(const std::string& pattern, const camera::BoardSpec& board,
                                               const std::filesystem::path& camera_xml, const std::string& camera_name);

/// `calibrate ground`: the floor plane from raw images of `board` lying on it, through the
/// intrinsics of `camera_xml`, written to `out`. Throws core::Error (invalid input) when the
/// images are not of the intrinsics' size or the options fail Check().
GroundResult CalibrateGroundFromImages(const std::string& pattern, const camera::BoardSpec& board,
                                       const std::filesystem::path& camera_xml, const std::string& camera_name,
                                       const GroundOptions& options, const std::filesystem::path& out);

/// Every raw image made ideal and written as OUT_DIR/<its name>.png (the folder is made).
/// Throws core::Error (invalid input) naming an image not of the calibrated raw size, before
/// anything is written.
void RectifyImages(const std::vector<std::filesystem::path>& files, const Rectifier& rectifier,
                   const std::filesystem::path& out_dir);

/// A raw photograph of `board` on the floor, rectified and measured (`calibrate verify`).
/// Throws core::Error (invalid input) naming the image when it is not of the calibrated raw
/// size or the board is not found in it once rectified.
IdealBoardMeasurement MeasureRectifiedBoard(const std::filesystem::path& file, const Rectifier& rectifier,
                                            const camera::BoardSpec& board);

/// `calibrate verify`: every photograph matching `pattern`, rectified with the ground
/// calibration in `ground` and measured, and the largest scale error among them.
struct RectificationCheck {
  std::vector<std::pair<std::filesystem::path, IdealBoardMeasurement>> images;
  double worst_scale_error = 0.0;  ///< relative: 0.001 is 0.1 %
};
/// Throws core::Error (invalid input) as MeasureRectifiedBoard and ReadGroundCalibration do.
RectificationCheck VerifyRectification(const std::string& pattern, const std::filesystem::path& ground,
                                       const camera::BoardSpec& board);

}  // namespace mosaicloc::calibration
