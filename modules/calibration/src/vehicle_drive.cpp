#include "mosaicloc/calibration/vehicle_drive.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <vector>

#include <Eigen/Core>
#include <yaml-cpp/yaml.h>

#include "mosaicloc/calibration/flat_field.hpp"
#include "mosaicloc/camera/ideal_camera.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/core/yaml.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/estimation/odometry.hpp"
#include "mosaicloc/tracking/tracker.hpp"

namespace mosaicloc::calibration {
namespace {

// What the encoders read at each sample, as angles: the two wheels' unwrapped (the PLC's
// int32 counters may wrap) from the first sample (differential), or the drive wheel's so and
// the steering angle as its absolute encoder reads it, before the offset (tricycle);
// interpolated at any time inside the recording.
class WheelAngles {
 public:
  WheelAngles(std::vector<dataset::EncoderSample> samples, const core::WheelGeometry& wheels)
      : samples_(std::move(samples)), kind_(wheels.kind), angles_(samples_.size(), Eigen::Vector2d::Zero()) {
    const double rad_per_tick = 2.0 * M_PI / static_cast<double>(wheels.ticks_per_revolution);
    const double steering_rad_per_tick = 2.0 * M_PI / static_cast<double>(wheels.steering_ticks_per_revolution);
    double first = 0.0, second = 0.0;  // unwrapped tick counts
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      const dataset::EncoderSample& s = samples_[i];
      if (kind_ == core::DriveKind::kTricycle) {
        if (i > 0) first += estimation::TickDelta(samples_[i - 1].counts.drive_ticks, s.counts.drive_ticks);
        angles_[i] = {rad_per_tick * first, steering_rad_per_tick * s.counts.steering_ticks};
      } else {
        if (i > 0) {
          first += estimation::TickDelta(samples_[i - 1].counts.left_ticks, s.counts.left_ticks);
          second += estimation::TickDelta(samples_[i - 1].counts.right_ticks, s.counts.right_ticks);
        }
        angles_[i] = rad_per_tick * Eigen::Vector2d(first, second);
      }
    }
  }

  /// The two angles at `time`, rad; nothing outside the recording.
  std::optional<Eigen::Vector2d> At(core::Timestamp time) const {
    const auto after = std::lower_bound(samples_.begin(), samples_.end(), time,
                                        [](const dataset::EncoderSample& s, core::Timestamp t) { return s.time < t; });
    if (after == samples_.end()) return std::nullopt;
    const std::size_t j = static_cast<std::size_t>(after - samples_.begin());
    if (after->time == time) return angles_[j];
    if (j == 0) return std::nullopt;
    const double a = static_cast<double>((time - samples_[j - 1].time).count()) /
                     static_cast<double>((samples_[j].time - samples_[j - 1].time).count());
    return angles_[j - 1] + a * (angles_[j] - angles_[j - 1]);
  }

  /// What the wheels did between two readings of At: each wheel's turn, or the drive wheel's
  /// and the steering angle's mean over the interval.
  WheelTurn Between(const Eigen::Vector2d& before, const Eigen::Vector2d& after) const {
    WheelTurn turn;
    if (kind_ == core::DriveKind::kTricycle) {
      turn.drive_wheel_rad = after(0) - before(0);
      turn.steering_rad = 0.5 * (before(1) + after(1));
    } else {
      turn.left_wheel_rad = after(0) - before(0);
      turn.right_wheel_rad = after(1) - before(1);
    }
    return turn;
  }

