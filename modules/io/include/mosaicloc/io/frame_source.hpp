#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/core/timestamp.hpp"

namespace mosaicloc::io {

/// One captured image, stamped on the monotonic clock (the epoch of every live timestamp).
struct CapturedFrame {
  core::Timestamp time;
  cv::Mat image;              ///< CV_8UC1
  std::int64_t sequence = 0;  ///< the source's frame counter; gaps are dropped frames
};

/// Where live frames come from: a V4L2 camera, or a recording played in real time. The
/// camera thread calls Next(); any thread may call Stop().
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// Blocks until the next frame; nothing at the end of a recording or after Stop().
  /// Throws core::Error when the device fails.
  virtual std::optional<CapturedFrame> Next() = 0;
  /// Makes a waiting or later Next() return nothing.
  virtual void Stop() = 0;
  /// "V4L2 /dev/video0 640x480 GREY at 60 Hz".
  virtual std::string Describe() const = 0;
  /// Frames the source knows it lost (sequence gaps, full queues).
  virtual std::int64_t dropped() const { return 0; }
};

}  // namespace mosaicloc::io
