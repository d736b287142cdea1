#include "mosaicloc/sim/imaging.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

namespace mosaicloc::sim {
namespace {

// A floor whose brightness is a linear function of the world position: area averages and
// bilinear interpolation of it are exact, so a rendered image is known in closed form.
class RampFloor : public Floor {
 public:
  RampFloor(double x0, double y0) : x0_(x0), y0_(y0) {}
  double mm_per_texel() const override { return 0.125; }
  static double Value(double x, double y, double x0, double y0) { return 128.0 + 0.45 * (x - x0) - 0.3 * (y - y0); }
  cv::Mat Render(std::int64_t col0, std::int64_t row0, int cols, int rows) const override {
    cv::Mat out(rows, cols, CV_8UC1);
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const double x = (static_cast<double>(col0 + c) + 0.5) * 0.125;
        const double y = -(static_cast<double>(row0 + r) + 0.5) * 0.125;
        out.at<std::uint8_t>(r, c) = cv::saturate_cast<std::uint8_t>(Value(x, y, x0_, y0_));
      }
    }
    return out;
  }
  std::string Describe() const override { return "ramp"; }

 private:
  double x0_;
  double y0_;
};

TEST(Imager, CleanRenderIsExactForALinearFloor) {
  const camera::IdealCamera camera(camera::IdealCameraOptions{160, 120, 0.25});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> position(-20000.0, 20000.0);
  std::uniform_real_distribution<double> yaw(-3.2, 3.2);
  for (int trial = 0; trial < 10; ++trial) {
    const core::Pose2 world_from_camera(position(rng), position(rng), yaw(rng));
    const RampFloor floor(world_from_camera.x_mm(), world_from_camera.y_mm());
    const Imager imager(floor, camera, ImagingOptions{}, 1);
    const cv::Mat image = imager.RenderClean(world_from_camera);
    double max_error = 0.0;
    for (int v = 0; v < image.rows; ++v) {
      for (int u = 0; u < image.cols; ++u) {
        const Eigen::Vector2d world = camera.PixelToWorld({u, v}, world_from_camera);
        const double expected = RampFloor::Value(world.x(), world.y(), world_from_camera.x_mm(), world_from_camera.y_mm());
        max_error = std::max(max_error, std::abs(image.at<std::uint8_t>(v, u) - expected));
      }
    }
    // 8-bit floor texels and 8-bit output: at most about one count of rounding.
    EXPECT_LT(max_error, 1.6) << "trial " << trial;
  }
}

// The ray path (a tilted pinhole over an uneven floor goes this way) renders the ideal camera's
// rays as the ideal camera's image, and a linear floor through any smooth map exactly.
TEST(Imager, RaysRenderWhatTheyLookAt) {
  const camera::IdealCamera camera(camera::IdealCameraOptions{160, 120, 0.25});
  const core::Pose2 world_from_camera(1500.0, -700.0, 0.8);
  const RampFloor floor(world_from_camera.x_mm(), world_from_camera.y_mm());
  const Imager imager(floor, camera, ImagingOptions{}, 1);
  const auto ideal = [&](const Eigen::Vector2d& pixel) { return camera.PixelToWorld(pixel, world_from_camera); };
  double max_difference = 0.0;
  cv::minMaxLoc(cv::abs(imager.RenderClean(ideal) - imager.RenderClean(world_from_camera)), nullptr, &max_difference);
  EXPECT_LE(max_difference, 1.0);
  // A keystone: the floor seen by a camera tilted by a degree.
  const auto tilted = [&](const Eigen::Vector2d& pixel) {
    const Eigen::Vector2d c = camera.PixelToCamera(pixel) / 200.0;
    const double w = 1.0 - 0.0175 * c.y();
    return world_from_camera * Eigen::Vector2d(200.0 * c.x() / w, 200.0 * (c.y() + 0.0175) / w);
  };
  const cv::Mat image = imager.RenderClean(tilted);
  double max_error = 0.0;
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      // The pixel's area average of a linear floor is its value at the pixel's centroid; for
      // a map this smooth that is the centre's image to well under a count.
      const Eigen::Vector2d world = tilted(Eigen::Vector2d(u, v));
      const double expected = RampFloor::Value(world.x(), world.y(), world_from_camera.x_mm(), world_from_camera.y_mm());
      max_error = std::max(max_error, std::abs(image.at<std::uint8_t>(v, u) - expected));
    }
  }
  EXPECT_LT(max_error, 1.6);
}

