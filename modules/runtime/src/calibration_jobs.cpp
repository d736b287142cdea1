#include "mosaicloc/runtime/calibration_jobs.hpp"

#include <cstddef>
#include <numbers>
#include <optional>

#include "mosaicloc/calibration/board_images.hpp"
#include "mosaicloc/calibration/ground.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/sim/config.hpp"
#include "mosaicloc/sim/raw_recordings.hpp"

namespace mosaicloc::runtime {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

nlohmann::json EstimateJson(const calibration::IntrinsicsEstimate& e) {
  const calibration::Intrinsics& k = e.intrinsics;
  return {{"fx_px", k.fx_px}, {"fy_px", k.fy_px}, {"cx_px", k.cx_px}, {"cy_px", k.cy_px},
          {"kud", k.kud},     {"kdu", k.kdu},     {"rms_px", e.rms_px}};
}

}  // namespace

nlohmann::json IntrinsicsJson(const calibration::ImagesIntrinsics& calibrated, const camera::BoardSpec& board,
                              const std::filesystem::path& camera_xml) {
  const calibration::IntrinsicsResult& result = calibrated.result;
  nlohmann::json images = nlohmann::json::array();
  for (const calibration::ViewReport& view : result.views) {
    images.push_back(view.used ? nlohmann::json{{"image", view.name}, {"used", true}, {"visp_rms_px", view.visp_rms_px},
                                                {"opencv_rms_px", view.opencv_rms_px}}
                               : nlohmann::json{{"image", view.name}, {"used", false},
                                                {"rejected_because", view.rejected_because}});
  }
  return {{"camera_xml", camera_xml.string()},   {"width_px", calibrated.width_px},
          {"height_px", calibrated.height_px},   {"board", board.ToString()},
          {"visp", EstimateJson(result.visp)},   {"opencv", EstimateJson(result.opencv)},
          {"images", images}};
}

nlohmann::json GroundJson(const calibration::GroundResult& result, const std::filesystem::path& out) {
  const calibration::GroundCalibration& c = result.calibration;
  nlohmann::json images = nlohmann::json::array();
  for (const calibration::GroundViewReport& view : result.views) {
    images.push_back({{"image", view.name},
                      {"residual_rms_mm", view.residual_rms_mm},
                      {"residual_max_mm", view.residual_max_mm},
                      {"scale_error_percent", 100.0 * view.scale_error}});
  }
  return {{"ground", out.string()},
          {"height_mm", c.height_mm()},
          {"tilt_deg", c.tilt_rad() * kDegPerRad},
          {"mm_per_px", c.ideal.mm_per_px},
          {"width_px", c.ideal.width_px},
          {"height_px", c.ideal.height_px},
          {"flatness_rms_mm", result.flatness_rms_mm},
          {"flatness_max_mm", result.flatness_max_mm},
          {"coverage", result.coverage},
          {"images", images}};
}

nlohmann::json RectificationCheckJson(const calibration::RectificationCheck& check) {
  nlohmann::json images = nlohmann::json::array();
  for (const auto& [file, m] : check.images) {
    images.push_back({{"image", file.filename().string()},
                      {"scale_error_percent", 100.0 * m.scale_error},
                      {"residual_rms_mm", m.residual_rms_mm},
                      {"residual_max_mm", m.residual_max_mm}});
  }
  return {{"images", images}, {"worst_scale_error_percent", 100.0 * check.worst_scale_error}};
}

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

nlohmann::json VehicleCalibrationJson(const calibration::VehicleDriveResult& drive, const std::filesystem::path& out) {
  const calibration::VehicleCalibrationResult& result = drive.calibration;
  nlohmann::json json = {{"frames", drive.frames},
                         {"steps", drive.steps},
                         {"consecutive_steps", drive.consecutive_steps},
                         {"not_registered", drive.not_registered},
                         {"iterations", result.iterations},
                         {"rms_translation_mm", result.rms_translation_mm},
                         {"rms_rotation_deg", result.rms_rotation_rad * kDegPerRad},
                         {"kind", core::ToString(drive.kind)}};
  const calibration::VehicleParameterNames& shown = calibration::ParameterNamesOf(drive.kind);
  for (std::size_t i = 0; i < drive.value.size(); ++i) {
    const double unit = shown.shown_per_value[i];
    nlohmann::json& value = json[shown.keys[i]];
    value = {{"value", drive.value[i] * unit}, {"sigma", drive.sigma[i] * unit}};
    if (drive.truth) {
      value["truth"] = (*drive.truth)[i] * unit;
      value["error"] = (drive.value[i] - (*drive.truth)[i]) * unit;
    }
  }
  if (!out.empty()) json["out"] = out.string();
  return json;
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
