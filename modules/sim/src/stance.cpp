#include "mosaicloc/sim/stance.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include <Eigen/Geometry>

namespace mosaicloc::sim {
namespace {

constexpr int kWaves = 8;

Eigen::Matrix3d RotationX(double angle) { return Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitX()).toRotationMatrix(); }
Eigen::Matrix3d RotationY(double angle) { return Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()).toRotationMatrix(); }
Eigen::Matrix3d RotationZ(double angle) { return Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix(); }

double Radians(double degrees) { return degrees * std::numbers::pi / 180.0; }

}  // namespace

FloorShape::FloorShape(double rms_mm, double wavelength_m, std::uint64_t seed) {
  if (!(rms_mm > 0.0)) return;
  std::mt19937_64 rng(seed ^ 0x5ea1f100ULL);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  // Equal amplitudes; a sum of n cosines of amplitude a has the standard deviation a sqrt(n / 2).
  const double amplitude = rms_mm * std::sqrt(2.0 / kWaves);
  for (int i = 0; i < kWaves; ++i) {
    const double direction = 2.0 * std::numbers::pi * unit(rng);
    const double wavelength_mm = 1000.0 * wavelength_m * (1.0 + unit(rng));
    const double k = 2.0 * std::numbers::pi / wavelength_mm;
    waves_.push_back({Eigen::Vector2d(k * std::cos(direction), k * std::sin(direction)), amplitude,
                      2.0 * std::numbers::pi * unit(rng)});
  }
}

double FloorShape::HeightMm(const Eigen::Vector2d& xy_mm) const {
  double height = 0.0;
  for (const Wave& wave : waves_) height += wave.amplitude_mm * std::cos(wave.wavevector.dot(xy_mm) + wave.phase);
  return height;
}

Eigen::Vector2d FloorShape::Gradient(const Eigen::Vector2d& xy_mm) const {
  Eigen::Vector2d gradient = Eigen::Vector2d::Zero();
  for (const Wave& wave : waves_) {
    gradient -= wave.amplitude_mm * std::sin(wave.wavevector.dot(xy_mm) + wave.phase) * wave.wavevector;
  }
  return gradient;
}

double FloorShape::HeightAndGradient(const Eigen::Vector2d& xy_mm, Eigen::Vector2d* gradient) const {
  double height = 0.0;
  *gradient = Eigen::Vector2d::Zero();
  for (const Wave& wave : waves_) {
    const double argument = wave.wavevector.dot(xy_mm) + wave.phase;
    height += wave.amplitude_mm * std::cos(argument);
    *gradient -= wave.amplitude_mm * std::sin(argument) * wave.wavevector;
  }
  return height;
}

Eigen::Vector2d FloorShape::Intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const {
  // Newton on g(tau) = origin_z + tau d_z - H(origin_xy + tau d_xy); slopes are small, so it
  // converges in two or three steps to far below a nanometre, where it stops.
  double tau = (origin.z() - HeightMm(origin.head<2>())) / -direction.z();
  for (int i = 0; i < 4 && !flat(); ++i) {
    const Eigen::Vector2d xy = origin.head<2>() + tau * direction.head<2>();
    Eigen::Vector2d gradient;
    const double g = origin.z() + tau * direction.z() - HeightAndGradient(xy, &gradient);
    const double step = g / (direction.z() - gradient.dot(direction.head<2>()));
    tau -= step;
    if (std::abs(step) < 1e-9) break;
  }
  return origin.head<2>() + tau * direction.head<2>();
}

bool SuspensionOptions::Check(std::string* why) const {
  if (!(std::abs(pitch_deg_per_mps2) <= 5.0 && std::abs(roll_deg_per_mps2) <= 5.0)) {
    *why = "pitch_deg_per_mps2 and roll_deg_per_mps2 must be within [-5, 5]";
    return false;
  }
  if (!(pivot_height_mm >= -1000.0 && pivot_height_mm <= 2000.0)) {
    *why = "pivot_height_mm must be in [-1000, 2000]";
    return false;
  }
  if (!(std::abs(caster_x_mm) >= 50.0 && std::abs(caster_x_mm) <= 5000.0)) {
    *why = "caster_x_mm must be between 50 and 5000 mm ahead of or behind the axle";
    return false;
  }
  return true;
}

CameraPlacement::CameraPlacement(const CameraPlacementOptions& options, double mm_per_px, double cx, double cy)
    : options_(options),
      mm_per_px_(mm_per_px),
      cx_(cx),
      cy_(cy),
      floor_(options.unevenness_mm, options.unevenness_wavelength_m, options.floor_seed) {}

