#include "mosaicloc/io/v4l2_camera.hpp"

#include <fcntl.h>
#include <libv4l2.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/stat.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>

#include <fmt/format.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/io/plc_link.hpp"

namespace mosaicloc::io {
namespace {

// ioctl through libv4l2, retried when a signal interrupts it.
int Xioctl(int fd, unsigned long request, void* argument) {
  int rc = 0;
  do {
    rc = v4l2_ioctl(fd, request, argument);
  } while (rc == -1 && errno == EINTR);
  return rc;
}

}  // namespace

bool V4l2Options::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (device.empty()) return fail("device must not be empty");
  if (width_px <= 0 || height_px <= 0) return fail("width_px and height_px must be positive");
  if (pixel_format != "auto" && !ParsePixelFormat(pixel_format)) return fail("pixel_format must be auto, grey, yuyv or mjpeg");
  if (!(frame_rate_hz > 0.0)) return fail("frame_rate_hz must be positive");
  if (buffers < 2 || buffers > 32) return fail("buffers must be in 2-32");
  if (!(exposure_us >= -1.0 && exposure_us <= 1e7)) return fail("exposure_us must be in [-1, 1e7] (-1: the camera's own)");
  if (gain < -1 || gain > (1 << 20)) return fail("gain must be in [-1, 1048576] (-1: the camera's own)");
  return true;
}

core::Timestamp DriverTimestampToMonotonic(std::int64_t driver_ns, std::uint32_t buffer_flags,
                                           core::Timestamp monotonic_now, std::int64_t realtime_now_ns) {
  const std::uint32_t kind = buffer_flags & V4L2_BUF_FLAG_TIMESTAMP_MASK;
  if (driver_ns <= 0) return monotonic_now;
  if (kind == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) return core::Timestamp::FromNanoseconds(driver_ns);
  // Unknown kind: old drivers stamped with gettimeofday. A stamp close to the wall clock is
  // one of those; anything else is not usable.
  const std::int64_t age_ns = realtime_now_ns - driver_ns;
  if (age_ns >= 0 && age_ns < 10'000'000'000) return monotonic_now - core::Duration(age_ns);
  return monotonic_now;
}

V4l2Camera::V4l2Camera(const V4l2Options& options) : options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("V4L2 camera: " + why);
  struct stat info {};
  if (stat(options_.device.c_str(), &info) != 0) {
    core::ThrowRuntime(fmt::format("V4L2 camera: {}: no such device ({}); is the camera connected? "
                                   "`v4l2-ctl --list-devices` lists the video devices",
                                   options_.device, std::strerror(errno)));
  }
  if (!S_ISCHR(info.st_mode)) core::ThrowRuntime(fmt::format("V4L2 camera: {} is not a device", options_.device));
  fd_ = v4l2_open(options_.device.c_str(), O_RDWR | O_NONBLOCK);
  if (fd_ < 0) {
    core::ThrowRuntime(fmt::format("V4L2 camera: cannot open {}: {}", options_.device, std::strerror(errno)));
  }
  try {
    Configure();
  } catch (...) {
    Release();
    throw;
  }
}

V4l2Camera::~V4l2Camera() { Release(); }

void V4l2Camera::Release() {
  if (streaming_) {
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    Xioctl(fd_, VIDIOC_STREAMOFF, &type);
    streaming_ = false;
  }
  for (const Buffer& buffer : buffers_) v4l2_munmap(buffer.start, buffer.length);
  buffers_.clear();
  if (fd_ >= 0) v4l2_close(fd_);
  fd_ = -1;
}

