#include "mosaicloc/sim/raw_recordings.hpp"

#include <chrono>
#include <cstdio>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <yaml-cpp/yaml.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/trajectory.hpp"
#include "mosaicloc/sim/raw_imaging.hpp"

namespace mosaicloc::sim {
namespace {

std::string Numbered(const char* stem, std::size_t index) {
  char name[64];
  std::snprintf(name, sizeof(name), "%s-%02zu.png", stem, index + 1);
  return name;
}
}  // namespace

bool CalibrationPhotographsOptions::Check(std::string* why) const {
  if (!board.Check(why) || !floor_board.Check(why)) return false;
  if (shots < 3 || shots > 100) {
    *why = "calibration photographs: shots must be in [3, 100]";
    return false;
  }
  return true;
}

CalibrationPhotographs WriteCalibrationPhotographs(const CalibrationPhotographsOptions& options,
                                                   const std::filesystem::path& out) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  const camera::RealCameraOptions truth = CalibrationTruthCamera();
  const std::vector<BoardShot> shots =
      RenderIntrinsicsShots(truth, options.board, options.shots, 0.42, RawImagingOptions{}, options.seed);
  // The floor board in the four quadrants of the view, so the fitted plane spans the image.
  const camera::RealCamera mounted(truth);
  const std::vector<core::Pose2> placements = {
      {-62.0, -42.0, 0.05}, {-18.0, -42.0, -0.05}, {-62.0, -8.0, 0.0}, {-18.0, -8.0, 0.05}, {-42.0, -30.0, -0.08}};
  const double scale = options.floor_board.pitch_mm / 10.0;
  // 16 x 16 samples per pixel: with fewer, an edge that runs along the pixel grid (the third
  // placement) moves in steps of a quarter pixel, which no real camera does, and its corners
  // err by 0.1 px: enough to tilt the fitted floor by 10^-4 rad.
  RawImagingOptions floor_imaging;
  floor_imaging.supersampling = 16;
  std::vector<cv::Mat> floor_images;
  for (std::size_t i = 0; i < placements.size(); ++i) {
    const core::Pose2 placement(placements[i].translation_mm() * scale, placements[i].yaw_rad());
    floor_images.push_back(
        RenderBoardRaw(mounted, options.floor_board, placement, floor_imaging, options.seed * 1000 + i));
  }
  std::filesystem::create_directories(out / "intrinsics");
  std::filesystem::create_directories(out / "ground");
  for (std::size_t i = 0; i < shots.size(); ++i) dataset::WritePng(out / "intrinsics" / Numbered("board", i), shots[i].image);
  for (std::size_t i = 0; i < floor_images.size(); ++i) {
    dataset::WritePng(out / "ground" / Numbered("floor", i), floor_images[i]);
  }
  YAML::Emitter yaml;
  yaml.SetDoublePrecision(17);
  yaml << YAML::Comment("The simulated camera the images were made with (camera::RealCamera).");
  yaml << YAML::BeginMap;
  yaml << YAML::Key << "fx_px" << YAML::Value << truth.fx_px << YAML::Key << "fy_px" << YAML::Value << truth.fy_px;
  yaml << YAML::Key << "cx_px" << YAML::Value << truth.cx_px << YAML::Key << "cy_px" << YAML::Value << truth.cy_px;
  yaml << YAML::Key << "k1" << YAML::Value << truth.k1;
  yaml << YAML::Key << "height_mm" << YAML::Value << truth.height_mm;
  yaml << YAML::Key << "tilt_x_rad" << YAML::Value << truth.tilt_x_rad;
  yaml << YAML::Key << "tilt_y_rad" << YAML::Value << truth.tilt_y_rad;
  yaml << YAML::Key << "board" << YAML::Value << options.board.ToString();
  yaml << YAML::Key << "floor_board" << YAML::Value << options.floor_board.ToString();
  yaml << YAML::EndMap;
  core::WriteFileAtomically(out / "truth.yaml", std::string(yaml.c_str()) + "\n");
  return {static_cast<int>(shots.size()), static_cast<int>(floor_images.size())};
}

std::int64_t WriteRawDrive(const std::filesystem::path& drive, const SimulatorOptions& simulator,
                           const std::filesystem::path& out, bool overwrite,
                           const std::function<void(double)>& progress) {
  const dataset::DatasetReader reader(drive);
  if (!reader.HasGroundTruth()) core::ThrowInvalidInput(drive.string() + ": needs ground truth");
  const auto floor = MakeFloor(simulator.floor);
  const dataset::Trajectory truth = reader.GroundTruth();
  // A simulated calibration drive records nominal values in dataset.yaml and its truth in
  // the provenance; the raw images must be made at the true mounting.
  const std::optional<dataset::VehicleTruth> recorded = dataset::RecordedVehicleTruth(reader.info());
  const core::Pose2 vehicle_from_camera =
      recorded ? recorded->vehicle_from_camera : reader.info().camera.vehicle_from_camera;
  const camera::RealCamera raw_camera(CalibrationTruthCamera());
  RawImagingOptions imaging;
  imaging.noise_std_dn = simulator.imaging.noise_std_dn;
  imaging.black_dn = 0.0;
  imaging.white_dn = 255.0;
  dataset::CameraInfo raw_info = reader.info().camera;
  raw_info.width_px = raw_camera.options().width_px;
  raw_info.height_px = raw_camera.options().height_px;
  dataset::DatasetWriter writer(
      out, dataset::DerivedInfo(reader, raw_info, "raw images of the simulated real camera (calibrate simulate-raw)"),
      overwrite);
  std::int64_t total = 0;
  for (auto listing = reader.Frames(); listing.Next(/*decode=*/false);) ++total;
  std::int64_t count = 0;
  for (auto frames = reader.Frames(); auto frame = frames.Next(/*decode=*/false);) {
    const auto world_from_vehicle = dataset::PoseAt(truth, frame->time, std::chrono::milliseconds(100));
    if (!world_from_vehicle) core::ThrowInvalidInput(frame->path.string() + ": no ground truth at its time");
    writer.AddFrame(frame->time, RenderFloorRaw(raw_camera, *floor, *world_from_vehicle * vehicle_from_camera, imaging,
                                                simulator.seed * 7919 + static_cast<std::uint64_t>(count)));
    ++count;
    if (progress) progress(static_cast<double>(count) / static_cast<double>(std::max<std::int64_t>(1, total)));
  }
  dataset::CopyEncodersAndTruth(reader, &writer);
  writer.Commit();
  return count;
}

}  // namespace mosaicloc::sim
