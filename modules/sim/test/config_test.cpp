#include "mosaicloc/sim/config.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::sim {
namespace {

using ::testing::HasSubstr;

// The shipped example must state exactly the compiled defaults, so the documentation of
// every key cannot drift from the code.
TEST(SimulatorConfig, DefaultFileEqualsCompiledDefaults) {
  const SimulatorOptions loaded = LoadSimulatorConfig(std::string(MOSAICLOC_CONFIG_DIR) + "/default/simulator.yaml");
  const SimulatorOptions defaults;
  EXPECT_EQ(loaded.floor.kind, defaults.floor.kind);
  EXPECT_EQ(loaded.floor.seed, defaults.floor.seed);
  EXPECT_EQ(loaded.floor.image, defaults.floor.image);
  EXPECT_EQ(loaded.floor.mm_per_texel, defaults.floor.mm_per_texel);
  EXPECT_EQ(loaded.route.name, defaults.route.name);
  EXPECT_EQ(loaded.route.straight_length_m, defaults.route.straight_length_m);
  EXPECT_EQ(loaded.route.loop_width_m, defaults.route.loop_width_m);
  EXPECT_EQ(loaded.route.loop_height_m, defaults.route.loop_height_m);
  EXPECT_EQ(loaded.route.corner_radius_m, defaults.route.corner_radius_m);
  EXPECT_EQ(loaded.route.network_scale, defaults.route.network_scale);
  EXPECT_EQ(loaded.route.serpentine_rows, defaults.route.serpentine_rows);
  EXPECT_EQ(loaded.route.serpentine_length_m, defaults.route.serpentine_length_m);
  EXPECT_EQ(loaded.route.serpentine_spacing_m, defaults.route.serpentine_spacing_m);
  EXPECT_EQ(loaded.route.speed_mps, defaults.route.speed_mps);
  EXPECT_EQ(loaded.route.max_accel_mps2, defaults.route.max_accel_mps2);
  EXPECT_EQ(loaded.route.max_lateral_accel_mps2, defaults.route.max_lateral_accel_mps2);
  EXPECT_EQ(loaded.route.stop_s, defaults.route.stop_s);
  EXPECT_EQ(loaded.route.lateral_deviation_mm, defaults.route.lateral_deviation_mm);
  EXPECT_EQ(loaded.camera.width_px, defaults.camera.width_px);
  EXPECT_EQ(loaded.camera.height_px, defaults.camera.height_px);
  EXPECT_EQ(loaded.camera.mm_per_px, defaults.camera.mm_per_px);
  EXPECT_EQ(loaded.frame_rate_hz, defaults.frame_rate_hz);
  EXPECT_EQ(loaded.timestamp_jitter_ms, defaults.timestamp_jitter_ms);
  EXPECT_EQ(loaded.drop_probability, defaults.drop_probability);
  EXPECT_EQ(loaded.vehicle_from_camera.x_mm(), defaults.vehicle_from_camera.x_mm());
  EXPECT_EQ(loaded.vehicle_from_camera.y_mm(), defaults.vehicle_from_camera.y_mm());
  EXPECT_EQ(loaded.vehicle_from_camera.yaw_rad(), defaults.vehicle_from_camera.yaw_rad());
  EXPECT_EQ(loaded.imaging.exposure_us, defaults.imaging.exposure_us);
  EXPECT_EQ(loaded.imaging.noise_std_dn, defaults.imaging.noise_std_dn);
  EXPECT_EQ(loaded.imaging.vignetting, defaults.imaging.vignetting);
  EXPECT_EQ(loaded.imaging.illumination_amplitude, defaults.imaging.illumination_amplitude);
  EXPECT_EQ(loaded.imaging.illumination_period_s, defaults.imaging.illumination_period_s);
  EXPECT_EQ(loaded.imaging.dust_fraction, defaults.imaging.dust_fraction);
  EXPECT_EQ(loaded.encoders.nominal.left_wheel_radius_mm, defaults.encoders.nominal.left_wheel_radius_mm);
  EXPECT_EQ(loaded.encoders.nominal.right_wheel_radius_mm, defaults.encoders.nominal.right_wheel_radius_mm);
  EXPECT_EQ(loaded.encoders.nominal.track_width_mm, defaults.encoders.nominal.track_width_mm);
  EXPECT_EQ(loaded.encoders.nominal.ticks_per_revolution, defaults.encoders.nominal.ticks_per_revolution);
  EXPECT_EQ(loaded.encoders.rate_hz, defaults.encoders.rate_hz);
  EXPECT_EQ(loaded.encoders.left_radius_error, defaults.encoders.left_radius_error);
  EXPECT_EQ(loaded.encoders.right_radius_error, defaults.encoders.right_radius_error);
  EXPECT_EQ(loaded.encoders.track_width_error, defaults.encoders.track_width_error);
  EXPECT_EQ(loaded.encoders.slip_std, defaults.encoders.slip_std);
  EXPECT_EQ(loaded.encoders.initial_left_ticks, defaults.encoders.initial_left_ticks);
  EXPECT_EQ(loaded.encoders.initial_right_ticks, defaults.encoders.initial_right_ticks);
  EXPECT_EQ(loaded.camera_height_mm, defaults.camera_height_mm);
  EXPECT_EQ(loaded.height_offset_mm, defaults.height_offset_mm);
  EXPECT_EQ(loaded.relief.depth_mm, defaults.relief.depth_mm);
  EXPECT_EQ(loaded.relief.source, defaults.relief.source);
  EXPECT_EQ(loaded.relief.height_image, defaults.relief.height_image);
  EXPECT_EQ(loaded.relief.low_fraction, defaults.relief.low_fraction);
  EXPECT_EQ(loaded.relief.slope_fraction, defaults.relief.slope_fraction);
  EXPECT_EQ(loaded.relief.smoothing_mm, defaults.relief.smoothing_mm);
  EXPECT_EQ(loaded.light.sources, defaults.light.sources);
  EXPECT_EQ(loaded.light.ring_radius_mm, defaults.light.ring_radius_mm);
  EXPECT_EQ(loaded.light.height_over_lens_mm, defaults.light.height_over_lens_mm);
  EXPECT_EQ(loaded.light.ambient, defaults.light.ambient);
  EXPECT_EQ(loaded.light.ring_gain, defaults.light.ring_gain);
  EXPECT_EQ(loaded.seed, defaults.seed);
  EXPECT_EQ(loaded.frames, defaults.frames);
  EXPECT_EQ(loaded.laps, defaults.laps);
  EXPECT_EQ(loaded.threads, defaults.threads);
}

TEST(SimulatorConfig, TypoIsRejectedWithFileLineAndSuggestion) {
  SimulatorOptions options;
  const YAML::Node node = YAML::Load("route:\n  name: loop\n  sped_mps: 2.0\nimaging:\n  noise_std_dn: -1\n");
  try {
    ReadSimulatorConfig(node, "site.yaml", &options);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_EQ(e.kind(), core::ErrorKind::kInvalidInput);
    EXPECT_THAT(e.what(), HasSubstr("site.yaml:3: route.sped_mps: unknown key (did you mean 'speed_mps'?)"));
    EXPECT_THAT(e.what(), HasSubstr("site.yaml:5: imaging.noise_std_dn: must be in [0, 64]"));
  }
}

TEST(SimulatorConfig, FloorComplaintsNameTheirLines) {
  SimulatorOptions options;
  const YAML::Node node = YAML::Load("floor:\n  kind: carpet\n  mm_per_texel: -2\n");
  try {
    ReadSimulatorConfig(node, "site.yaml", &options);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("site.yaml:2: floor.kind: must be procedural or image, got 'carpet'"));
  }
  options = SimulatorOptions{};
  try {
    ReadSimulatorConfig(YAML::Load("floor:\n  kind: image\n"), "site.yaml", &options);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("site.yaml:1: floor: image must name an image file when kind is image"));
  }
}