 private:
  std::vector<dataset::EncoderSample> samples_;
  core::DriveKind kind_;
  std::vector<Eigen::Vector2d> angles_;
};

// Share of the frame both images show, from the displacement of the frame's corners.
// Why a mecanum vehicle's file or drive is refused.
constexpr const char* kMecanumRefusal =
    "a mecanum vehicle has no calibration drive: the localizer learns its wheels' common scale and its sideways "
    "scale from fixes (a run's and a replay's summary give them)";

double Overlap(const core::Pose2& motion, double width_mm, double height_mm) {
  double shift_x = 0.0, shift_y = 0.0;
  for (const double x : {-0.5 * width_mm, 0.5 * width_mm}) {
    for (const double y : {-0.5 * height_mm, 0.5 * height_mm}) {
      const Eigen::Vector2d moved = motion * Eigen::Vector2d(x, y);
      shift_x = std::max(shift_x, std::abs(moved.x() - x));
      shift_y = std::max(shift_y, std::abs(moved.y() - y));
    }
  }
  return std::max(0.0, 1.0 - shift_x / width_mm) * std::max(0.0, 1.0 - shift_y / height_mm);
}

// The camera's motion for a wheel turn under the nominal geometry (one arc approximated by
// its chord: the prior of a registration, not a measurement).
core::Pose2 NominalMotion(const VehicleCalibrationOptions& nominal, const WheelTurn& turn) {
  const VehicleParameters wheels = ToVehicleParameters(nominal.initial_vehicle_from_camera, nominal.initial_wheels);
  const Eigen::Vector2d moved =
      ArcLengthAndTurn(turn, nominal.initial_wheels.kind, Eigen::Vector3d(wheels[3], wheels[4], wheels[5]));
  const core::Pose2& x = nominal.initial_vehicle_from_camera;
  return x.Inverse() * core::Pose2(moved.x(), 0.0, moved.y()) * x;
}

// The tracker's matcher, set for accuracy rather than speed: the whole frame cut into
// templates (every part of the overlap used), and a wider low-pass, which keeps the
// sub-pixel estimate from locking onto the pixel grid (a bias that repeats with the same
// fractional shift and would not average out).
tracking::TrackerOptions AccurateMatcher() {
  tracking::TrackerOptions options;
  options.templates.mode = tracking::TemplateMode::kTiled;
  options.templates.tile_cols = 6;
  options.templates.tile_rows = 4;
  options.refine.prefilter_sigma_px = 2.0;
  return options;
}

}  // namespace

bool VehicleDriveOptions::Check(std::string* why) const {
  if (baselines < 0 || baselines > 100) {
    *why = "vehicle drive baselines must be in [0, 100]";
    return false;
  }
  if (!(min_overlap > 0.0 && min_overlap < 1.0)) {
    *why = "vehicle drive min_overlap must be in (0, 1)";
    return false;
  }
  if (!(prior_sigma_mm > 0.0 && prior_sigma_rad > 0.0)) {
    *why = "vehicle drive prior sigmas must be > 0";
    return false;
  }
  return true;
}

