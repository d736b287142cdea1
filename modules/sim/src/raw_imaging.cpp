#include "mosaicloc/sim/raw_imaging.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::sim {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Floor points (camera frame C, mm) seen at the pixel corners (u - 0.5, v - 0.5) for
// u in [0, w], v in [0, h]; NaN where the ray misses the floor. Within a pixel the map is
// interpolated bilinearly: its curvature over one pixel is far below a texel.
struct CornerGrid {
  int width = 0, height = 0;
  std::vector<Eigen::Vector2d> points;
  const Eigen::Vector2d& at(int u, int v) const { return points[static_cast<std::size_t>(v) * (width + 1) + u]; }
};

CornerGrid FloorAtCorners(const camera::RealCamera& camera) {
  CornerGrid grid;
  grid.width = camera.options().width_px;
  grid.height = camera.options().height_px;
  grid.points.resize(static_cast<std::size_t>(grid.width + 1) * (grid.height + 1));
  for (int v = 0; v <= grid.height; ++v) {
    for (int u = 0; u <= grid.width; ++u) {
      const auto floor = camera.PixelToFloor(Eigen::Vector2d(u - 0.5, v - 0.5));
      grid.points[static_cast<std::size_t>(v) * (grid.width + 1) + u] = floor ? *floor : Eigen::Vector2d(kNaN, kNaN);
    }
  }
  return grid;
}

void CheckOptions(const RawImagingOptions& options) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
}

// Image from a reflectance function over the floor frame C (0 black .. 1 white).
template <typename Reflectance>
cv::Mat Render(const CornerGrid& grid, const RawImagingOptions& options, std::uint64_t seed,
               const Reflectance& reflectance) {
  cv::Mat image(grid.height, grid.width, CV_8UC1);
  std::mt19937_64 random(seed);
  std::normal_distribution<double> noise(0.0, options.noise_std_dn);
  const int k = options.supersampling;
  for (int v = 0; v < grid.height; ++v) {
    auto* out = image.ptr<unsigned char>(v);
    for (int u = 0; u < grid.width; ++u) {
      const Eigen::Vector2d& p00 = grid.at(u, v);
      const Eigen::Vector2d& p10 = grid.at(u + 1, v);
      const Eigen::Vector2d& p01 = grid.at(u, v + 1);
      const Eigen::Vector2d& p11 = grid.at(u + 1, v + 1);
      double sum = 0.0;
      int count = 0;
      for (int j = 0; j < k; ++j) {
        const double b = (j + 0.5) / k;
        for (int i = 0; i < k; ++i) {
          const double a = (i + 0.5) / k;
          const Eigen::Vector2d p = (1 - a) * (1 - b) * p00 + a * (1 - b) * p10 + (1 - a) * b * p01 + a * b * p11;
          if (!std::isfinite(p.x())) continue;
          sum += reflectance(p);
          ++count;
        }
      }
      const double r = count > 0 ? sum / count : 0.0;
      const double dn = options.black_dn + (options.white_dn - options.black_dn) * r +
                        (options.noise_std_dn > 0.0 ? noise(random) : 0.0);
      out[u] = static_cast<unsigned char>(std::clamp(std::lround(dn), 0L, 255L));
    }
  }
  return image;
}

}  // namespace

bool RawImagingOptions::Check(std::string* why) const {
  if (supersampling < 1 || supersampling > 16) {
    *why = "raw imaging supersampling must be in [1, 16]";
    return false;
  }
  if (!(noise_std_dn >= 0.0 && noise_std_dn < 100.0)) {
    *why = "raw imaging noise_std_dn must be in [0, 100)";
    return false;
  }
  if (!(black_dn >= 0.0 && white_dn <= 255.0 && black_dn < white_dn)) {
    *why = "raw imaging needs 0 <= black_dn < white_dn <= 255";
    return false;
  }
  return true;
}

cv::Mat RenderBoardRaw(const camera::RealCamera& camera, const camera::BoardSpec& board,
                       const core::Pose2& camera_from_board, const RawImagingOptions& options, std::uint64_t seed) {
  CheckOptions(options);
  std::string why;
  if (!board.Check(&why)) core::ThrowInvalidInput(why);
  const core::Pose2 board_from_camera = camera_from_board.Inverse();
  const Eigen::Matrix2d rotation = board_from_camera.Rotation();
  const Eigen::Vector2d translation = board_from_camera.translation_mm();
  return Render(FloorAtCorners(camera), options, seed, [&](const Eigen::Vector2d& p_camera) {
    const Eigen::Vector2d p_board = rotation * p_camera + translation;
    return camera::BoardReflectance(board, p_board.x(), p_board.y());
  });
}

