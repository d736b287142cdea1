#include "mosaicloc/runtime/run_config.hpp"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/yaml.hpp"

namespace mosaicloc::runtime {
namespace {

using core::InRange;
using core::IntegerInRange;
using core::Positive;

void ReadField(core::YamlMap* registers, const char* key, io::RegisterField* field) {
  core::YamlMap m = registers->OptionalMap(key);
  m.Optional("address", &field->address, IntegerInRange(0, 65535));
  m.Optional("width_bits", &field->width_bits, IntegerInRange(16, 32));
  m.Optional("signed", &field->is_signed);
  m.Optional("scale", &field->scale, Positive());
  m.OptionalEnum("word_order", &field->word_order, io::kWordOrders);
  m.Finish();
}

// Reads the fields; the map's consistency is then reported on `parent` (the plc section).
// Returns whether the map is consistent.
bool ReadRegisters(core::YamlMap* parent, core::YamlMap* registers, io::RegisterMap* map) {
  // One word order for every 32-bit field, unless a field says otherwise.
  if (registers->Has("word_order")) {
    io::WordOrder word_order = io::WordOrder::kHighFirst;
    registers->OptionalEnum("word_order", &word_order, io::kWordOrders);
    for (io::RegisterField* field : {&map->left_ticks, &map->right_ticks, &map->drive_ticks, &map->steering_ticks,
                                     &map->front_left_ticks, &map->front_right_ticks, &map->rear_left_ticks,
                                     &map->rear_right_ticks, &map->plc_heartbeat, &map->fix_request,
                                     &map->relocalize_request,
                                     &map->fix_x, &map->fix_y, &map->fix_yaw, &map->fix_status, &map->fix_quality,
                                     &map->fix_request_echo, &map->heartbeat, &map->fix_mode}) {
      field->word_order = word_order;
    }
  }
  ReadField(registers, "left_ticks", &map->left_ticks);
  ReadField(registers, "right_ticks", &map->right_ticks);
  ReadField(registers, "drive_ticks", &map->drive_ticks);
  ReadField(registers, "steering_ticks", &map->steering_ticks);
  ReadField(registers, "front_left_ticks", &map->front_left_ticks);
  ReadField(registers, "front_right_ticks", &map->front_right_ticks);
  ReadField(registers, "rear_left_ticks", &map->rear_left_ticks);
  ReadField(registers, "rear_right_ticks", &map->rear_right_ticks);
  ReadField(registers, "plc_heartbeat", &map->plc_heartbeat);
  ReadField(registers, "fix_request", &map->fix_request);
  ReadField(registers, "relocalize_request", &map->relocalize_request);
  ReadField(registers, "fix_x", &map->fix_x);
  ReadField(registers, "fix_y", &map->fix_y);
  ReadField(registers, "fix_yaw", &map->fix_yaw);
  ReadField(registers, "fix_status", &map->fix_status);
  ReadField(registers, "fix_quality", &map->fix_quality);
  ReadField(registers, "fix_request_echo", &map->fix_request_echo);
  ReadField(registers, "heartbeat", &map->heartbeat);
  ReadField(registers, "fix_mode", &map->fix_mode);
  registers->Finish();
  std::string why;
  if (map->Check(&why)) return true;
  parent->AddProblem("registers", why);
  return false;
}

void ReadPose(core::YamlMap* parent, const char* key, core::Pose2* pose) {
  core::YamlMap m = parent->OptionalMap(key);
  double x = pose->x_mm(), y = pose->y_mm(), yaw = pose->yaw_rad();
  m.Optional("x_mm", &x, InRange(-1e9, 1e9));
  m.Optional("y_mm", &y, InRange(-1e9, 1e9));
  m.Optional("yaw_rad", &yaw, InRange(-10.0, 10.0));
  m.Finish();
  *pose = core::Pose2(x, y, yaw);
}

}  // namespace

void ReadRegisterMap(const YAML::Node& node, const std::string& file_name, io::RegisterMap* map) {
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, file_name, &problems);
  core::YamlMap plc = root.OptionalMap("plc");
  core::YamlMap registers = plc.OptionalMap("registers");
  ReadRegisters(&plc, &registers, map);
  problems.ThrowIfAny();
}

