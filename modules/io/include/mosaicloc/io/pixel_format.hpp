#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::io {

/// The capture formats mosaicloc takes from a camera. Only luminance is used.
enum class PixelFormat { kGrey, kYuyv, kMjpeg };

/// "grey", "yuyv", "mjpeg" (case-insensitive); nothing for anything else.
std::optional<PixelFormat> ParsePixelFormat(std::string_view name);
const char* ToString(PixelFormat format);
/// The V4L2 four-character code (V4L2_PIX_FMT_GREY, _YUYV, _MJPEG).
std::uint32_t FourCc(PixelFormat format);
/// "YUYV" from a four-character code, for messages.
std::string FourCcName(std::uint32_t fourcc);

/// One driver buffer as it arrives.
struct PixelBuffer {
  const std::uint8_t* data = nullptr;
  std::size_t bytes = 0;      ///< bytes used in the buffer
  int width = 0;
  int height = 0;
  int bytes_per_line = 0;     ///< 0: packed (width x bytes per pixel)
};

/// The 8-bit luminance image of a buffer: GREY rows copied (dropping line padding), YUYV's
/// Y samples taken, MJPEG decoded by OpenCV (Debian's libjpeg-turbo supplies the standard
/// Huffman tables that many UVC cameras leave out of their frames). A truncated or
/// undecodable buffer, or one whose size differs from the negotiated one, is a failure
/// that says so.
core::Result<cv::Mat> ToGrey(PixelFormat format, const PixelBuffer& buffer);

}  // namespace mosaicloc::io