bool CameraPlacement::straight_down() const {
  const SuspensionOptions& s = options_.suspension;
  return floor_.flat() && options_.height_drift_mm_per_min == 0.0 && options_.residual_k1 == 0.0 &&
         s.pitch_deg_per_mps2 == 0.0 && s.roll_deg_per_mps2 == 0.0;
}

CameraView CameraPlacement::At(const core::Pose2& world_from_vehicle, const Eigen::Vector2d& acceleration_mps2,
                               double time_s) const {
  // The contact plane through the two drive wheels and the caster.
  const double half_track = 0.5 * options_.track_width_mm;
  const SuspensionOptions& s = options_.suspension;
  const double z_left = floor_.HeightMm(world_from_vehicle * Eigen::Vector2d(0.0, half_track));
  const double z_right = floor_.HeightMm(world_from_vehicle * Eigen::Vector2d(0.0, -half_track));
  const double z_caster = floor_.HeightMm(world_from_vehicle * Eigen::Vector2d(s.caster_x_mm, 0.0));
  const double z_origin = 0.5 * (z_left + z_right);
  const double slope_x = (z_caster - z_origin) / s.caster_x_mm;
  const double slope_y = (z_left - z_right) / options_.track_width_mm;
  // Rotation about y by a positive angle lowers the nose; about x, raises the left side.
  const Eigen::Matrix3d world_from_plane =
      RotationZ(world_from_vehicle.yaw_rad()) * RotationY(-std::atan(slope_x)) * RotationX(std::atan(slope_y));
  const Eigen::Matrix3d plane_from_body = RotationY(-Radians(s.pitch_deg_per_mps2) * acceleration_mps2.x()) *
                                          RotationX(Radians(s.roll_deg_per_mps2) * acceleration_mps2.y());
  const double height = options_.calibrated_height_mm + options_.height_offset_mm +
                        options_.height_drift_mm_per_min * time_s / 60.0;
  const Eigen::Vector3d mount(options_.vehicle_from_camera.x_mm(), options_.vehicle_from_camera.y_mm(), height);
  const Eigen::Vector3d pivot(0.0, 0.0, s.pivot_height_mm);
  CameraView view;
  view.lens_mm = Eigen::Vector3d(world_from_vehicle.x_mm(), world_from_vehicle.y_mm(), z_origin) +
                 world_from_plane * (pivot + plane_from_body * (mount - pivot));
  view.world_from_camera = world_from_plane * plane_from_body * RotationZ(options_.vehicle_from_camera.yaw_rad());
  return view;
}

Eigen::Vector2d CameraPlacement::PixelToWorld(const CameraView& view, const Eigen::Vector2d& pixel) const {
  const double f = options_.calibrated_height_mm / mm_per_px_;
  Eigen::Vector2d normalized((pixel.x() - cx_) / f, -(pixel.y() - cy_) / f);
  normalized *= 1.0 + options_.residual_k1 * normalized.squaredNorm();
  const Eigen::Vector3d direction = view.world_from_camera * Eigen::Vector3d(normalized.x(), normalized.y(), -1.0);
  return floor_.Intersect(view.lens_mm, direction);
}

dataset::CameraTruth CameraPlacement::Truth(const CameraView& view, const core::Pose2& world_from_vehicle) const {
  const Eigen::Vector3d axis = -view.world_from_camera.col(2);
  const Eigen::Vector2d centre = floor_.Intersect(view.lens_mm, axis);
  const Eigen::Vector2d gradient = floor_.Gradient(centre);
  const Eigen::Vector3d normal = Eigen::Vector3d(-gradient.x(), -gradient.y(), 1.0).normalized();
  const Eigen::Vector3d on_floor(centre.x(), centre.y(), floor_.HeightMm(centre));
  dataset::CameraTruth truth;
  truth.height_mm = (view.lens_mm - on_floor).dot(normal);
  // The floor's normal in camera axes is (-tilt_y, tilt_x, 1) to first order.
  const Eigen::Vector3d n = view.world_from_camera.transpose() * normal;
  truth.tilt_x_rad = std::atan2(n.y(), n.z());
  truth.tilt_y_rad = std::atan2(-n.x(), n.z());
  const Eigen::Vector2d nominal = world_from_vehicle * options_.vehicle_from_camera.translation_mm();
  truth.centre_offset_mm = world_from_vehicle.Rotation().transpose() * (centre - nominal);
  return truth;
}

}  // namespace mosaicloc::sim
