#include <string>

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/runtime/soak.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::runtime {
namespace {

// The drive keeps the configuration's conditions; what the command names replaces the rest.
TEST(SoakOptions, RequestReplacesTheConfigurationsDrive) {
  test::ScratchDir dir;
  test::WriteFile(dir / "simulator.yaml",
                  "floor:\n  unevenness_mm: 1.5\nroute:\n  name: loop\n  network_scale: 1.0\n  speed_mps: 0.3\n");
  SoakRequest request;
  request.simulator_config = dir / "simulator.yaml";
  request.route = "serpentine";
  request.speed_mps = 2.0;
  request.frames = 1234;
  request.seed = 11;
  request.threads = 3;
  request.map_laps = 2;
  const SoakOptions options = SoakOptionsFor(request);
  EXPECT_DOUBLE_EQ(options.drive.floor.unevenness_mm, 1.5);
  EXPECT_DOUBLE_EQ(options.drive.route.network_scale, 1.0);
  EXPECT_EQ(options.drive.route.name, "serpentine");
  EXPECT_DOUBLE_EQ(options.drive.route.speed_mps, 2.0);
  EXPECT_EQ(options.drive.frames, 1234);
  EXPECT_EQ(options.drive.laps, 0);
  EXPECT_EQ(options.drive.seed, 11u);
  EXPECT_EQ(options.drive.threads, 3);
  EXPECT_EQ(options.map_laps, 2);
  EXPECT_EQ(options.work.parent_path(), std::filesystem::temp_directory_path());
  request.work = dir / "work";
  EXPECT_EQ(SoakOptionsFor(request).work, dir / "work");
}

TEST(SoakOptions, BadConfigurationNamesFileAndKey) {
  test::ScratchDir dir;
  test::WriteFile(dir / "simulator.yaml", "route:\n  speed_mps: fast\n");
  SoakRequest request;
  request.simulator_config = dir / "simulator.yaml";
  try {
    SoakOptionsFor(request);
    FAIL() << "a configuration that cannot be read was accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("simulator.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("speed_mps"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mosaicloc::runtime
