#include "mosaicloc/runtime/calibration_jobs.hpp"

#include <cstddef>
#include <numbers>
#include <optional>
#include <string>

#include <fmt/printf.h>

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

std::string IntrinsicsText(const calibration::ImagesIntrinsics& calibrated, const camera::BoardSpec& board,
                           const std::filesystem::path& camera_xml, const std::string& camera_name) {
  const calibration::IntrinsicsResult& result = calibrated.result;
  const int width = calibrated.width_px, height = calibrated.height_px;
  const std::size_t images_found = result.views.size();
  std::string out;
  out += fmt::sprintf("%zu of %zu images used (board %s, %dx%d px)\n", result.used.size(), images_found,
                      board.ToString().c_str(), width, height);
  out += fmt::sprintf("  %-28s %12s %12s\n", "image", "ViSP rms px", "OpenCV rms px");
  for (const calibration::ViewReport& view : result.views) {
    if (view.used) {
      out += fmt::sprintf("  %-28s %12.4f %12.4f\n", view.name.c_str(), view.visp_rms_px, view.opencv_rms_px);
    } else {
      out += fmt::sprintf("  %-28s rejected: %s\n", view.name.c_str(), view.rejected_because.c_str());
    }
  }
  const calibration::Intrinsics& v = result.visp.intrinsics;
  const calibration::Intrinsics& o = result.opencv.intrinsics;
  out += fmt::sprintf("  %-10s %14s %14s\n", "", "ViSP", "OpenCV");
  out += fmt::sprintf("  %-10s %14.3f %14.3f\n", "fx px", v.fx_px, o.fx_px);
  out += fmt::sprintf("  %-10s %14.3f %14.3f\n", "fy px", v.fy_px, o.fy_px);
  out += fmt::sprintf("  %-10s %14.3f %14.3f\n", "cx px", v.cx_px, o.cx_px);
  out += fmt::sprintf("  %-10s %14.3f %14.3f\n", "cy px", v.cy_px, o.cy_px);
  out += fmt::sprintf("  %-10s %14.6f %14.6f\n", "kud (k1)", v.kud, o.kud);
  out += fmt::sprintf("  %-10s %14.6f %14s\n", "kdu", v.kdu, "-");
  out += fmt::sprintf("  %-10s %14.4f %14.4f\n", "rms px", result.visp.rms_px, result.opencv.rms_px);
  out += fmt::sprintf("camera XML (ViSP): %s, camera '%s'\n", camera_xml.string().c_str(), camera_name.c_str());
  return out;
}

std::string GroundText(const calibration::GroundResult& result, const std::filesystem::path& out_file) {
  const calibration::GroundCalibration& c = result.calibration;
  const std::size_t image_count = result.views.size();
  std::string out;
  out += fmt::sprintf("floor %.3f mm below the camera, optical axis %.3f deg from vertical (%zu images)\n", c.height_mm(),
                      c.tilt_rad() * kDegPerRad, image_count);
  out += fmt::sprintf("  %-28s %14s %14s %14s\n", "image", "residual mm", "max mm", "scale error %");
  for (const auto& view : result.views) {
    out += fmt::sprintf("  %-28s %14.4f %14.4f %14.4f\n", view.name.c_str(), view.residual_rms_mm, view.residual_max_mm,
                        100.0 * view.scale_error);
  }
  out += fmt::sprintf("  floor flatness over all boards: rms %.4f mm, max %.4f mm\n", result.flatness_rms_mm,
                      result.flatness_max_mm);
  out += fmt::sprintf("ideal image %dx%d px at %.4f mm/px, %.1f %% of it inside the raw image: %s\n", c.ideal.width_px,
                      c.ideal.height_px, c.ideal.mm_per_px, 100.0 * result.coverage, out_file.string().c_str());
  return out;
}

std::string RectificationCheckText(const calibration::RectificationCheck& check) {
  std::string out;
  out += fmt::sprintf("  %-28s %14s %14s %14s\n", "image", "scale error %", "residual mm", "max mm");
  for (const auto& [file, m] : check.images) {
    out += fmt::sprintf("  %-28s %14.4f %14.4f %14.4f\n", file.filename().string().c_str(), 100.0 * m.scale_error,
                        m.residual_rms_mm, m.residual_max_mm);
  }
  out += fmt::sprintf("rectified images measure the board to within %.4f %% of its printed size\n",
                      100.0 * check.worst_scale_error);
  return out;
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

std::string VehicleCalibrationText(const calibration::VehicleDriveResult& drive, const std::filesystem::path& out_file) {
  std::string out;
  const calibration::VehicleCalibrationResult& result = drive.calibration;
  const calibration::VehicleParameters& value = drive.value;
  const calibration::VehicleParameters& sigma = drive.sigma;
  const std::optional<calibration::VehicleParameters>& truth = drive.truth;
  const calibration::VehicleParameterNames& shown = calibration::ParameterNamesOf(drive.kind);
  const auto& names = shown.labels;
  const auto& unit = shown.shown_per_value;
  out += fmt::sprintf("%d of %d consecutive frame pairs registered, %d pairs in all; residuals %.4f mm, %.5f deg per pair\n",
                      drive.consecutive_steps, drive.frames - 1, drive.steps, result.rms_translation_mm,
                      result.rms_rotation_rad * kDegPerRad);
  out += fmt::sprintf("  %-20s %14s %12s", "", "calibrated", "sigma");
  if (truth) out += fmt::sprintf(" %14s %12s", "truth", "error");
  out += fmt::sprintf("\n");
  for (std::size_t i = 0; i < 6; ++i) {
    out += fmt::sprintf("  %-20s %14.4f %12.4f", names[i], value[i] * unit[i], sigma[i] * unit[i]);
    if (truth) out += fmt::sprintf(" %14.4f %12.4f", (*truth)[i] * unit[i], (value[i] - (*truth)[i]) * unit[i]);
    out += fmt::sprintf("\n");
  }
  if (!out_file.empty()) out += fmt::sprintf("vehicle calibration: %s\n", out_file.string().c_str());
  return out;
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