VehicleDriveResult CalibrateVehicleFromDrive(const std::filesystem::path& dataset_dir,
                                             const VehicleDriveOptions& options,
                                             const std::function<void(double)>& progress) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput(why);
  const dataset::DatasetReader reader(dataset_dir);
  const dataset::DatasetInfo& info = reader.info();
  if (info.vehicle.kind == core::DriveKind::kMecanum) {
    core::ThrowInvalidInput(dataset_dir.string() + ": dataset.yaml: vehicle.kind: " + kMecanumRefusal);
  }
  std::vector<dataset::EncoderSample> encoders;
  for (auto stream = reader.Encoders(); auto sample = stream.Next();) encoders.push_back(*sample);
  if (encoders.size() < 2) core::ThrowInvalidInput(dataset_dir.string() + ": the drive has no encoder samples");
  const WheelAngles wheels(std::move(encoders), info.vehicle);

  camera::IdealCameraOptions camera_options;
  camera_options.width_px = info.camera.width_px;
  camera_options.height_px = info.camera.height_px;
  camera_options.mm_per_px = info.camera.mm_per_px;
  const camera::IdealCamera camera(camera_options);
  const tracking::Tracker tracker(camera, AccurateMatcher());
  VehicleCalibrationOptions fit;
  fit.initial_wheels = info.vehicle;
  fit.initial_vehicle_from_camera = info.camera.vehicle_from_camera;

  // The lens's vignetting stays on the pixels while the floor moves: estimated from the drive
  // itself and divided out before registering.
  cv::Mat gain;
  int total = 0;
  {
    FlatFieldEstimator flat;
    for (auto all = reader.Frames(); auto frame = all.Next();) {
      flat.Add(frame->image);
      ++total;
    }
    gain = flat.Gain();
  }

  struct Kept {
    cv::Mat image;
    WheelTurn turn;                 // since the previous frame
    core::Pose2 chain_from_camera;  // from the consecutive registrations
  };
  std::deque<Kept> window;
  std::vector<DriveStep> steps;
  VehicleDriveResult result;
  Eigen::Vector2d previous_angles = Eigen::Vector2d::Zero();
  std::optional<core::Pose2> last_motion;
  const double width_mm = camera.width_px() * camera.mm_per_px(), height_mm = camera.height_px() * camera.mm_per_px();
  const Eigen::Matrix3d consecutive_prior =
      Eigen::Vector3d(options.prior_sigma_mm * options.prior_sigma_mm, options.prior_sigma_mm * options.prior_sigma_mm,
                      options.prior_sigma_rad * options.prior_sigma_rad)
          .asDiagonal();
  // The chain predicts the longer baselines to a fraction of a pixel.
  const Eigen::Matrix3d chained_prior = Eigen::Vector3d(0.25, 0.25, 1e-6).asDiagonal();
  for (auto stream = reader.Frames(); auto frame = stream.Next();) {
    ++result.frames;
    if (progress) progress(static_cast<double>(result.frames) / std::max(1, total));
    const auto angles = wheels.At(frame->time);
    if (!angles) continue;
    Kept current{DivideByGain(frame->image, gain), {}, core::Pose2()};
    if (!window.empty()) {
      DriveStep step;
      current.turn = wheels.Between(previous_angles, *angles);
      step.arcs = {current.turn};
      // The prior: the last registered motion (the drive is smooth), or the nominal odometry.
      const core::Pose2 prior = last_motion.value_or(NominalMotion(fit, current.turn));
      const tracking::TrackResult r =
          tracking::RegisterFrames(tracker, window.back().image, current.image, prior, consecutive_prior);
      if (r.ok()) {
        step.previous_from_current_camera = r.world_from_camera;
        last_motion = r.world_from_camera;
        steps.push_back(step);
        ++result.consecutive_steps;
        current.chain_from_camera = window.back().chain_from_camera * r.world_from_camera;
        while (window.size() > 1 && Overlap(window.front().chain_from_camera.Inverse() * current.chain_from_camera,
                                            width_mm, height_mm) < options.min_overlap) {
          window.pop_front();
        }
        // Up to `baselines` of the earlier frames, evenly spread, the oldest first.
        const int earlier = static_cast<int>(window.size()) - 1;
        const int used = std::min(earlier, options.baselines);
        for (int n = 0; n < used; ++n) {
          const int index = static_cast<int>(std::lround(static_cast<double>(n) * earlier / used));
          const Kept& from = window[static_cast<std::size_t>(index)];
          const tracking::TrackResult far = tracking::RegisterFrames(
              tracker, from.image, current.image, from.chain_from_camera.Inverse() * current.chain_from_camera,
              chained_prior);
          if (!far.ok()) continue;
          DriveStep long_step;
          long_step.previous_from_current_camera = far.world_from_camera;
          for (std::size_t i = static_cast<std::size_t>(index) + 1; i < window.size(); ++i) {
            long_step.arcs.push_back(window[i].turn);
          }
          long_step.arcs.push_back(current.turn);
          steps.push_back(long_step);
        }
      } else {
        ++result.not_registered;
        last_motion.reset();
        window.clear();
        core::Log().debug("frame {}: not registered to the previous one: {}", frame->time.nanoseconds(), r.reason);
      }
    }
    window.push_back(std::move(current));
    previous_angles = *angles;
  }
  // The pairs of a frame share its noise: the uncertainty counts frames, not pairs.
  fit.independent_steps = result.consecutive_steps;
  result.steps = static_cast<int>(steps.size());
  result.calibration = CalibrateVehicle(steps, fit);
  if (!result.calibration.converged) {
    core::ThrowInvalidInput(dataset_dir.string() + ": vehicle calibration failed: " + result.calibration.message +
                            " (" + std::to_string(result.consecutive_steps) + " consecutive frame pairs registered, " +
                            std::to_string(result.not_registered) + " not)");
  }
  result.kind = info.vehicle.kind;
  result.value = ToVehicleParameters(result.calibration.vehicle_from_camera, result.calibration.wheels);
  for (std::size_t i = 0; i < result.sigma.size(); ++i) result.sigma[i] = result.calibration.sigma(static_cast<int>(i));
  if (const std::optional<dataset::VehicleTruth> truth = dataset::RecordedVehicleTruth(info)) {
    result.truth = ToVehicleParameters(truth->vehicle_from_camera, truth->wheels);
  }
  return result;
}

