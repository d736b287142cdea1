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

// The map of a ray render is evaluated exactly on a grid of nodes every kStep pixels from the
// image's outer edge (pixel -0.5) and interpolated bilinearly between: a smooth map's error is
// far below a thousandth of a pixel.
class NodeGrid {
 public:
  static constexpr double kStep = 8.0;
  NodeGrid(int width_px, int height_px)
      : nodes_u_(static_cast<int>(std::ceil(width_px / kStep)) + 1),
        nodes_v_(static_cast<int>(std::ceil(height_px / kStep)) + 1) {}
  std::size_t size() const { return static_cast<std::size_t>(nodes_u_) * nodes_v_; }
  Eigen::Vector2d Pixel(std::size_t n) const {
    const auto i = static_cast<int>(n % static_cast<std::size_t>(nodes_u_));
    const auto j = static_cast<int>(n / static_cast<std::size_t>(nodes_u_));
    return {-0.5 + kStep * i, -0.5 + kStep * j};
  }
  /// Where supersample (us, vs) of a k-times supersampled image lies among the nodes (its
  /// centre is at pixel ((us + 0.5) / k - 0.5, ...)): the node before it and the fraction of
  /// the way to the next, for every column and every row. Bilinear interpolation is then one
  /// blend of two node rows per image row (Row) and one of two values per sample (At).
  struct Weights {
    std::vector<int> cell;
    std::vector<double> fraction;
  };
  Weights Columns(int width, int k) const { return Along(width, k, nodes_u_); }
  Weights Rows(int height, int k) const { return Along(height, k, nodes_v_); }
  /// The nodes' values blended to image row `vs` (rows = Rows(...)).
  template <class T>
  void Row(const std::vector<T>& nodes, const Weights& rows, int vs, std::vector<T>* row) const {
    const std::size_t n = static_cast<std::size_t>(rows.cell[vs]) * nodes_u_;
    const double f = rows.fraction[vs];
    row->resize(nodes_u_);
    for (int i = 0; i < nodes_u_; ++i) (*row)[i] = (1 - f) * nodes[n + i] + f * nodes[n + nodes_u_ + i];
  }
  /// The value at column `us` of a row from Row (columns = Columns(...)).
  template <class T>
  static T At(const std::vector<T>& row, const Weights& columns, int us) {
    const int i = columns.cell[us];
    const double f = columns.fraction[us];
    return (1 - f) * row[i] + f * row[i + 1];
  }

 private:
  static Weights Along(int size, int k, int nodes) {
    Weights w;
    w.cell.resize(size);
    w.fraction.resize(size);
    for (int s = 0; s < size; ++s) {
      const double g = ((s + 0.5) / k) / kStep;
      w.cell[s] = std::min(static_cast<int>(g), nodes - 2);
      w.fraction[s] = g - w.cell[s];
    }
    return w;
  }
  int nodes_u_;
  int nodes_v_;
};

// Texel (c, r) has its centre at x = (c + 0.5) t, y = -(r + 0.5) t.
Eigen::Vector2d TexelOf(const Eigen::Vector2d& world, double t) { return {world.x() / t - 0.5, -world.y() / t - 0.5}; }

// The bounding box of texel coordinates.
struct Box {
  double min_c = 1e300, min_r = 1e300, max_c = -1e300, max_r = -1e300;
  void Add(const Eigen::Vector2d& cr) {
    min_c = std::min(min_c, cr.x());
    max_c = std::max(max_c, cr.x());
    min_r = std::min(min_r, cr.y());
    max_r = std::max(max_r, cr.y());
  }
};

// The texels of a floor patch: the box grown by `margin` texels on every side.
struct Patch {
  Patch(const Box& box, int margin)
      : col0(static_cast<std::int64_t>(std::floor(box.min_c)) - margin),
        row0(static_cast<std::int64_t>(std::floor(box.min_r)) - margin),
        cols(static_cast<int>(std::ceil(box.max_c) - static_cast<double>(col0)) + margin + 1),
        rows(static_cast<int>(std::ceil(box.max_r) - static_cast<double>(row0)) + margin + 1) {}
  /// Floor texel coordinates made the patch's (its first texel's centre at 0, 0).
  void Into(std::vector<Eigen::Vector2d>& texels) const {
    const Eigen::Vector2d origin(static_cast<double>(col0), static_cast<double>(row0));
    for (Eigen::Vector2d& texel : texels) texel -= origin;
  }
  std::int64_t col0, row0;
  int cols, rows;
};

