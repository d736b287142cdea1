#include "mosaicloc/runtime/calibration_jobs.hpp"

#include <numbers>
#include <optional>

#include "mosaicloc/calibration/board_images.hpp"
#include "mosaicloc/calibration/ground.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/sim/config.hpp"
#include "mosaicloc/sim/raw_recordings.hpp"

namespace mosaicloc::runtime {

BoardPrint WriteBoardImage(const std::string& spec, double px_per_mm, const std::filesystem::path& out) {
  BoardPrint print;
  print.board = camera::ParseBoardSpec(spec);
  const cv::Mat image = camera::DrawBoard(print.board, px_per_mm);
  dataset::WritePng(out, image);
  print.width_px = image.cols;
  print.height_px = image.rows;
  return print;
}

calibration::VehicleDriveResult CalibrateVehicle(const std::filesystem::path& dataset, const std::filesystem::path& out,
                                                 const std::function<void(double)>& progress) {
  calibration::VehicleDriveResult drive = calibration::CalibrateVehicleFromDrive(dataset, {}, progress);
  if (!out.empty()) calibration::WriteVehicleCalibration(out, drive, dataset);
  return drive;
}

std::size_t RectifyImageFiles(const std::filesystem::path& ground, const std::string& pattern,
                              const std::filesystem::path& out_dir) {
  const calibration::Rectifier rectifier(calibration::ReadGroundCalibration(ground));
  const std::vector<std::filesystem::path> files = calibration::MatchImages(pattern);
  calibration::RectifyImages(files, rectifier, out_dir);
  return files.size();
}

RectifiedDataset RectifyRecording(const std::filesystem::path& dataset, const std::filesystem::path& ground,
                                  const std::filesystem::path& vehicle, const std::filesystem::path& out,
                                  bool overwrite) {
  const calibration::Rectifier rectifier(calibration::ReadGroundCalibration(ground));
  std::optional<core::Pose2> mounting;
  if (!vehicle.empty()) mounting = calibration::ReadVehicleCalibration(vehicle).vehicle_from_camera;
  RectifiedDataset result;
  result.frames = calibration::RectifyDataset(
      dataset, rectifier, "rectified with " + ground.filename().string() + " (calibrate rectify-dataset)", mounting,
      out, overwrite);
  result.ideal = rectifier.calibration().ideal;
  return result;
}

std::int64_t SimulateRawRecording(const std::filesystem::path& dataset, const std::filesystem::path& config,
                                  const std::filesystem::path& out, bool overwrite,
                                  const std::function<void(double)>& progress) {
  const sim::SimulatorOptions options = sim::SimulatorConfigOrDefaults(config);
  return sim::WriteRawDrive(dataset, options, out, overwrite, progress);
}

SimulatedCalibrationDrive SimulateCalibrationDrive(const CalibrationDriveJob& job) {
  SimulatedCalibrationDrive drive;
  sim::CalibrationDriveOptions& options = drive.options;
  options = sim::CalibrationDriveFor(job.kind);
  options.seed = job.seed;
  options.floor.seed = job.seed;
  options.vehicle_from_camera = core::Pose2(options.vehicle_from_camera.x_mm(), options.vehicle_from_camera.y_mm(),
                                            job.mounting_yaw_deg * std::numbers::pi / 180.0);
  options.ramp_frames = job.ramp_frames;
  drive.summary = sim::WriteCalibrationDrive(options, job.out, job.overwrite);
  return drive;
}

}  // namespace mosaicloc::runtime