TEST(FloorChoiceTest, ACommandLineNamesProceduralOrAnImage) {
  FloorChoice base;
  base.seed = 7;
  base.mm_per_texel = 0.5;
  const FloorChoice image = FloorChoice::Named("/data/brick.png", base);
  EXPECT_EQ(image.kind, "image");
  EXPECT_EQ(image.image, "/data/brick.png");
  EXPECT_EQ(image.seed, 7U);
  EXPECT_EQ(image.mm_per_texel, 0.5);
  const FloorChoice procedural = FloorChoice::Named("procedural", image);
  EXPECT_EQ(procedural.kind, "procedural");
  EXPECT_TRUE(procedural.image.empty());
  std::string why;
  EXPECT_TRUE(procedural.Check(&why)) << why;
}

TEST(SimulatorConfig, OverridesApply) {
  SimulatorOptions options;
  ReadSimulatorConfig(YAML::Load("route: {name: network, speed_mps: 2.5}\nrun: {laps: 3}\n"), "x.yaml", &options);
  EXPECT_EQ(options.route.name, "network");
  EXPECT_DOUBLE_EQ(options.route.speed_mps, 2.5);
  EXPECT_EQ(options.laps, 3);
  EXPECT_EQ(options.frames, 900);
}

// A command line's overrides replace what they name and keep the rest of the file; a frame
// count replaces the file's laps.
TEST(SimulatorConfig, CommandLineOverridesKeepTheRestOfTheFile) {
  test::ScratchDir dir;
  test::WriteFile(dir / "simulator.yaml",
                  "floor:\n  seed: 4\n  unevenness_mm: 1.5\nroute:\n  name: serpentine\n  speed_mps: 0.3\n"
                  "camera:\n  drop_probability: 0.02\nrun:\n  laps: 3\n  seed: 9\n");
  const SimulatorOptions unchanged = SimulatorOptionsFor(dir / "simulator.yaml", {});
  EXPECT_EQ(unchanged.route.name, "serpentine");
  EXPECT_DOUBLE_EQ(unchanged.route.speed_mps, 0.3);
  EXPECT_EQ(unchanged.laps, 3);
  EXPECT_EQ(unchanged.seed, 9U);

  SimulatorOverrides overrides;
  overrides.floor = "/data/asphalt.jpg";
  overrides.floor_mm_per_texel = 0.5;
  overrides.route = "network";
  overrides.frames = 1234;
  overrides.speed_mps = 2.0;
  overrides.seed = 11;
  overrides.threads = 3;
  const SimulatorOptions options = SimulatorOptionsFor(dir / "simulator.yaml", overrides);
  EXPECT_EQ(options.floor.kind, "image");
  EXPECT_EQ(options.floor.image, "/data/asphalt.jpg");
  EXPECT_EQ(options.floor.seed, 4U);
  EXPECT_DOUBLE_EQ(options.floor.unevenness_mm, 1.5);
  EXPECT_DOUBLE_EQ(options.floor.mm_per_texel, 0.5);
  EXPECT_EQ(options.route.name, "network");
  EXPECT_DOUBLE_EQ(options.route.speed_mps, 2.0);
  EXPECT_EQ(options.frames, 1234);
  EXPECT_EQ(options.laps, 0);
  EXPECT_EQ(options.seed, 11U);
  EXPECT_EQ(options.threads, 3);
  EXPECT_DOUBLE_EQ(options.drop_probability, 0.02);

  SimulatorOverrides laps;
  laps.laps = 2;
  laps.floor_seed = 8;
  const SimulatorOptions by_laps = SimulatorOptionsFor({}, laps);
  EXPECT_EQ(by_laps.laps, 2);
  EXPECT_EQ(by_laps.floor.seed, 8U);
  EXPECT_EQ(by_laps.floor.kind, SimulatorOptions{}.floor.kind);

  test::WriteFile(dir / "bad.yaml", "route:\n  speed_mps: fast\n");
  try {
    SimulatorOptionsFor(dir / "bad.yaml", overrides);
    FAIL() << "a configuration that cannot be read was accepted";
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("bad.yaml"));
    EXPECT_THAT(e.what(), HasSubstr("speed_mps"));
  }
}