cv::Mat RenderFloorRaw(const camera::RealCamera& camera, const Floor& floor, const core::Pose2& world_from_camera,
                       const RawImagingOptions& options, std::uint64_t seed) {
  CheckOptions(options);
  const CornerGrid grid = FloorAtCorners(camera);
  // The texel window under the whole footprint, plus one texel for interpolation.
  double min_x = std::numeric_limits<double>::infinity(), max_x = -min_x, min_y = min_x, max_y = -min_x;
  for (const Eigen::Vector2d& p : grid.points) {
    if (!std::isfinite(p.x())) continue;
    const Eigen::Vector2d w = world_from_camera * p;
    min_x = std::min(min_x, w.x());
    max_x = std::max(max_x, w.x());
    min_y = std::min(min_y, w.y());
    max_y = std::max(max_y, w.y());
  }
  if (!std::isfinite(min_x)) core::ThrowInvalidInput("the raw camera does not see the floor");
  const double t = floor.mm_per_texel();
  // Texel (col, row) has its centre at ((col + 0.5) t, -(row + 0.5) t).
  const auto col0 = static_cast<std::int64_t>(std::floor(min_x / t - 0.5)) - 1;
  const auto col1 = static_cast<std::int64_t>(std::ceil(max_x / t - 0.5)) + 1;
  const auto row0 = static_cast<std::int64_t>(std::floor(-max_y / t - 0.5)) - 1;
  const auto row1 = static_cast<std::int64_t>(std::ceil(-min_y / t - 0.5)) + 1;
  const cv::Mat texels = floor.Render(col0, row0, static_cast<int>(col1 - col0 + 1), static_cast<int>(row1 - row0 + 1));
  const Eigen::Matrix2d rotation = world_from_camera.Rotation();
  const Eigen::Vector2d translation = world_from_camera.translation_mm();
  return Render(grid, options, seed, [&](const Eigen::Vector2d& p_camera) {
    const Eigen::Vector2d w = rotation * p_camera + translation;
    const double fc = w.x() / t - 0.5 - static_cast<double>(col0);
    const double fr = -w.y() / t - 0.5 - static_cast<double>(row0);
    const int c = std::clamp(static_cast<int>(std::floor(fc)), 0, texels.cols - 2);
    const int r = std::clamp(static_cast<int>(std::floor(fr)), 0, texels.rows - 2);
    const double a = std::clamp(fc - c, 0.0, 1.0), b = std::clamp(fr - r, 0.0, 1.0);
    const double value = (1 - a) * (1 - b) * texels.at<unsigned char>(r, c) + a * (1 - b) * texels.at<unsigned char>(r, c + 1) +
                         (1 - a) * b * texels.at<unsigned char>(r + 1, c) + a * b * texels.at<unsigned char>(r + 1, c + 1);
    return value / 255.0;
  });
}

camera::RealCameraOptions CalibrationTruthCamera() {
  camera::RealCameraOptions truth;
  truth.width_px = 640;
  truth.height_px = 480;
  truth.fx_px = 812.0;
  truth.fy_px = 806.0;
  truth.cx_px = 326.4;
  truth.cy_px = 233.7;
  truth.k1 = -0.14;
  truth.k2 = 0.0;
  truth.height_mm = 200.0;
  truth.tilt_x_rad = 0.035;
  truth.tilt_y_rad = -0.02;
  return truth;
}

std::vector<BoardShot> RenderIntrinsicsShots(const camera::RealCameraOptions& camera, const camera::BoardSpec& board,
                                             int count, double max_tilt_rad, const RawImagingOptions& options,
                                             std::uint64_t seed) {
  CheckOptions(options);
  std::string why;
  if (!board.Check(&why)) core::ThrowInvalidInput(why);
  if (count < 1 || !(max_tilt_rad >= 0.0 && max_tilt_rad < 0.5)) {
    core::ThrowInvalidInput("board shots need count >= 1 and a tilt in [0, 0.5) rad");
  }
  const std::vector<Eigen::Vector3d> features = board.FeaturePoints();
  Eigen::Vector2d low(features.front().head<2>()), high(low);
  for (const Eigen::Vector3d& p : features) {
    low = low.cwiseMin(p.head<2>());
    high = high.cwiseMax(p.head<2>());
  }
  const Eigen::Vector2d centre_board = 0.5 * (low + high);
  const double extent_mm = (high - low).x() + 2.0 * board.pitch_mm;
  const double nominal_height_mm = camera.fx_px * extent_mm / (0.7 * camera.width_px);
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<BoardShot> shots;
  for (int attempt = 0; attempt < 200 * count && static_cast<int>(shots.size()) < count; ++attempt) {
    BoardShot shot;
    shot.camera = camera;
    shot.camera.tilt_x_rad = max_tilt_rad * (2.0 * unit(random) - 1.0);
    shot.camera.tilt_y_rad = max_tilt_rad * (2.0 * unit(random) - 1.0);
    shot.camera.height_mm = nominal_height_mm * (0.8 + 0.6 * unit(random));
    const camera::RealCamera real(shot.camera);
    const auto axis = real.PixelToFloor(Eigen::Vector2d(camera.cx_px, camera.cy_px));
    if (!axis) continue;
    const double yaw = 0.35 * (2.0 * unit(random) - 1.0);
    const Eigen::Vector2d shift(0.15 * extent_mm * (2.0 * unit(random) - 1.0),
                                0.10 * extent_mm * (2.0 * unit(random) - 1.0));
    const Eigen::Vector2d turned_centre = Eigen::Rotation2Dd(yaw) * centre_board;
    shot.camera_from_board = core::Pose2(*axis + shift - turned_centre, yaw);
    bool inside = true;
    const double margin_px = 2.0;
    for (const Eigen::Vector3d& p : features) {
      // The feature and the board around it (one pitch each way) must be in the image.
      for (const Eigen::Vector2d& d : {Eigen::Vector2d(0, 0), Eigen::Vector2d(-1, -1), Eigen::Vector2d(1, 1),
                                       Eigen::Vector2d(-1, 1), Eigen::Vector2d(1, -1)}) {
        const auto px = real.FloorToPixel(shot.camera_from_board * (p.head<2>() + 1.3 * board.pitch_mm * d));
        inside = inside && px && px->x() > margin_px && px->y() > margin_px &&
                 px->x() < camera.width_px - 1 - margin_px && px->y() < camera.height_px - 1 - margin_px;
      }
    }
    if (!inside) continue;
    shot.image = RenderBoardRaw(real, board, shot.camera_from_board, options, seed + 7919 * (shots.size() + 1));
    shots.push_back(std::move(shot));
  }
  if (static_cast<int>(shots.size()) < count) {
    core::ThrowInvalidInput("the board (" + board.ToString() + ") does not fit in the image for enough views");
  }
  return shots;
}

}  // namespace mosaicloc::sim
