#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "mosaicloc/camera/board.hpp"
#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/pose2.hpp"
#include "mosaicloc/calibration/intrinsics.hpp"

namespace mosaicloc::calibration {

/// Where the floor is under a real camera, and the ideal image made from its raw images.
///
/// The camera floor frame C (design.md section 3) is fixed by the floor and the camera:
/// origin at the foot of the perpendicular from the optical centre to the floor (the nadir),
/// z up, x along the floor projection of the optical x axis (image right), y = z × x (image
/// up). Expressed in the optical frame O (x right, y down, z along the optical axis), a floor
/// point p_C = (X, Y) is at
///   P_O = M (X, Y, 1)^T,  M = [x_C | y_C | o_C],
/// x_C, y_C the unit axes of C and o_C its origin (mm). For camera::RealCamera this is
/// M = Rx(tilt_x) Ry(tilt_y) diag(1, -1, h): the same frame C.
///
/// Ideal pixel (u, v) sees p_C = ((u - cx) s, -(v - cy) s), cx = (w - 1)/2, cy = (h - 1)/2, so
/// the undistorted raw pixel (homogeneous) is K M A (u, v, 1)^T with
///   A = [s 0 -s cx; 0 -s s cy; 0 0 1],  K = [fx 0 cx_raw; 0 fy cy_raw; 0 0 1],
/// and the raw pixel follows through the distortion of `intrinsics`.
struct GroundCalibration {
  Intrinsics intrinsics;
  camera::IdealCameraOptions ideal;
  Eigen::Matrix3d optical_from_floor = Eigen::Matrix3d::Identity();  ///< M above; columns mm-scaled only in o_C

  bool Check(std::string* why) const;
  /// The homography from ideal pixels to undistorted raw pixels, K M A.
  Eigen::Matrix3d UndistortedRawFromIdeal() const;
  /// Its inverse, normalized to h22 = 1: what turns an undistorted raw image ideal.
  Eigen::Matrix3d IdealFromUndistortedRaw() const;
  /// Raw pixel of an ideal pixel (through the distortion).
  Eigen::Vector2d RawFromIdeal(const Eigen::Vector2d& ideal_px) const;
  /// Floor point in C (mm) of a raw pixel; nothing if its ray does not reach the floor.
  std::optional<Eigen::Vector2d> FloorFromRaw(const Eigen::Vector2d& raw_px) const;
  /// Height of the optical centre above the floor, mm, and the optical axis' angle to the
  /// floor normal, rad.
  double height_mm() const;
  double tilt_rad() const;
};

struct GroundOptions {
  double mm_per_px = 0.25;  ///< of the ideal image
  int width_px = 0;         ///< of the ideal image; 0 = the raw image's
  int height_px = 0;
  bool Check(std::string* why) const;
};

/// How well one floor view fits the calibrated plane: its detected features mapped to the
/// floor (mm) against the board's layout after the best rigid (and similarity) fit.
struct GroundViewReport {
  std::string name;
  double residual_rms_mm = 0.0;   ///< after the best rigid fit
  double residual_max_mm = 0.0;
  double scale_error = 0.0;       ///< best similarity scale - 1 (dimensionless)
};

struct GroundResult {
  GroundCalibration calibration;
  std::vector<GroundViewReport> views;
  /// Distances of every feature of every view (posed by PnP) from the one fitted floor
  /// plane, mm: zero with one view; with several, how flat the floor is where they lay.
  double flatness_rms_mm = 0.0;
  double flatness_max_mm = 0.0;
  /// Fraction of ideal pixels whose raw source lies inside the raw image (1 = no border).
  double coverage = 0.0;
};

/// Calibrates the ground plane from views of `board` lying flat on the floor (at least one;
/// more, in different places, average the detection noise and measure flatness). Each view
/// is posed by PnP on the undistorted features; one plane is fitted to all features.
/// Throws core::Error (invalid input) if a view lacks the board or the options are bad.
GroundResult CalibrateGround(const std::vector<BoardView>& views, const camera::BoardSpec& board,
                             const Intrinsics& intrinsics, const GroundOptions& options);

/// Maps for cv::remap from the ideal image to the raw one (CV_32FC1, ideal size): ideal
/// pixel (u, v) takes raw pixel (map_x(v, u), map_y(v, u)).
void BuildRectificationMaps(const GroundCalibration& calibration, cv::Mat* map_x, cv::Mat* map_y);

/// Turns raw frames into ideal ones with the precomputed maps (bilinear; raw pixels outside
/// the image give 0). Thread-safe after construction.
class Rectifier {
 public:
  /// Throws core::Error (invalid input) if the calibration fails Check().
  explicit Rectifier(const GroundCalibration& calibration);
  const GroundCalibration& calibration() const { return calibration_; }
  /// False (and *ideal untouched) if `raw` is not CV_8UC1 of the calibrated raw size.
  bool Rectify(const cv::Mat& raw, cv::Mat* ideal) const;
  double coverage() const { return coverage_; }

 private:
  GroundCalibration calibration_;
  cv::Mat map_x_, map_y_;
  double coverage_ = 0.0;
};

/// The ground calibration file (YAML, documented in calib/README.md), written atomically.
/// Throws core::Error (runtime) naming the file when it cannot be written.
void WriteGroundCalibration(const std::filesystem::path& file, const GroundCalibration& calibration,
                            const std::string& provenance);
/// Reads it strictly: every key present, none unknown, the stored homography consistent with
/// the rest. Throws core::Error (invalid input) naming the file, line and key.
GroundCalibration ReadGroundCalibration(const std::filesystem::path& file);

/// A recording of raw images made ideal, as a camera source does it live: every frame of
/// the dataset at `raw` rectified, the header's camera made the ideal one (with the mounting
/// `vehicle_from_camera` when given, e.g. from a vehicle calibration), encoders and ground
/// truth copied. Throws core::Error (invalid input) naming the frame that is not of the
/// calibrated raw size; nothing is left at `out` on failure. Returns the number of frames.
std::int64_t RectifyDataset(const std::filesystem::path& raw, const Rectifier& rectifier, const std::string& note,
                            const std::optional<core::Pose2>& vehicle_from_camera, const std::filesystem::path& out,
                            bool overwrite);

}  // namespace mosaicloc::calibration

namespace mosaicloc::calibration {

/// A board seen in an ideal image, measured: its features in the camera floor frame C
/// against the board's layout after the best rigid and similarity fits.
struct IdealBoardMeasurement {
  double scale_error = 0.0;      ///< similarity scale - 1: the ideal image's scale error
  double residual_rms_mm = 0.0;  ///< after the rigid fit: what is left (non-flatness, distortion)
  double residual_max_mm = 0.0;
};

/// Measures `detection` (in an ideal image of `ideal`'s geometry) against `board`.
IdealBoardMeasurement MeasureIdealBoard(const BoardDetection& detection, const camera::BoardSpec& board,
                                        const camera::IdealCameraOptions& ideal);

}  // namespace mosaicloc::calibration