void V4l2Camera::Configure() {
  const std::string& device = options_.device;
  v4l2_capability capability{};
  if (Xioctl(fd_, VIDIOC_QUERYCAP, &capability) != 0) {
    core::ThrowRuntime(fmt::format("V4L2 camera: {} is not a V4L2 device: {}", device, std::strerror(errno)));
  }
  const std::uint32_t caps =
      (capability.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? capability.device_caps : capability.capabilities;
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0 || (caps & V4L2_CAP_STREAMING) == 0) {
    core::ThrowRuntime(fmt::format("V4L2 camera: {} ({}) cannot stream video capture", device,
                                   reinterpret_cast<const char*>(capability.card)));
  }

  // The formats to try, in order.
  std::vector<PixelFormat> candidates;
  if (options_.pixel_format == "auto") {
    candidates = {PixelFormat::kGrey, PixelFormat::kYuyv, PixelFormat::kMjpeg};
  } else {
    candidates = {*ParsePixelFormat(options_.pixel_format)};
  }
  bool set = false;
  std::string offered;
  for (const PixelFormat candidate : candidates) {
    v4l2_format format{};
    format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    format.fmt.pix.width = static_cast<std::uint32_t>(options_.width_px);
    format.fmt.pix.height = static_cast<std::uint32_t>(options_.height_px);
    format.fmt.pix.pixelformat = FourCc(candidate);
    format.fmt.pix.field = V4L2_FIELD_NONE;
    if (Xioctl(fd_, VIDIOC_S_FMT, &format) != 0) continue;
    offered += (offered.empty() ? "" : ", ") + FourCcName(format.fmt.pix.pixelformat);
    if (format.fmt.pix.pixelformat != FourCc(candidate)) continue;
    if (static_cast<int>(format.fmt.pix.width) != options_.width_px ||
        static_cast<int>(format.fmt.pix.height) != options_.height_px) {
      core::ThrowRuntime(fmt::format("V4L2 camera: {} gives {}x{} in {}, not the configured {}x{}", device,
                                     format.fmt.pix.width, format.fmt.pix.height, ToString(candidate),
                                     options_.width_px, options_.height_px));
    }
    format_ = candidate;
    width_ = static_cast<int>(format.fmt.pix.width);
    height_ = static_cast<int>(format.fmt.pix.height);
    bytes_per_line_ = static_cast<int>(format.fmt.pix.bytesperline);
    set = true;
    break;
  }
  if (!set) {
    core::ThrowRuntime(fmt::format("V4L2 camera: {} takes none of the formats asked for ({}); it offered {}", device,
                                   options_.pixel_format, offered.empty() ? "nothing" : offered));
  }

  v4l2_streamparm parameters{};
  parameters.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  parameters.parm.capture.timeperframe.numerator = 1000;
  parameters.parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(std::lround(options_.frame_rate_hz * 1000.0));
  if (Xioctl(fd_, VIDIOC_S_PARM, &parameters) != 0) {
    core::Log().warn("V4L2 camera: {} does not take a frame rate ({})", device, std::strerror(errno));
  }
  if (options_.exposure_us >= 0.0) {
    SetControl(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "manual exposure");
    // V4L2_CID_EXPOSURE_ABSOLUTE counts 100 us units.
    SetControl(V4L2_CID_EXPOSURE_ABSOLUTE, static_cast<std::int32_t>(std::max(1L, std::lround(options_.exposure_us / 100.0))),
               "exposure");
  }
  if (options_.gain >= 0) SetControl(V4L2_CID_GAIN, options_.gain, "gain");

  v4l2_requestbuffers request{};
  request.count = static_cast<std::uint32_t>(options_.buffers);
  request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  request.memory = V4L2_MEMORY_MMAP;
  if (Xioctl(fd_, VIDIOC_REQBUFS, &request) != 0 || request.count < 2) {
    core::ThrowRuntime(fmt::format("V4L2 camera: {} has no mmap streaming buffers: {}", device, std::strerror(errno)));
  }
  for (std::uint32_t i = 0; i < request.count; ++i) {
    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    buffer.index = i;
    if (Xioctl(fd_, VIDIOC_QUERYBUF, &buffer) != 0) {
      core::ThrowRuntime(fmt::format("V4L2 camera: {}: buffer {}: {}", device, i, std::strerror(errno)));
    }
    void* start = v4l2_mmap(nullptr, buffer.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buffer.m.offset);
    if (start == MAP_FAILED) {
      core::ThrowRuntime(fmt::format("V4L2 camera: {}: cannot map buffer {}: {}", device, i, std::strerror(errno)));
    }
    buffers_.push_back({start, buffer.length});
    if (Xioctl(fd_, VIDIOC_QBUF, &buffer) != 0) {
      core::ThrowRuntime(fmt::format("V4L2 camera: {}: cannot queue buffer {}: {}", device, i, std::strerror(errno)));
    }
  }
  v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (Xioctl(fd_, VIDIOC_STREAMON, &type) != 0) {
    core::ThrowRuntime(fmt::format("V4L2 camera: {}: cannot start streaming: {}", device, std::strerror(errno)));
  }
  streaming_ = true;
  core::Log().info("V4L2 camera: {}", Describe());
}