// What the LEDs at `lights` (world) shine on a Lambertian surface at `point` with `normal`:
// each an emitter along `axis_down` (cosine of the emission angle) at the inverse square,
// times the cosine of incidence, unless `shadowed(to_light)`.
template <class Shadowed>
double Irradiance(const std::vector<Eigen::Vector3d>& lights, const Eigen::Vector3d& axis_down,
                  const Eigen::Vector3d& point, const Eigen::Vector3d& normal, const Shadowed& shadowed) {
  double irradiance = 0.0;
  for (const Eigen::Vector3d& source : lights) {
    const Eigen::Vector3d to_light = source - point;
    const double distance2 = to_light.squaredNorm();
    const Eigen::Vector3d l = to_light / std::sqrt(distance2);
    const double incidence = normal.dot(l);
    const double emission = -l.dot(axis_down);
    if (incidence <= 0.0 || emission <= 0.0 || shadowed(to_light)) continue;
    irradiance += incidence * emission / distance2;
  }
  return irradiance;
}

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
               std::uint64_t seed, const Surface& surface)
    : floor_(floor), camera_(camera), options_(options), surface_(surface) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("imaging: " + why);
  if (!surface_.light.Check(&why)) core::ThrowInvalidInput("light: " + why);
  if (surface_.light.any()) {
    // The ring in camera axes, and what it shines on the image centre of a flat floor at the
    // calibrated height: the light's unit.
    const LightOptions& light = surface_.light;
    const double over_floor = surface_.calibrated_height_mm + light.height_over_lens_mm;
    if (!(over_floor > 1.0)) core::ThrowInvalidInput("light: the ring must be above the floor (height_over_lens_mm)");
    for (int i = 0; i < light.sources; ++i) {
      const double angle = 2.0 * std::numbers::pi * (i + 0.5) / light.sources;
      light_in_camera_.emplace_back(light.ring_radius_mm * std::cos(angle), light.ring_radius_mm * std::sin(angle),
                                    light.height_over_lens_mm);
    }
    const double distance2 = light.ring_radius_mm * light.ring_radius_mm + over_floor * over_floor;
    light_e0_ = light.sources * (over_floor * over_floor / distance2) / distance2;
  }
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
  Box box;
  for (const double u : {-margin, width - 1 + margin}) {
    for (const double v : {-margin, height - 1 + margin}) box.Add(texel_from_super * Eigen::Vector3d(u, v, 1.0));
  }
  const Patch window(box, 1);
  const cv::Mat patch = floor_.Render(window.col0, window.row0, window.cols, window.rows);

  cv::Mat map(2, 3, CV_64F);
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) map.at<double>(r, c) = texel_from_super(r, c);
  }
  map.at<double>(0, 2) -= static_cast<double>(window.col0);
  map.at<double>(1, 2) -= static_cast<double>(window.row0);
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
  const NodeGrid grid(camera_.width_px(), camera_.height_px());
  std::vector<Eigen::Vector2d> texel(grid.size());
  Box box;
  for (std::size_t n = 0; n < grid.size(); ++n) {
    texel[n] = TexelOf(pixel_to_world(grid.Pixel(n)), t);
    box.Add(texel[n]);
  }
  const Patch window(box, 2);
  const cv::Mat patch = floor_.Render(window.col0, window.row0, window.cols, window.rows);
  window.Into(texel);
  const NodeGrid::Weights columns = grid.Columns(width, k);
  const NodeGrid::Weights grid_rows = grid.Rows(height, k);
  std::vector<Eigen::Vector2d> row;
  cv::Mat map_c(height, width, CV_32F);
  cv::Mat map_r(height, width, CV_32F);
  for (int vs = 0; vs < height; ++vs) {
    grid.Row(texel, grid_rows, vs, &row);
    auto* out_c = map_c.ptr<float>(vs);
    auto* out_r = map_r.ptr<float>(vs);
    for (int us = 0; us < width; ++us) {
      const Eigen::Vector2d value = NodeGrid::At(row, columns, us);
      out_c[us] = static_cast<float>(value.x());
      out_r[us] = static_cast<float>(value.y());
    }
  }
  cv::Mat super;
  cv::remap(patch, super, map_c, map_r, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return super;
}

