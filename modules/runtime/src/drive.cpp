#include "mosaicloc/runtime/drive.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <numbers>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/dataset/camera_truth.hpp"
#include "mosaicloc/estimation/odometry.hpp"
#include "mosaicloc/runtime/settings.hpp"

namespace mosaicloc::runtime {

camera::IdealCamera CameraOf(const dataset::DatasetInfo& info) {
  return camera::IdealCamera(
      camera::IdealCameraOptions{info.camera.width_px, info.camera.height_px, info.camera.mm_per_px});
}

std::optional<double> CalibratedHeightMm(const std::filesystem::path& dataset, const dataset::DatasetInfo& info) {
  const auto calibrated = info.provenance.find("camera_height_mm");
  if (calibrated == info.provenance.end()) return std::nullopt;
  char* end = nullptr;
  const double height_mm = std::strtod(calibrated->second.c_str(), &end);
  if (end == calibrated->second.c_str() || *end != '\0' || !(height_mm > 0.0)) {
    core::ThrowInvalidInput(dataset.string() + ": provenance camera_height_mm '" + calibrated->second +
                            "' is not a positive number");
  }
  return height_mm;
}

ViewTruth ViewTruthOf(const std::filesystem::path& dataset, const dataset::DatasetReader& reader) {
  ViewTruth truth{reader.GroundTruth(), {}};
  const std::filesystem::path file = dataset / dataset::kCameraTruthFile;
  const std::optional<double> calibrated_mm = CalibratedHeightMm(dataset, reader.info());
  std::error_code ec;
  if (!calibrated_mm || !std::filesystem::exists(file, ec)) return truth;
  const std::vector<dataset::CameraTruthSample> views = dataset::ReadCameraTruth(file);
  truth.world_from_vehicle = dataset::ViewPoses(truth.world_from_vehicle, views);
  truth.focal_px = *calibrated_mm / reader.info().camera.mm_per_px;
  truth.views = FrameViews(views, *calibrated_mm);
  return truth;
}

std::unordered_map<std::int64_t, FrameView> FrameViews(const std::vector<dataset::CameraTruthSample>& views,
                                                       double calibrated_height_mm) {
  std::unordered_map<std::int64_t, FrameView> by_time;
  by_time.reserve(views.size());
  for (const dataset::CameraTruthSample& view : views) {
    by_time.emplace(view.time.nanoseconds(), FrameView{view.truth.height_mm / calibrated_height_mm,
                                                       view.truth.tilt_x_rad, view.truth.tilt_y_rad});
  }
  return by_time;
}

core::Pose2 StartPose(const std::optional<dataset::Trajectory>& groundtruth, const dataset::DatasetInfo& info,
                      core::Timestamp time) {
  if (groundtruth) {
    return dataset::PoseAt(*groundtruth, time, std::chrono::seconds(1))
        .value_or(groundtruth->front().world_from_vehicle);
  }
  const auto noted = info.provenance.find("start_pose");
  if (noted == info.provenance.end()) return core::Pose2::Identity();
  double x = 0.0, y = 0.0, yaw_deg = 0.0;
  if (std::sscanf(noted->second.c_str(), "%lf,%lf,%lf", &x, &y, &yaw_deg) != 3) {
    core::ThrowInvalidInput("dataset.yaml: provenance.start_pose: '" + noted->second +
                            "' is not x_mm,y_mm,yaw_deg");
  }
  return core::Pose2(x, y, yaw_deg * std::numbers::pi / 180.0);
}

std::optional<dataset::Trajectory> GroundTruthOf(const dataset::DatasetReader& reader) {
  if (!reader.HasGroundTruth()) return std::nullopt;
  return reader.GroundTruth();
}

dataset::Trajectory WheelTrajectory(const dataset::DatasetReader& reader, const core::Pose2& start,
                                    std::int64_t* rejected) {
  const localizer::LocalizerOptions geometry = LocalizerOptionsFor(
      localizer::LocalizerOptions{}, reader.info().camera, reader.info().vehicle, 0.0);
  estimation::WheelOdometry odometry(geometry.odometry, start);
  dataset::Trajectory integrated;
  auto encoders = reader.Encoders();
  while (const auto sample = encoders.Next()) {
    const auto increment = odometry.Update(sample->time, sample->counts);
    if (!increment) {
      ++*rejected;
      core::Log().warn("{}: encoder sample at {} ns skipped: {}", reader.directory().string(),
                       sample->time.nanoseconds(), estimation::ToString(increment.error()));
      continue;
    }
    integrated.push_back({sample->time, odometry.world_from_vehicle()});
  }
  if (integrated.empty()) core::ThrowInvalidInput(reader.directory().string() + ": no encoder samples");
  if (*rejected > 0) core::Log().warn("{} encoder samples rejected", *rejected);
  return integrated;
}


}  // namespace mosaicloc::runtime
