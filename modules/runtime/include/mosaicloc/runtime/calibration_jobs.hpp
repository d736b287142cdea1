#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <numbers>
#include <string>

#include <nlohmann/json.hpp>

#include "mosaicloc/calibration/board_images.hpp"
#include "mosaicloc/calibration/ground.hpp"
#include "mosaicloc/calibration/vehicle_drive.hpp"
#include "mosaicloc/camera/board.hpp"
#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/wheel_geometry.hpp"
#include "mosaicloc/sim/calibration_drive.hpp"

namespace mosaicloc::runtime {

/// What `mosaicloc calibrate board` wrote: the board and the image's size in pixels.
struct BoardPrint {
  camera::BoardSpec board;
  int width_px = 0, height_px = 0;
};
/// `mosaicloc calibrate board`: the board named by `spec` (camera::ParseBoardSpec) drawn at
/// `px_per_mm` and written to `out` as PNG (atomically). Throws core::Error for a bad spec.
BoardPrint WriteBoardImage(const std::string& spec, double px_per_mm, const std::filesystem::path& out);

/// `calibrate intrinsics --json`: the camera XML written, the images' size, the board, the ViSP
/// and the OpenCV estimates, and every image, used (with its residual in each) or why not.
nlohmann::json IntrinsicsJson(const calibration::ImagesIntrinsics& calibrated, const camera::BoardSpec& board,
                              const std::filesystem::path& camera_xml);

/// `calibrate ground --json`: the file written, the floor's distance and the optical axis's tilt,
/// the ideal image, the floor's flatness over all boards, the ideal image's coverage of the raw
/// one, and every image's residuals and scale error.
nlohmann::json GroundJson(const calibration::GroundResult& result, const std::filesystem::path& out);

/// `calibrate verify --json`: every rectified image's measure of the board, and the worst.
nlohmann::json RectificationCheckJson(const calibration::RectificationCheck& check);

/// What `calibrate intrinsics`, `ground` and `verify` print: the same figures as their JSON
/// forms, as tables (the images, then ViSP beside OpenCV; the floor and the ideal image).
std::string IntrinsicsText(const calibration::ImagesIntrinsics& calibrated, const camera::BoardSpec& board,
                           const std::filesystem::path& camera_xml, const std::string& camera_name);
std::string GroundText(const calibration::GroundResult& result, const std::filesystem::path& out);
std::string RectificationCheckText(const calibration::RectificationCheck& check);

/// `mosaicloc calibrate vehicle`: the camera's place on the vehicle and the wheel geometry
/// from a calibration drive (calibration::CalibrateVehicleFromDrive), written to `out` (YAML,
/// atomically) unless it is empty.
calibration::VehicleDriveResult CalibrateVehicle(const std::filesystem::path& dataset, const std::filesystem::path& out,
                                                 const std::function<void(double)>& progress = {});
/// `calibrate vehicle --json`: the drive's counts, the fit's residuals, each of the six values
/// in its shown unit (calibration::ParameterNamesOf) with its sigma, and with a known truth
/// the truth and the error; the file written when `out` is not empty.
nlohmann::json VehicleCalibrationJson(const calibration::VehicleDriveResult& drive, const std::filesystem::path& out);
/// What `calibrate vehicle` prints: the pairs registered, the fit's residuals, and each value
/// with its sigma (and the truth and the error where known).
std::string VehicleCalibrationText(const calibration::VehicleDriveResult& drive, const std::filesystem::path& out);

/// `mosaicloc calibrate rectify`: every raw image matching `pattern` made ideal with the
/// ground calibration in `ground`, written into `out_dir` under its own name. Returns the
/// number of images.
std::size_t RectifyImageFiles(const std::filesystem::path& ground, const std::string& pattern,
                              const std::filesystem::path& out_dir);

struct RectifiedDataset {
  std::int64_t frames = 0;
  camera::IdealCameraOptions ideal;  ///< the camera of the written dataset
};

/// `mosaicloc calibrate rectify-dataset`: a recording of raw frames made ideal with the ground
/// calibration `ground`; with a vehicle calibration (`vehicle` not empty), its
/// vehicle_from_camera goes in the written dataset. Written as a whole or not at all
/// (calibration::RectifyDataset).
RectifiedDataset RectifyRecording(const std::filesystem::path& dataset, const std::filesystem::path& ground,
                                  const std::filesystem::path& vehicle, const std::filesystem::path& out,
                                  bool overwrite);

/// `mosaicloc calibrate simulate-raw`: a simulated dataset seen through the simulated real
/// camera; `config` is the simulator configuration it was made with (its floor), or empty for
/// the defaults. Returns the frames written.
std::int64_t SimulateRawRecording(const std::filesystem::path& dataset, const std::filesystem::path& config,
                                  const std::filesystem::path& out, bool overwrite,
                                  const std::function<void(double)>& progress = {});

/// `mosaicloc calibrate simulate-drive`: the calibration drive of a vehicle of the given kind
/// (sim::CalibrationDriveFor), its floor and noise from `seed`, its camera turned by
/// `mounting_yaw_deg` on the vehicle.
struct CalibrationDriveJob {
  std::filesystem::path out;
  core::DriveKind kind = core::DriveKind::kDifferential;
  std::uint64_t seed = 1;
  double mounting_yaw_deg = sim::CalibrationDriveOptions{}.vehicle_from_camera.yaw_rad() * 180.0 / std::numbers::pi;
  double ramp_frames = 0.0;  ///< sim::CalibrationDriveOptions::ramp_frames
  bool overwrite = false;
};
struct SimulatedCalibrationDrive {
  sim::CalibrationDriveOptions options;  ///< as driven
  sim::CalibrationDriveSummary summary;
};
SimulatedCalibrationDrive SimulateCalibrationDrive(const CalibrationDriveJob& job);

}  // namespace mosaicloc::runtime
