#include "mosaicloc/dataset/camera_truth.hpp"

#include <cmath>
#include <fstream>
#include <limits>
#include <unordered_map>

#include <fmt/format.h>

#include "mosaicloc/core/error.hpp"
#include "text_fields.hpp"

namespace mosaicloc::dataset {

std::string CameraTruthHeader() { return "#timestamp_ns,height_mm,tilt_x_rad,tilt_y_rad,centre_dx_mm,centre_dy_mm\n"; }

std::string CameraTruthRow(core::Timestamp time, const CameraTruth& truth) {
  return fmt::format("{},{:.6f},{:.9f},{:.9f},{:.6f},{:.6f}\n", time.nanoseconds(), truth.height_mm, truth.tilt_x_rad,
                     truth.tilt_y_rad, truth.centre_offset_mm.x(), truth.centre_offset_mm.y());
}

std::vector<CameraTruthSample> ReadCameraTruth(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) core::ThrowInvalidInput(file.string() + ": cannot open");
  std::vector<CameraTruthSample> samples;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line.front() == '#') continue;
    const std::vector<std::string> f = detail::SplitCsv(line);
    if (f.size() != 6) {
      detail::LineError(file, number,
                        std::to_string(f.size()) +
                            " fields, 6 expected (timestamp_ns,height_mm,tilt_x_rad,tilt_y_rad,centre_dx_mm,centre_dy_mm)");
    }
    std::int64_t ns = 0;
    if (!detail::ParseInt64(f[0], &ns)) detail::LineError(file, number, "timestamp_ns '" + f[0] + "' is not an integer");
    static constexpr const char* kNames[] = {"", "height_mm", "tilt_x_rad", "tilt_y_rad", "centre_dx_mm", "centre_dy_mm"};
    double values[6] = {};
    for (std::size_t i = 1; i < 6; ++i) {
      const std::optional<double> value = detail::ParseDouble(f[i]);
      if (!value || !std::isfinite(*value)) {
        detail::LineError(file, number, std::string(kNames[i]) + " '" + f[i] + "' is not a number");
      }
      values[i] = *value;
    }
    if (!(values[1] > 0.0)) detail::LineError(file, number, "height_mm " + f[1] + " is not positive");
    for (std::size_t i : {2, 3}) {
      if (!(std::abs(values[i]) < 0.5)) detail::LineError(file, number, std::string(kNames[i]) + " " + f[i] + " is not within (-0.5, 0.5)");
    }
    CameraTruthSample sample;
    sample.time = core::Timestamp::FromNanoseconds(ns);
    if (!samples.empty() && sample.time <= samples.back().time) detail::LineError(file, number, "timestamp_ns does not increase");
    sample.truth = {values[1], values[2], values[3], Eigen::Vector2d(values[4], values[5])};
    samples.push_back(sample);
  }
  return samples;
}

Trajectory ViewPoses(const Trajectory& world_from_vehicle, const std::vector<CameraTruthSample>& views) {
  std::unordered_map<std::int64_t, Eigen::Vector2d> offsets;
  offsets.reserve(views.size());
  for (const CameraTruthSample& view : views) offsets.emplace(view.time.nanoseconds(), view.truth.centre_offset_mm);
  Trajectory moved = world_from_vehicle;
  for (StampedPose& sample : moved) {
    const auto it = offsets.find(sample.time.nanoseconds());
    if (it == offsets.end()) continue;
    const core::Pose2& pose = sample.world_from_vehicle;
    sample.world_from_vehicle = core::Pose2(pose.translation_mm() + pose.Rotation() * it->second, pose.yaw_rad());
  }
  return moved;
}

}  // namespace mosaicloc::dataset