const VehicleParameterNames& ParameterNamesOf(core::DriveKind kind) {
  constexpr double kDeg = 180.0 / M_PI;
  static const VehicleParameterNames differential{
      {"camera x mm", "camera y mm", "camera yaw deg", "left radius mm", "right radius mm", "track width mm"},
      {"x_mm", "y_mm", "yaw_deg", "left_wheel_radius_mm", "right_wheel_radius_mm", "track_width_mm"},
      {1.0, 1.0, kDeg, 1.0, 1.0, 1.0}};
  static const VehicleParameterNames tricycle{
      {"camera x mm", "camera y mm", "camera yaw deg", "drive radius mm", "wheelbase mm", "steering offset deg"},
      {"x_mm", "y_mm", "yaw_deg", "drive_wheel_radius_mm", "wheelbase_mm", "steering_offset_deg"},
      {1.0, 1.0, kDeg, 1.0, 1.0, kDeg}};
  return kind == core::DriveKind::kTricycle ? tricycle : differential;
}

VehicleParameters ToVehicleParameters(const core::Pose2& vehicle_from_camera, const core::WheelGeometry& wheels) {
  const core::Pose2& x = vehicle_from_camera;
  if (wheels.kind == core::DriveKind::kTricycle) {
    return {x.x_mm(), x.y_mm(), x.yaw_rad(), wheels.drive_wheel_radius_mm, wheels.wheelbase_mm,
            wheels.steering_offset_deg * M_PI / 180.0};
  }
  return {x.x_mm(), x.y_mm(), x.yaw_rad(), wheels.left_wheel_radius_mm, wheels.right_wheel_radius_mm,
          wheels.track_width_mm};
}

void WriteVehicleCalibration(const std::filesystem::path& file, const VehicleCalibrationFile& calibration,
                             const std::string& comment) {
  const core::Pose2& x = calibration.vehicle_from_camera;
  const core::WheelGeometry& w = calibration.wheels;
  const VehicleParameters& sigma = calibration.sigma;
  YAML::Emitter yaml;
  yaml.SetDoublePrecision(17);
  yaml << YAML::Comment(comment);
  yaml << YAML::BeginMap;
  yaml << YAML::Key << "format_version" << YAML::Value << 1;
  const auto pose = [&yaml](const char* key, double x_mm, double y_mm, double yaw_rad) {
    yaml << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginMap;
    yaml << YAML::Key << "x_mm" << YAML::Value << x_mm << YAML::Key << "y_mm" << YAML::Value << y_mm;
    yaml << YAML::Key << "yaw_rad" << YAML::Value << yaw_rad << YAML::EndMap;
  };
  yaml << YAML::Key << "kind" << YAML::Value << core::ToString(w.kind);
  pose("vehicle_from_camera", x.x_mm(), x.y_mm(), x.yaw_rad());
  pose("vehicle_from_camera_sigma", sigma[0], sigma[1], sigma[2]);
  // The kind's three, under the keys a dataset's and a run's `vehicle:` give them.
  const VehicleParameterNames& names = ParameterNamesOf(w.kind);
  const VehicleParameters value = ToVehicleParameters(x, w);
  for (std::size_t i = 3; i < 6; ++i) {
    yaml << YAML::Key << names.keys[i] << YAML::Value << value[i] * names.shown_per_value[i];
  }
  yaml << YAML::Key << "wheel_sigma" << YAML::Value << YAML::Flow << YAML::BeginMap;
  for (std::size_t i = 3; i < 6; ++i) {
    yaml << YAML::Key << names.keys[i] << YAML::Value << sigma[i] * names.shown_per_value[i];
  }
  yaml << YAML::EndMap;
  yaml << YAML::EndMap;
  if (!yaml.good()) core::ThrowRuntime(file.string() + ": cannot write YAML: " + yaml.GetLastError());
  core::WriteFileAtomically(file, std::string(yaml.c_str()) + "\n");
}

