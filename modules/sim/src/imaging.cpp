#include "mosaicloc/sim/imaging.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::sim {
namespace {

// A line kernel of length `length_px` along (dx, dy), anti-aliased by splatting points with
// bilinear weights; sums to one.
cv::Mat MotionKernel(double length_px, double dx, double dy) {
  const int half = static_cast<int>(std::ceil(0.5 * length_px)) + 1;
  cv::Mat kernel = cv::Mat::zeros(2 * half + 1, 2 * half + 1, CV_32F);
  const int points = std::max(16, static_cast<int>(8.0 * length_px));
  for (int i = 0; i < points; ++i) {
    const double t = (static_cast<double>(i) + 0.5) / points - 0.5;
    const double x = half + t * length_px * dx;
    const double y = half + t * length_px * dy;
    const int x0 = static_cast<int>(std::floor(x));
    const int y0 = static_cast<int>(std::floor(y));
    const double fx = x - x0;
    const double fy = y - y0;
    kernel.at<float>(y0, x0) += static_cast<float>((1 - fx) * (1 - fy));
    kernel.at<float>(y0, x0 + 1) += static_cast<float>(fx * (1 - fy));
    kernel.at<float>(y0 + 1, x0) += static_cast<float>((1 - fx) * fy);
    kernel.at<float>(y0 + 1, x0 + 1) += static_cast<float>(fx * fy);
  }
  return kernel / cv::sum(kernel)[0];
}

}  // namespace

bool ImagingOptions::Check(std::string* why) const {
  if (!(exposure_us >= 0.0 && exposure_us <= 100000.0)) {
    *why = "exposure_us must be in [0, 100000]";
    return false;
  }
  if (!(noise_std_dn >= 0.0 && noise_std_dn <= 64.0)) {
    *why = "noise_std_dn must be in [0, 64]";
    return false;
  }
  if (!(vignetting >= 0.0 && vignetting < 1.0) || !(illumination_amplitude >= 0.0 && illumination_amplitude < 1.0)) {
    *why = "vignetting and illumination_amplitude must be in [0, 1)";
    return false;
  }
  if (!(illumination_period_s > 0.0)) {
    *why = "illumination_period_s must be > 0";
    return false;
  }
  if (!(dust_fraction >= 0.0 && dust_fraction <= 0.5)) {
    *why = "dust_fraction must be in [0, 0.5]";
    return false;
  }
  return true;
}

Imager::Imager(const Floor& floor, const camera::IdealCamera& camera, const ImagingOptions& options,
               std::uint64_t seed)
    : floor_(floor), camera_(camera), options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("imaging: " + why);
  // At least 2x2 samples per pixel, and at least one per floor texel.
  supersampling_ = std::max(2, static_cast<int>(std::ceil(camera_.mm_per_px() / floor_.mm_per_texel() - 1e-9)));

  const int width = camera_.width_px();
  const int height = camera_.height_px();
  static_gain_ = cv::Mat(height, width, CV_32F);
  const double corner_r2 = camera_.cx() * camera_.cx() + camera_.cy() * camera_.cy();
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const double du = u - camera_.cx();
      const double dv = v - camera_.cy();
      static_gain_.at<float>(v, u) = static_cast<float>(1.0 - options_.vignetting * (du * du + dv * dv) / corner_r2);
    }
  }
  std::mt19937_64 rng(seed ^ 0xd057ULL);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  illumination_phase_ = 2.0 * std::numbers::pi * unit(rng);
  if (options_.dust_fraction > 0.0) {
    // Soft dark discs until their area reaches the requested fraction.
    cv::Mat dust(height, width, CV_32F, cv::Scalar(1.0));
    double covered = 0.0;
    const double target = options_.dust_fraction * width * height;
    while (covered < target) {
      const double radius = 3.0 + 12.0 * unit(rng);
      const float transmission = static_cast<float>(0.3 + 0.5 * unit(rng));
      const cv::Point centre(static_cast<int>(unit(rng) * width), static_cast<int>(unit(rng) * height));
      cv::Mat blob = cv::Mat::zeros(height, width, CV_32F);
      cv::circle(blob, centre, static_cast<int>(radius), cv::Scalar(1.0), cv::FILLED, cv::LINE_AA);
      cv::GaussianBlur(blob, blob, cv::Size(0, 0), 0.4 * radius);
      dust = dust.mul(1.0f - blob * (1.0f - transmission));
      covered += std::numbers::pi * radius * radius;
    }
    static_gain_ = static_gain_.mul(dust);
  }
}

