#include "mosaicloc/sim/raw_imaging.hpp"

#include <gtest/gtest.h>

namespace mosaicloc::sim {
namespace {

TEST(CalibrationTruthCamera, IsAValidTiltedDistortedCameraThatSeesTheIdealImage) {
  const camera::RealCameraOptions truth = CalibrationTruthCamera();
  std::string why;
  ASSERT_TRUE(truth.Check(&why)) << why;
  EXPECT_EQ(truth.width_px, 640);
  EXPECT_EQ(truth.height_px, 480);
  EXPECT_LT(truth.k1, 0.0);  // barrel distortion, so calibration has a term to recover
  EXPECT_NE(truth.tilt_x_rad, 0.0);
  EXPECT_NE(truth.tilt_y_rad, 0.0);
  // The 560x400 ideal image at 0.25 mm/px of the calibration tutorial lies inside the raw
  // image, with room for interpolation: every corner of it projects at least 5 px inside.
  const camera::RealCamera camera(truth);
  for (const double x : {-0.25 * 279.5, 0.25 * 279.5}) {
    for (const double y : {-0.25 * 199.5, 0.25 * 199.5}) {
      const auto pixel = camera.FloorToPixel(Eigen::Vector2d(x, y));
      ASSERT_TRUE(pixel.has_value());
      EXPECT_GT(pixel->x(), 5.0);
      EXPECT_GT(pixel->y(), 5.0);
      EXPECT_LT(pixel->x(), truth.width_px - 6.0);
      EXPECT_LT(pixel->y(), truth.height_px - 6.0);
    }
  }
}

}  // namespace
}  // namespace mosaicloc::sim
