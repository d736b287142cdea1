#include "mosaicloc/sim/config.hpp"

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/core/yaml.hpp"

namespace mosaicloc::sim {

void ReadSimulatorConfig(const YAML::Node& node, const std::string& file_name, SimulatorOptions* options) {
  using core::InRange;
  using core::IntegerInRange;
  using core::NonNegative;
  using core::Positive;
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, file_name, &problems);

  core::YamlMap floor = root.OptionalMap("floor");
  floor.Optional("kind", &options->floor.kind, core::OneOf({"procedural", "image"}));
  std::int64_t floor_seed = static_cast<std::int64_t>(options->floor.seed);
  floor.Optional("seed", &floor_seed, IntegerInRange(0, INT64_MAX));
  options->floor.seed = static_cast<std::uint64_t>(floor_seed);
  std::string image = options->floor.image.string();
  floor.Optional("image", &image);
  options->floor.image = image;
  floor.Optional("mm_per_texel", &options->floor.mm_per_texel, InRange(0.0, 100.0));
  floor.Finish();

  core::YamlMap route = root.OptionalMap("route");
  RouteOptions& r = options->route;
  route.Optional("name", &r.name, core::OneOf({"straight", "loop", "network", "serpentine"}));
  route.Optional("straight_length_m", &r.straight_length_m, Positive());
  route.Optional("loop_width_m", &r.loop_width_m, Positive());
  route.Optional("loop_height_m", &r.loop_height_m, Positive());
  route.Optional("corner_radius_m", &r.corner_radius_m, Positive());
  route.Optional("network_scale", &r.network_scale, InRange(0.05, 100.0));
  route.Optional("serpentine_rows", &r.serpentine_rows, IntegerInRange(2, 10000));
  route.Optional("serpentine_length_m", &r.serpentine_length_m, Positive());
  route.Optional("serpentine_spacing_m", &r.serpentine_spacing_m, Positive());
  route.Optional("speed_mps", &r.speed_mps, InRange(0.001, 30.0));
  route.Optional("max_accel_mps2", &r.max_accel_mps2, Positive());
  route.Optional("max_lateral_accel_mps2", &r.max_lateral_accel_mps2, Positive());
  route.Optional("stop_s", &r.stop_s, NonNegative());
  route.Optional("lateral_deviation_mm", &r.lateral_deviation_mm, InRange(0.0, 99.0));
  route.Finish();

  core::YamlMap camera = root.OptionalMap("camera");
  camera.Optional("width_px", &options->camera.width_px, IntegerInRange(8, 16384));
  camera.Optional("height_px", &options->camera.height_px, IntegerInRange(8, 16384));
  camera.Optional("mm_per_px", &options->camera.mm_per_px, InRange(1e-3, 99.0));
  camera.Optional("frame_rate_hz", &options->frame_rate_hz, InRange(0.1, 10000.0));
  camera.Optional("timestamp_jitter_ms", &options->timestamp_jitter_ms, InRange(0.0, 100.0));
  camera.Optional("drop_probability", &options->drop_probability, InRange(0.0, 0.99));
  core::YamlMap mount = camera.OptionalMap("vehicle_from_camera");
  double x_mm = options->vehicle_from_camera.x_mm();
  double y_mm = options->vehicle_from_camera.y_mm();
  double yaw_rad = options->vehicle_from_camera.yaw_rad();
  mount.Optional("x_mm", &x_mm);
  mount.Optional("y_mm", &y_mm);
  mount.Optional("yaw_rad", &yaw_rad, InRange(-4.0, 4.0));
  mount.Finish();
  options->vehicle_from_camera = core::Pose2(x_mm, y_mm, yaw_rad);
  camera.Finish();

  core::YamlMap imaging = root.OptionalMap("imaging");
  ImagingOptions& i = options->imaging;
  imaging.Optional("exposure_us", &i.exposure_us, InRange(0.0, 100000.0));
  imaging.Optional("noise_std_dn", &i.noise_std_dn, InRange(0.0, 64.0));
  imaging.Optional("vignetting", &i.vignetting, InRange(0.0, 0.99));
  imaging.Optional("illumination_amplitude", &i.illumination_amplitude, InRange(0.0, 0.99));
  imaging.Optional("illumination_period_s", &i.illumination_period_s, Positive());
  imaging.Optional("dust_fraction", &i.dust_fraction, InRange(0.0, 0.5));
  imaging.Finish();

  core::YamlMap vehicle = root.OptionalMap("vehicle");
  dataset::VehicleInfo& v = options->encoders.nominal;
  core::ReadWheelGeometry(vehicle, &v, /*required=*/false);
  vehicle.Finish();

  core::YamlMap encoders = root.OptionalMap("encoders");
  EncoderOptions& e = options->encoders;
  encoders.Optional("rate_hz", &e.rate_hz, InRange(0.1, 10000.0));
  encoders.Optional("left_radius_error", &e.left_radius_error, InRange(-0.49, 0.49));
  encoders.Optional("right_radius_error", &e.right_radius_error, InRange(-0.49, 0.49));
  encoders.Optional("track_width_error", &e.track_width_error, InRange(-0.49, 0.49));
  encoders.Optional("slip_std", &e.slip_std, InRange(0.0, 0.49));
  encoders.Optional("initial_left_ticks", &e.initial_left_ticks, IntegerInRange(INT32_MIN, INT32_MAX));
  encoders.Optional("initial_right_ticks", &e.initial_right_ticks, IntegerInRange(INT32_MIN, INT32_MAX));
  encoders.Finish();

  core::YamlMap run = root.OptionalMap("run");
  std::int64_t seed = static_cast<std::int64_t>(options->seed);
  run.Optional("seed", &seed, IntegerInRange(0, INT64_MAX));
  options->seed = static_cast<std::uint64_t>(seed);
  run.Optional("frames", &options->frames, IntegerInRange(1, 100'000'000));
  run.Optional("laps", &options->laps, IntegerInRange(0, 100'000));
  run.Optional("threads", &options->threads, IntegerInRange(1, 64));
  run.Finish();

  root.Finish();
  problems.ThrowIfAny();
}

SimulatorOptions LoadSimulatorConfig(const std::filesystem::path& file) {
  SimulatorOptions options;
  ReadSimulatorConfig(core::LoadYamlFile(file), file.string(), &options);
  return options;
}

SimulatorOptions SimulatorConfigOrDefaults(const std::filesystem::path& file) {
  if (file.empty()) return SimulatorOptions{};
  core::Log().info("the simulated drive of {}", file.string());
  return LoadSimulatorConfig(file);
}

}  // namespace mosaicloc::sim