RunConfig LoadRunConfig(const std::filesystem::path& file) {
  const YAML::Node node = core::LoadYamlFile(file);
  const std::filesystem::path folder = file.parent_path();
  const auto resolve = [&](const std::string& path) -> std::filesystem::path {
    if (path.empty()) return {};
    const std::filesystem::path p(path);
    return p.is_absolute() ? p : folder / p;
  };
  RunConfig config;
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, file.string(), &problems);

  std::string map;
  root.Required("map", &map);
  config.map = resolve(map);
  root.Optional("mapping", &config.mapping);
  std::string localizer;
  root.Optional("localizer", &localizer);

  core::YamlMap camera = root.OptionalMap("camera");
  // The ranges are the options' Check()s, run per section so that a complaint names its key
  // and line.
  camera.Optional("source", &config.camera_source);
  camera.Optional("width_px", &config.camera.width_px);
  camera.Optional("height_px", &config.camera.height_px);
  camera.Optional("mm_per_px", &config.camera.mm_per_px);
  camera.CheckOwnKeys(config, {{"camera_source", "source"}});
  ReadPose(&camera, "vehicle_from_camera", &config.camera.vehicle_from_camera);
  core::YamlMap v4l2 = camera.OptionalMap("v4l2");
  v4l2.Optional("device", &config.v4l2.device);
  v4l2.Optional("pixel_format", &config.v4l2.pixel_format);
  v4l2.Optional("frame_rate_hz", &config.v4l2.frame_rate_hz);
  v4l2.Optional("exposure_us", &config.v4l2.exposure_us);
  v4l2.Optional("gain", &config.v4l2.gain);
  v4l2.Optional("buffers", &config.v4l2.buffers);
  v4l2.CheckOwnKeys(config.v4l2);
  v4l2.Finish();
  core::YamlMap recording = camera.OptionalMap("dataset");
  std::string dataset;
  recording.Optional("path", &dataset);
  config.dataset = resolve(dataset);
  recording.Optional("start_unix_s", &config.dataset_start_unix_s);
  recording.CheckOwnKeys(config, {{"dataset_start_unix_s", "start_unix_s"}});
  recording.Finish();
  core::YamlMap simulator = camera.OptionalMap("simulator");
  std::string simulator_config;
  simulator.Optional("config", &simulator_config);
  config.simulator_config = resolve(simulator_config);
  simulator.Optional("start_unix_s", &config.dataset_start_unix_s);
  simulator.CheckOwnKeys(config, {{"dataset_start_unix_s", "start_unix_s"}});
  simulator.Finish();
  std::string ground;
  camera.Optional("ground", &ground);
  camera.Finish();
  if (config.camera_source == "dataset" && config.dataset.empty()) {
    camera.AddProblem("dataset", "source: dataset needs dataset.path, the recording to play");
  }
  config.v4l2.width_px = config.camera.width_px;
  config.v4l2.height_px = config.camera.height_px;
  if (!ground.empty()) {
    config.ground = resolve(ground);
    if (config.camera_source == "simulator") {
      camera.AddProblem("ground", "the simulator renders ideal images; a ground calibration is for a real camera");
    } else {
      config.ground_calibration = calibration::ReadGroundCalibration(config.ground);
      const camera::IdealCameraOptions& ideal = config.ground_calibration->ideal;
      if (config.camera_source == "v4l2" &&
          (ideal.width_px != config.camera.width_px || ideal.height_px != config.camera.height_px ||
           std::abs(ideal.mm_per_px - config.camera.mm_per_px) > 1e-9)) {
        camera.AddProblem("ground", fmt::format("{} makes {}x{} ideal images at {} mm/px, but camera.width_px, "
                                                "height_px and mm_per_px say {}x{} at {} mm/px",
                                                config.ground.string(), ideal.width_px, ideal.height_px,
                                                ideal.mm_per_px, config.camera.width_px, config.camera.height_px,
                                                config.camera.mm_per_px));
      }
      // The device delivers the raw image the calibration was made with.
      config.v4l2.width_px = config.ground_calibration->intrinsics.width_px;
      config.v4l2.height_px = config.ground_calibration->intrinsics.height_px;
    }
  }

  core::YamlMap vehicle = root.OptionalMap("vehicle");
  core::ReadWheelGeometry(vehicle, &config.vehicle, /*required=*/false);
  vehicle.Finish();

  core::YamlMap plc = root.OptionalMap("plc");
  io::PlcLinkOptions& link = config.plc;
  plc.Optional("role", &link.role);
  plc.Optional("transport", &link.transport);
  plc.Optional("host", &link.host);
  plc.Optional("port", &link.port);
  plc.Optional("device", &link.device);
  plc.Optional("baud", &link.baud);
  plc.Optional("parity", &link.parity);
  plc.Optional("data_bits", &link.data_bits);
  plc.Optional("stop_bits", &link.stop_bits);
  plc.Optional("unit_id", &link.unit_id);
  plc.Optional("response_timeout_ms", &link.response_timeout_ms);
  plc.Optional("reconnect_min_ms", &link.reconnect_min_ms);
  plc.Optional("reconnect_max_ms", &link.reconnect_max_ms);
  plc.Optional("cycle_ms", &config.plc_cycle_ms);
  plc.Optional("fix_period_ms", &config.fix_period_ms);
  plc.Optional("heartbeat_timeout_ms", &config.heartbeat_timeout_ms);
  plc.Optional("encoder_latency_ms", &config.encoder_latency_ms);
  plc.Optional("encoder_timing_sigma_ms", &config.encoder_timing_sigma_ms);
  plc.Optional("stationary_after_ms", &config.stationary_after_ms);
  plc.Optional("counter_period_ms", &config.counter_period_ms);
  plc.Optional("odometry_bridge_ms", &config.odometry_bridge_ms);
  plc.Optional("lock_age_ms", &config.lock_age_ms);
  plc.Optional("thread_priority", &config.plc_thread_priority);
  plc.CheckOwnKeys(config, {{"plc_cycle_ms", "cycle_ms"}, {"plc_thread_priority", "thread_priority"}});
  core::YamlMap registers = plc.OptionalMap("registers");
  link.registers.kind = config.vehicle.kind;  // the counters of the vehicle configured
  const bool registers_ok = ReadRegisters(&plc, &registers, &link.registers);
  // The link's ranges are its Check()'s; the register map reports its own problems above.
  if (registers_ok) plc.Check(link);
  plc.Finish();
  core::YamlMap start = root.OptionalMap("start");
  double x = 0.0, y = 0.0, yaw_deg = 0.0;
  start.Optional("x_mm", &x, InRange(-1e9, 1e9));
  start.Optional("y_mm", &y, InRange(-1e9, 1e9));
  start.Optional("yaw_deg", &yaw_deg, InRange(-360.0, 360.0));
  start.Optional("sigma_mm", &config.start_sigma_mm);
  start.Optional("sigma_deg", &config.start_sigma_deg);
  start.Optional("unknown", &config.start_unknown);
  start.CheckOwnKeys(config, {{"start_sigma_mm", "sigma_mm"}, {"start_sigma_deg", "sigma_deg"}, {"start_unknown", "unknown"}});
  start.Finish();
  config.start = core::Pose2(x, y, yaw_deg * std::numbers::pi / 180.0);

  core::YamlMap console = root.OptionalMap("console");
  bool console_enabled = false;
  console::ConsoleOptions console_options;
  console.Optional("enabled", &console_enabled);
  console.Optional("listen", &console_options.listen);
  console.Optional("allow_remote", &console_options.allow_remote);
  std::string token_file;
  console.Optional("token_file", &token_file);
  if (!token_file.empty()) {
    try {
      console_options.token = console::ReadTokenFile(resolve(token_file));
    } catch (const core::Error& error) {
      console.AddProblem("token_file", error.what());
    }
  }
  console.Check(console_options);
  if (console_enabled) config.console = console_options;
  console.Finish();

  root.Optional("max_encoder_wait_ms", &config.max_encoder_wait_ms);
  root.CheckOwnKeys(config);
  root.Finish();
  problems.ThrowIfAny();

  if (!localizer.empty()) config.localizer = LoadLocalizerConfig(resolve(localizer));
  return config;
}

}  // namespace mosaicloc::runtime
