#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <string>
#include <utility>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "floor_internal.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/sim/floor.hpp"

namespace mosaicloc::sim {
namespace {

constexpr int kMinImageSidePx = 16;

/// Any decoded image as 8-bit grey: colour by the ITU-R BT.601 luma weights (cv::cvtColor),
/// alpha dropped, 16-bit scaled by 255/65535, float taken as 0..1.
cv::Mat ToGrey8(const cv::Mat& decoded) {
  cv::Mat grey;
  switch (decoded.channels()) {
    case 1: grey = decoded; break;
    case 3: cv::cvtColor(decoded, grey, cv::COLOR_BGR2GRAY); break;
    case 4: cv::cvtColor(decoded, grey, cv::COLOR_BGRA2GRAY); break;
    default: cv::extractChannel(decoded, grey, 0); break;
  }
  switch (grey.depth()) {
    case CV_8U: return grey;
    case CV_8S: grey.convertTo(grey, CV_8U, 1.0, 128.0); return grey;
    case CV_16U: grey.convertTo(grey, CV_8U, 255.0 / 65535.0); return grey;
    case CV_16S: grey.convertTo(grey, CV_8U, 255.0 / 65535.0, 128.0); return grey;
    case CV_32F:
    case CV_64F:
    case CV_16F: grey.convertTo(grey, CV_8U, 255.0); return grey;
    default: {
      double min_value = 0.0;
      double max_value = 0.0;
      cv::minMaxLoc(grey, &min_value, &max_value);
      const double scale = max_value > min_value ? 255.0 / (max_value - min_value) : 1.0;
      grey.convertTo(grey, CV_8U, scale, -min_value * scale);
      return grey;
    }
  }
}

class ImageFloor final : public Floor {
 public:
  ImageFloor(cv::Mat image, ImageFloorOptions options)
      : image_(std::move(image)), options_(std::move(options)) {}

  double mm_per_texel() const override { return options_.mm_per_texel; }

  cv::Mat Render(std::int64_t col0, std::int64_t row0, int cols, int rows) const override {
    internal::CheckWindowSize(cols, rows);
    cv::Mat out(rows, cols, CV_8UC1);
    const int width = image_.cols;
    const int height = image_.rows;
    const int first_col = static_cast<int>(internal::FloorMod(col0, width));
    const int first_row = static_cast<int>(internal::FloorMod(row0, height));
    for (int y = 0; y < rows; ++y) {
      const std::uint8_t* source = image_.ptr<std::uint8_t>((first_row + y) % height);
      std::uint8_t* target = out.ptr<std::uint8_t>(y);
      int x = 0;
      int source_col = first_col;
      while (x < cols) {
        const int run = std::min(cols - x, width - source_col);
        std::memcpy(target + x, source + source_col, static_cast<std::size_t>(run));
        x += run;
        source_col = 0;
      }
    }
    return out;
  }

  std::string Describe() const override {
    std::ostringstream text;
    text << "image file=" << options_.image.string() << " size=" << image_.cols << "x"
         << image_.rows << " mm_per_texel=" << options_.mm_per_texel;
    return text.str();
  }

 private:
  cv::Mat image_;  // CV_8UC1, never modified: safe to read from several threads
  ImageFloorOptions options_;
};

}  // namespace

bool ImageFloorOptions::Check(std::string* why) const {
  auto fail = [why](const std::string& reason) {
    if (why != nullptr) *why = reason;
    return false;
  };
  if (image.empty()) return fail("image floor: image: no file given");
  if (!std::isfinite(mm_per_texel) || mm_per_texel <= 0.0 || mm_per_texel > 100.0) {
    return fail("image floor: mm_per_texel = " + std::to_string(mm_per_texel) +
                ": must be in (0, 100]");
  }
  return true;
}

std::unique_ptr<Floor> MakeImageFloor(const ImageFloorOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  const std::string file = options.image.string();
  std::error_code error;
  if (!std::filesystem::is_regular_file(options.image, error)) {
    core::ThrowInvalidInput("image floor: cannot read '" + file + "': no such file");
  }
  cv::Mat decoded;
  try {
    decoded = cv::imread(file, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    core::ThrowInvalidInput("image floor: cannot read '" + file + "': " + e.what());
  }
  if (decoded.empty()) {
    core::ThrowInvalidInput("image floor: cannot read '" + file +
                            "': unreadable or not an image OpenCV can decode");
  }
  if (decoded.cols < kMinImageSidePx || decoded.rows < kMinImageSidePx) {
    core::ThrowInvalidInput("image floor: '" + file + "' is " + std::to_string(decoded.cols) +
                            " x " + std::to_string(decoded.rows) + " pixels; need at least " +
                            std::to_string(kMinImageSidePx) + " x " +
                            std::to_string(kMinImageSidePx));
  }
  return std::make_unique<ImageFloor>(ToGrey8(decoded), options);
}

}  // namespace mosaicloc::sim