cv::Mat Imager::RenderSurface(const PixelToWorld& pixel_to_world, const SurfaceView& view) const {
  const int k = supersampling_;
  const double t = floor_.mm_per_texel();
  const int width = camera_.width_px() * k;
  const int height = camera_.height_px() * k;
  const double depth_max = surface_.relief != nullptr ? surface_.relief->depth_mm() : 0.0;
  std::vector<Eigen::Vector3d> lights;
  for (const Eigen::Vector3d& light : light_in_camera_) lights.push_back(view.lens_mm + view.world_from_camera * light);
  const Eigen::Vector3d axis_down = -view.world_from_camera.col(2);

  // Per node: where the ray meets the top surface (texels), how far it moves on for every mm
  // it goes deeper (texels per mm), and the top surface's height there.
  const NodeGrid grid(camera_.width_px(), camera_.height_px());
  std::vector<Eigen::Vector2d> texel(grid.size());
  std::vector<Eigen::Vector2d> parallax(grid.size());
  std::vector<double> top_z(grid.size());
  std::vector<double> flat_irradiance(grid.size(), 0.0);  // a level top's, for the common case
  Box box;
  double reach = 0.0;  // texels per mm of depth, along a ray or towards a light
  for (std::size_t n = 0; n < grid.size(); ++n) {
    const Eigen::Vector2d world = pixel_to_world(grid.Pixel(n));
    top_z[n] = view.floor_height_mm ? view.floor_height_mm(world) : 0.0;
    const Eigen::Vector2d away = (world - view.lens_mm.head<2>()) / (view.lens_mm.z() - top_z[n]);
    texel[n] = TexelOf(world, t);
    parallax[n] = Eigen::Vector2d(away.x() / t, -away.y() / t);
    reach = std::max(reach, parallax[n].norm());
    for (const Eigen::Vector3d& light : lights) {
      reach = std::max(reach, (light.head<2>() - world).norm() / std::max(light.z() - top_z[n], 1.0) / t);
    }
    flat_irradiance[n] = Irradiance(lights, axis_down, Eigen::Vector3d(world.x(), world.y(), top_z[n]),
                                    Eigen::Vector3d::UnitZ(), [](const Eigen::Vector3d&) { return false; });
    box.Add(texel[n]);
  }
  const Patch window(box, static_cast<int>(std::ceil(depth_max * reach)) + 3);
  cv::Mat albedo;
  floor_.Render(window.col0, window.row0, window.cols, window.rows).convertTo(albedo, CV_32F);
  const cv::Mat depth =
      depth_max > 0.0 ? surface_.relief->Depth(window.col0, window.row0, window.cols, window.rows) : cv::Mat();
  // Texels whose 4 x 4 neighbourhood (every bilinear sample of a point in the texel and half a
  // texel around it) is all top: the common case, with no slope to take.
  cv::Mat level;
  if (depth_max > 0.0) {
    cv::Mat low = depth > 0.0f;
    cv::dilate(low, low, cv::Mat::ones(4, 4, CV_8U), cv::Point(1, 1), 1, cv::BORDER_CONSTANT, cv::Scalar(255));
    level = low == 0;
  }
  const auto is_level = [&](const Eigen::Vector2d& at) {
    if (depth_max <= 0.0) return true;
    const int c = static_cast<int>(std::floor(at.x())), r = static_cast<int>(std::floor(at.y()));
    return c >= 0 && r >= 0 && c < level.cols && r < level.rows && level.at<std::uint8_t>(r, c) != 0;
  };

  // Bilinear samples at patch coordinates (texel centres at integers), clamped to the patch.
  const auto sample = [](const cv::Mat& raster, double c, double r) {
    c = std::clamp(c, 0.0, raster.cols - 1.001);
    r = std::clamp(r, 0.0, raster.rows - 1.001);
    const int c0 = static_cast<int>(c);
    const int r0 = static_cast<int>(r);
    const double fc = c - c0;
    const double fr = r - r0;
    const float* a = raster.ptr<float>(r0) + c0;
    const float* b = raster.ptr<float>(r0 + 1) + c0;
    return (1 - fr) * ((1 - fc) * a[0] + fc * a[1]) + fr * ((1 - fc) * b[0] + fc * b[1]);
  };
  const auto depth_at = [&](double c, double r) { return depth_max > 0.0 ? sample(depth, c, r) : 0.0; };

  window.Into(texel);
  const NodeGrid::Weights columns = grid.Columns(width, k);
  const NodeGrid::Weights grid_rows = grid.Rows(height, k);
  std::vector<Eigen::Vector2d> texel_row, parallax_row;
  std::vector<double> top_z_row, flat_irradiance_row;
  cv::Mat super(height, width, CV_32F);
  const LightOptions& light = surface_.light;
  for (int vs = 0; vs < height; ++vs) {
    grid.Row(texel, grid_rows, vs, &texel_row);
    grid.Row(parallax, grid_rows, vs, &parallax_row);
    grid.Row(top_z, grid_rows, vs, &top_z_row);
    grid.Row(flat_irradiance, grid_rows, vs, &flat_irradiance_row);
    auto* out = super.ptr<float>(vs);
    for (int us = 0; us < width; ++us) {
      const Eigen::Vector2d top = NodeGrid::At(texel_row, columns, us);
      const Eigen::Vector2d step_dir = NodeGrid::At(parallax_row, columns, us);
      // March down the ray until it is below the surface, then place the hit between the last
      // two steps (the surface's first crossing: what lies in front hides what lies behind).
      double hit_depth = 0.0;
      const bool level_top = is_level(top);
      if (!level_top) {
        double gap = depth_at(top.x(), top.y());
        if (gap > 0.0) {
          const double step = std::min(0.25 * depth_max, 0.5 / std::max(step_dir.norm(), 1e-9));
          double previous_depth = 0.0;
          double previous_gap = gap;
          for (double d = step;; d += step) {
            d = std::min(d, depth_max);
            gap = depth_at(top.x() + d * step_dir.x(), top.y() + d * step_dir.y()) - d;
            if (gap <= 0.0 || d >= depth_max) {
              hit_depth = gap <= 0.0 ? previous_depth + (d - previous_depth) * previous_gap / (previous_gap - gap) : d;
              break;
            }
            previous_depth = d;
            previous_gap = gap;
          }
        }
      }
      const Eigen::Vector2d hit = top + hit_depth * step_dir;
      double value = sample(albedo, hit.x(), hit.y());
      if (!lights.empty()) {
        // The surface's normal from the depth's slope (height = top - depth).
        double irradiance = 0.0;
        const double ddx =
            level_top ? 0.0 : (depth_at(hit.x() + 0.5, hit.y()) - depth_at(hit.x() - 0.5, hit.y())) / t;
        const double ddy =
            level_top ? 0.0 : -(depth_at(hit.x(), hit.y() + 0.5) - depth_at(hit.x(), hit.y() - 0.5)) / t;
        if (hit_depth == 0.0 && ddx == 0.0 && ddy == 0.0) {
          irradiance = NodeGrid::At(flat_irradiance_row, columns, us);  // a level top: smooth over the view
        } else {
          const Eigen::Vector3d normal = Eigen::Vector3d(ddx, ddy, 1.0).normalized();
          const Eigen::Vector3d point((hit.x() + static_cast<double>(window.col0) + 0.5) * t,
                                      -(hit.y() + static_cast<double>(window.row0) + 0.5) * t,
                                      NodeGrid::At(top_z_row, columns, us) - hit_depth);
          // Shadow: walk towards the light while below the top surface.
          const auto shadowed = [&](const Eigen::Vector3d& to_light) {
            if (hit_depth <= 0.0) return false;
            const Eigen::Vector2d rise(to_light.x() / to_light.z() / t, -to_light.y() / to_light.z() / t);
            const double step = std::min(hit_depth, 1.0 / std::max(rise.norm(), 1e-9));
            for (double e = step; e < hit_depth; e += step) {
              if (depth_at(hit.x() + e * rise.x(), hit.y() + e * rise.y()) < hit_depth - e - 1e-3) return true;
            }
            return false;
          };
          irradiance = Irradiance(lights, axis_down, point, normal, shadowed);
        }
        value *= light.ambient + (1.0 - light.ambient) * light.ring_gain * irradiance / light_e0_;
      }
      out[us] = static_cast<float>(value);
    }
  }
  return super;
}

cv::Mat Imager::RenderClean(const PixelToWorld& pixel_to_world, const SurfaceView& view) const {
  cv::Mat image;
  cv::resize(RenderSurface(pixel_to_world, view), image, cv::Size(camera_.width_px(), camera_.height_px()), 0, 0,
             cv::INTER_AREA);
  image.convertTo(image, CV_8U);
  return image;
}

cv::Mat Imager::Render(const PixelToWorld& pixel_to_world, const SurfaceView& view,
                       const Eigen::Vector2d& camera_velocity_mm_per_s, double time_s, std::uint64_t frame_seed) const {
  return Develop(RenderSurface(pixel_to_world, view), camera_velocity_mm_per_s, time_s, frame_seed);
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
