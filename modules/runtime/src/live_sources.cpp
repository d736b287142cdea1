#include "mosaicloc/runtime/live_sources.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include <fmt/format.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/io/plc_link.hpp"

namespace mosaicloc::runtime {

Playback Playback::Of(const dataset::DatasetReader& reader, double start_unix_s) {
  auto frames = reader.Frames();
  auto encoders = reader.Encoders();
  const auto first_frame = frames.Next(/*decode=*/false);
  const auto first_sample = encoders.Next();
  if (!first_frame && !first_sample) core::ThrowInvalidInput(reader.directory().string() + ": the dataset is empty");
  return Starting(first_frame && first_sample ? std::min(first_frame->time, first_sample->time)
                  : first_frame               ? first_frame->time
                                              : first_sample->time,
                  start_unix_s);
}

Playback Playback::Starting(core::Timestamp origin, double start_unix_s) {
  Playback playback;
  playback.origin = origin;
  const core::Timestamp now = io::MonotonicNow();
  playback.start = now;
  if (start_unix_s > 0.0) {
    const double wall_now_s =
        std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    playback.start = now + core::FromSeconds(start_unix_s - wall_now_s);
  }
  return playback;
}

bool SleepUntil(core::Timestamp when, const std::atomic<bool>& stop) {
  while (!stop) {
    const core::Duration left = when - io::MonotonicNow();
    if (left <= core::Duration::zero()) return true;
    std::this_thread::sleep_for(std::min<core::Duration>(left, std::chrono::milliseconds(20)));
  }
  return false;
}

SimulatedFrameSource::SimulatedFrameSource(std::shared_ptr<const sim::PlannedDrive> drive, double start_unix_s)
    : drive_(std::move(drive)), playback_(Playback::Starting(core::Timestamp(), start_unix_s)) {}

std::optional<io::CapturedFrame> SimulatedFrameSource::Next() {
  if (stop_ || next_ >= drive_->capture_s().size()) return std::nullopt;
  io::CapturedFrame captured;
  captured.time = playback_.ToMonotonic(core::Timestamp::FromSeconds(drive_->capture_s()[next_]));
  captured.image = drive_->RenderFrame(next_);
  if (!SleepUntil(captured.time, stop_)) return std::nullopt;
  captured.sequence = static_cast<std::int64_t>(next_++);
  return captured;
}

std::string SimulatedFrameSource::Describe() const {
  const dataset::CameraInfo& camera = drive_->info().camera;
  return fmt::format("the simulator, {} frames rendered as they are due ({}x{}, {:.0f} s)", drive_->capture_s().size(),
                     camera.width_px, camera.height_px, drive_->capture_s().back());
}

DatasetFrameSource::DatasetFrameSource(const std::filesystem::path& directory, double start_unix_s)
    : reader_(directory), frames_(reader_.Frames()), playback_(Playback::Of(reader_, start_unix_s)) {}

std::optional<io::CapturedFrame> DatasetFrameSource::Next() {
  std::optional<dataset::Frame> frame = frames_.Next();
  if (!frame || stop_) return std::nullopt;
  io::CapturedFrame captured;
  captured.time = playback_.ToMonotonic(frame->time);
  if (!SleepUntil(captured.time, stop_)) return std::nullopt;
  captured.image = std::move(frame->image);
  captured.sequence = sequence_++;
  return captured;
}

std::string DatasetFrameSource::Describe() const {
  return fmt::format("recording {} played in real time ({}x{})", reader_.directory().string(),
                     reader_.info().camera.width_px, reader_.info().camera.height_px);
}

RectifyingFrameSource::RectifyingFrameSource(std::unique_ptr<io::FrameSource> raw,
                                             const calibration::GroundCalibration& calibration)
    : raw_(std::move(raw)), rectifier_(calibration) {}

std::optional<io::CapturedFrame> RectifyingFrameSource::Next() {
  std::optional<io::CapturedFrame> frame = raw_->Next();
  if (!frame) return std::nullopt;
  cv::Mat ideal;
  if (!rectifier_.Rectify(frame->image, &ideal)) {
    const calibration::Intrinsics& raw = rectifier_.calibration().intrinsics;
    core::ThrowRuntime(fmt::format("{}: a {}x{} frame (type {}) where the ground calibration expects {}x{} 8-bit grey",
                                   raw_->Describe(), frame->image.cols, frame->image.rows, frame->image.type(),
                                   raw.width_px, raw.height_px));
  }
  frame->image = std::move(ideal);
  return frame;
}

std::string RectifyingFrameSource::Describe() const {
  const camera::IdealCameraOptions& ideal = rectifier_.calibration().ideal;
  return fmt::format("{}, rectified to {}x{} at {} mm/px", raw_->Describe(), ideal.width_px, ideal.height_px,
                     ideal.mm_per_px);
}

}  // namespace mosaicloc::runtime
