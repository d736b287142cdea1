#pragma once

// What the tracking module's tests share: a real floor texture seen by an ideal camera at
// exactly known poses, and short descriptions of priors and results.

#include <cmath>
#include <cstdint>
#include <memory>
#include <numbers>
#include <optional>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mosaicloc/sim/resample.hpp"
#include "mosaicloc/test/test_support.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::tracking {

using core::Pose2;
using Affine = Eigen::Matrix<double, 2, 3>;
constexpr double kMmPerPx = 0.25;
constexpr double kDeg = std::numbers::pi / 180.0;

// A reference image cut from a real texture and live frames of it at exactly known poses.
// The texture is sampled at half resolution (2x2 area average of exact bicubic samples), like
// a camera seeing a continuous floor. The world frame is the reference image's camera frame.
class Scene {
 public:
  explicit Scene(cv::Mat texture, cv::Size reference_size = {960, 800})
      : texture_(std::move(texture)), camera_(camera::IdealCameraOptions{}) {
    source_from_reference_ << 2.0, 0.0, 0.5 + 40.0, 0.0, 2.0, 0.5 + 40.0;
    cv::Mat exact = sim::ResampleExact(texture_, source_from_reference_, reference_size, 2);
    exact.convertTo(reference_image_, CV_8UC1);
    reference_ = std::make_unique<ImageReference>(reference_image_, Pose2::Identity(), kMmPerPx);
  }

  // The live frame at world_from_camera, with gain, offset and Gaussian noise, seen from
  // `height_scale` times the calibrated height.
  cv::Mat Frame(const Pose2& world_from_camera, double noise = 0.0, double gain = 1.0, double offset = 0.0,
                std::uint64_t seed = 1, double height_scale = 1.0) const {
    const Affine reference_from_view = ComposeAffine(
        reference_->WorldToRaster(), camera_.Scaled(height_scale).PixelToWorldAffine(world_from_camera));
    cv::Mat exact = sim::ResampleExact(texture_, ComposeAffine(source_from_reference_, reference_from_view),
                                       cv::Size(camera_.width_px(), camera_.height_px()), 2);
    exact = exact * gain + offset;
    if (noise > 0.0) {
      cv::Mat n(exact.size(), CV_32FC1);
      cv::RNG rng(seed);
      rng.fill(n, cv::RNG::NORMAL, 0.0, noise);
      exact += n;
    }
    cv::Mat frame;
    exact.convertTo(frame, CV_8UC1);
    return frame;
  }

  const camera::IdealCamera& camera() const { return camera_; }
  const ImageReference& reference() const { return *reference_; }
  const cv::Mat& reference_image() const { return reference_image_; }

 private:
  cv::Mat texture_;
  camera::IdealCamera camera_;
  Affine source_from_reference_;
  cv::Mat reference_image_;
  std::unique_ptr<ImageReference> reference_;
};

inline std::optional<cv::Mat> Asphalt() {
  const auto file = test::SharedTexture("asphalt_02_2048.jpg");
  if (!file) return std::nullopt;
  return cv::imread(file->string(), cv::IMREAD_GRAYSCALE);
}

#define REQUIRE_ASPHALT(texture)                                   \
  const std::optional<cv::Mat> texture = Asphalt();                \
  if (!texture) GTEST_SKIP() << test::SharedDataMissingMessage();

// Every template's fate, for failure messages.
inline std::string Describe(const TrackResult& r) {
  std::string text = r.reason;
  for (const TemplateReport& t : r.templates) {
    text += "\n  template at " + std::to_string(t.spot.rect.x) + "," + std::to_string(t.spot.rect.y) +
            ": range " + std::to_string(t.search_range_px) + " peak " + std::to_string(t.coarse.peak) +
            " ambiguity " + std::to_string(t.coarse.ambiguity) + " refined zncc " + std::to_string(t.refined.zncc) +
            " " + (t.rejected.empty() ? "used" : t.rejected);
  }
  return text;
}

inline Eigen::Matrix3d PriorCovariance(double sigma_px, double sigma_deg) {
  return Eigen::Vector3d(std::pow(sigma_px * kMmPerPx, 2), std::pow(sigma_px * kMmPerPx, 2),
                         std::pow(sigma_deg * kDeg, 2))
      .asDiagonal();
}

}  // namespace mosaicloc::tracking
