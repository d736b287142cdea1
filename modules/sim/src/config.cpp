#include "mosaicloc/sim/config.hpp"

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/core/yaml.hpp"

namespace mosaicloc::sim {

void ReadSimulatorConfig(const YAML::Node& node, const std::string& file_name, SimulatorOptions* options) {
  using core::InRange;
  using core::IntegerInRange;
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, file_name, &problems);

  core::YamlMap floor = root.OptionalMap("floor");
  floor.Optional("kind", &options->floor.kind);
  std::int64_t floor_seed = static_cast<std::int64_t>(options->floor.seed);
  floor.Optional("seed", &floor_seed, IntegerInRange(0, INT64_MAX));
  options->floor.seed = static_cast<std::uint64_t>(floor_seed);
  std::string image = options->floor.image.string();
  floor.Optional("image", &image);
  options->floor.image = image;
  floor.Optional("mm_per_texel", &options->floor.mm_per_texel);
  floor.Optional("image_layout", &options->floor.image_layout);
  floor.Optional("patch_mm", &options->floor.patch_mm);
  floor.Optional("unevenness_mm", &options->floor.unevenness_mm);
  floor.Optional("unevenness_wavelength_m", &options->floor.unevenness_wavelength_m);
  // The ranges are the options' Check()s, run per section so that a complaint names its key
  // and line, then over the whole.
  floor.Check(options->floor);
  floor.Finish();

  core::YamlMap route = root.OptionalMap("route");
  RouteOptions& r = options->route;
  route.Optional("name", &r.name);
  route.Optional("straight_length_m", &r.straight_length_m);
  route.Optional("loop_width_m", &r.loop_width_m);
  route.Optional("loop_height_m", &r.loop_height_m);
  route.Optional("corner_radius_m", &r.corner_radius_m);
  route.Optional("network_scale", &r.network_scale);
  route.Optional("serpentine_rows", &r.serpentine_rows);
  route.Optional("serpentine_length_m", &r.serpentine_length_m);
  route.Optional("serpentine_spacing_m", &r.serpentine_spacing_m);
  route.Optional("speed_mps", &r.speed_mps);
  route.Optional("max_accel_mps2", &r.max_accel_mps2);
  route.Optional("max_lateral_accel_mps2", &r.max_lateral_accel_mps2);
  route.Optional("stop_s", &r.stop_s);
  route.Optional("curvature_transition_m", &r.curvature_transition_m);
  route.Optional("lateral_deviation_mm", &r.lateral_deviation_mm);
  route.Optional("crab_amplitude_deg", &r.crab_amplitude_deg);
  route.Optional("crab_wavelength_m", &r.crab_wavelength_m);
  route.Check(r);
  route.Finish();

  core::YamlMap camera = root.OptionalMap("camera");
  camera.Optional("width_px", &options->camera.width_px);
  camera.Optional("height_px", &options->camera.height_px);
  camera.Optional("mm_per_px", &options->camera.mm_per_px);
  camera.Optional("frame_rate_hz", &options->frame_rate_hz);
  camera.Optional("timestamp_jitter_ms", &options->timestamp_jitter_ms);
  camera.Optional("drop_probability", &options->drop_probability);
  camera.Optional("height_mm", &options->camera_height_mm);
  camera.Optional("height_offset_mm", &options->height_offset_mm);
  camera.Optional("height_drift_mm_per_min", &options->height_drift_mm_per_min);
  camera.Optional("residual_k1", &options->residual_k1);
  camera.CheckOwnKeys(*options, {{"camera_height_mm", "height_mm"}});
  camera.Check(options->camera);
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

  core::YamlMap suspension = root.OptionalMap("suspension");
  SuspensionOptions& u = options->suspension;
  suspension.Optional("pitch_deg_per_mps2", &u.pitch_deg_per_mps2);
  suspension.Optional("roll_deg_per_mps2", &u.roll_deg_per_mps2);
  suspension.Optional("pivot_height_mm", &u.pivot_height_mm);
  suspension.Optional("caster_x_mm", &u.caster_x_mm);
  suspension.Check(u);
  suspension.Finish();

  core::YamlMap changes = root.OptionalMap("changes");
  FloorChangeOptions& f = options->changes;
  std::int64_t changes_seed = static_cast<std::int64_t>(f.seed);
  changes.Optional("seed", &changes_seed, IntegerInRange(0, INT64_MAX));
  f.seed = static_cast<std::uint64_t>(changes_seed);
  changes.Optional("grime_fraction", &f.grime_fraction);
  changes.Optional("grime_strength", &f.grime_strength);
  changes.Optional("stains_per_m2", &f.stains_per_m2);
  changes.Optional("tyre_marks", &f.tyre_marks);
  changes.Optional("tyre_mark_width_mm", &f.tyre_mark_width_mm);
  changes.Optional("tyre_track_width_mm", &f.tyre_track_width_mm);
  core::YamlMap wet = changes.OptionalMap("wet_patch");
  wet.Optional("x_mm", &f.wet_x_mm);
  wet.Optional("y_mm", &f.wet_y_mm);
  wet.Optional("radius_mm", &f.wet_radius_mm);
  wet.Optional("strength", &f.wet_strength);
  wet.Finish();
  core::YamlMap tile = changes.OptionalMap("replaced_tile");
  tile.Optional("x_mm", &f.tile_x_mm);
  tile.Optional("y_mm", &f.tile_y_mm);
  tile.Optional("size_mm", &f.tile_size_mm);
  tile.Finish();
  core::YamlMap lane = changes.OptionalMap("lane_line");
  lane.Optional("x0_mm", &f.lane_x0_mm);
  lane.Optional("y0_mm", &f.lane_y0_mm);
  lane.Optional("x1_mm", &f.lane_x1_mm);
  lane.Optional("y1_mm", &f.lane_y1_mm);
  lane.Optional("width_mm", &f.lane_width_mm);
  lane.Optional("dn", &f.lane_dn);
  lane.Finish();
  changes.Check(f);
  changes.Finish();

