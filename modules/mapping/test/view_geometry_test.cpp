#include "mosaicloc/mapping/view_geometry.hpp"

#include <cmath>
#include <cstdio>
#include <complex>
#include <numbers>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::mapping {
namespace {

// A pinhole over the floor plane z = 0: the lens at (x, y, height) mm, looking down, turned by
// yaw about the vertical and tilted by small angles about the world's x and y axes. Image axes:
// x right, y down; the calibrated camera (200 mm, 0.25 mm a pixel) has a focal length of 800 px.
struct Pinhole {
  Eigen::Vector3d lens;
  Eigen::Matrix3d world_from_camera;  // columns: the camera's x (right), y (down), z (optical axis)

  Pinhole(double x, double y, double height, double yaw, double tilt_x, double tilt_y) : lens(x, y, height) {
    Eigen::Matrix3d down;  // the camera at yaw 0, untilted: x = world x, y = -world y, z = -world z
    down << 1, 0, 0, 0, -1, 0, 0, 0, -1;
    world_from_camera = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(tilt_x, Eigen::Vector3d::UnitX()) *
                         Eigen::AngleAxisd(tilt_y, Eigen::Vector3d::UnitY()))
                            .toRotationMatrix() *
                        down;
  }
  static constexpr double kFocalPx = 800.0, kCx = 319.5, kCy = 239.5;
  Eigen::Vector2d Project(const Eigen::Vector3d& floor_point) const {
    const Eigen::Vector3d c = world_from_camera.transpose() * (floor_point - lens);
    return {kFocalPx * c.x() / c.z() + kCx, kFocalPx * c.y() / c.z() + kCy};
  }
  Eigen::Vector3d FloorPoint(const Eigen::Vector2d& pixel) const {
    const Eigen::Vector3d ray = world_from_camera * Eigen::Vector3d((pixel.x() - kCx) / kFocalPx, (pixel.y() - kCy) / kFocalPx, 1.0);
    return lens + ray * (-lens.z() / ray.z());
  }
  // The image centre's floor point and the camera's heading on the floor: the pose the mapper's
  // nodes stand for (x along the image's right, y along its up).
  core::Pose2 Node() const {
    const Eigen::Vector3d centre = FloorPoint({kCx, kCy});
    const Eigen::Vector3d right = FloorPoint({kCx + 100.0, kCy}) - centre;
    return core::Pose2(centre.x(), centre.y(), std::atan2(right.y(), right.x()));
  }
};

// What the tracker reports of a later view registered against an earlier one: its refined
// template centres (a grid over the overlap) where the exact pinholes put them, and the pose a
// similarity fit of them gives at the calibrated scale.
tracking::TrackResult Register(const Pinhole& earlier, const Pinhole& later) {
  tracking::TrackResult r;
  std::vector<Eigen::Vector2d> from, to;
  for (int gy = 0; gy < 5; ++gy) {
    for (int gx = 0; gx < 5; ++gx) {
      const Eigen::Vector2d pixel(48.5 + 136.0 * gx, 48.5 + 96.0 * gy);  // a 96 px template's centre
      const Eigen::Vector2d seen = earlier.Project(later.FloorPoint(pixel));
      if (seen.x() < 48 || seen.y() < 48 || seen.x() > 591 || seen.y() > 431) continue;
      tracking::TemplateReport t;
      t.spot.rect = cv::Rect(1 + 136 * gx, 1 + 96 * gy, 96, 96);
      t.refined.centre_raster = seen;
      t.inlier = true;
      r.templates.push_back(t);
      from.push_back(pixel - Eigen::Vector2d(Pinhole::kCx, Pinhole::kCy));
      to.push_back(seen - Eigen::Vector2d(Pinhole::kCx, Pinhole::kCy));
    }
  }
  // Similarity w = s R c + t by least squares (complex numbers).
  std::complex<double> mean_c, mean_w;
  for (std::size_t i = 0; i < from.size(); ++i) {
    mean_c += std::complex<double>(from[i].x(), from[i].y());
    mean_w += std::complex<double>(to[i].x(), to[i].y());
  }
  mean_c /= static_cast<double>(from.size());
  mean_w /= static_cast<double>(from.size());
  std::complex<double> num, den;
  for (std::size_t i = 0; i < from.size(); ++i) {
    const std::complex<double> c = std::complex<double>(from[i].x(), from[i].y()) - mean_c;
    num += std::conj(c) * (std::complex<double>(to[i].x(), to[i].y()) - mean_w);
    den += std::conj(c) * c;
  }
  const std::complex<double> a = num / den;
  const std::complex<double> t = mean_w - a * mean_c;
  // Image axes (y down) to the camera's floor frame (y up), at 0.25 mm a pixel.
  r.world_from_camera = core::Pose2(0.25 * t.real(), -0.25 * t.imag(), -std::arg(a));
  return r;
}

