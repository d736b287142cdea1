#include "mosaicloc/sim/relief.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::sim {
namespace {

// The window whose brightness quantiles set the albedo relief's thresholds, texels.
constexpr int kSampleTexels = 1024;

}  // namespace

bool ReliefOptions::Check(std::string* why) const {
  if (!(depth_mm >= 0.0 && depth_mm <= 20.0)) {
    *why = "depth_mm must be in [0, 20]";
    return false;
  }
  if (source != "albedo" && source != "image") {
    *why = "source must be albedo or image, got '" + source + "'";
    return false;
  }
  if (source == "image" && depth_mm > 0.0 && height_image.empty()) {
    *why = "height_image must name an image file when source is image";
    return false;
  }
  if (!(low_fraction >= 0.01 && low_fraction <= 0.9) || !(slope_fraction >= 0.01 && slope_fraction <= 0.5) ||
      !(low_fraction + slope_fraction < 1.0)) {
    *why = "low_fraction must be in [0.01, 0.9], slope_fraction in [0.01, 0.5], and their sum under 1";
    return false;
  }
  if (!(smoothing_mm >= 0.0 && smoothing_mm <= 5.0)) {
    *why = "smoothing_mm must be in [0, 5]";
    return false;
  }
  return true;
}

bool LightOptions::Check(std::string* why) const {
  if (sources < 0 || sources > 64) {
    *why = "sources must be in [0, 64]";
    return false;
  }
  if (!(ring_radius_mm >= 0.0 && ring_radius_mm <= 1000.0)) {
    *why = "ring_radius_mm must be in [0, 1000]";
    return false;
  }
  if (!(std::abs(height_over_lens_mm) <= 1000.0)) {
    *why = "height_over_lens_mm must be within [-1000, 1000]";
    return false;
  }
  if (!(ambient >= 0.0 && ambient <= 1.0)) {
    *why = "ambient must be in [0, 1]";
    return false;
  }
  if (!(ring_gain >= 0.0 && ring_gain <= 4.0)) {
    *why = "ring_gain must be in [0, 4]";
    return false;
  }
  return true;
}

Relief::Relief(std::unique_ptr<Floor> source, const ReliefOptions& options) : Relief(*source, options) {
  owned_ = std::move(source);
}

Relief::Relief(const Floor& source, const ReliefOptions& options) : source_(&source), options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("relief: " + why);
  if (options_.source != "albedo") return;
  sigma_ = options_.smoothing_mm / source_->mm_per_texel();
  margin_ = sigma_ > 0.0 ? static_cast<int>(std::ceil(3.0 * sigma_)) + 1 : 0;
  // The thresholds: brightness quantiles of the smoothed picture over a window at the origin.
  const cv::Mat smooth = Smoothed(0, 0, kSampleTexels, kSampleTexels);
  std::vector<float> values(smooth.begin<float>(), smooth.end<float>());
  const auto quantile = [&](double q) {
    const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(values.size() - 1));
    std::nth_element(values.begin(), values.begin() + k, values.end());
    return static_cast<double>(values[static_cast<std::size_t>(k)]);
  };
  dark_ = quantile(options_.low_fraction);
  light_ = std::max(quantile(options_.low_fraction + options_.slope_fraction), dark_ + 1.0);
}

cv::Mat Relief::Smoothed(std::int64_t col0, std::int64_t row0, int cols, int rows) const {
  cv::Mat smooth;
  source_->Render(col0 - margin_, row0 - margin_, cols + 2 * margin_, rows + 2 * margin_).convertTo(smooth, CV_32F);
  if (margin_ > 0) cv::GaussianBlur(smooth, smooth, cv::Size(2 * margin_ + 1, 2 * margin_ + 1), sigma_);
  return smooth(cv::Rect(margin_, margin_, cols, rows));
}

cv::Mat Relief::Depth(std::int64_t col0, std::int64_t row0, int cols, int rows) const {
  if (cols < 0 || rows < 0) throw std::invalid_argument("Relief::Depth: negative size");
  if (cols == 0 || rows == 0) return {};
  cv::Mat depth;
  if (options_.source == "image") {
    // (255 - DN) first, so that white is exactly the top.
    source_->Render(col0, row0, cols, rows).convertTo(depth, CV_32F);
    cv::subtract(255.0, depth, depth);
    return depth * (options_.depth_mm / 255.0);
  }
  const cv::Mat smooth = Smoothed(col0, row0, cols, rows);
  depth.create(rows, cols, CV_32F);
  const double scale = 1.0 / (light_ - dark_);
  for (int r = 0; r < rows; ++r) {
    const float* in = smooth.ptr<float>(r);
    float* out = depth.ptr<float>(r);
    for (int c = 0; c < cols; ++c) {
      // 1 at and below dark_, 0 at and above light_, a smooth step between.
      const double t = std::clamp((light_ - in[c]) * scale, 0.0, 1.0);
      out[c] = static_cast<float>(options_.depth_mm * t * t * (3.0 - 2.0 * t));
    }
  }
  return depth;
}

}  // namespace mosaicloc::sim
