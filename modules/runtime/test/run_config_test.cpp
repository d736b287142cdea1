#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"
#include "mosaicloc/runtime/run_config.hpp"

namespace mosaicloc::runtime {
namespace {

void ExpectSameField(const io::RegisterField& a, const io::RegisterField& b) {
  EXPECT_EQ(a.address, b.address) << a.name;
  EXPECT_EQ(a.width_bits, b.width_bits) << a.name;
  EXPECT_EQ(a.is_signed, b.is_signed) << a.name;
  EXPECT_EQ(a.scale, b.scale) << a.name;
  EXPECT_EQ(a.word_order, b.word_order) << a.name;
}

// The documented defaults are the compiled ones: a reader can trust the example file.
TEST(RunConfig, DefaultFileEqualsCompiledDefaults) {
  const std::filesystem::path file = std::string(MOSAICLOC_CONFIG_DIR) + "/default/run.yaml";
  const RunConfig loaded = LoadRunConfig(file);
  const RunConfig compiled;
  EXPECT_EQ(loaded.map, file.parent_path() / "site.mosaic");
  EXPECT_EQ(loaded.camera_source, compiled.camera_source);
  EXPECT_EQ(loaded.camera.width_px, compiled.camera.width_px);
  EXPECT_EQ(loaded.camera.height_px, compiled.camera.height_px);
  EXPECT_EQ(loaded.camera.mm_per_px, compiled.camera.mm_per_px);
  EXPECT_EQ(loaded.camera.vehicle_from_camera.x_mm(), 200.0);
  EXPECT_EQ(loaded.v4l2.device, compiled.v4l2.device);
  EXPECT_EQ(loaded.v4l2.pixel_format, compiled.v4l2.pixel_format);
  EXPECT_EQ(loaded.v4l2.frame_rate_hz, compiled.v4l2.frame_rate_hz);
  EXPECT_EQ(loaded.v4l2.exposure_us, compiled.v4l2.exposure_us);
  EXPECT_EQ(loaded.v4l2.gain, compiled.v4l2.gain);
  EXPECT_EQ(loaded.v4l2.buffers, compiled.v4l2.buffers);
  EXPECT_EQ(loaded.dataset_start_unix_s, compiled.dataset_start_unix_s);
  EXPECT_EQ(loaded.vehicle.left_wheel_radius_mm, compiled.vehicle.left_wheel_radius_mm);
  EXPECT_EQ(loaded.vehicle.right_wheel_radius_mm, compiled.vehicle.right_wheel_radius_mm);
  EXPECT_EQ(loaded.vehicle.track_width_mm, compiled.vehicle.track_width_mm);
  EXPECT_EQ(loaded.vehicle.ticks_per_revolution, compiled.vehicle.ticks_per_revolution);
  const io::PlcLinkOptions& a = loaded.plc;
  const io::PlcLinkOptions& b = compiled.plc;
  EXPECT_EQ(a.role, b.role);
  EXPECT_EQ(a.transport, b.transport);
  EXPECT_EQ(a.host, b.host);
  EXPECT_EQ(a.port, b.port);
  EXPECT_EQ(a.device, b.device);
  EXPECT_EQ(a.baud, b.baud);
  EXPECT_EQ(a.parity, b.parity);
  EXPECT_EQ(a.data_bits, b.data_bits);
  EXPECT_EQ(a.stop_bits, b.stop_bits);
  EXPECT_EQ(a.unit_id, b.unit_id);
  EXPECT_EQ(a.response_timeout_ms, b.response_timeout_ms);
  EXPECT_EQ(a.reconnect_min_ms, b.reconnect_min_ms);
  EXPECT_EQ(a.reconnect_max_ms, b.reconnect_max_ms);
  EXPECT_EQ(loaded.plc_cycle_ms, compiled.plc_cycle_ms);
  EXPECT_EQ(loaded.fix_period_ms, compiled.fix_period_ms);
  EXPECT_EQ(loaded.heartbeat_timeout_ms, compiled.heartbeat_timeout_ms);
  EXPECT_EQ(loaded.counter_period_ms, compiled.counter_period_ms);
  EXPECT_EQ(loaded.stationary_after_ms, compiled.stationary_after_ms);
  EXPECT_EQ(loaded.encoder_latency_ms, compiled.encoder_latency_ms);
  EXPECT_EQ(loaded.encoder_timing_sigma_ms, compiled.encoder_timing_sigma_ms);
  const io::RegisterMap& r = a.registers;
  const io::RegisterMap& s = b.registers;
  ExpectSameField(r.left_ticks, s.left_ticks);
  ExpectSameField(r.right_ticks, s.right_ticks);
  ExpectSameField(r.plc_heartbeat, s.plc_heartbeat);
  ExpectSameField(r.fix_request, s.fix_request);
  ExpectSameField(r.relocalize_request, s.relocalize_request);
  ExpectSameField(r.fix_x, s.fix_x);
  ExpectSameField(r.fix_y, s.fix_y);
  ExpectSameField(r.fix_yaw, s.fix_yaw);
  ExpectSameField(r.fix_status, s.fix_status);
  ExpectSameField(r.fix_quality, s.fix_quality);
  ExpectSameField(r.fix_request_echo, s.fix_request_echo);
  ExpectSameField(r.heartbeat, s.heartbeat);
  EXPECT_EQ(loaded.start.x_mm(), 0.0);
  EXPECT_EQ(loaded.start_sigma_mm, compiled.start_sigma_mm);
  EXPECT_EQ(loaded.start_sigma_deg, compiled.start_sigma_deg);
  EXPECT_EQ(loaded.max_encoder_wait_ms, compiled.max_encoder_wait_ms);
}

std::string ErrorOf(const std::string& yaml) {
  test::ScratchDir scratch;
  test::WriteFile(scratch / "run.yaml", yaml);
  try {
    LoadRunConfig(scratch / "run.yaml");
  } catch (const core::Error& e) {
    EXPECT_EQ(e.kind(), core::ErrorKind::kInvalidInput);
    const std::string message = e.what();
    const std::string prefix = (scratch / "run.yaml").string();
    EXPECT_NE(message.find(prefix), std::string::npos) << message;
    return message;
  }
  ADD_FAILURE() << "no error for:\n" << yaml;
  return {};
}

TEST(RunConfig, ProblemsNameFileLineAndKey) {
  EXPECT_NE(ErrorOf("camera: {source: v4l2}\n").find("map"), std::string::npos);
  const std::string typo = ErrorOf("map: a.mosaic\nplc:\n  prot: 502\n");
  EXPECT_NE(typo.find(":3"), std::string::npos) << typo;
  EXPECT_NE(typo.find("prot"), std::string::npos) << typo;
  const std::string overlap =
      ErrorOf("map: a.mosaic\nplc:\n  registers:\n    fix_y: {address: 101}\n");
  EXPECT_NE(overlap.find("fix_x (registers 100-101) overlaps fix_y (registers 101-102)"), std::string::npos) << overlap;
  const std::string order = ErrorOf("map: a.mosaic\nplc:\n  registers:\n    fix_x: {word_order: middle}\n");
  EXPECT_NE(order.find("word_order"), std::string::npos) << order;
  const std::string source = ErrorOf("map: a.mosaic\ncamera: {source: dataset}\n");
  EXPECT_NE(source.find("needs dataset.path"), std::string::npos) << source;
}

// The ranges are RunConfig::Check()'s (and the V4L2 options'); a complaint lands on the
// line of the key the file calls the field by.
TEST(RunConfig, RangesAreTheOptionsChecksAtTheirLines) {
  const std::pair<const char*, const char*> cases[] = {
      {"map: a.mosaic\ncamera:\n  source: usb\n", ":3: camera.source: must be v4l2, dataset or simulator, got 'usb'"},
      {"map: a.mosaic\ncamera:\n  width_px: 8\n", ":3: camera.width_px: must be in [16, 16384]"},
      {"map: a.mosaic\ncamera:\n  dataset: {path: d, start_unix_s: -5}\n",
       ":3: camera.dataset.start_unix_s: must be in [0, 1e11]"},
      {"map: a.mosaic\ncamera:\n  v4l2:\n    gain: -7\n", ":4: camera.v4l2.gain: must be in [-1, 1048576]"},
      {"map: a.mosaic\nplc:\n  role: client\n  cycle_ms: 0\n", ":4: plc.cycle_ms: must be in [1, 10000]"},
      {"map: a.mosaic\nplc:\n  thread_priority: 100\n", ":3: plc.thread_priority: must be in [0, 99]"},
      {"map: a.mosaic\nstart:\n  sigma_deg: 500\n", ":3: start.sigma_deg: must be in [0.0001, 180]"},
      {"map: a.mosaic\nmax_encoder_wait_ms: -1\n", ":2: max_encoder_wait_ms: must be in [0, 10000]"},
      {"map: a.mosaic\nconsole:\n  enabled: true\n  listen: 0.0.0.0:8080\n", ":4: console.listen: 0.0.0.0:8080 is not a loopback"},
      {"map: a.mosaic\nconsole:\n  listen: 127.0.0.1:99999\n", ":3: console.listen: '127.0.0.1:99999': the port"},
      {"map: a.mosaic\nconsole:\n  allow_remote: true\n", "console: token of at least 16 characters is needed"},
      {"map: a.mosaic\nconsole:\n  token_file: missing.txt\n", ":3: console.token_file: "},
  };
  for (const auto& [yaml, expected] : cases) {
    const std::string error = ErrorOf(yaml);
    EXPECT_NE(error.find(expected), std::string::npos) << yaml << "\n" << error;
  }
  std::string why;
  EXPECT_TRUE(RunConfig{}.Check(&why)) << why;
}

TEST(RunConfig, TheConsoleIsOffUnlessEnabledAndReadsItsTokenFromAFile) {
  test::ScratchDir scratch;
  test::WriteFile(scratch / "run.yaml", "map: a.mosaic\nconsole:\n  listen: 127.0.0.1:9000\n");
  EXPECT_FALSE(LoadRunConfig(scratch / "run.yaml").console.has_value());
  test::WriteFile(scratch / "token", "  a-token-of-enough-length \nsecond line\n");
  test::WriteFile(scratch / "run.yaml", "map: a.mosaic\nconsole:\n  enabled: true\n  listen: 192.168.4.2:9000\n"
                                        "  allow_remote: true\n  token_file: token\n");
  const RunConfig config = LoadRunConfig(scratch / "run.yaml");
  ASSERT_TRUE(config.console.has_value());
  EXPECT_EQ(config.console->listen, "192.168.4.2:9000");
  EXPECT_EQ(config.console->token, "a-token-of-enough-length");
}

TEST(RunConfig, OneWordOrderForEveryField) {
  test::ScratchDir scratch;
  test::WriteFile(scratch / "run.yaml", "map: a.mosaic\nplc:\n  registers:\n    word_order: low_first\n    fix_y: {word_order: high_first}\n");
  const RunConfig config = LoadRunConfig(scratch / "run.yaml");
  EXPECT_EQ(config.plc.registers.left_ticks.word_order, io::WordOrder::kLowFirst);
  EXPECT_EQ(config.plc.registers.fix_x.word_order, io::WordOrder::kLowFirst);
  EXPECT_EQ(config.plc.registers.fix_y.word_order, io::WordOrder::kHighFirst);
  EXPECT_EQ(config.map, scratch.path() / "a.mosaic");
}

}  // namespace
}  // namespace mosaicloc::runtime
