#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mosaicloc/calibration/board_detection.hpp"
#include "mosaicloc/camera/board.hpp"

namespace mosaicloc::calibration {

/// Pinhole intrinsics with one radial distortion term, in ViSP's vpCameraParameters
/// "perspective projection with distortion" model. For normalized undistorted coordinates
/// (x, y) = (X/Z, Y/Z) in the optical frame (x right, y down, z along the axis):
///   u = cx + fx x (1 + kud r^2),  v = cy + fy y (1 + kud r^2),  r^2 = x^2 + y^2,
/// which is camera::RealCamera with k1 = kud, k2 = 0, and OpenCV's model with k1 = kud and every
/// other coefficient zero. ViSP also stores the approximate inverse (pixel to normalized):
///   x = (u - cx)/fx (1 + kdu r_d^2),  r_d^2 = ((u - cx)/fx)^2 + ((v - cy)/fy)^2.
/// Pixel centres are at integer (u, v).
struct Intrinsics {
  int width_px = 0;
  int height_px = 0;
  double fx_px = 0.0;
  double fy_px = 0.0;
  double cx_px = 0.0;
  double cy_px = 0.0;
  double kud = 0.0;  ///< undistorted -> distorted, r^2 coefficient
  double kdu = 0.0;  ///< distorted -> undistorted, r^2 coefficient
  bool Check(std::string* why) const;
};

/// One calibration image: its name (for reports and errors) and the board found in it.
struct BoardView {
  std::string name;
  BoardDetection detection;
};

struct IntrinsicsOptions {
  /// A view is an outlier when its reprojection RMS exceeds both `outlier_factor` times the
  /// median view RMS and `outlier_min_rms_px`; outliers are dropped and the rest recalibrated.
  double outlier_factor = 3.0;
  double outlier_min_rms_px = 0.3;
  /// Views needed after rejection.
  int min_views = 3;
  bool Check(std::string* why) const;
};

/// A calibration's figures: intrinsics plus reprojection errors, RMS over all points of
/// sqrt(du^2 + dv^2), pixels (the figure OpenCV's calibrateCamera returns).
struct IntrinsicsEstimate {
  Intrinsics intrinsics;
  double rms_px = 0.0;
  std::vector<double> view_rms_px;  ///< per used view, in the order of IntrinsicsResult::used
};

struct ViewReport {
  std::string name;
  bool used = false;
  /// Why the view was left out (empty when used).
  std::string rejected_because;
  /// Reprojection RMS with ViSP's first calibration on all views, px.
  double first_pass_rms_px = 0.0;
  /// Reprojection RMS of the final ViSP and OpenCV calibrations, px (used views only).
  double visp_rms_px = 0.0;
  double opencv_rms_px = 0.0;
};

struct IntrinsicsResult {
  /// ViSP vpCalibration, virtual visual servoing with distortion, over the used views.
  IntrinsicsEstimate visp;
  /// OpenCV calibrateCamera on the same detections with the same model (k1 only, no
  /// tangential terms), for comparison.
  IntrinsicsEstimate opencv;
  std::vector<ViewReport> views;  ///< every input view, in input order
  std::vector<std::string> used;  ///< names of the views both calibrations used
};

/// Calibrates the intrinsics from views of `board` in images of width x height pixels.
/// ViSP is started from the image centre and a 60-degree field of view, pose by pose
/// (Lagrange then virtual visual servoing), then refines all views together without and then
/// with distortion. Outlier views (IntrinsicsOptions) are dropped once and the rest
/// recalibrated. Throws core::Error: invalid input when fewer than min_views views remain
/// (naming the rejected ones) or the options are bad; runtime when ViSP fails.
IntrinsicsResult CalibrateIntrinsics(const std::vector<BoardView>& views, const camera::BoardSpec& board, int width_px,
                                     int height_px, const IntrinsicsOptions& options);

/// Writes the intrinsics as ViSP camera XML (vpXmlParserCamera, perspective projection with
/// distortion) under `camera_name`, replacing `file` atomically. `note` goes in the file's
/// additional information. Throws core::Error (runtime) naming the file on failure.
void WriteVispCameraXml(const std::filesystem::path& file, const Intrinsics& intrinsics,
                        const std::string& camera_name, const std::string& note);

/// Reads camera `camera_name` (perspective projection with distortion) from ViSP camera XML;
/// an empty name takes the first camera. Throws core::Error (invalid input) naming the file.
Intrinsics ReadVispCameraXml(const std::filesystem::path& file, const std::string& camera_name);

/// Raw pixel of a point in the optical frame (Z > 0) with the model above.
Eigen::Vector2d ProjectWithDistortion(const Intrinsics& intrinsics, const Eigen::Vector3d& point_optical);
/// Normalized undistorted coordinates of a raw pixel: inverts the kud model by Newton's
/// method along the radius (kdu is not used: it is only approximate).
Eigen::Vector2d UndistortToNormalized(const Intrinsics& intrinsics, const Eigen::Vector2d& pixel);

}  // namespace mosaicloc::calibration
