#include "mosaicloc/io/pixel_format.hpp"

#include <linux/videodev2.h>

#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/io/v4l2_camera.hpp"

namespace mosaicloc::io {
namespace {

cv::Mat Pattern(int width, int height) {
  cv::Mat image(height, width, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return image;
}

TEST(PixelFormatTest, NamesAndFourCcs) {
  EXPECT_EQ(ParsePixelFormat("GREY"), PixelFormat::kGrey);
  EXPECT_EQ(ParsePixelFormat("mjpg"), PixelFormat::kMjpeg);
  EXPECT_FALSE(ParsePixelFormat("rgb24"));
  EXPECT_EQ(FourCc(PixelFormat::kYuyv), V4L2_PIX_FMT_YUYV);
  EXPECT_EQ(FourCcName(V4L2_PIX_FMT_MJPEG), "MJPG");
}

TEST(PixelFormatTest, GreyRowsDropTheLinePadding) {
  const cv::Mat expected = Pattern(6, 3);
  const int stride = 8;
  std::vector<std::uint8_t> buffer(static_cast<std::size_t>(stride * 3), 0xEE);
  for (int row = 0; row < 3; ++row) std::copy_n(expected.ptr(row), 6, buffer.data() + row * stride);
  const auto grey = ToGrey(PixelFormat::kGrey, {buffer.data(), buffer.size(), 6, 3, stride});
  ASSERT_TRUE(grey.ok()) << grey.error();
  EXPECT_EQ(cv::norm(grey.value(), expected, cv::NORM_INF), 0.0);
}

TEST(PixelFormatTest, YuyvKeepsTheLumaSamples) {
  const cv::Mat expected = Pattern(4, 2);
  std::vector<std::uint8_t> buffer;
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 4; col += 2) {
      buffer.insert(buffer.end(), {expected.at<std::uint8_t>(row, col), 128, expected.at<std::uint8_t>(row, col + 1), 64});
    }
  }
  const auto grey = ToGrey(PixelFormat::kYuyv, {buffer.data(), buffer.size(), 4, 2, 0});
  ASSERT_TRUE(grey.ok()) << grey.error();
  EXPECT_EQ(cv::norm(grey.value(), expected, cv::NORM_INF), 0.0);
}

TEST(PixelFormatTest, TruncatedBuffersAreRefused) {
  std::vector<std::uint8_t> buffer(640 * 480 * 2 - 1);
  const auto grey = ToGrey(PixelFormat::kYuyv, {buffer.data(), buffer.size(), 640, 480, 0});
  ASSERT_FALSE(grey.ok());
  EXPECT_EQ(grey.error(), "yuyv buffer of 614399 bytes is truncated: 640x480 needs 614400");
  const auto short_line = ToGrey(PixelFormat::kGrey, {buffer.data(), buffer.size(), 640, 2, 600});
  ASSERT_FALSE(short_line.ok());
  EXPECT_EQ(short_line.error(), "grey line of 600 bytes is shorter than 640 pixels");
}

// Removes every DHT segment, as many UVC cameras send their MJPEG frames.
std::vector<std::uint8_t> WithoutHuffmanTables(const std::vector<std::uint8_t>& jpeg) {
  std::vector<std::uint8_t> out(jpeg.begin(), jpeg.begin() + 2);
  std::size_t at = 2;
  while (at + 4 <= jpeg.size()) {
    const std::size_t length = (static_cast<std::size_t>(jpeg[at + 2]) << 8U) | jpeg[at + 3];
    const bool sos = jpeg[at + 1] == 0xDA;
    if (jpeg[at + 1] != 0xC4 || sos) out.insert(out.end(), jpeg.begin() + static_cast<std::ptrdiff_t>(at),
                                                 sos ? jpeg.end() : jpeg.begin() + static_cast<std::ptrdiff_t>(at + 2 + length));
    if (sos) break;
    at += 2 + length;
  }
  return out;
}

TEST(PixelFormatTest, MjpegDecodesWithAndWithoutHuffmanTables) {
  const cv::Mat image = Pattern(64, 48);
  for (const bool colour : {false, true}) {
    cv::Mat source = image;
    if (colour) cv::merge(std::vector<cv::Mat>{image, image, image}, source);
    std::vector<std::uint8_t> jpeg;
    ASSERT_TRUE(cv::imencode(".jpg", source, jpeg));
    const cv::Mat reference = cv::imdecode(jpeg, cv::IMREAD_GRAYSCALE);
    const auto decoded = ToGrey(PixelFormat::kMjpeg, {jpeg.data(), jpeg.size(), 64, 48, 0});
    ASSERT_TRUE(decoded.ok()) << decoded.error();
    EXPECT_EQ(cv::norm(decoded.value(), reference, cv::NORM_INF), 0.0);

    const std::vector<std::uint8_t> bare = WithoutHuffmanTables(jpeg);
    ASSERT_LT(bare.size(), jpeg.size());
    const auto restored = ToGrey(PixelFormat::kMjpeg, {bare.data(), bare.size(), 64, 48, 0});
    ASSERT_TRUE(restored.ok()) << restored.error();
    EXPECT_EQ(cv::norm(restored.value(), reference, cv::NORM_INF), 0.0) << (colour ? "colour" : "grey");
  }
}

TEST(PixelFormatTest, BadMjpegIsAFailure) {
  const std::vector<std::uint8_t> garbage(1000, 0x5A);
  const auto decoded = ToGrey(PixelFormat::kMjpeg, {garbage.data(), garbage.size(), 64, 48, 0});
  ASSERT_FALSE(decoded.ok());
  EXPECT_EQ(decoded.error(), "MJPEG frame of 1000 bytes cannot be decoded");
  std::vector<std::uint8_t> jpeg;
  cv::imencode(".jpg", Pattern(32, 32), jpeg);
  const auto wrong_size = ToGrey(PixelFormat::kMjpeg, {jpeg.data(), jpeg.size(), 64, 48, 0});
  ASSERT_FALSE(wrong_size.ok());
  EXPECT_EQ(wrong_size.error(), "MJPEG frame is 32x32, not the negotiated 64x48");
}

TEST(V4l2CameraTest, DriverTimestampsEndOnTheMonotonicClock) {
  const auto now = core::Timestamp::FromNanoseconds(5'000'000'000);
  EXPECT_EQ(DriverTimestampToMonotonic(4'990'000'000, V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC, now, 0).nanoseconds(),
            4'990'000'000);
  // A wall-clock stamp 20 ms old.
  const std::int64_t wall = 1'700'000'000'000'000'000;
  EXPECT_EQ(DriverTimestampToMonotonic(wall - 20'000'000, V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN, now, wall).nanoseconds(),
            4'980'000'000);
  EXPECT_EQ(DriverTimestampToMonotonic(0, V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC, now, wall), now);
}

TEST(V4l2CameraTest, NoDeviceIsAClearErrorNamingThePath) {
  V4l2Options options;
  options.device = "/dev/video-mosaicloc-absent";
  try {
    V4l2Camera camera(options);
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/video-mosaicloc-absent: no such device"), std::string::npos) << e.what();
  }
  options.device = "/dev/null";  // a character device, but not a camera
  EXPECT_THROW(V4l2Camera{options}, core::Error);
  options.pixel_format = "rgb";
  try {
    V4l2Camera camera(options);
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    EXPECT_EQ(std::string(e.what()), "V4L2 camera: pixel_format must be auto, grey, yuyv or mjpeg");
  }
}

}  // namespace
}  // namespace mosaicloc::io