cv::Mat Imager::RenderSupersampled(const core::Pose2& world_from_camera, double blur_margin_px) const {
  const int k = supersampling_;
  const double t = floor_.mm_per_texel();
  // Supersample (u', v') has its centre at ideal pixel ((u' + 0.5) / k - 0.5, ...).
  const Eigen::Matrix<double, 2, 3> world_from_pixel = camera_.PixelToWorldAffine(world_from_camera);
  Eigen::Matrix3d pixel_from_super = Eigen::Matrix3d::Identity();
  pixel_from_super(0, 0) = pixel_from_super(1, 1) = 1.0 / k;
  pixel_from_super(0, 2) = pixel_from_super(1, 2) = 0.5 / k - 0.5;
  // Texel (c, r) has its centre at x = (c + 0.5) t, y = -(r + 0.5) t.
  Eigen::Matrix<double, 2, 3> texel_from_world;
  texel_from_world << 1.0 / t, 0.0, -0.5, 0.0, -1.0 / t, -0.5;
  Eigen::Matrix3d world_from_pixel3 = Eigen::Matrix3d::Identity();
  world_from_pixel3.topRows<2>() = world_from_pixel;
  const Eigen::Matrix<double, 2, 3> texel_from_super = texel_from_world * world_from_pixel3 * pixel_from_super;

  // Bounding box of the footprint (plus the blur margin) in texels.
  const int width = camera_.width_px() * k;
  const int height = camera_.height_px() * k;
  const double margin = blur_margin_px + 2.0;
  double min_c = 1e300, min_r = 1e300, max_c = -1e300, max_r = -1e300;
  for (const double u : {-margin, width - 1 + margin}) {
    for (const double v : {-margin, height - 1 + margin}) {
      const Eigen::Vector2d texel = texel_from_super * Eigen::Vector3d(u, v, 1.0);
      min_c = std::min(min_c, texel.x());
      max_c = std::max(max_c, texel.x());
      min_r = std::min(min_r, texel.y());
      max_r = std::max(max_r, texel.y());
    }
  }
  const auto col0 = static_cast<std::int64_t>(std::floor(min_c)) - 1;
  const auto row0 = static_cast<std::int64_t>(std::floor(min_r)) - 1;
  const int cols = static_cast<int>(std::ceil(max_c) - static_cast<double>(col0)) + 2;
  const int rows = static_cast<int>(std::ceil(max_r) - static_cast<double>(row0)) + 2;
  const cv::Mat patch = floor_.Render(col0, row0, cols, rows);

  cv::Mat map(2, 3, CV_64F);
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) map.at<double>(r, c) = texel_from_super(r, c);
  }
  map.at<double>(0, 2) -= static_cast<double>(col0);
  map.at<double>(1, 2) -= static_cast<double>(row0);
  cv::Mat super;
  cv::warpAffine(patch, super, map, cv::Size(width, height), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                 cv::BORDER_REPLICATE);
  return super;
}

cv::Mat Imager::RenderClean(const core::Pose2& world_from_camera) const {
  cv::Mat image;
  cv::resize(RenderSupersampled(world_from_camera, 0.0), image, cv::Size(camera_.width_px(), camera_.height_px()), 0, 0,
             cv::INTER_AREA);
  return image;
}