// A straight drive along x over a floor whose lean under the camera changes smoothly, with the
// camera's height varying too: each registration's yaw is biased by the tilt across its step
// and its step by the height, and both come out of the registrations themselves.
TEST(ViewGeometry, TiltAndHeightFromTheRegistrationsCorrectTheirYawAndStep) {
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};
  constexpr int kFrames = 120;
  std::vector<Pinhole> views;
  for (int i = 0; i < kFrames; ++i) {
    const double s = 16.0 * i;  // mm along the drive
    const double height = 200.0 + 0.15 * std::sin(s / 300.0);
    const double tilt_x = 6e-4 * std::sin(s / 250.0 + 1.0), tilt_y = 4e-4 * std::cos(s / 350.0);
    views.emplace_back(s, 0.0, height, 0.0, tilt_x, tilt_y);
  }
  // Registrations to the frame before and to the one five back, as the mapper's keyframes.
  std::vector<ViewObservation> observations;
  struct Link {
    int earlier, later;
    core::Pose2 measured, truth;
  };
  std::vector<Link> links;
  for (int i = 1; i < kFrames; ++i) {
    for (const int back : {1, 5}) {
      if (i - back < 0) continue;
      const tracking::TrackResult r = Register(views[i - back], views[i]);
      const auto o = ObserveView(r, camera, i - back, i);
      ASSERT_TRUE(o.has_value());
      observations.push_back(*o);
      links.push_back({i - back, i, r.world_from_camera, views[i - back].Node().Inverse() * views[i].Node()});
    }
  }
  const ViewGeometry geometry = SolveViewGeometry(observations, kFrames, camera, 200.0, ViewGeometryOptions{});
  // The registrations to the previous frame and the longer ones tell the same floor.
  EXPECT_TRUE(geometry.height_applied) << geometry.height_agreement;
  EXPECT_TRUE(geometry.tilt_applied) << geometry.tilt_agreement.transpose();
  EXPECT_GT(geometry.tilt_agreement.minCoeff(), 0.95);
  // Heights within 3e-5 of the truth (they vary by 7.5e-4).
  double height_error = 0.0;
  for (int i = 5; i < kFrames - 5; ++i) {
    height_error = std::max(height_error, std::abs(geometry.scale[i] - views[i].lens.z() / 200.0));
  }
  EXPECT_LT(height_error, 3e-5);
  // Each registration corrected: its yaw and step against the truth, RMS over the drive.
  double yaw_before = 0.0, yaw_after = 0.0, step_before = 0.0, step_after = 0.0;
  std::size_t index = 0;
  for (const Link& link : links) {
    const core::Pose2 corrected = CorrectRegistration(link.measured, observations[index++], geometry, camera, 200.0);
    yaw_before += std::pow(link.measured.yaw_rad() - link.truth.yaw_rad(), 2);
    yaw_after += std::pow(corrected.yaw_rad() - link.truth.yaw_rad(), 2);
    step_before += (link.measured.translation_mm() - link.truth.translation_mm()).squaredNorm();
    step_after += (corrected.translation_mm() - link.truth.translation_mm()).squaredNorm();
  }
  const double n = static_cast<double>(links.size());
  yaw_before = std::sqrt(yaw_before / n), yaw_after = std::sqrt(yaw_after / n);
  step_before = std::sqrt(step_before / n), step_after = std::sqrt(step_after / n);
  // The first-order correction takes two thirds of the yaw bias out; the rest is the
  // similarity's share of the views' tilt against each other (view_geometry.hpp).
  EXPECT_GT(yaw_before, 3e-5);
  EXPECT_LT(yaw_after, 0.4 * yaw_before) << yaw_before;
  EXPECT_LT(step_after, 0.5 * step_before) << step_before;
  std::printf("yaw RMS %.2e -> %.2e rad, step RMS %.2e -> %.2e mm\n", yaw_before, yaw_after, step_before, step_after);
}

// Views straight down at the calibrated height give no tilt and no height change, whatever the
// steps.
TEST(ViewGeometry, AFlatFloorAtTheCalibratedHeightLeavesTheRegistrationsAlone) {
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};
  std::vector<Pinhole> views;
  for (int i = 0; i < 40; ++i) views.emplace_back(14.0 * i, 3.0 * std::sin(0.2 * i), 200.0, 0.01 * i, 0.0, 0.0);
  std::vector<ViewObservation> observations;
  for (int i = 1; i < 40; ++i) {
    const auto o = ObserveView(Register(views[i - 1], views[i]), camera, i - 1, i);
    ASSERT_TRUE(o.has_value());
    EXPECT_NEAR(o->log_scale, 0.0, 1e-9);
    EXPECT_LT(o->anisotropy.norm(), 1e-9);
    observations.push_back(*o);
  }
  const ViewGeometry geometry = SolveViewGeometry(observations, 40, camera, 200.0, ViewGeometryOptions{});
  EXPECT_FALSE(geometry.height_applied);
  EXPECT_FALSE(geometry.tilt_applied);
  for (int i = 0; i < 40; ++i) {
    EXPECT_NEAR(geometry.scale[i], 1.0, 1e-9);
    EXPECT_LT(geometry.tilt[i].norm(), 1e-9);
  }
}

TEST(ViewGeometry, TooFewTemplatesOrBadOptionsAreRefused) {
  const camera::IdealCamera camera{camera::IdealCameraOptions{}};
  tracking::TrackResult r = Register(Pinhole(0, 0, 200, 0, 0, 0), Pinhole(16, 0, 200, 0, 0, 0));
  r.templates.resize(5);
  EXPECT_FALSE(ObserveView(r, camera, 0, 1).has_value());
  ViewGeometryOptions bad;
  bad.tilt_step_sigma_rad = 0.0;
  std::string why;
  EXPECT_FALSE(bad.Check(&why));
  EXPECT_NE(why.find("sigma"), std::string::npos);
  EXPECT_THROW(SolveViewGeometry({}, 3, camera, 200.0, bad), core::Error);
  EXPECT_THROW(SolveViewGeometry({}, 3, camera, 0.0, ViewGeometryOptions{}), core::Error);
}

}  // namespace
}  // namespace mosaicloc::mapping