void V4l2Camera::SetControl(std::uint32_t id, std::int32_t value, const char* name) {
  v4l2_control control{};
  control.id = id;
  control.value = value;
  if (Xioctl(fd_, VIDIOC_S_CTRL, &control) != 0) {
    core::Log().warn("V4L2 camera: {} does not take {} = {}: {}", options_.device, name, value, std::strerror(errno));
  }
}

std::string V4l2Camera::Describe() const {
  return fmt::format("V4L2 {} {}x{} {} at {:g} Hz", options_.device, width_, height_, FourCcName(FourCc(format_)),
                     options_.frame_rate_hz);
}

std::optional<CapturedFrame> V4l2Camera::Next() {
  while (!stop_) {
    pollfd waiting{fd_, POLLIN, 0};
    const int ready = poll(&waiting, 1, 100);
    if (ready < 0 && errno != EINTR) {
      core::ThrowRuntime(fmt::format("V4L2 camera: {}: poll failed: {}", options_.device, std::strerror(errno)));
    }
    if (ready <= 0) continue;
    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    if (Xioctl(fd_, VIDIOC_DQBUF, &buffer) != 0) {
      if (errno == EAGAIN) continue;
      core::ThrowRuntime(fmt::format("V4L2 camera: {}: cannot dequeue a frame: {}", options_.device, std::strerror(errno)));
    }
    timespec realtime{};
    clock_gettime(CLOCK_REALTIME, &realtime);
    const std::int64_t driver_ns = static_cast<std::int64_t>(buffer.timestamp.tv_sec) * 1'000'000'000 +
                                   static_cast<std::int64_t>(buffer.timestamp.tv_usec) * 1000;
    CapturedFrame frame;
    frame.time = DriverTimestampToMonotonic(driver_ns, buffer.flags, MonotonicNow(),
                                            static_cast<std::int64_t>(realtime.tv_sec) * 1'000'000'000 + realtime.tv_nsec);
    frame.sequence = buffer.sequence;
    if (last_sequence_ && buffer.sequence > *last_sequence_ + 1) dropped_ += buffer.sequence - *last_sequence_ - 1;
    last_sequence_ = buffer.sequence;
    const Buffer& mapped = buffers_.at(buffer.index);
    const PixelBuffer pixels{static_cast<const std::uint8_t*>(mapped.start), buffer.bytesused, width_, height_,
                             bytes_per_line_};
    core::Result<cv::Mat> grey = (buffer.flags & V4L2_BUF_FLAG_ERROR) != 0
                                     ? core::Result<cv::Mat>(core::Fail(std::string("the driver flagged it corrupt")))
                                     : ToGrey(format_, pixels);
    if (Xioctl(fd_, VIDIOC_QBUF, &buffer) != 0) {
      core::ThrowRuntime(fmt::format("V4L2 camera: {}: cannot requeue a buffer: {}", options_.device, std::strerror(errno)));
    }
    if (!grey) {
      ++dropped_;
      core::Log().warn("V4L2 camera: {}: frame {} skipped: {}", options_.device, buffer.sequence, grey.error());
      continue;
    }
    frame.image = std::move(grey.value());
    return frame;
  }
  return std::nullopt;
}

}  // namespace mosaicloc::io
