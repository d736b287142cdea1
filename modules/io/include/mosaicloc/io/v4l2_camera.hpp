#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mosaicloc/core/timestamp.hpp"
#include "mosaicloc/io/frame_source.hpp"
#include "mosaicloc/io/pixel_format.hpp"

namespace mosaicloc::io {

struct V4l2Options {
  std::string device = "/dev/video0";
  int width_px = 640;
  int height_px = 480;
  /// "auto" takes the first the camera offers of grey, yuyv, mjpeg (least work first).
  std::string pixel_format = "auto";
  double frame_rate_hz = 60.0;
  /// Manual exposure, us (a downward camera under a strobe wants it short and fixed);
  /// negative leaves the camera's automatic exposure on.
  double exposure_us = -1.0;
  /// Analogue gain in the driver's units; negative leaves it as it is.
  int gain = -1;
  int buffers = 4;  ///< mmap streaming buffers
  bool Check(std::string* why) const;
};

/// The capture instant on the monotonic clock, from a V4L2 buffer's timestamp. Drivers that
/// stamp with the monotonic clock (V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC, nearly all today) are
/// taken as they are; a driver stamping with the wall clock is shifted by the offset between
/// the clocks; a driver that stamps nothing gets the dequeue time.
core::Timestamp DriverTimestampToMonotonic(std::int64_t driver_ns, std::uint32_t buffer_flags,
                                           core::Timestamp monotonic_now, std::int64_t realtime_now_ns);

/// A V4L2 camera streaming through mmap buffers (opened through libv4l2, so its format
/// emulation and device quirks apply). Frames are converted to 8-bit luminance and stamped
/// with the driver's capture time on the monotonic clock.
class V4l2Camera final : public FrameSource {
 public:
  /// Opens, configures and starts streaming. Throws core::Error naming the device when it
  /// is absent, is not a streaming capture device, or takes none of the formats.
  explicit V4l2Camera(const V4l2Options& options);
  ~V4l2Camera() override;
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  std::optional<CapturedFrame> Next() override;
  void Stop() override { stop_ = true; }
  std::string Describe() const override;
  std::int64_t dropped() const override { return dropped_; }

 private:
  struct Buffer {
    void* start = nullptr;
    std::size_t length = 0;
  };
  void Configure();
  void Release();
  void SetControl(std::uint32_t id, std::int32_t value, const char* name);

  V4l2Options options_;
  int fd_ = -1;
  PixelFormat format_ = PixelFormat::kGrey;
  int width_ = 0;
  int height_ = 0;
  int bytes_per_line_ = 0;
  std::vector<Buffer> buffers_;
  bool streaming_ = false;
  std::atomic<bool> stop_{false};
  std::optional<std::uint32_t> last_sequence_;
  std::int64_t dropped_ = 0;
};

}  // namespace mosaicloc::io