void WriteVehicleCalibration(const std::filesystem::path& file, const VehicleDriveResult& drive,
                             const std::filesystem::path& dataset) {
  WriteVehicleCalibration(
      file, {drive.calibration.vehicle_from_camera, drive.calibration.wheels, drive.sigma},
      "mosaicloc vehicle calibration (mosaicloc calibrate vehicle --dataset " + dataset.string() + ")\nfrom " +
          std::to_string(drive.steps) + " registered frame pairs (" + std::to_string(drive.consecutive_steps) +
          " consecutive); *_sigma are one-sigma uncertainties.\n"
          "Copy the values into run.yaml (camera.vehicle_from_camera, vehicle.*).");
}

VehicleCalibrationFile ReadVehicleCalibration(const std::filesystem::path& file) {
  const YAML::Node node = core::LoadYamlFile(file);
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, file.string(), &problems);
  VehicleCalibrationFile c;
  int version = 0;
  root.Required("format_version", &version, core::IntegerInRange(1, 1));
  double x = 0.0, y = 0.0, yaw = 0.0;
  core::YamlMap mounting = root.RequiredMap("vehicle_from_camera");
  mounting.Required("x_mm", &x);
  mounting.Required("y_mm", &y);
  mounting.Required("yaw_rad", &yaw, core::InRange(-M_PI, M_PI));
  mounting.Finish();
  c.vehicle_from_camera = core::Pose2(x, y, yaw);
  core::YamlMap mounting_sigma = root.RequiredMap("vehicle_from_camera_sigma");
  mounting_sigma.Required("x_mm", &c.sigma[0], core::NonNegative());
  mounting_sigma.Required("y_mm", &c.sigma[1], core::NonNegative());
  mounting_sigma.Required("yaw_rad", &c.sigma[2], core::NonNegative());
  mounting_sigma.Finish();
  root.OptionalEnum("kind", &c.wheels.kind, core::kDriveKinds);  // differential when absent
  if (c.wheels.kind == core::DriveKind::kMecanum) {
    core::ThrowInvalidInput(file.string() + ": kind: " + kMecanumRefusal);
  }
  const VehicleParameterNames& names = ParameterNamesOf(c.wheels.kind);
  double* const wheel_values[2][3] = {
      {&c.wheels.left_wheel_radius_mm, &c.wheels.right_wheel_radius_mm, &c.wheels.track_width_mm},
      {&c.wheels.drive_wheel_radius_mm, &c.wheels.wheelbase_mm, &c.wheels.steering_offset_deg}};
  const int kind_index = c.wheels.kind == core::DriveKind::kTricycle ? 1 : 0;
  for (std::size_t i = 3; i < 6; ++i) root.Required(names.keys[i], wheel_values[kind_index][i - 3]);
  root.Check(c.wheels);
  core::YamlMap wheel_sigma = root.RequiredMap("wheel_sigma");
  for (std::size_t i = 3; i < 6; ++i) {
    wheel_sigma.Required(names.keys[i], &c.sigma[i], core::NonNegative());
    c.sigma[i] /= names.shown_per_value[i];
  }
  wheel_sigma.Finish();
  root.Finish();
  problems.ThrowIfAny();
  return c;
}

}  // namespace mosaicloc::calibration