  core::YamlMap relief = root.OptionalMap("relief");
  ReliefOptions& h = options->relief;
  relief.Optional("depth_mm", &h.depth_mm);
  relief.Optional("source", &h.source);
  std::string height_image = h.height_image.string();
  relief.Optional("height_image", &height_image);
  h.height_image = height_image;
  relief.Optional("low_fraction", &h.low_fraction);
  relief.Optional("slope_fraction", &h.slope_fraction);
  relief.Optional("smoothing_mm", &h.smoothing_mm);
  relief.Check(h);
  relief.Finish();

  core::YamlMap light = root.OptionalMap("light");
  LightOptions& l = options->light;
  light.Optional("sources", &l.sources);
  light.Optional("ring_radius_mm", &l.ring_radius_mm);
  light.Optional("height_over_lens_mm", &l.height_over_lens_mm);
  light.Optional("ambient", &l.ambient);
  light.Optional("ring_gain", &l.ring_gain);
  light.Check(l);
  light.Finish();

  core::YamlMap imaging = root.OptionalMap("imaging");
  ImagingOptions& i = options->imaging;
  imaging.Optional("exposure_us", &i.exposure_us);
  imaging.Optional("noise_std_dn", &i.noise_std_dn);
  imaging.Optional("vignetting", &i.vignetting);
  imaging.Optional("illumination_amplitude", &i.illumination_amplitude);
  imaging.Optional("illumination_period_s", &i.illumination_period_s);
  imaging.Optional("dust_fraction", &i.dust_fraction);
  imaging.Check(i);
  imaging.Finish();

  core::YamlMap vehicle = root.OptionalMap("vehicle");
  dataset::VehicleInfo& v = options->encoders.nominal;
  core::ReadWheelGeometry(vehicle, &v, /*required=*/false);
  vehicle.Finish();

  core::YamlMap encoders = root.OptionalMap("encoders");
  EncoderOptions& e = options->encoders;
  encoders.Optional("rate_hz", &e.rate_hz);
  encoders.Optional("left_radius_error", &e.left_radius_error);
  encoders.Optional("right_radius_error", &e.right_radius_error);
  encoders.Optional("track_width_error", &e.track_width_error);
  encoders.Optional("drive_radius_error", &e.drive_radius_error);
  encoders.Optional("wheelbase_error", &e.wheelbase_error);
  encoders.Optional("steering_offset_error_deg", &e.steering_offset_error_deg);
  encoders.Optional("steering_backlash_deg", &e.steering_backlash_deg);
  encoders.Optional("mecanum_radius_error", &e.mecanum_radius_error);
  encoders.Optional("lateral_slip", &e.lateral_slip);
  encoders.Optional("slip_std", &e.slip_std);
  encoders.Optional("initial_left_ticks", &e.initial_left_ticks, IntegerInRange(INT32_MIN, INT32_MAX));
  encoders.Optional("initial_right_ticks", &e.initial_right_ticks, IntegerInRange(INT32_MIN, INT32_MAX));
  encoders.Optional("initial_drive_ticks", &e.initial_drive_ticks, IntegerInRange(INT32_MIN, INT32_MAX));
  encoders.Optional("initial_rear_left_ticks", &e.initial_rear_left_ticks, IntegerInRange(INT32_MIN, INT32_MAX));
  encoders.Optional("initial_rear_right_ticks", &e.initial_rear_right_ticks, IntegerInRange(INT32_MIN, INT32_MAX));
  encoders.CheckOwnKeys(e);
  encoders.Finish();

  core::YamlMap run = root.OptionalMap("run");
  std::int64_t seed = static_cast<std::int64_t>(options->seed);
  run.Optional("seed", &seed, IntegerInRange(0, INT64_MAX));
  options->seed = static_cast<std::uint64_t>(seed);
  run.Optional("frames", &options->frames);
  run.Optional("laps", &options->laps);
  run.Optional("threads", &options->threads);
  run.CheckOwnKeys(*options);
  run.Finish();

  root.Finish();
  // What no section reported (a rule across sections) is reported for the file.
  if (problems.empty()) root.Check(*options);
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

SimulatorOptions SimulatorOptionsFor(const std::filesystem::path& file, const SimulatorOverrides& overrides) {
  SimulatorOptions options = SimulatorConfigOrDefaults(file);
  if (!overrides.floor.empty()) options.floor = FloorChoice::Named(overrides.floor, options.floor);
  if (overrides.floor_seed) options.floor.seed = *overrides.floor_seed;
  if (overrides.floor_mm_per_texel) options.floor.mm_per_texel = *overrides.floor_mm_per_texel;
  if (!overrides.route.empty()) options.route.name = overrides.route;
  if (overrides.frames) {
    options.frames = *overrides.frames;
    options.laps = 0;
  }
  if (overrides.laps) options.laps = *overrides.laps;
  if (overrides.speed_mps) options.route.speed_mps = *overrides.speed_mps;
  if (overrides.seed) options.seed = *overrides.seed;
  if (overrides.threads) options.threads = *overrides.threads;
  return options;
}

}  // namespace mosaicloc::sim