TEST(SimulatorConfig, ReliefAndLightAreReadAndChecked) {
  SimulatorOptions options;
  ReadSimulatorConfig(YAML::Load("relief: {depth_mm: 2.5, smoothing_mm: 0.5}\nlight: {sources: 6, ring_gain: 0.85}\n"),
                      "x.yaml", &options);
  EXPECT_DOUBLE_EQ(options.relief.depth_mm, 2.5);
  EXPECT_DOUBLE_EQ(options.relief.smoothing_mm, 0.5);
  EXPECT_EQ(options.light.sources, 6);
  EXPECT_DOUBLE_EQ(options.light.ring_gain, 0.85);
  const auto complaint = [](const std::string& text) {
    SimulatorOptions ignored;
    try {
      ReadSimulatorConfig(YAML::Load(text), "x.yaml", &ignored);
    } catch (const core::Error& error) {
      return std::string(error.what());
    }
    return std::string();
  };
  EXPECT_NE(complaint("relief:\n  depth_mm: 30\n").find("x.yaml:2"), std::string::npos);
  EXPECT_NE(complaint("relief: {depth_mm: 1, source: image}\n").find("height_image"), std::string::npos);
  EXPECT_NE(complaint("light:\n  sources: 1\n  height_over_lens_mm: -250\n").find("below the floor"), std::string::npos);
}

}  // namespace
}  // namespace mosaicloc::sim