cv::Mat Imager::RenderSupersampled(const PixelToWorld& pixel_to_world) const {
  const int k = supersampling_;
  const double t = floor_.mm_per_texel();
  const int width = camera_.width_px() * k;
  const int height = camera_.height_px() * k;
  // The map exactly on a grid of nodes every kStep pixels from the image's outer edge
  // (pixel -0.5), bilinear between: a smooth map's error is far below a thousandth of a pixel.
  constexpr double kStep = 8.0;
  const int nodes_u = static_cast<int>(std::ceil(camera_.width_px() / kStep)) + 1;
  const int nodes_v = static_cast<int>(std::ceil(camera_.height_px() / kStep)) + 1;
  std::vector<Eigen::Vector2d> texel(static_cast<std::size_t>(nodes_u) * nodes_v);
  double min_c = 1e300, min_r = 1e300, max_c = -1e300, max_r = -1e300;
  for (int j = 0; j < nodes_v; ++j) {
    for (int i = 0; i < nodes_u; ++i) {
      const Eigen::Vector2d world = pixel_to_world(Eigen::Vector2d(-0.5 + kStep * i, -0.5 + kStep * j));
      // Texel (c, r) has its centre at x = (c + 0.5) t, y = -(r + 0.5) t.
      const Eigen::Vector2d cr(world.x() / t - 0.5, -world.y() / t - 0.5);
      texel[static_cast<std::size_t>(j) * nodes_u + i] = cr;
      min_c = std::min(min_c, cr.x());
      max_c = std::max(max_c, cr.x());
      min_r = std::min(min_r, cr.y());
      max_r = std::max(max_r, cr.y());
    }
  }
  const auto col0 = static_cast<std::int64_t>(std::floor(min_c)) - 2;
  const auto row0 = static_cast<std::int64_t>(std::floor(min_r)) - 2;
  const int cols = static_cast<int>(std::ceil(max_c) - static_cast<double>(col0)) + 3;
  const int rows = static_cast<int>(std::ceil(max_r) - static_cast<double>(row0)) + 3;
  const cv::Mat patch = floor_.Render(col0, row0, cols, rows);

  cv::Mat map_c(height, width, CV_32F);
  cv::Mat map_r(height, width, CV_32F);
  for (int vs = 0; vs < height; ++vs) {
    // Supersample (u', v') has its centre at pixel ((u' + 0.5) / k - 0.5, ...).
    const double gv = ((vs + 0.5) / k) / kStep;
    const int j = std::min(static_cast<int>(gv), nodes_v - 2);
    const double fv = gv - j;
    auto* out_c = map_c.ptr<float>(vs);
    auto* out_r = map_r.ptr<float>(vs);
    for (int us = 0; us < width; ++us) {
      const double gu = ((us + 0.5) / k) / kStep;
      const int i = std::min(static_cast<int>(gu), nodes_u - 2);
      const double fu = gu - i;
      const std::size_t n = static_cast<std::size_t>(j) * nodes_u + i;
      const Eigen::Vector2d value = (1 - fv) * ((1 - fu) * texel[n] + fu * texel[n + 1]) +
                                    fv * ((1 - fu) * texel[n + nodes_u] + fu * texel[n + nodes_u + 1]);
      out_c[us] = static_cast<float>(value.x() - static_cast<double>(col0));
      out_r[us] = static_cast<float>(value.y() - static_cast<double>(row0));
    }
  }
  cv::Mat super;
  cv::remap(patch, super, map_c, map_r, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return super;
}

cv::Mat Imager::RenderClean(const PixelToWorld& pixel_to_world) const {
  cv::Mat image;
  cv::resize(RenderSupersampled(pixel_to_world), image, cv::Size(camera_.width_px(), camera_.height_px()), 0, 0,
             cv::INTER_AREA);
  return image;
}

double Imager::BlurSupersamples(const Eigen::Vector2d& camera_velocity_mm_per_s) const {
  return camera_velocity_mm_per_s.norm() * options_.exposure_us * 1e-6 / camera_.mm_per_px() * supersampling_;
}

cv::Mat Imager::Render(const core::Pose2& world_from_camera, const Eigen::Vector2d& camera_velocity_mm_per_s,
                       double time_s, std::uint64_t frame_seed) const {
  return Develop(RenderSupersampled(world_from_camera, BlurSupersamples(camera_velocity_mm_per_s)),
                 camera_velocity_mm_per_s, time_s, frame_seed);
}

cv::Mat Imager::Render(const PixelToWorld& pixel_to_world, const Eigen::Vector2d& camera_velocity_mm_per_s,
                       double time_s, std::uint64_t frame_seed) const {
  return Develop(RenderSupersampled(pixel_to_world), camera_velocity_mm_per_s, time_s, frame_seed);
}

cv::Mat Imager::Develop(cv::Mat super, const Eigen::Vector2d& camera_velocity_mm_per_s, double time_s,
                        std::uint64_t frame_seed) const {
  // Motion during the exposure, in supersamples. The floor moves against the camera; a
  // symmetric line kernel does not care about the sign. Image v grows against C's y.
  const double blur_px = BlurSupersamples(camera_velocity_mm_per_s);
  if (blur_px > 0.05) {
    const Eigen::Vector2d direction = camera_velocity_mm_per_s.normalized();
    cv::filter2D(super, super, -1, MotionKernel(blur_px, direction.x(), -direction.y()), cv::Point(-1, -1), 0,
                 cv::BORDER_REPLICATE);
  }
  cv::Mat image;
  super.convertTo(super, CV_32F);
  cv::resize(super, image, cv::Size(camera_.width_px(), camera_.height_px()), 0, 0, cv::INTER_AREA);

  const double illumination =
      1.0 + options_.illumination_amplitude *
                std::sin(2.0 * std::numbers::pi * time_s / options_.illumination_period_s + illumination_phase_);
  image = image.mul(static_gain_, illumination);
  if (options_.noise_std_dn > 0.0) {
    cv::Mat noise(image.size(), CV_32F);
    cv::RNG rng(frame_seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, options_.noise_std_dn);
    image += noise;
  }
  cv::Mat out;
  image.convertTo(out, CV_8U);  // rounds and saturates
  return out;
}

}  // namespace mosaicloc::sim
