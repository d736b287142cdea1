#pragma once

#include <atomic>
#include <filesystem>
#include <memory>
#include <optional>

#include "mosaicloc/calibration/ground.hpp"
#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/io/frame_source.hpp"
#include "mosaicloc/sim/simulator.hpp"

namespace mosaicloc::runtime {

/// How a recording is played in real time: dataset time `origin` (the earlier of its first
/// frame and first encoder sample) happens at `start` on the monotonic clock. The camera
/// source and the PLC simulator compute the same origin, so started with the same wall-clock
/// instant they play in step.
struct Playback {
  core::Timestamp origin;  ///< dataset clock
  core::Timestamp start;   ///< monotonic clock

  /// start_unix_s: when to start, seconds since the Unix epoch (0: now).
  static Playback Of(const dataset::DatasetReader& reader, double start_unix_s);
  /// Dataset time `origin` at start_unix_s (0: now).
  static Playback Starting(core::Timestamp origin, double start_unix_s);
  core::Timestamp ToMonotonic(core::Timestamp dataset_time) const { return start + (dataset_time - origin); }
  core::Timestamp ToDataset(core::Timestamp monotonic) const { return origin + (monotonic - start); }
};

/// Sleeps until `when` on the monotonic clock, in slices, returning early (false) when
/// `stop` is set.
bool SleepUntil(core::Timestamp when, const std::atomic<bool>& stop);

/// The frames of a drive of the built-in simulator, each rendered when it is due and delivered
/// at its capture instant, stamped on the monotonic clock, as a camera would deliver them: no
/// recording is written, so a drive of hours plays as well as one of seconds. `plc-sim
/// --simulate` with the same simulator options plays the same drive's encoder counts (the
/// simulator is deterministic; both count the drive's time from 0 at the same start instant).
/// A frame that takes longer to render than the frame period comes late, as from a slow camera.
class SimulatedFrameSource final : public io::FrameSource {
 public:
  SimulatedFrameSource(std::shared_ptr<const sim::PlannedDrive> drive, double start_unix_s);
  std::optional<io::CapturedFrame> Next() override;
  void Stop() override { stop_ = true; }
  std::string Describe() const override;

 private:
  std::shared_ptr<const sim::PlannedDrive> drive_;
  Playback playback_;
  std::size_t next_ = 0;
  std::atomic<bool> stop_{false};
};

/// A recorded dataset's frames delivered in real time and stamped on the monotonic clock,
/// as a camera would deliver them.
class DatasetFrameSource final : public io::FrameSource {
 public:
  DatasetFrameSource(const std::filesystem::path& directory, double start_unix_s);
  std::optional<io::CapturedFrame> Next() override;
  void Stop() override { stop_ = true; }
  std::string Describe() const override;
  const dataset::DatasetInfo& info() const { return reader_.info(); }
  const Playback& playback() const { return playback_; }

 private:
  dataset::DatasetReader reader_;
  dataset::DatasetReader::FrameStream frames_;
  Playback playback_;
  std::int64_t sequence_ = 0;
  std::atomic<bool> stop_{false};
};

/// A real camera's raw frames made ideal (calibration::Rectifier, from the ground calibration)
/// before they enter the pipeline: what every source of raw images is wrapped in.
class RectifyingFrameSource final : public io::FrameSource {
 public:
  /// Throws core::Error (invalid input) if the calibration fails its check.
  RectifyingFrameSource(std::unique_ptr<io::FrameSource> raw, const calibration::GroundCalibration& calibration);
  /// The next frame, rectified. Throws core::Error (runtime) naming the source when a frame
  /// is not the calibrated raw size.
  std::optional<io::CapturedFrame> Next() override;
  void Stop() override { raw_->Stop(); }
  std::string Describe() const override;
  std::int64_t dropped() const override { return raw_->dropped(); }

 private:
  std::unique_ptr<io::FrameSource> raw_;
  calibration::Rectifier rectifier_;
};

}  // namespace mosaicloc::runtime