class ImagerEffects : public ::testing::Test {
 protected:
  // A floor of fine random texture.
  class NoiseFloor : public Floor {
   public:
    double mm_per_texel() const override { return 0.125; }
    cv::Mat Render(std::int64_t col0, std::int64_t row0, int cols, int rows) const override {
      cv::Mat out(rows, cols, CV_8UC1);
      for (int r = 0; r < rows; ++r) {
        for (int c = 0; c < cols; ++c) {
          std::uint64_t h = static_cast<std::uint64_t>(col0 + c) * 0x9e3779b97f4a7c15ULL ^
                            static_cast<std::uint64_t>(row0 + r) * 0xc2b2ae3d27d4eb4fULL;
          h ^= h >> 29;
          h *= 0xbf58476d1ce4e5b9ULL;
          h ^= h >> 32;
          out.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(64 + (h % 128));
        }
      }
      return out;
    }
    std::string Describe() const override { return "noise"; }
  };
  NoiseFloor floor_;
  camera::IdealCamera camera_{camera::IdealCameraOptions{160, 120, 0.25}};
};

TEST_F(ImagerEffects, MotionBlurSmoothsAlongTheMotionOnly) {
  ImagingOptions options;
  options.noise_std_dn = 0.0;
  options.vignetting = 0.0;
  options.illumination_amplitude = 0.0;
  options.exposure_us = 1000.0;  // 5 m/s: 5 mm = 20 px of blur along x
  const Imager imager(floor_, camera_, options, 1);
  const cv::Mat sharp = imager.Render(core::Pose2(), {0.0, 0.0}, 0.0, 1);
  const cv::Mat blurred = imager.Render(core::Pose2(), {5000.0, 0.0}, 0.0, 1);
  const auto energy = [](const cv::Mat& image, int dx, int dy) {
    cv::Mat gradient;
    cv::Sobel(image, gradient, CV_32F, dx, dy);
    return cv::norm(gradient);
  };
  EXPECT_LT(energy(blurred, 1, 0), 0.3 * energy(sharp, 1, 0));
  EXPECT_GT(energy(blurred, 0, 1), 0.15 * energy(sharp, 0, 1));
  EXPECT_GT(energy(blurred, 0, 1), 2.0 * energy(blurred, 1, 0));
}

TEST_F(ImagerEffects, NoiseVignettingAndDeterminism) {
  ImagingOptions options;
  options.noise_std_dn = 3.0;
  options.vignetting = 0.2;
  options.illumination_amplitude = 0.0;
  const Imager imager(floor_, camera_, options, 1);
  const cv::Mat a = imager.Render(core::Pose2(10, 20, 0.3), {0, 0}, 0.0, 42);
  const cv::Mat b = imager.Render(core::Pose2(10, 20, 0.3), {0, 0}, 0.0, 42);
  const cv::Mat c = imager.Render(core::Pose2(10, 20, 0.3), {0, 0}, 0.0, 43);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  cv::Mat difference;
  cv::subtract(a, c, difference, cv::noArray(), CV_32F);
  cv::Scalar mean, stddev;
  cv::meanStdDev(difference, mean, stddev);
  // Two independent noise draws differ with std sqrt(2) sigma.
  EXPECT_NEAR(stddev[0], std::sqrt(2.0) * 3.0, 0.4);
  // Corners are darker than the centre by about the vignetting.
  const cv::Mat clean = imager.RenderClean(core::Pose2(10, 20, 0.3));
  cv::Mat ratio;
  cv::divide(a, clean, ratio, 1.0, CV_32F);
  const double centre = cv::mean(ratio(cv::Rect(70, 50, 20, 20)))[0];
  const double corner = cv::mean(ratio(cv::Rect(0, 0, 8, 8)))[0];
  EXPECT_NEAR(centre, 1.0, 0.02);
  EXPECT_NEAR(corner, 0.8, 0.04);
}

}  // namespace
}  // namespace mosaicloc::sim
