#include "mosaicloc/sim/relief.hpp"

#include <cmath>
#include <functional>
#include <memory>
#include <numbers>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/sim/imaging.hpp"

namespace mosaicloc::sim {
namespace {

constexpr double kTexel = 0.125;

// A floor whose texel values are any function of the texel's world centre.
class FunctionFloor : public Floor {
 public:
  explicit FunctionFloor(std::function<double(double x, double y)> value) : value_(std::move(value)) {}
  double mm_per_texel() const override { return kTexel; }
  cv::Mat Render(std::int64_t col0, std::int64_t row0, int cols, int rows) const override {
    cv::Mat out(rows, cols, CV_8UC1);
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const double x = (static_cast<double>(col0 + c) + 0.5) * kTexel;
        const double y = -(static_cast<double>(row0 + r) + 0.5) * kTexel;
        out.at<std::uint8_t>(r, c) = cv::saturate_cast<std::uint8_t>(value_(x, y));
      }
    }
    return out;
  }
  std::string Describe() const override { return "function"; }

 private:
  std::function<double(double, double)> value_;
};

ReliefOptions FromImage(double depth_mm) {
  ReliefOptions options;
  options.depth_mm = depth_mm;
  options.source = "image";
  options.height_image = "heights.png";  // the test's floor stands for it
  return options;
}

ImagingOptions Plain() {
  ImagingOptions options;
  options.noise_std_dn = 0.0;
  options.vignetting = 0.0;
  options.illumination_amplitude = 0.0;
  return options;
}

// A camera looking straight down from `height` over (x, y): the rays' floor points on the
// top surface z = 0.
struct StraightDown {
  camera::IdealCamera camera{camera::IdealCameraOptions{160, 120, 0.25}};
  double height = 200.0;
  Eigen::Vector2d at{0.0, 0.0};
  Imager::PixelToWorld rays() const {
    return [this](const Eigen::Vector2d& pixel) {
      return Eigen::Vector2d(at + camera.PixelToCamera(pixel) * (height / 200.0));
    };
  }
  SurfaceView view() const {
    SurfaceView v;
    v.lens_mm = Eigen::Vector3d(at.x(), at.y(), height);
    return v;
  }
};

TEST(Relief, AHeightImageMapsWhiteToTheTopAndBlackToTheDepth) {
  const Relief relief(std::make_unique<FunctionFloor>([](double x, double) { return x < 0.0 ? 0.0 : 255.0; }),
                      FromImage(2.0));
  const cv::Mat depth = relief.Depth(-4, 0, 8, 2);
  EXPECT_FLOAT_EQ(depth.at<float>(0, 0), 2.0f);
  EXPECT_FLOAT_EQ(depth.at<float>(1, 3), 2.0f);
  EXPECT_FLOAT_EQ(depth.at<float>(0, 4), 0.0f);
  EXPECT_FLOAT_EQ(depth.at<float>(1, 7), 0.0f);
}

TEST(Relief, TheFloorsDarkestShareLiesAtTheFullDepthWhateverTheWindow) {
  // Dark 1 mm dots on a 4 mm grid (about 5 % of the floor) and a lighter grain.
  const auto value = [](double x, double y) {
    const double dx = std::remainder(x, 4.0);
    const double dy = std::remainder(y, 4.0);
    return std::hypot(dx, dy) < 0.5 ? 30.0 : 150.0 + 20.0 * std::sin(7.0 * x) * std::cos(5.0 * y);
  };
  ReliefOptions options;
  options.depth_mm = 1.5;
  options.low_fraction = 0.02;
  options.slope_fraction = 0.05;
  options.smoothing_mm = 0.125;
  const Relief relief(std::make_unique<FunctionFloor>(value), options);
  const cv::Mat depth = relief.Depth(-300, -200, 600, 400);
  double lowest = 0.0;
  double highest = 0.0;
  cv::minMaxLoc(depth, &highest, &lowest);
  EXPECT_NEAR(lowest, 1.5, 1e-4);
  EXPECT_NEAR(highest, 0.0, 1e-4);
  // A dot's centre (x = y = 0 at texel -0.5) is at the bottom; the grain between dots is top.
  EXPECT_NEAR(depth.at<float>(200 - 1, 300 - 1), 1.5, 1e-4);
  EXPECT_NEAR(depth.at<float>(200 - 1 + 16, 300 - 1), 0.0, 1e-4);
  // The same texels in another window.
  const cv::Mat part = relief.Depth(-123, -77, 50, 40);
  EXPECT_EQ(cv::norm(part, depth(cv::Rect(300 - 123, 200 - 77, 50, 40)), cv::NORM_INF), 0.0);
}

