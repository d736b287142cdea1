#include "mosaicloc/runtime/registration_bench.hpp"

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::runtime {
namespace {

// Pairs from a camera up to 3 % higher or lower and tilted by up to a degree: the tracker that
// estimates the scale and the tilt registers every one, to a few hundredths of a pixel at the
// image centre; the default one (scale only, four templates) does not hold that accuracy.
TEST(RegistrationBench, PinholePairsAreRegisteredWithTheTiltEstimated) {
  const auto texture = test::SharedTexture("asphalt_02_2048.jpg");
  if (!texture) GTEST_SKIP() << test::SharedDataMissingMessage();
  RegistrationBenchOptions options;
  options.textures = {*texture};
  options.pairs = 4;
  options.max_scale_change = 0.03;
  options.max_tilt_deg = 1.0;
  options.methods = {"ours", "ours-tilt"};
  const std::vector<RegistrationBenchRow> rows = RunRegistrationBench(options);
  ASSERT_EQ(rows.size(), 2u);
  const RegistrationBenchRow& plain = rows[0];
  const RegistrationBenchRow& tilt = rows[1];
  EXPECT_EQ(tilt.pairs, 4u);
  EXPECT_EQ(tilt.failure_rate, 0.0);
  EXPECT_LT(tilt.rms_px, 0.05);
  EXPECT_LT(tilt.rms_deg, 0.03);
  EXPECT_TRUE(plain.failure_rate > 0.0 || plain.rms_px > 2.0 * tilt.rms_px);
}

TEST(RegistrationBench, BadOptionsAreRefused) {
  RegistrationBenchOptions options;
  options.textures = {"floor.png"};
  options.max_tilt_deg = 20.0;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("tilts up to 10 deg"), std::string::npos);
  EXPECT_THROW(RunRegistrationBench(options), core::Error);
}

}  // namespace
}  // namespace mosaicloc::runtime
