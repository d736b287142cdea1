#include "mosaicloc/io/pixel_format.hpp"

#include <linux/videodev2.h>

#include <algorithm>
#include <cctype>
#include <cstring>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

namespace mosaicloc::io {

std::optional<PixelFormat> ParsePixelFormat(std::string_view name) {
  std::string lower(name);
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  if (lower == "grey" || lower == "gray") return PixelFormat::kGrey;
  if (lower == "yuyv") return PixelFormat::kYuyv;
  if (lower == "mjpeg" || lower == "mjpg") return PixelFormat::kMjpeg;
  return std::nullopt;
}

const char* ToString(PixelFormat format) {
  switch (format) {
    case PixelFormat::kGrey: return "grey";
    case PixelFormat::kYuyv: return "yuyv";
    case PixelFormat::kMjpeg: return "mjpeg";
  }
  return "unknown";
}

std::uint32_t FourCc(PixelFormat format) {
  switch (format) {
    case PixelFormat::kGrey: return V4L2_PIX_FMT_GREY;
    case PixelFormat::kYuyv: return V4L2_PIX_FMT_YUYV;
    case PixelFormat::kMjpeg: return V4L2_PIX_FMT_MJPEG;
  }
  return 0;
}

std::string FourCcName(std::uint32_t fourcc) {
  std::string name(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const auto c = static_cast<char>((fourcc >> (8U * static_cast<unsigned>(i))) & 0xFFU);
    name[static_cast<std::size_t>(i)] = std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  }
  return name;
}

core::Result<cv::Mat> ToGrey(PixelFormat format, const PixelBuffer& buffer) {
  const int w = buffer.width;
  const int h = buffer.height;
  if (w <= 0 || h <= 0 || buffer.data == nullptr) return core::Fail(std::string("empty buffer"));
  if (format == PixelFormat::kMjpeg) {
    cv::Mat decoded;
    try {
      // A header over the driver's buffer: no copy.
      const cv::Mat stream(1, static_cast<int>(buffer.bytes), CV_8UC1, const_cast<std::uint8_t*>(buffer.data));
      decoded = cv::imdecode(stream, cv::IMREAD_GRAYSCALE);
    } catch (const cv::Exception& e) {
      return core::Fail(fmt::format("MJPEG frame of {} bytes cannot be decoded: {}", buffer.bytes, e.what()));
    }
    if (decoded.empty()) return core::Fail(fmt::format("MJPEG frame of {} bytes cannot be decoded", buffer.bytes));
    if (decoded.cols != w || decoded.rows != h) {
      return core::Fail(fmt::format("MJPEG frame is {}x{}, not the negotiated {}x{}", decoded.cols, decoded.rows, w, h));
    }
    return decoded;
  }
  const int pixel_bytes = format == PixelFormat::kYuyv ? 2 : 1;
  const std::size_t stride = buffer.bytes_per_line > 0 ? static_cast<std::size_t>(buffer.bytes_per_line)
                                                       : static_cast<std::size_t>(w * pixel_bytes);
  if (stride < static_cast<std::size_t>(w * pixel_bytes)) {
    return core::Fail(fmt::format("{} line of {} bytes is shorter than {} pixels", ToString(format), stride, w));
  }
  const std::size_t needed = stride * static_cast<std::size_t>(h - 1) + static_cast<std::size_t>(w * pixel_bytes);
  if (buffer.bytes < needed) {
    return core::Fail(fmt::format("{} buffer of {} bytes is truncated: {}x{} needs {}", ToString(format), buffer.bytes,
                                  w, h, needed));
  }
  cv::Mat grey(h, w, CV_8UC1);
  for (int row = 0; row < h; ++row) {
    const std::uint8_t* src = buffer.data + stride * static_cast<std::size_t>(row);
    std::uint8_t* dst = grey.ptr<std::uint8_t>(row);
    if (format == PixelFormat::kGrey) {
      std::memcpy(dst, src, static_cast<std::size_t>(w));
    } else {  // YUYV: Y0 U Y1 V
      for (int col = 0; col < w; ++col) dst[col] = src[2 * col];
    }
  }
  return grey;
}

}  // namespace mosaicloc::io