// A floor sunk everywhere by d is the floor seen from d higher: the picture shrinks by
// h / (h + d) about the point straight below the lens.
TEST(Relief, RaysFollowedIntoTheReliefSeeTheSunkenFloor) {
  const auto ramp = [](double x, double y) { return 128.0 + 1.5 * x - 1.0 * y; };
  const FunctionFloor floor(ramp);
  const Relief sunk(std::make_unique<FunctionFloor>([](double, double) { return 0.0; }), FromImage(3.0));
  StraightDown camera;
  const Imager imager(floor, camera.camera, Plain(), 1, Surface{&sunk, LightOptions{}, 200.0});
  const cv::Mat image = imager.RenderClean(camera.rays(), camera.view());
  double max_error = 0.0;
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      const Eigen::Vector2d world = camera.camera.PixelToCamera(Eigen::Vector2d(u, v)) * (203.0 / 200.0);
      max_error = std::max(max_error, std::abs(image.at<std::uint8_t>(v, u) - ramp(world.x(), world.y())));
    }
  }
  EXPECT_LT(max_error, 1.6);
}

// A trench 4 mm wide and 2 mm deep along y under the lens, lit by one LED 50 mm to the -x
// side: the trench's floor is in shadow for 2 x 50 / 200 = 0.5 mm from its -x wall; the rest of
// it, and the tops, see the light.
TEST(Relief, TheRingLightShadesAndShadowsTheRelief) {
  const FunctionFloor grey([](double, double) { return 200.0; });
  const Relief trench(std::make_unique<FunctionFloor>([](double x, double) { return std::abs(x) < 2.0 ? 0.0 : 255.0; }),
                      FromImage(2.0));
  LightOptions light;
  light.sources = 1;  // at angle pi: camera (-50, 0, 0)
  light.ring_radius_mm = 50.0;
  light.ambient = 0.2;
  StraightDown camera;
  const Imager imager(grey, camera.camera, Plain(), 1, Surface{&trench, light, 200.0});
  const cv::Mat image = imager.RenderClean(camera.rays(), camera.view());
  // Pixel u sees the trench floor at x = (u - cx) s (h + d) / h; columns from x.
  const auto column = [&](double x_on_trench_floor) {
    return static_cast<int>(std::lround(x_on_trench_floor / (0.25 * 202.0 / 200.0) + camera.camera.cx()));
  };
  const auto brightness = [&](int u) { return image.at<std::uint8_t>(60, u); };
  // A point (x, 0, z) of a level surface: the ambient part and the LED's inverse square and
  // cosines, against the calibrated centre's.
  const auto lit = [](double x, double z) {
    const auto irradiance = [](double dx, double dz) { return std::pow(dz, 2) / std::pow(dx * dx + dz * dz, 2); };
    return 200.0 * (0.2 + 0.8 * irradiance(-50.0 - x, 200.0 - z) / irradiance(50.0, 200.0));
  };
  // Shadowed: ambient only.
  EXPECT_NEAR(brightness(column(-1.8)), 200.0 * 0.2, 3.0);
  // Lit, at the trench's bottom.
  EXPECT_NEAR(brightness(column(0.0)), lit(0.0, -2.0), 2.0);
  EXPECT_NEAR(brightness(column(1.4)), lit(1.4, -2.0), 2.0);
  // Tops well away from the trench, nearer the LED than the centre.
  EXPECT_NEAR(brightness(column(-10.0) - 1), lit(-10.1, 0.0), 2.0);
}

// With the light alone (no relief) a flat floor is lit by the ring's inverse square and
// cosines: darker towards the corners, and by the ring's gain with the ambient part kept.
TEST(Relief, AFlatFloorUnderTheRingFallsOffTowardsTheCorners) {
  const FunctionFloor grey([](double, double) { return 200.0; });
  LightOptions light;
  light.sources = 8;
  light.ring_radius_mm = 50.0;
  light.ambient = 0.1;
  StraightDown camera;
  const Imager imager(grey, camera.camera, Plain(), 1, Surface{nullptr, light, 200.0});
  const cv::Mat image = imager.RenderClean(camera.rays(), camera.view());
  EXPECT_NEAR(image.at<std::uint8_t>(60, 80), 200.0, 1.0);
  // A corner (20, 15) mm from the centre: the ring's irradiance, summed over its 8 LEDs.
  const Eigen::Vector3d point(-19.875, 14.875, 0.0);
  double irradiance = 0.0;
  for (int i = 0; i < 8; ++i) {
    const double angle = 2.0 * std::numbers::pi * (i + 0.5) / 8;
    const Eigen::Vector3d to_light = Eigen::Vector3d(50.0 * std::cos(angle), 50.0 * std::sin(angle), 200.0) - point;
    irradiance += std::pow(to_light.z() / to_light.norm(), 2) / to_light.squaredNorm();
  }
  const double centre = 8 * std::pow(200.0 / std::hypot(50.0, 200.0), 2) / (50.0 * 50.0 + 200.0 * 200.0);
  EXPECT_NEAR(image.at<std::uint8_t>(0, 0), 200.0 * (0.1 + 0.9 * irradiance / centre), 1.0);
  light.ring_gain = 0.85;
  const Imager dimmer(grey, camera.camera, Plain(), 1, Surface{nullptr, light, 200.0});
  EXPECT_NEAR(dimmer.RenderClean(camera.rays(), camera.view()).at<std::uint8_t>(60, 80), 200.0 * (0.1 + 0.9 * 0.85),
              1.0);
}

}  // namespace
}  // namespace mosaicloc::sim
