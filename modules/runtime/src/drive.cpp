#include "mosaicloc/runtime/drive.hpp"

#include <chrono>
#include <cstdio>
#include <numbers>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/estimation/odometry.hpp"
#include "mosaicloc/runtime/settings.hpp"

namespace mosaicloc::runtime {

camera::IdealCamera CameraOf(const dataset::DatasetInfo& info) {
  return camera::IdealCamera(
      camera::IdealCameraOptions{info.camera.width_px, info.camera.height_px, info.camera.mm_per_px});
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
